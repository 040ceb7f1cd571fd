// The pattern backend: options, deterministic images, simulated clocks, and sets through a graph.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <tuple>
#include <vector>

#include "mixray/graph/synchronizer.h"
#include "mixray/pattern/pattern_backend.h"

namespace mixray::pattern {
namespace {

using std::chrono::seconds;

DeviceConfig config(const std::string& name, const std::string& id,
                    std::map<std::string, std::string> options) {
    DeviceConfig c;
    c.name = name;
    c.driver = "pattern";
    c.id = id;
    c.options = std::move(options);
    return c;
}

std::unique_ptr<PatternDevice> openDevice(const DeviceConfig& c) {
    PatternBackend backend;
    auto device = backend.open(c);
    EXPECT_TRUE(device) << device.status().toString();
    if (!device)
        return nullptr;
    return std::unique_ptr<PatternDevice>(static_cast<PatternDevice*>(device->release()));
}

// Pops everything from `queue` until it is closed and empty.
std::vector<FrameRef> drain(FrameQueue& queue) {
    std::vector<FrameRef> out;
    while (auto frame = queue.pop(seconds(10)))
        out.push_back(std::move(*frame));
    return out;
}

TEST(PatternBackend, EnumeratesTheVirtualDevices) {
    PatternBackend backend;
    EXPECT_EQ(backend.name(), "pattern");
    auto devices = backend.enumerate();
    ASSERT_TRUE(devices);
    ASSERT_EQ(devices->size(), 2u);
    EXPECT_EQ((*devices)[0].id, "rgbd");
    EXPECT_EQ((*devices)[1].id, "mono");
    EXPECT_EQ((*devices)[0].modes.front(), "color 640x480@30 rgb8");
    EXPECT_EQ((*devices)[1].modes.front(), "mono 1280x960@30 mono8");

    BackendRegistry registry;
    ASSERT_TRUE(registry.add(std::make_unique<PatternBackend>()));
    auto device = registry.open(config("cam", "mono", {}));
    ASSERT_TRUE(device);
    EXPECT_EQ((*device)->descriptor().model, "mixray test pattern mono");
}

TEST(PatternOptions, DefaultsPerVirtualDevice) {
    auto rgbd = PatternOptions::fromConfig(config("k", "", {}));
    ASSERT_TRUE(rgbd);
    ASSERT_EQ(rgbd->streams.size(), 2u);
    EXPECT_EQ(rgbd->streams[0].stream, PatternStream::kColor);
    EXPECT_EQ(rgbd->streams[1].stream, PatternStream::kDepth);
    EXPECT_EQ(rgbd->streams[1].width, 640);
    EXPECT_TRUE(rgbd->realtime);
    EXPECT_EQ(rgbd->clock_domain, defaultClockDomain("k"));
    EXPECT_NE(rgbd->clock_domain, kHostClockDomain);

    auto mono = PatternOptions::fromConfig(config("m", "mono", {}));
    ASSERT_TRUE(mono);
    ASSERT_EQ(mono->streams.size(), 1u);
    EXPECT_EQ(mono->streams[0].width, 1280);
    EXPECT_EQ(mono->streams[0].height, 960);
    EXPECT_NE(mono->clock_domain, rgbd->clock_domain);

    auto custom = PatternOptions::fromConfig(config("k", "rgbd",
                                                    {{"streams", "depth, ir"},
                                                     {"ir.width", "320"},
                                                     {"ir.height", "240"},
                                                     {"fps", "29.97"},
                                                     {"frames", "5"},
                                                     {"realtime", "off"},
                                                     {"drift_ppm", "-12.5"},
                                                     {"jitter_us", "800"},
                                                     {"latency_us", "1500"},
                                                     {"reset_at_frame", "3"},
                                                     {"drop_ratio", "0.1"},
                                                     {"seed", "42"},
                                                     {"fill", "stamp"},
                                                     {"clock_domain", "77"},
                                                     {"phase_us", "-250"}}));
    ASSERT_TRUE(custom) << custom.status().toString();
    ASSERT_EQ(custom->streams.size(), 2u);
    EXPECT_EQ(custom->streams[1].stream, PatternStream::kInfrared);
    EXPECT_EQ(custom->streams[1].width, 320);
    EXPECT_DOUBLE_EQ(custom->fps, 29.97);
    EXPECT_EQ(custom->frames, 5u);
    EXPECT_FALSE(custom->realtime);
    EXPECT_DOUBLE_EQ(custom->drift_ppm, -12.5);
    EXPECT_DOUBLE_EQ(custom->jitter_ns, 800e3);
    EXPECT_EQ(custom->latency_ns, 1'500'000);
    EXPECT_EQ(custom->phase_ns, -250'000);
    EXPECT_EQ(custom->reset_at_frame, 3u);
    EXPECT_EQ(custom->fill, PatternOptions::Fill::kStamp);
    EXPECT_EQ(custom->clock_domain, 77u);

    DeviceConfig listed = config("k", "rgbd", {});
    listed.streams = {"ir"};
    auto from_rig = PatternOptions::fromConfig(listed);
    ASSERT_TRUE(from_rig);
    EXPECT_EQ(from_rig->streams.size(), 1u);
}

// Each bad option is refused with a message naming it.
TEST(PatternOptions, ErrorsNameTheOption) {
    struct Case {
        std::map<std::string, std::string> options;
        std::string needle;
    };
    const std::vector<Case> cases = {
        {{{"fps", "abc"}}, "'fps'"},
        {{{"fps", "0"}}, "'fps'"},
        {{{"frames", "-1"}}, "'frames'"},
        {{{"realtime", "maybe"}}, "'realtime'"},
        {{{"drop_ratio", "1"}}, "'drop_ratio'"},
        {{{"color.width", "8"}}, "'color.width'"},
        {{{"depth.height", "12x"}}, "'depth.height'"},
        {{{"jitter_us", "-5"}}, "'jitter_us'"},
        {{{"drift_ppm", "nan"}}, "'drift_ppm'"},
        {{{"fill", "half"}}, "'fill'"},
        {{{"clock_domain", "0"}}, "'clock_domain'"},
        {{{"buffers", "0"}}, "'buffers'"},
        {{{"streams", "color,mono"}}, "'mono'"},
        {{{"streams", "color,color"}}, "listed twice"},
        {{{"fsp", "30"}}, "unknown option 'fsp'"},
        {{{"mono.width", "320"}}, "unknown option 'mono.width'"},  // mono is not enabled
    };
    for (const Case& c : cases) {
        auto result = PatternOptions::fromConfig(config("cam", "rgbd", c.options));
        ASSERT_FALSE(result) << c.needle;
        EXPECT_EQ(result.status().code(), ErrorCode::kInvalidArgument) << c.needle;
        EXPECT_NE(result.status().message().find(c.needle), std::string::npos)
            << result.status().message();
        EXPECT_NE(result.status().message().find("'cam'"), std::string::npos);
    }
    auto unknown = PatternOptions::fromConfig(config("cam", "stereo", {}));
    EXPECT_EQ(unknown.status().code(), ErrorCode::kNotFound);
    DeviceConfig both = config("cam", "rgbd", {{"streams", "color"}});
    both.streams = {"depth"};
    EXPECT_FALSE(PatternOptions::fromConfig(both));
    EXPECT_FALSE(PatternBackend().open(config("", "rgbd", {})));
}

TEST(PatternImage, IsAFunctionOfStreamAndSequence) {
    for (size_t i = 0; i < kPatternStreamCount; ++i) {
        const auto stream = static_cast<PatternStream>(i);
        SCOPED_TRACE(toString(stream));
        EXPECT_EQ(patternStreamFromString(toString(stream)), stream);
        const Image a = renderPattern(stream, 160, 120, 41);
        const Image b = renderPattern(stream, 160, 120, 41);
        const Image c = renderPattern(stream, 160, 120, 42);
        EXPECT_TRUE(sameImage(a.view(), b.view()));
        EXPECT_FALSE(sameImage(a.view(), c.view()));
        EXPECT_EQ(readSequence(a.view()), 41u);
        EXPECT_EQ(readSequence(c.view()), 42u);

        // Any stride: the pixels are the same, the padding untouched.
        ImageDesc padded = ImageDesc::packed(formatOf(stream), 160, 120);
        padded.stride_bytes += 64;
        Image p(padded);
        std::fill(p.bytes().begin(), p.bytes().end(), uint8_t{0xAB});
        renderPattern(stream, 41, p.mutableView());
        EXPECT_TRUE(sameImage(a.view(), p.view()));
        EXPECT_EQ(p.bytes()[padded.stride_bytes - 1], 0xAB);
    }
    Image blank(ImageDesc::packed(PixelFormat::kMono8, 64, 8));
    EXPECT_FALSE(readSequence(blank.view()).has_value());
    EXPECT_EQ(readSequence(renderPattern(PatternStream::kMono, 16, 8, UINT64_MAX - 3).view()),
              UINT64_MAX - 3);
}

TEST(PatternImage, DepthHasAWallABoxAndHoles) {
    const Image depth = renderPattern(PatternStream::kDepth, 640, 480, 10);
    const ImageView v = depth.view();
    size_t holes = 0;
    size_t box = 0;
    size_t wall = 0;
    for (int y = 1; y < 480; ++y) {  // row 0 carries the sequence stamp
        for (int x = 0; x < 640; ++x) {
            const uint16_t d = v.row<uint16_t>(y)[x];
            if (d == 0) {
                ++holes;
            } else if (d >= 1100 && d <= 1300) {
                ++box;
            } else if (d >= 1700 && d <= 2600) {
                ++wall;
            } else {
                ADD_FAILURE() << "unexpected depth " << d << " at " << x << "," << y;
                return;
            }
        }
    }
    const size_t total = 640 * 479;
    EXPECT_GT(holes, total / 100);  // shadow, border and scattered dropouts
    EXPECT_LT(holes, total / 10);
    EXPECT_GT(box, total / 20);
    EXPECT_GT(wall, total / 2);
    // The box moves with the sequence.
    EXPECT_FALSE(sameImage(v, renderPattern(PatternStream::kDepth, 640, 480, 11).view()));
}

// A non-realtime device publishes the right frames, stamps and end of stream.
TEST(PatternDevice, PublishesDeterministicFramesAndEnds) {
    auto device = openDevice(config("kinect", "rgbd",
                                    {{"realtime", "false"},
                                     {"frames", "20"},
                                     {"color.width", "64"},
                                     {"color.height", "48"},
                                     {"depth.width", "64"},
                                     {"depth.height", "48"},
                                     {"offset_ns", "5000000000000"},
                                     {"drift_ppm", "100"},
                                     {"latency_us", "2000"},
                                     {"jitter_us", "500"},
                                     {"buffers", "4"}}));
    ASSERT_TRUE(device);
    PatternDevice* dev = device.get();
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(device)));
    ASSERT_EQ(graph.streamCount(), 2u);
    const StreamInfo color = graph.stream(0);
    EXPECT_EQ(color.name, "kinect/color");
    EXPECT_EQ(color.device, "kinect");
    EXPECT_EQ(color.kind, StreamKind::kColor);
    EXPECT_EQ(color.format, ImageDesc::packed(PixelFormat::kRGB8, 64, 48));
    EXPECT_EQ(color.clock_domain, dev->options().clock_domain);
    EXPECT_EQ(graph.stream(1).name, "kinect/depth");

    auto qc = *graph.subscribe(0, {4, QueuePolicy::kLossless, "test"});
    auto qd = *graph.subscribe(1, {4, QueuePolicy::kLossless, "test"});
    ASSERT_TRUE(graph.start());
    // Two lossless queues of one device: read them in step, or the device blocks on one. The
    // frames are released at once: the pools have 4 buffers.
    uint64_t expected = 0;
    while (true) {
        auto c = qc->pop(seconds(10));
        auto d = qd->pop(seconds(10));
        if (!c || !d)
            break;
        EXPECT_EQ(c->meta().sequence, expected);
        EXPECT_EQ(d->meta().sequence, expected);
        EXPECT_EQ(readSequence(c->image()), expected);
        EXPECT_TRUE(
            sameImage(d->image(), renderPattern(PatternStream::kDepth, 64, 48, expected).view()));
        EXPECT_EQ(c->meta().device_stamp_ns, d->meta().device_stamp_ns);  // one capture
        EXPECT_EQ(c->meta().device_stamp_ns, dev->deviceStampNs(expected));
        ++expected;
    }
    EXPECT_EQ(expected, 20u);
    EXPECT_TRUE(qc->closed());
    graph.stop();
    EXPECT_TRUE(dev->finished());
    EXPECT_EQ(dev->publishedFrames(), 40u);
}

TEST(PatternDevice, StampsContentDropsAndResetsAreReproducible) {
    auto runOnce = [] {
        auto device = openDevice(config("cam", "mono",
                                        {{"realtime", "false"},
                                         {"frames", "60"},
                                         {"mono.width", "32"},
                                         {"mono.height", "16"},
                                         {"drop_ratio", "0.25"},
                                         {"seed", "5"},
                                         {"jitter_us", "1000"},
                                         {"latency_us", "3000"},
                                         {"offset_ns", "777"},
                                         {"drift_ppm", "50"},
                                         {"reset_at_frame", "40"},
                                         {"buffers", "64"}}));
        PatternDevice* dev = device.get();
        Graph graph;
        EXPECT_TRUE(graph.addNode(std::move(device)));
        auto q = *graph.subscribe(0, {64, QueuePolicy::kLossless, "test"});
        EXPECT_TRUE(graph.start());
        std::vector<FrameRef> frames = drain(*q);
        graph.stop();
        EXPECT_EQ(frames.size() + dev->droppedFrames(), 60u);
        EXPECT_GT(dev->droppedFrames(), 5u);
        EXPECT_EQ(graph.lostCount(0), dev->droppedFrames()) << "drops reach Graph::lostCount";
        std::vector<std::tuple<uint64_t, int64_t, int64_t>> stamps;
        for (const FrameRef& f : frames) {
            const FrameMetadata& m = f.meta();
            stamps.emplace_back(m.sequence, m.device_stamp_ns, m.host_stamp_ns);
            EXPECT_EQ(m.device_stamp_ns, dev->deviceStampNs(m.sequence));
            const int64_t t = dev->captureInstantNs(m.sequence);
            EXPECT_GE(m.host_stamp_ns, t + 3'000'000);  // latency is never negative
            EXPECT_LT(m.host_stamp_ns, t + 3'000'000 + 20'000'000);
            EXPECT_EQ(m.clock_domain, dev->options().clock_domain);
            // Bit-exact content, regenerated from the sequence alone.
            const Image expected = renderPattern(PatternStream::kMono, 32, 16, m.sequence);
            EXPECT_TRUE(sameImage(f.image(), expected.view())) << m.sequence;
        }
        EXPECT_EQ(dev->deviceStampNs(0), 777);
        EXPECT_EQ(dev->deviceStampNs(40), 0);  // the clock restarted at frame 40
        const int64_t since = dev->captureInstantNs(41) - dev->captureInstantNs(40);
        EXPECT_EQ(dev->deviceStampNs(41), std::llround(static_cast<double>(since) * (1 + 50e-6)));
        return stamps;
    };
    EXPECT_EQ(runOnce(), runOnce());
}

TEST(PatternDevice, RealtimeDevicePacesAndStopsPromptly) {
    auto device = openDevice(
        config("cam", "mono", {{"fps", "200"}, {"mono.width", "16"}, {"mono.height", "8"}}));
    PatternDevice* dev = device.get();
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(device)));
    auto q = *graph.subscribe(0, {4, QueuePolicy::kLive, "test"});
    ASSERT_TRUE(graph.start());
    auto first = q->pop(seconds(5));
    auto second = q->pop(seconds(5));
    ASSERT_TRUE(first && second);
    EXPECT_GT(second->meta().sequence, first->meta().sequence);
    EXPECT_GT(second->meta().host_stamp_ns, first->meta().host_stamp_ns);
    const auto before = std::chrono::steady_clock::now();
    graph.stop();  // no frame limit: stop() must end the capture thread by itself
    EXPECT_LT(std::chrono::steady_clock::now() - before, seconds(2));
    EXPECT_TRUE(dev->finished());
}

// Three streams from two devices with unrelated drifting clocks, through the graph and a
// SyncNode: every capture instant comes out as one complete set.
TEST(PatternSync, ThreeStreamsFromTwoDevicesGiveCompleteSets) {
    constexpr int kFrames = 900;  // 30 s of simulated time
    const std::string frames = std::to_string(kFrames);
    auto kinect = openDevice(config("kinect", "rgbd",
                                    {{"realtime", "false"},
                                     {"frames", frames},
                                     {"color.width", "64"},
                                     {"color.height", "48"},
                                     {"depth.width", "64"},
                                     {"depth.height", "48"},
                                     {"offset_ns", "4200000000000000000"},
                                     {"drift_ppm", "100"},
                                     {"latency_us", "3000"},
                                     {"jitter_us", "1000"},
                                     {"seed", "1"}}));
    auto mono = openDevice(config("cam", "mono",
                                  {{"realtime", "false"},
                                   {"frames", frames},
                                   {"mono.width", "128"},
                                   {"mono.height", "96"},
                                   {"offset_ns", "123456789"},
                                   {"drift_ppm", "-80"},
                                   {"latency_us", "3000"},
                                   {"jitter_us", "1500"},
                                   {"seed", "2"}}));
    ASSERT_TRUE(kinect && mono);
    const ClockDomainId kinect_domain = kinect->options().clock_domain;
    const ClockDomainId mono_domain = mono->options().clock_domain;

    std::mutex mutex;
    std::vector<uint64_t> set_sequences;
    std::vector<std::string> problems;
    std::map<DropReason, int> drops;
    SyncNodeOptions options;
    options.name = "sync";
    options.streams = {"kinect/color", "kinect/depth", "cam/mono"};
    options.queue = {4, QueuePolicy::kLossless, ""};
    auto node = std::make_unique<SyncNode>(
        options,
        [&](const SyncSet& set) {
            std::lock_guard lock(mutex);
            const uint64_t k = set.frames[0].meta().sequence;
            set_sequences.push_back(k);
            for (const FrameRef& f : set.frames) {
                if (f.meta().sequence != k || readSequence(f.image()) != k) {
                    problems.push_back("set " + std::to_string(set.index) + " mixes captures");
                }
            }
            if (set.skew_ns > 10'000'000)
                problems.push_back("skew above the bound");
        },
        [&](const FrameRef&, DropReason reason) {
            std::lock_guard lock(mutex);
            ++drops[reason];
        });
    SyncNode* sync = node.get();

    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(kinect)));
    ASSERT_TRUE(graph.addNode(std::move(mono)));
    ASSERT_TRUE(graph.addNode(std::move(node)));
    ASSERT_TRUE(graph.start());
    ASSERT_TRUE(sync->waitDone(seconds(60)));
    graph.stop();

    std::lock_guard lock(mutex);
    EXPECT_TRUE(problems.empty()) << problems.front();
    ASSERT_EQ(set_sequences.size(), static_cast<size_t>(kFrames));
    for (int k = 0; k < kFrames; ++k)
        EXPECT_EQ(set_sequences[k], static_cast<uint64_t>(k));
    EXPECT_TRUE(drops.empty());
    const SyncStats stats = sync->stats();
    EXPECT_EQ(stats.sets_emitted, static_cast<uint64_t>(kFrames));
    EXPECT_EQ(stats.frames_added, 3u * kFrames);
    EXPECT_LT(stats.skew_mean_ns, 1'000'000);

    // 30 s of data pin the drifts down to about a ppm (sync_test shows < 1 ppm with 60 s).
    auto k_est = sync->clockEstimate(kinect_domain);
    auto m_est = sync->clockEstimate(mono_domain);
    ASSERT_TRUE(k_est && m_est);
    EXPECT_NEAR(k_est->drift_ppm, 100, 3);
    EXPECT_NEAR(m_est->drift_ppm, -80, 3);
    EXPECT_EQ(k_est->resets + m_est->resets, 0u);
}

TEST(PatternSync, SyncNodeRejectsUnknownStreams) {
    Graph graph;
    SyncNodeOptions options;
    options.streams = {"nowhere/color"};
    auto status = graph.addNode(std::make_unique<SyncNode>(options, [](const SyncSet&) {}));
    EXPECT_EQ(status.code(), ErrorCode::kNotFound);
    EXPECT_NE(status.message().find("nowhere/color"), std::string::npos);
}

}  // namespace
}  // namespace mixray::pattern
