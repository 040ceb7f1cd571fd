// LiveCalibrationNode on the simulated calibration session replayed through a graph: every
// view judged with its rule, coverage and pair views growing, the missing list shrinking,
// repeats rejected as too similar, and the kept instants recorded for the offline solve.
#include "mixray/calibration/live_calibration.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "mixray/graph/mkv.h"
#include "mixray/replay/replay_backend.h"
#include "test_data.h"

namespace mixray::calibration {
namespace {

namespace fs = std::filesystem;

const char* const kTarget = "charuco:7x5:0.05:0.037:DICT_6X6_250";

fs::path session() {
    return test::fixturesDir() / "sessions" / "sim_calibration.mkv";
}

// What the node said about each view, and the session's state right after.
struct Seen {
    LiveDecision decision;
    int cells_covered = 0;
    size_t missing = 0;
};

struct Session {
    std::unique_ptr<Graph> graph = std::make_unique<Graph>();
    LiveCalibrationNode* node = nullptr;
    replay::ReplayDevice* device = nullptr;
    std::mutex mutex;
    std::vector<Seen> seen;

    std::vector<Seen> of(const std::string& camera) {
        std::lock_guard lock(mutex);
        std::vector<Seen> out;
        for (const Seen& s : seen)
            if (s.decision.camera == camera)
                out.push_back(s);
        return out;
    }
};

// The session replayed as fast as the node takes it (lossless: every view judged).
std::unique_ptr<Session> open(bool loop) {
    auto s = std::make_unique<Session>();
    DeviceConfig config;
    config.name = "session";
    config.driver = "replay";
    config.id = session().string();
    config.options = {{"pace", "fast"}, {"names", "recorded"}, {"loop", loop ? "true" : "false"}};
    replay::ReplayBackend backend;
    auto device = backend.open(config);
    EXPECT_TRUE(device) << device.status().toString();
    if (!device)
        return nullptr;
    s->device = static_cast<replay::ReplayDevice*>(device->get());
    EXPECT_TRUE(s->graph->addNode(std::move(device).value()));
    LiveCalibrationOptions o;
    o.target = parseTarget(kTarget).value();
    o.lossless = true;
    // Every stream has a frame at every instant; on cores shared with other work the replay
    // can take longer than the default wait to publish the last frame of one.
    o.group_wait_s = 5;
    Session* raw = s.get();
    auto node = LiveCalibrationNode::create(o, [raw](const LiveDecision& d) {
        const LiveCalibrationStatus status = raw->node->status();
        Seen seen{d, 0, status.missing.size()};
        for (const LiveCameraStatus& c : status.cameras)
            if (c.camera == d.camera)
                seen.cells_covered = c.cells_covered;
        std::lock_guard lock(raw->mutex);
        raw->seen.push_back(std::move(seen));
    });
    EXPECT_TRUE(node) << node.status().toString();
    if (!node)
        return nullptr;
    s->node = node->get();
    const Status added = s->graph->addNode(std::move(node).value());
    EXPECT_TRUE(added) << added.toString();
    return s;
}

const LiveCameraStatus& cameraOf(const LiveCalibrationStatus& s, const std::string& name) {
    for (const LiveCameraStatus& c : s.cameras)
        if (c.camera == name)
            return c;
    ADD_FAILURE() << "no camera " << name;
    static LiveCameraStatus none;
    return none;
}

TEST(LiveCalibration, JudgesEveryViewAndRecordsTheKeptOnes) {
    auto s = open(false);
    ASSERT_TRUE(s);
    EXPECT_EQ(s->node->cameras(),
              (std::vector<std::string>{"kinect/color", "env/color", "kinect/ir"}));
    ASSERT_TRUE(s->graph->start());
    for (int i = 0; i < 1200 && !s->node->finished(); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    ASSERT_TRUE(s->node->finished()) << "the session was not judged within 60 s";
    s->graph->stop();
    const LiveCalibrationStatus status = s->node->status();
    std::printf("%s", status.summary().c_str());

    // Every view of every camera judged once; each decision names its rule.
    const LiveCameraStatus& color = cameraOf(status, "kinect/color");
    const LiveCameraStatus& env = cameraOf(status, "env/color");
    EXPECT_EQ(color.judged, 20u);
    EXPECT_EQ(env.judged, 20u);
    EXPECT_EQ(status.instants, 20u);
    for (const Seen& seen : s->of("env/color"))
        EXPECT_FALSE(seen.decision.reason.empty());
    // The colour camera sees the whole board in every pose; poses held over the fish-eye look
    // alike from the Kinect, so some are too similar to one kept before (the default 16 px).
    // The fish-eye sees the board only where it is held over it: its other views are "no
    // target" or too few corners.
    for (const Seen& seen : s->of("kinect/color"))
        std::printf("kinect/color @%llu: %s\n",
                    static_cast<unsigned long long>(seen.decision.sequence),
                    seen.decision.reason.c_str());
    EXPECT_GE(color.kept, 15u);
    EXPECT_EQ(color.kept + color.rejected_by.at("too similar"), 20u);
    EXPECT_GE(env.kept, 3u);
    EXPECT_LE(env.kept, 10u);
    EXPECT_EQ(env.kept + env.rejected, 20u);
    EXPECT_GT(env.rejected_by.count("no target") ? env.rejected_by.at("no target") : 0, 0u)
        << "env/color rejections by rule: " << status.json();

    // Coverage only grows, and grows; what is missing shrinks.
    const std::vector<Seen> colour_seen = s->of("kinect/color");
    ASSERT_EQ(colour_seen.size(), 20u);
    for (size_t i = 1; i < colour_seen.size(); ++i)
        EXPECT_GE(colour_seen[i].cells_covered, colour_seen[i - 1].cells_covered);
    EXPECT_GT(colour_seen.back().cells_covered, colour_seen.front().cells_covered);
    EXPECT_GT(color.cells_covered, color.cells_total / 2);
    EXPECT_LT(s->seen.back().missing, s->seen.front().missing);
    EXPECT_FALSE(color.tilts.empty());

    // Pair views: the Kinect's two cameras in every pose, colour and fish-eye in some.
    for (const LivePairStatus& p : status.pairs) {
        if (p.a == "kinect/color" && p.b == "kinect/ir") {
            EXPECT_GE(p.views, 15);
        }
        if (p.a == "kinect/color" && p.b == "env/color") {
            EXPECT_GE(p.views, 3);
        }
    }
    for (const std::string& line : status.missing)
        EXPECT_EQ(line.find("views seen by both"), std::string::npos) << line;

    // A coverage map per camera, and an overlay of the last detection.
    const auto coverage = s->graph->findStream("coverage/kinect/color");
    ASSERT_TRUE(coverage);
    EXPECT_GE(s->graph->publishedCount(*coverage), 20u);
    const auto overlay = nlohmann::json::parse(s->node->overlay("kinect/color"));
    EXPECT_FALSE(overlay["circles"].empty());
    EXPECT_TRUE(overlay.contains("polygons"));
    const auto figures = nlohmann::json::parse(status.json());
    EXPECT_TRUE(figures["messages"].is_array());
    EXPECT_EQ(figures["calibration"]["cameras"].size(), 3u);

    // The recording holds the kept instants; detection offline finds the same usable views.
    const fs::path out =
        test::binaryDir() / "test-tmp" / ("live_calibration-" + std::to_string(getpid()) + ".mkv");
    fs::create_directories(out.parent_path());
    const Status written = s->node->writeRecording(out);
    ASSERT_TRUE(written) << written.toString();
    auto found = detectInRecording(out, parseTarget(kTarget).value());
    ASSERT_TRUE(found) << found.status().toString();
    size_t colour_views = 0;
    for (const CameraViews& c : found->cameras)
        if (c.camera == "kinect/color")
            colour_views = c.usable().size();
    EXPECT_EQ(colour_views, color.kept);
    ASSERT_EQ(found->depth.size(), 1u);
    EXPECT_EQ(found->depth[0].stream, "kinect/depth");
    fs::remove(out);
}

TEST(LiveCalibration, RepeatedPosesAreRejectedAsTooSimilar) {
    auto s = open(true);
    ASSERT_TRUE(s);
    ASSERT_TRUE(s->graph->start());
    for (int i = 0; i < 1200 && s->of("kinect/color").size() < 40; ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    s->graph->stop();
    const std::vector<Seen> colour = s->of("kinect/color");
    ASSERT_GE(colour.size(), 40u) << "the second pass was not judged within 60 s";
    size_t kept_first = 0, kept_second = 0, similar_second = 0;
    for (size_t i = 0; i < 40; ++i) {
        (i < 20 ? kept_first : kept_second) += colour[i].decision.kept;
        if (i >= 20 && colour[i].decision.reason.rfind("too similar to kept view ", 0) == 0)
            ++similar_second;
    }
    EXPECT_GE(kept_first, 15u);
    // Every pose again: each is now too similar to the view kept for it the first time.
    EXPECT_EQ(kept_second, 0u);
    EXPECT_EQ(similar_second, 20u) << colour[25].decision.reason;
    EXPECT_GT(cameraOf(s->node->status(), "kinect/color").rejected_by.at("too similar"), 0u);
}

TEST(LiveCalibration, BadOptionsAndAbsentCamerasAreErrors) {
    LiveCalibrationOptions o;
    o.target = parseTarget(kTarget).value();
    o.grid_cols = 1;
    auto bad = LiveCalibrationNode::create(o, {});
    ASSERT_FALSE(bad);
    EXPECT_NE(bad.status().message().find("grid_cols"), std::string::npos);

    o.grid_cols = 8;
    o.cameras = {"kinect/color"};
    auto node = LiveCalibrationNode::create(o, {});
    ASSERT_TRUE(node);
    Graph graph;
    const Status s = graph.addNode(std::move(node).value());
    EXPECT_EQ(s.code(), ErrorCode::kNotFound);
    EXPECT_NE(s.message().find("kinect/color"), std::string::npos) << s.toString();
}

}  // namespace
}  // namespace mixray::calibration
