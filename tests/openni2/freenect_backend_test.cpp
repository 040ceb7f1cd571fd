// Kinect v1 through mixray's OpenNI2 backend: the project's libfreenect plug-in inside the
// private OpenNI2 folder, against a USB bus umockdev emulates (tests/usb/kinect_v1.umockdev,
// the camera's usbfs node answered by a handler). The backend initialises OpenNI2 once per
// process and keeps it, so these tests live apart from FreenectDriver's
// (freenect_driver_test.cpp), which initialise and shut OpenNI2 down in each test: in one
// process, a FreenectDriver test run after these saw the backend's OpenNI2 and its bus, listed
// the Kinect under another index and corrupted the heap when its own bus went away.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "kinect_usb_emulator.h"
#include "memory_in_use.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/rig.h"
#include "mixray/openni2/openni2_backend.h"
#include "mixray/pattern/pattern_backend.h"
#include "mixray/render/ar_pipeline.h"
#include "mixray/render/scene_file.h"
#include "mixray/replay/open_recording.h"
#include "test_data.h"
#include "umockdev_preload.h"

namespace mixray::openni2 {
namespace {

using test::KinectUsbEmulator;

std::string tree(const char* name) {
    return (mixray::test::sourceDir() / "tests/usb" / name).string();
}

// The backend's OpenNI2 stays initialised (see below), and libusb inside its Kinect plug-in keeps
// listening to the hot-plug events of the bus it first saw: the backend's tests share that bus,
// kept for the whole process (never destroyed: OpenNI2's threads may use it until exit).
KinectUsbEmulator* backendKinect(std::string* why) {
    static KinectUsbEmulator* kinect =
        KinectUsbEmulator::create(tree("kinect_v1.umockdev"), true, why).release();
    return kinect;
}

TEST(FreenectOpenNI2Backend, OpensTheEmulatedKinectByUriAndSerialAndStreams) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    KinectUsbEmulator* kinect = backendKinect(&why);
    ASSERT_TRUE(kinect) << why;
    OpenNI2Backend backend;
    auto list = backend.enumerate();
    ASSERT_TRUE(list) << list.status().message();
    ASSERT_EQ(list->size(), 1u);
    const DeviceDescriptor& d = list->front();
    EXPECT_EQ(d.backend, "openni2");
    // freenect://<index>/<serial>: libfreenect's index counts the cameras it has seen on this
    // bus, so it grows with each replug an earlier test made.
    EXPECT_TRUE(d.id.starts_with("freenect://") &&
                d.id.ends_with(std::string("/") + KinectUsbEmulator::kCameraSerial))
        << d.id;
    EXPECT_EQ(d.model, "Microsoft Kinect");
    EXPECT_EQ(d.serial, KinectUsbEmulator::kCameraSerial);
    EXPECT_EQ(d.modes, (std::vector<std::string>{"depth 640x480@30 depth16",
                                                 "color 640x480@30 rgb8", "ir 640x488@30 ir16"}));

    DeviceConfig config;
    config.name = "kinect";
    config.driver = "openni2";
    config.id = KinectUsbEmulator::kCameraSerial;  // by serial; the URI is tried first
    config.options = {{"registration", "on"}, {"buffers", "16"}};
    auto opened = backend.open(config);
    ASSERT_TRUE(opened) << opened.status().message();
    auto* device = static_cast<OpenNI2Device*>(opened->get());
    EXPECT_EQ(device->descriptor().serial, KinectUsbEmulator::kCameraSerial);
    EXPECT_EQ(device->softwareUnmirror(), (std::vector<bool>{false, false}));
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*opened)));
    std::map<std::string, std::shared_ptr<FrameQueue>> queues;
    for (const StreamInfo& info : graph.streams()) {
        auto queue =
            graph.subscribe(*graph.findStream(info.name), {64, QueuePolicy::kLossless, "test"});
        ASSERT_TRUE(queue);
        queues[info.name] = *queue;
    }
    ASSERT_EQ(queues.size(), 2u);
    ASSERT_TRUE(graph.start());
    std::vector<FrameRef> depth;
    std::vector<FrameRef> color;
    while (depth.size() < 3 || color.size() < 3) {
        auto dframe = queues.at("kinect/depth")->pop(std::chrono::seconds(10));
        auto cframe = queues.at("kinect/color")->pop(std::chrono::seconds(10));
        ASSERT_TRUE(dframe && cframe) << "the emulated Kinect stopped delivering";
        depth.push_back(std::move(*dframe));
        color.push_back(std::move(*cframe));
    }
    graph.stop();
    EXPECT_TRUE(device->status()) << device->status().toString();
    // Registration on is accepted (the plug-in asks libfreenect for registered depth).
    EXPECT_EQ(depth.front().image().desc, ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    EXPECT_EQ(color.front().image().desc, ImageDesc::packed(PixelFormat::kRGB8, 640, 480));
    for (const auto* frames : {&depth, &color}) {
        for (size_t i = 1; i < frames->size(); ++i) {
            const FrameMetadata& a = (*frames)[i - 1].meta();
            const FrameMetadata& b = (*frames)[i].meta();
            ASSERT_GT(b.sequence, a.sequence);
            // Device stamps are the camera's 60 MHz clock: whole frame periods apart (a full
            // pool may drop a frame; the sequence says how many).
            const double periods = static_cast<double>(b.sequence - a.sequence);
            EXPECT_NEAR(static_cast<double>(b.device_stamp_ns - a.device_stamp_ns),
                        periods * 2e9 / 60, 1000.0);
            EXPECT_EQ(b.clock_domain, defaultClockDomain("kinect"));
        }
    }
    // Depth and colour share the camera's clock: their stamps are whole periods apart too.
    const double periods = static_cast<double>(depth.front().meta().device_stamp_ns -
                                               color.front().meta().device_stamp_ns) /
                           (2e9 / 60);
    EXPECT_NEAR(periods, std::round(periods), 1e-3);
}

// The emulated Kinect streaming through the backend beside a pattern device, in one graph.
struct KinectInAGraph {
    OpenNI2Device* kinect = nullptr;
    Graph graph;
    std::map<std::string, std::shared_ptr<FrameQueue>> queues;
};

void openKinectInAGraph(KinectInAGraph& out, const std::string& reconnect) {
    OpenNI2Backend backend;
    DeviceConfig config;
    config.name = "kinect";
    config.driver = "openni2";
    config.id = KinectUsbEmulator::kCameraSerial;
    config.options = {{"streams", "depth,color"}, {"reconnect", reconnect}};
    auto opened = backend.open(config);
    ASSERT_TRUE(opened) << opened.status().message();
    out.kinect = static_cast<OpenNI2Device*>(opened->get());
    ASSERT_TRUE(out.graph.addNode(std::move(*opened)));
    pattern::PatternBackend patterns;
    DeviceConfig pattern_config;
    pattern_config.name = "pattern";
    pattern_config.driver = "pattern";
    pattern_config.id = "rgbd";
    pattern_config.options = {{"streams", "color"}};
    auto pattern = patterns.open(pattern_config);
    ASSERT_TRUE(pattern) << pattern.status().message();
    ASSERT_TRUE(out.graph.addNode(std::move(*pattern)));
    for (const StreamInfo& info : out.graph.streams()) {
        // Live queues: a consumer that looks away never holds a device back.
        auto queue =
            out.graph.subscribe(*out.graph.findStream(info.name), {8, QueuePolicy::kLive, "test"});
        ASSERT_TRUE(queue);
        out.queues[info.name] = *queue;
    }
    ASSERT_EQ(out.queues.size(), 3u);
    ASSERT_TRUE(out.graph.start());
}

// Pops pattern frames (the graph's other device) until `done` holds; false if the pattern
// stopped delivering or 20 s of its frames passed without it.
template <typename Done>
bool patternDeliversUntil(KinectInAGraph& g, Done done, uint64_t* pattern_frames) {
    std::optional<uint64_t> last;
    for (int i = 0; i < 600; ++i) {
        auto frame = g.queues.at("pattern/color")->pop(std::chrono::seconds(5));
        if (!frame)
            return false;
        if (last && frame->meta().sequence <= *last)
            return false;
        last = frame->meta().sequence;
        ++*pattern_frames;
        if (done())
            return true;
    }
    return false;
}

void drain(FrameQueue& queue) {
    while (queue.tryPop()) {
    }
}

// Issue 5: a Kinect unplugged while streaming through the graph is reported lost, the graph's
// other device keeps delivering, and the camera plugged in again streams on through the same
// graph streams.
TEST(FreenectOpenNI2Backend, ReportsAnUnpluggedKinectAndReopensItWhenItReturns) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    KinectUsbEmulator* kinect = backendKinect(&why);
    ASSERT_TRUE(kinect) << why;
    KinectInAGraph g;
    openKinectInAGraph(g, "true");
    ASSERT_FALSE(HasFatalFailure());
    FrameQueue& depth = *g.queues.at("kinect/depth");
    FrameQueue& color = *g.queues.at("kinect/color");
    std::optional<FrameRef> before_depth;
    std::optional<FrameRef> before_color;
    for (int i = 0; i < 3; ++i) {
        before_depth = depth.pop(std::chrono::seconds(10));
        before_color = color.pop(std::chrono::seconds(10));
        ASSERT_TRUE(before_depth && before_color) << "the emulated Kinect did not stream";
    }
    EXPECT_TRUE(g.kinect->error()) << g.kinect->error().toString();
    EXPECT_EQ(g.kinect->reconnects(), 0u);

    kinect->unplugCamera();
    uint64_t pattern_frames = 0;
    ASSERT_TRUE(patternDeliversUntil(
        g, [&] { return g.kinect->error().code() == ErrorCode::kUnavailable; }, &pattern_frames))
        << "no loss reported: " << g.kinect->error().toString();
    const std::string message = g.kinect->error().message();
    EXPECT_NE(message.find("'kinect'"), std::string::npos) << message;
    EXPECT_NE(message.find(KinectUsbEmulator::kCameraSerial), std::string::npos) << message;
    EXPECT_NE(message.find("reopening it when it returns"), std::string::npos) << message;
    // Released: the frames queued before the loss are all there is while it lasts; the pattern
    // device goes on meanwhile.
    drain(depth);
    drain(color);
    const uint64_t lost_at = pattern_frames;
    ASSERT_TRUE(patternDeliversUntil(
        g, [&] { return pattern_frames >= lost_at + 10; }, &pattern_frames));
    EXPECT_FALSE(depth.tryPop());
    EXPECT_FALSE(color.tryPop());
    EXPECT_EQ(g.kinect->error().code(), ErrorCode::kUnavailable);
    EXPECT_EQ(g.kinect->reconnects(), 0u);

    ASSERT_TRUE(kinect->replugCamera(tree("kinect_v1.umockdev"), &why)) << why;
    std::vector<FrameRef> after_depth;
    std::vector<FrameRef> after_color;
    while (after_depth.size() < 3 || after_color.size() < 3) {
        auto d = depth.pop(std::chrono::seconds(20));
        auto c = color.pop(std::chrono::seconds(20));
        ASSERT_TRUE(d && c) << "no frames after the replug: " << g.kinect->error().toString();
        after_depth.push_back(std::move(*d));
        after_color.push_back(std::move(*c));
    }
    EXPECT_TRUE(g.kinect->error()) << g.kinect->error().toString();
    EXPECT_EQ(g.kinect->reconnects(), 1u);
    // The pattern device never stopped.
    const uint64_t replugged_at = pattern_frames;
    ASSERT_TRUE(patternDeliversUntil(
        g, [&] { return pattern_frames >= replugged_at + 3; }, &pattern_frames));
    g.graph.stop();

    // The camera restarted its frame count and 60 MHz clock; the graph's streams go on: later
    // sequences, later device and host stamps, frames still one camera period apart.
    for (const auto& [before, after] :
         {std::pair{&*before_depth, &after_depth}, std::pair{&*before_color, &after_color}}) {
        const FrameMetadata& last = before->meta();
        const FrameMetadata& first = after->front().meta();
        EXPECT_GT(first.sequence, last.sequence);
        EXPECT_GT(first.host_stamp_ns, last.host_stamp_ns);
        EXPECT_GT(first.device_stamp_ns, last.device_stamp_ns);
        EXPECT_EQ(first.clock_domain, last.clock_domain);
        EXPECT_EQ(after->front().image().desc, before->image().desc);
        for (size_t i = 1; i < after->size(); ++i) {
            const FrameMetadata& a = (*after)[i - 1].meta();
            const FrameMetadata& b = (*after)[i].meta();
            ASSERT_GT(b.sequence, a.sequence);
            EXPECT_NEAR(static_cast<double>(b.device_stamp_ns - a.device_stamp_ns),
                        static_cast<double>(b.sequence - a.sequence) * 2e9 / 60, 1000.0);
        }
    }
    // The emulated camera powered up again: libfreenect set it up and it streamed anew.
    EXPECT_GT(kinect->framesSent(0x82), 0u);
}

// reconnect=false: the lost Kinect's streams end; the rest of the graph runs on.
TEST(FreenectOpenNI2Backend, EndsTheStreamsOfAnUnpluggedKinectWithoutReconnect) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    KinectUsbEmulator* kinect = backendKinect(&why);
    ASSERT_TRUE(kinect) << why;
    KinectInAGraph g;
    openKinectInAGraph(g, "false");
    ASSERT_FALSE(HasFatalFailure());
    FrameQueue& depth = *g.queues.at("kinect/depth");
    FrameQueue& color = *g.queues.at("kinect/color");
    ASSERT_TRUE(depth.pop(std::chrono::seconds(10))) << "the emulated Kinect did not stream";
    ASSERT_TRUE(color.pop(std::chrono::seconds(10)));

    kinect->unplugCamera();
    uint64_t pattern_frames = 0;
    ASSERT_TRUE(patternDeliversUntil(
        g, [&] { return depth.closed() && color.closed(); }, &pattern_frames))
        << "the lost Kinect's streams did not end: " << g.kinect->error().toString();
    EXPECT_EQ(g.kinect->error().code(), ErrorCode::kUnavailable);
    EXPECT_NE(g.kinect->error().message().find("its streams end"), std::string::npos)
        << g.kinect->error().message();
    EXPECT_EQ(g.kinect->reconnects(), 0u);
    const uint64_t ended_at = pattern_frames;
    EXPECT_TRUE(patternDeliversUntil(
        g, [&] { return pattern_frames >= ended_at + 5; }, &pattern_frames));
    g.graph.stop();
    // Released, it cannot start again.
    const Status restarted = g.kinect->start();
    EXPECT_EQ(restarted.code(), ErrorCode::kUnavailable) << restarted.toString();
    EXPECT_NE(restarted.message().find("was lost"), std::string::npos) << restarted.toString();
    // Back on the bus for the tests after this one.
    ASSERT_TRUE(kinect->replugCamera(tree("kinect_v1.umockdev"), &why)) << why;
}

// Polls `done` until it holds or `seconds` pass: an upper bound against hangs.
template <typename F>
bool eventually(F done, int seconds) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(seconds);
    while (std::chrono::steady_clock::now() < deadline) {
        if (done())
            return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return done();
}

std::string deviceState(const render::ArPipelineStats& stats, const std::string& name) {
    for (const auto& d : stats.devices)
        if (d.name == name)
            return d.state;
    return "absent";
}

uint64_t composites(const render::ArPipeline& p) {
    const render::ArPipelineStats stats = p.stats();
    return stats.compositor ? stats.compositor->composites : 0;
}

// Issue 13: the emulated Kinect unplugged and replugged while a live AR pipeline composites
// its colour stream (a fixed camera, no tracking) and records everything, beside a pattern
// device that says nothing of its state. The Kinect's state follows its driver (reconnecting,
// then streaming), the pattern's is judged from its frames and stays streaming, composites
// resume, and the recording reads back to its end.
TEST(FreenectOpenNI2Backend, UnpluggedAndRepluggedUnderALiveArPipeline) {
    MIXRAY_REQUIRE_UMOCKDEV();
    std::string why;
    KinectUsbEmulator* kinect = backendKinect(&why);
    ASSERT_TRUE(kinect) << why;
    auto rig = parseRig(std::string(R"(rig: kinect-live
devices:
  - name: kinect
    driver: openni2
    serial: )") + KinectUsbEmulator::kCameraSerial +
                            R"(
    streams: [depth, color]
    options: { reconnect: true }
  - name: pattern
    driver: pattern
    id: rgbd
    streams: [color]
)",
                        "kinect-live rig");
    ASSERT_TRUE(rig.isOk()) << rig.status().toString();
    BackendRegistry registry;
    ASSERT_TRUE(registry.add(std::make_unique<OpenNI2Backend>()).isOk());
    ASSERT_TRUE(registry.add(std::make_unique<pattern::PatternBackend>()).isOk());
    auto scene = render::parseScene(R"(version: 1
materials:
  clay: { type: diffuse, albedo: [0.7, 0.35, 0.2] }
objects:
  - name: box
    shape: { box: { size: [0.2, 0.2, 0.2] } }
    material: clay
    pose: { translation: [0, 0, 1] }
)",
                                    "kinect fault scene");
    ASSERT_TRUE(scene.isOk()) << scene.status().toString();
    scene->camera = render::FixedCamera{};
    scene->camera->model = calibration::CameraModel::pinhole(640, 480, 525, 525, 319.5, 239.5);
    const std::filesystem::path out =
        std::filesystem::path(::testing::TempDir()) / "ar_pipeline_kinect_faults.mkv";
    std::filesystem::remove(out);
    render::ArPipelineOptions options;
    options.scene = std::move(scene).value();
    options.color_stream = "kinect/color";
    options.use_depth = false;
    options.render.samples_per_pixel = 1;
    options.render.max_depth = 1;
    options.render.threads = 1;
    options.target_fps = -1;
    options.record = out;
    render::ArSource source;
    source.rig = *rig;
    auto created = render::ArPipeline::create(registry, source, std::move(options));
    ASSERT_TRUE(created.isOk()) << created.status().toString();
    render::ArPipeline& pipeline = **created;
    ASSERT_TRUE(pipeline.start().isOk());
    ASSERT_TRUE(eventually([&] { return composites(pipeline) >= 10; }, 30))
        << pipeline.stats().json();
    EXPECT_EQ(deviceState(pipeline.stats(), "kinect"), "streaming");

    size_t rss_after_first_return = 0;
    for (int cycle = 0; cycle < 2; ++cycle) {
        SCOPED_TRACE("unplug and replug #" + std::to_string(cycle + 1));
        kinect->unplugCamera();
        ASSERT_TRUE(eventually(
            [&] { return deviceState(pipeline.stats(), "kinect") == "reconnecting"; }, 30))
            << pipeline.stats().json();
        EXPECT_NE(pipeline.stats().json().find(R"("state":"reconnecting")"), std::string::npos)
            << pipeline.stats().json();
        // The other device goes on meanwhile, judged from its frames.
        std::this_thread::sleep_for(std::chrono::milliseconds(300));
        EXPECT_EQ(deviceState(pipeline.stats(), "pattern"), "streaming") << pipeline.stats().json();
        EXPECT_TRUE(pipeline.status().isOk()) << pipeline.status().toString();
        const uint64_t while_lost = composites(pipeline);

        ASSERT_TRUE(kinect->replugCamera(tree("kinect_v1.umockdev"), &why)) << why;
        ASSERT_TRUE(
            eventually([&] { return deviceState(pipeline.stats(), "kinect") == "streaming"; }, 30))
            << pipeline.stats().json();
        ASSERT_TRUE(eventually([&] { return composites(pipeline) >= while_lost + 10; }, 30))
            << "composites did not resume: " << pipeline.stats().json();
        if (cycle == 0)
            rss_after_first_return = ::mixray::test::memoryInUse();
    }
    // A second unplug and replug costs no memory the first did not: OpenNI2 and the plug-in
    // reopen the same device, the pipeline's buffers come from the same pools.
    const size_t rss_back = ::mixray::test::memoryInUse();
    EXPECT_LT(rss_back, rss_after_first_return + (16u << 20))
        << "memory in use grew from " << rss_after_first_return << " to " << rss_back
        << " bytes over one unplug and replug";
    pipeline.stop();
    const render::ArPipelineStats stats = pipeline.stats();
    ASSERT_TRUE(stats.recorder.has_value());
    ASSERT_TRUE(stats.recorder->error.isOk()) << stats.recorder->error.toString();

    auto reader = replay::openRecording(out);
    ASSERT_TRUE(reader.isOk()) << reader.status().toString();
    std::map<std::string, uint64_t> counts;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            EXPECT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        ++counts[(*reader)->streams()[frame->meta().stream].name];
    }
    for (const RecorderStreamStats& s : stats.recorder->streams)
        EXPECT_EQ(counts[s.stream], s.written) << s.stream;
    EXPECT_GT(counts["kinect/color"], 10u);
    EXPECT_GT(counts[pipeline.compositeStream()], 10u);
}

}  // namespace
}  // namespace mixray::openni2

int main(int argc, char** argv) {
    mixray::test::reexecWithUmockdevPreload(argc, argv);
    testing::InitGoogleTest(&argc, argv);
    return RUN_ALL_TESTS();
}
