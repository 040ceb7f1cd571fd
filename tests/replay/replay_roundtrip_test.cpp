// Real TUM and PCL data through Matroska and back, bit-exactly; the replay backend on mkv files.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <thread>

#include "mixray/graph/mkv.h"
#include "mixray/replay/convert.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/pcl_tiff.h"
#include "mixray/replay/replay_backend.h"
#include "mixray/replay/tum.h"
#include "replay_test_util.h"
#include "test_data.h"

namespace mixray::replay {
namespace {

using Clock = std::chrono::steady_clock;
using test::OwnedFrame;
using test::readFile;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// Converts `reader` into a new mkv file and returns its path.
std::filesystem::path toMkv(RecordingReader& reader, const std::filesystem::path& file) {
    auto writer = createMkvWriter(file, headerOf(reader));
    EXPECT_TRUE(writer) << writer.status().toString();
    if (!writer)
        return file;
    uint64_t calls = 0;
    auto summary = convertRecording(reader, **writer, [&](const ConvertProgress& p) {
        EXPECT_EQ(p.frames, ++calls);
        return true;
    });
    EXPECT_TRUE(summary) << summary.status().toString();
    return file;
}

void expectSameHeader(const RecordingReader& a, const RecordingReader& b) {
    ASSERT_EQ(a.streams().size(), b.streams().size());
    for (size_t i = 0; i < a.streams().size(); ++i) {
        const StreamInfo& x = a.streams()[i];
        const StreamInfo& y = b.streams()[i];
        EXPECT_EQ(x.name, y.name);
        EXPECT_EQ(x.device, y.device);
        EXPECT_EQ(x.kind, y.kind);
        EXPECT_EQ(x.format, y.format);
        EXPECT_EQ(x.clock_domain, y.clock_domain);
        EXPECT_NEAR(x.nominal_fps, y.nominal_fps, 1e-6);
        EXPECT_EQ(x.tags, y.tags) << x.name;
    }
    EXPECT_EQ(a.attachments(), b.attachments());
    for (const auto& [key, value] : a.tags()) {
        auto it = b.tags().find(key);
        ASSERT_NE(it, b.tags().end()) << key;
        EXPECT_EQ(it->second, value) << key;
    }
}

// TUM folder -> mkv -> TUM folder: the same frames, metadata, lists and PNG pixel values.
void tumRoundTrip(const std::filesystem::path& tum, const std::filesystem::path& tmp) {
    auto original = openTum(tum);
    ASSERT_TRUE(original) << original.status().toString();
    const auto mkv = toMkv(**original, tmp / "session.mkv");
    ASSERT_TRUE((*original)->seek(0));
    const auto expected = test::readAll(**original);

    auto replayed = openMkv(mkv);
    ASSERT_TRUE(replayed) << replayed.status().toString();
    expectSameHeader(**original, **replayed);
    EXPECT_EQ(*depthScalePerMetre((*replayed)->streams()[1]), kTumDepthPerMetre);
    test::expectSameFrames(expected, test::readAll(**replayed), "tum -> mkv");

    ASSERT_TRUE((*replayed)->seek(0));
    const auto back = tmp / "back";
    auto summary = exportTum(**replayed, back);
    ASSERT_TRUE(summary) << summary.status().toString();
    EXPECT_EQ(summary->frames, expected.size());
    for (const char* list_name : {"rgb.txt", "depth.txt"}) {
        EXPECT_EQ(readFile(back / list_name), readFile(tum / list_name)) << list_name;
        auto list = parseTumList(readFile(tum / list_name), list_name);
        ASSERT_TRUE(list);
        for (const auto& e : list->entries)
            test::expectSamePixels(tum / e.file, back / e.file);
    }
    for (const char* side : {"accelerometer.txt", "groundtruth.txt"}) {
        ASSERT_EQ(std::filesystem::exists(back / side), std::filesystem::exists(tum / side));
        if (std::filesystem::exists(tum / side)) {
            EXPECT_EQ(readFile(back / side), readFile(tum / side));
        }
    }
}

TEST(ReplayRoundTrip, RealTumFramePairThroughMkvIsBitExact) {
    MIXRAY_REQUIRE_SHARED_DATA(test::realTumColor());
    MIXRAY_REQUIRE_SHARED_DATA(test::realTumDepth());
    const auto tmp = test::tempDir();
    ASSERT_TRUE(test::writeRealTum(tmp / "tum"));
    tumRoundTrip(tmp / "tum", tmp);
    // The folder that came back holds the published files' own pixel values.
    test::expectSamePixels(test::realTumColor(), tmp / "back/rgb/1305031102.175304.png");
    test::expectSamePixels(test::realTumDepth(), tmp / "back/depth/1305031102.160407.png");
}

TEST(ReplayRoundTrip, SyntheticTumWithSubMillimetreDepthAndSideFiles) {
    const auto tmp = test::tempDir();
    test::writeSyntheticTum(tmp / "tum", 5);
    tumRoundTrip(tmp / "tum", tmp);
}

TEST(ReplayRoundTrip, RealPclOpenNiFrameThroughMkvIsBitExact) {
    const auto pcl = test::realPclDir();
    const auto depth_file = pcl / "frame_20121214T142255.814212_depth.tiff";
    const auto rgb_file = pcl / "frame_20121214T142255.814212_rgb.tiff";
    MIXRAY_REQUIRE_SHARED_DATA(depth_file);
    MIXRAY_REQUIRE_SHARED_DATA(rgb_file);
    const auto tmp = test::tempDir();
    auto original = openPclTiff(pcl);
    ASSERT_TRUE(original) << original.status().toString();
    const auto mkv = toMkv(**original, tmp / "pcl.mkv");
    ASSERT_TRUE((*original)->seek(0));
    const auto expected = test::readAll(**original);
    ASSERT_EQ(expected.size(), 2u);

    auto replayed = openRecording(mkv);
    ASSERT_TRUE(replayed) << replayed.status().toString();
    expectSameHeader(**original, **replayed);
    test::expectSameFrames(expected, test::readAll(**replayed), "pcl -> mkv");

    ASSERT_TRUE((*replayed)->seek(0));
    auto summary = exportPclTiff(**replayed, tmp / "back");
    ASSERT_TRUE(summary) << summary.status().toString();
    test::expectSamePixels(depth_file, tmp / "back" / depth_file.filename());
    test::expectSamePixels(rgb_file, tmp / "back" / rgb_file.filename());
    const char* xml = "frame_20121214T142255.814212.xml";
    EXPECT_EQ(readFile(tmp / "back" / xml), readFile(pcl / xml));
    // The folder that came back opens like the original.
    auto again = openRecording(tmp / "back");
    ASSERT_TRUE(again) << again.status().toString();
    EXPECT_EQ((*again)->format(), "pcl-tiff");
    test::expectSameFrames(expected, test::readAll(**again), "pcl -> mkv -> pcl");
}

TEST(OpenRecording, DispatchesByContentAndListsWhatItUnderstands) {
    const auto tmp = test::tempDir();
    test::writeSyntheticTum(tmp / "tum", 2);
    auto tum = openRecording(tmp / "tum");
    ASSERT_TRUE(tum) << tum.status().toString();
    EXPECT_EQ((*tum)->format(), "tum");
    toMkv(**tum, tmp / "a.mkv");
    auto mkv = openRecording(tmp / "a.mkv");
    ASSERT_TRUE(mkv) << mkv.status().toString();
    EXPECT_NE((*mkv)->format(), "tum");

    auto missing = openRecording(tmp / "nothing.mkv");
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_TRUE(contains(missing.status().message(), "nothing.mkv"));

    std::filesystem::create_directories(tmp / "empty");
    std::ofstream(tmp / "notes.txt") << "not a recording\n";
    for (const auto& path : {tmp / "empty", tmp / "notes.txt"}) {
        auto r = openRecording(path);
        ASSERT_FALSE(r) << path;
        EXPECT_EQ(r.status().code(), ErrorCode::kUnsupported);
        for (const char* format : {"Matroska", "TUM RGB-D folder", "PCL OpenNI TIFF folder"}) {
            EXPECT_TRUE(contains(r.status().message(), format)) << r.status().message();
        }
    }
}

// A synthetic TUM session as an mkv file, with its frames as read from the folder.
struct MkvSession {
    std::filesystem::path mkv;
    std::vector<OwnedFrame> frames;  // stream 0 colour, 1 depth (raw TUM units)
};

MkvSession makeSession(const std::filesystem::path& tmp, int frames) {
    MkvSession session;
    test::writeSyntheticTum(tmp / "tum", frames);
    auto reader = openTum(tmp / "tum");
    EXPECT_TRUE(reader);
    session.frames = test::readAll(**reader);
    EXPECT_TRUE((*reader)->seek(0));
    session.mkv = toMkv(**reader, tmp / "session.mkv");
    return session;
}

DeviceConfig replayConfig(const std::filesystem::path& mkv,
                          std::map<std::string, std::string> options) {
    DeviceConfig config;
    config.name = "kinect";
    config.driver = "replay";
    config.id = mkv.string();
    config.options = std::move(options);
    return config;
}

// Plays `config` through a graph with a lossless consumer per stream; frames by graph stream.
std::vector<std::vector<OwnedFrame>> play(const DeviceConfig& config, size_t limit = SIZE_MAX,
                                          double* seconds = nullptr,
                                          std::vector<StreamInfo>* streams = nullptr) {
    ReplayBackend backend;
    auto device = backend.open(config);
    EXPECT_TRUE(device) << device.status().toString();
    if (!device)
        return {};
    Graph graph;
    EXPECT_TRUE(graph.addNode(std::move(*device)));
    if (streams)
        *streams = graph.streams();
    std::vector<std::shared_ptr<FrameQueue>> queues;
    for (StreamId id = 0; id < graph.streamCount(); ++id) {
        queues.push_back(*graph.subscribe(id, {4, QueuePolicy::kLossless, "test"}));
    }
    std::vector<std::vector<OwnedFrame>> frames(queues.size());
    const auto t0 = Clock::now();
    EXPECT_TRUE(graph.start());
    std::vector<std::thread> consumers;
    for (size_t i = 0; i < queues.size(); ++i) {
        consumers.emplace_back([&, i] {
            while (frames[i].size() < limit) {
                auto f = queues[i]->pop(std::chrono::seconds(10));
                if (!f)
                    break;
                frames[i].push_back({f->meta(), Image::copyOf(f->image())});
            }
        });
    }
    for (auto& t : consumers)
        t.join();
    if (seconds)
        *seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    graph.stop();
    return frames;
}

TEST(ReplayBackend, FastPaceDeliversEveryFrameBitExactly) {
    const auto tmp = test::tempDir();
    const MkvSession session = makeSession(tmp, 12);
    const auto played =
        play(replayConfig(session.mkv, {{"pace", "fast"}, {"depth_units", "recorded"}}));
    ASSERT_EQ(played.size(), 2u);  // kinect/color, kinect/depth
    size_t next[2] = {0, 0};
    for (const OwnedFrame& expected : session.frames) {
        const uint32_t s = expected.meta.stream;
        ASSERT_LT(next[s], played[s].size());
        const OwnedFrame& got = played[s][next[s]++];
        EXPECT_EQ(got.meta.stream, s);  // graph ids equal the recording's in this graph
        EXPECT_EQ(got.meta.sequence, expected.meta.sequence);
        EXPECT_EQ(got.meta.host_stamp_ns, expected.meta.host_stamp_ns);
        EXPECT_EQ(got.meta.device_stamp_ns, expected.meta.device_stamp_ns);
        EXPECT_EQ(got.meta.clock_domain, expected.meta.clock_domain);
        EXPECT_TRUE(sameImage(got.image.view(), expected.image.view()));
    }
    EXPECT_EQ(next[0], played[0].size());
    EXPECT_EQ(next[1], played[1].size());
}

TEST(ReplayBackend, OriginalPaceTakesAboutTheRecordingsDuration) {
    const auto tmp = test::tempDir();
    const MkvSession session = makeSession(tmp, 10);  // colour spans 9 x 33.333 ms
    const double span_s = static_cast<double>(session.frames.back().meta.host_stamp_ns -
                                              session.frames.front().meta.host_stamp_ns) /
                          1e9;
    double seconds = 0;
    const auto played = play(replayConfig(session.mkv, {}), SIZE_MAX, &seconds);
    ASSERT_EQ(played.size(), 2u);
    EXPECT_EQ(played[0].size() + played[1].size(), session.frames.size());
    EXPECT_GE(seconds, span_s * 0.9);
    EXPECT_LT(seconds, span_s + 1.5);  // loose: shared machines
}

TEST(ReplayBackend, LoopProducesMonotonicTimestamps) {
    const auto tmp = test::tempDir();
    const MkvSession session = makeSession(tmp, 3);
    const auto played = play(replayConfig(session.mkv, {{"pace", "fast"}, {"loop", "true"}}), 10);
    ASSERT_EQ(played.size(), 2u);
    for (const auto& stream : played) {
        ASSERT_EQ(stream.size(), 10u);  // more than three passes
        for (size_t i = 1; i < stream.size(); ++i) {
            EXPECT_GT(stream[i].meta.host_stamp_ns, stream[i - 1].meta.host_stamp_ns) << i;
            EXPECT_GT(stream[i].meta.device_stamp_ns, stream[i - 1].meta.device_stamp_ns) << i;
            EXPECT_GT(stream[i].meta.sequence, stream[i - 1].meta.sequence) << i;
            // Every pass shows the same pictures.
            EXPECT_TRUE(sameImage(stream[i].image.view(), stream[i % 3].image.view())) << i;
        }
    }
}

TEST(ReplayBackend, StartSeeksToTheRightFrame) {
    const auto tmp = test::tempDir();
    const MkvSession session = makeSession(tmp, 8);
    const int64_t first = session.frames.front().meta.host_stamp_ns;
    const auto played = play(replayConfig(
        session.mkv, {{"pace", "fast"}, {"start", "0.1"}, {"depth_units", "recorded"}}));
    ASSERT_EQ(played.size(), 2u);
    for (uint32_t s = 0; s < 2; ++s) {
        // The recording's frames of this stream at or after first + 100 ms, all of them.
        std::vector<const OwnedFrame*> expected;
        for (const auto& f : session.frames) {
            if (f.meta.stream == s && f.meta.host_stamp_ns >= first + 100'000'000) {
                expected.push_back(&f);
            }
        }
        ASSERT_EQ(played[s].size(), expected.size()) << s;
        ASSERT_FALSE(expected.empty());
        EXPECT_EQ(played[s][0].meta.host_stamp_ns, expected[0]->meta.host_stamp_ns);
        EXPECT_EQ(played[s][0].meta.sequence, expected[0]->meta.sequence);
        EXPECT_TRUE(sameImage(played[s][0].image.view(), expected[0]->image.view()));
    }
}

TEST(ReplayBackend, EnumeratesNothingAndExplainsBadConfigs) {
    ReplayBackend backend;
    EXPECT_EQ(backend.name(), "replay");
    auto list = backend.enumerate();
    ASSERT_TRUE(list);
    EXPECT_TRUE(list->empty());

    const auto tmp = test::tempDir();
    test::writeSyntheticTum(tmp / "tum", 2);
    DeviceConfig config = replayConfig(tmp / "tum", {});
    EXPECT_TRUE(backend.open(config));

    config.id.clear();
    auto no_id = backend.open(config);
    ASSERT_FALSE(no_id);
    EXPECT_TRUE(contains(no_id.status().message(), "needs id = the recording's path"));

    config.id = (tmp / "missing.mkv").string();
    auto missing = backend.open(config);
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_TRUE(contains(missing.status().message(), "missing.mkv"));

    config.id = (tmp / "tum").string();
    config.options = {{"pase", "fast"}};
    auto unknown = backend.open(config);
    ASSERT_FALSE(unknown);
    EXPECT_TRUE(contains(unknown.status().message(), "unknown replay option 'pase'"));
    config.options = {{"loop", "sometimes"}};
    auto bad = backend.open(config);
    ASSERT_FALSE(bad);
    EXPECT_TRUE(contains(bad.status().message(), "loop='sometimes'"));

    // Through a registry, as the app opens rig devices.
    BackendRegistry registry;
    ASSERT_TRUE(registry.add(std::make_unique<ReplayBackend>()));
    config.options = {{"pace", "fast"}};
    auto device = registry.open(config);
    ASSERT_TRUE(device) << device.status().toString();
    EXPECT_EQ((*device)->descriptor().backend, "replay");
    EXPECT_EQ((*device)->descriptor().model, "tum recording");
}

TEST(ReplayBackend, AzureKinectRecordingReplays) {
    const auto mkv = test::sharedDataDir() / "07_azure_kinect_mkv" / "pyk4a_recording.mkv";
    MIXRAY_REQUIRE_SHARED_DATA(mkv);
    setFfmpegLogging(false);
    std::vector<StreamInfo> streams;
    const auto played = play(replayConfig(mkv, {{"pace", "fast"}}), SIZE_MAX, nullptr, &streams);
    setFfmpegLogging(true);
    ASSERT_EQ(played.size(), streams.size());
    // MANIFEST.md (pyk4a test_playback.py L104-106, L134-135): the first capture's colour,
    // depth and IR are stamped 800222 us, the first IMU sample 336277 us.
    const std::map<std::string, int64_t> first_us = {{"kinect/color", 800222},
                                                     {"kinect/depth", 800222},
                                                     {"kinect/ir", 800222},
                                                     {"kinect/imu", 336277}};
    for (const auto& [name, stamp_us] : first_us) {
        auto it = std::find_if(streams.begin(), streams.end(),
                               [&](const StreamInfo& s) { return s.name == name; });
        ASSERT_NE(it, streams.end()) << name;
        const auto& frames = played[static_cast<size_t>(it - streams.begin())];
        ASSERT_FALSE(frames.empty()) << name;
        EXPECT_EQ(frames[0].meta.device_stamp_ns, stamp_us * 1000) << name;
        EXPECT_EQ(it->device, "kinect");
    }
}

TEST(ReplayRoundTrip, AzureKinectRecordingExportsToTum) {
    const auto mkv = test::sharedDataDir() / "07_azure_kinect_mkv" / "pyk4a_recording.mkv";
    MIXRAY_REQUIRE_SHARED_DATA(mkv);
    setFfmpegLogging(false);
    auto azure = openRecording(mkv);
    setFfmpegLogging(true);
    ASSERT_TRUE(azure) << azure.status().toString();
    const auto frames = test::readAll(**azure);
    ASSERT_TRUE((*azure)->seek(0));
    const auto tmp = test::tempDir();
    // MJPEG colour is decoded into rgb/, mm depth multiplied by 5 into depth/, IR and IMU left.
    auto summary = exportTum(**azure, tmp / "tum");
    ASSERT_TRUE(summary) << summary.status().toString();
    auto tum = openTum(tmp / "tum");
    ASSERT_TRUE(tum) << tum.status().toString();
    ASSERT_EQ((*tum)->streams().size(), 2u);
    EXPECT_EQ((*tum)->streams()[0].format, ImageDesc::packed(PixelFormat::kRGB8, 1280, 720));
    EXPECT_EQ((*tum)->streams()[1].format, ImageDesc::packed(PixelFormat::kDepth16, 640, 576));
    const auto exported = test::readAll(**tum);
    const auto depth_stream =
        std::find_if((*azure)->streams().begin(), (*azure)->streams().end(),
                     [](const StreamInfo& s) { return s.name == "azure_kinect/depth"; });
    ASSERT_NE(depth_stream, (*azure)->streams().end());
    const auto depth_id = static_cast<uint32_t>(depth_stream - (*azure)->streams().begin());
    const auto mm = std::find_if(frames.begin(), frames.end(),
                                 [&](const OwnedFrame& f) { return f.meta.stream == depth_id; });
    const auto raw = std::find_if(exported.begin(), exported.end(),
                                  [](const OwnedFrame& f) { return f.meta.stream == 1; });
    ASSERT_NE(mm, frames.end());
    ASSERT_NE(raw, exported.end());
    EXPECT_EQ(raw->meta.host_stamp_ns, mm->meta.host_stamp_ns);
    // depth_units=mm of the replay device turns them back into the same millimetres.
    Image back(mm->image.desc());
    ASSERT_TRUE(rescaleDepth(raw->image.view(), kTumDepthPerMetre, back.mutableView(),
                             kMillimetresPerMetre));
    EXPECT_TRUE(sameImage(back.view(), mm->image.view()));
}

}  // namespace
}  // namespace mixray::replay
