// The replay device over readers that need no Matroska: options, pacing, loops, seeking,
// zero-copy forwarding, depth units, stream filters.
#include <gtest/gtest.h>

#include <chrono>
#include <set>
#include <thread>

#include "mixray/replay/depth_units.h"
#include "mixray/replay/replay_backend.h"
#include "mixray/replay/tum.h"
#include "replay_test_util.h"
#include "test_data.h"

namespace mixray::replay {
namespace {

using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// An in-memory recording: one mono8 stream, frames at the given host stamps (device stamps
// offset by a constant, sequence from 10), remembering every buffer it hands out.
class FakeReader : public RecordingReader {
public:
    explicit FakeReader(std::vector<int64_t> stamps, size_t buffers = 4)
        : stamps_(std::move(stamps)) {
        StreamInfo info;
        info.name = "cam/mono";
        info.device = "cam";
        info.kind = StreamKind::kMono;
        info.format = ImageDesc::packed(PixelFormat::kMono8, 4, 2);
        info.clock_domain = 7;
        info.tags["lens"] = "fisheye";
        streams_.push_back(info);
        pool_ = BufferPool::create({info.format, 0, buffers, info.name});
    }
    std::string format() const override { return "fake"; }
    const std::vector<StreamInfo>& streams() const override { return streams_; }
    const std::vector<Attachment>& attachments() const override { return attachments_; }
    const std::map<std::string, std::string>& tags() const override { return tags_; }
    Result<FrameRef> next() override {
        if (position_ >= stamps_.size())
            return {ErrorCode::kEndOfStream, "end"};
        if (position_ == cut_after)
            return {ErrorCode::kCorruptData, "memory: file is cut off: it ends after " +
                                                 std::to_string(cut_after) + " complete frames"};
        WritableFrame w = pool_->acquire();
        if (!w)
            return {ErrorCode::kUnavailable, "held"};
        for (int i = 0; i < 8; ++i)
            w.image().data[i] = static_cast<uint8_t>(position_ * 8 + i);
        FrameMetadata& m = w.meta();
        m.stream = 0;
        m.sequence = 10 + position_;
        m.host_stamp_ns = stamps_[position_];
        m.device_stamp_ns = stamps_[position_] + 5'000;
        m.clock_domain = 7;
        m.exposure_us = 250;
        m.status = position_ == 1 ? FrameStatus::kIncomplete : FrameStatus::kOk;
        ++position_;
        handed_out.insert(w.image().data);
        return std::move(w).publish();
    }
    Status seek(int64_t stamp) override {
        position_ = 0;
        while (position_ < stamps_.size() && stamps_[position_] < stamp)
            ++position_;
        return Status::ok();
    }
    std::set<const uint8_t*> handed_out;
    size_t cut_after = SIZE_MAX;  // next() fails as a truncated file does after this many frames

private:
    std::vector<int64_t> stamps_;
    std::vector<StreamInfo> streams_;
    std::vector<Attachment> attachments_;
    std::map<std::string, std::string> tags_;
    std::shared_ptr<BufferPool> pool_;
    size_t position_ = 0;
};

DeviceConfig config(std::map<std::string, std::string> options,
                    std::vector<std::string> streams = {}) {
    DeviceConfig c;
    c.name = "rec";
    c.driver = "replay";
    c.id = "memory";
    c.options = std::move(options);
    c.streams = std::move(streams);
    return c;
}

// Pops `queue` until it closes (or `limit` frames), copying frames out.
std::vector<test::OwnedFrame> drain(FrameQueue& queue, size_t limit = SIZE_MAX) {
    std::vector<test::OwnedFrame> frames;
    while (frames.size() < limit) {
        auto frame = queue.pop(std::chrono::seconds(10));
        if (!frame)
            break;
        frames.push_back({frame->meta(), Image::copyOf(frame->image())});
    }
    return frames;
}

// The graph API the device forwards frames with (frame.h): only a sole handle is reclaimed.
TEST(WritableFrameReclaim, OnlyTheSoleHandleBecomesWritableAgain) {
    auto pool = BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 4, 2), 0, 2, "p"});
    WritableFrame w = pool->acquire();
    w.meta().sequence = 5;
    FrameRef frame = std::move(w).publish();
    const uint8_t* data = frame.data();
    FrameRef other = frame;
    EXPECT_FALSE(WritableFrame::reclaim(frame));  // shared: must stay immutable
    EXPECT_TRUE(frame);
    other.reset();
    WritableFrame again = WritableFrame::reclaim(frame);
    ASSERT_TRUE(again);
    EXPECT_FALSE(frame);
    EXPECT_EQ(again.meta().sequence, 5u);
    again.meta().sequence = 6;
    FrameRef republished = std::move(again).publish();
    EXPECT_EQ(republished.data(), data);
    EXPECT_EQ(republished.meta().sequence, 6u);
    EXPECT_EQ(republished.useCount(), 1u);
    EXPECT_EQ(pool->inFlight(), 1u);
    republished.reset();
    EXPECT_EQ(pool->inFlight(), 0u);
    FrameRef empty;
    EXPECT_FALSE(WritableFrame::reclaim(empty));
}

TEST(ReplayOptions, ParsesAndExplainsMistakes) {
    auto options = ReplayOptions::fromConfig({{"pace", "original"},
                                              {"speed", "2.5"},
                                              {"loop", "true"},
                                              {"start", "1.25"},
                                              {"depth_units", "recorded"},
                                              {"buffers", "3"}});
    ASSERT_TRUE(options) << options.status().toString();
    EXPECT_EQ(options->pace, ReplayOptions::Pace::kOriginal);
    EXPECT_EQ(options->speed, 2.5);
    EXPECT_TRUE(options->loop);
    EXPECT_EQ(options->start_s, 1.25);
    EXPECT_FALSE(options->depth_in_mm);
    EXPECT_EQ(options->buffers_per_stream, 3u);
    auto defaults = ReplayOptions::fromConfig({});
    ASSERT_TRUE(defaults);
    EXPECT_EQ(defaults->pace, ReplayOptions::Pace::kOriginal);
    EXPECT_TRUE(defaults->depth_in_mm);

    const std::pair<std::map<std::string, std::string>, std::string> bad[] = {
        {{{"paec", "fast"}}, "unknown replay option 'paec' (known: pace, speed"},
        {{{"pace", "slow"}}, "pace='slow': expected original or fast"},
        {{{"speed", "0"}}, "speed='0': expected a positive number"},
        {{{"speed", "fast"}}, "speed='fast'"},
        {{{"loop", "maybe"}}, "loop='maybe': expected true or false"},
        {{{"start", "-1"}}, "start='-1'"},
        {{{"start", "1s"}}, "start='1s'"},
        {{{"buffers", "0"}}, "buffers='0'"},
        {{{"depth_units", "m"}}, "depth_units='m': expected mm or recorded"},
        {{{"pace", "fast"}, {"speed", "2"}}, "speed applies only with pace=original"},
    };
    for (const auto& [opts, message] : bad) {
        auto r = ReplayOptions::fromConfig(opts);
        ASSERT_FALSE(r) << message;
        EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument);
        EXPECT_TRUE(contains(r.status().message(), message)) << r.status().message();
    }
}

TEST(ReplayDevice, ForwardsTheReadersBuffersWithExactMetadata) {
    auto reader = std::make_unique<FakeReader>(std::vector<int64_t>{1000, 2000, 3000, 4000});
    FakeReader* fake = reader.get();
    auto device = openReplayDevice(std::move(reader), config({{"pace", "fast"}}));
    ASSERT_TRUE(device) << device.status().toString();
    EXPECT_EQ((*device)->name(), "rec");
    EXPECT_EQ((*device)->descriptor().backend, "replay");
    EXPECT_EQ((*device)->descriptor().model, "fake recording");
    ASSERT_EQ((*device)->descriptor().modes.size(), 1u);
    EXPECT_EQ((*device)->descriptor().modes[0], "mono 4x2 mono8");

    Graph graph;
    ReplayDevice* replay = device->get();
    ASSERT_TRUE(
        graph.addStream(StreamInfo{"other/stream", "other", StreamKind::kData, {}, 0, 0, {}}));
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto id = graph.findStream("rec/mono");
    ASSERT_TRUE(id);
    EXPECT_EQ(*id, 1u);  // not the recording's 0: ids are remapped
    const StreamInfo info = graph.stream(*id);
    EXPECT_EQ(info.device, "rec");
    EXPECT_EQ(info.kind, StreamKind::kMono);
    EXPECT_EQ(info.clock_domain, 7u);
    EXPECT_EQ(info.tags.at("lens"), "fisheye");
    auto queue = *graph.subscribe(*id, {8, QueuePolicy::kLossless, "test"});
    ASSERT_TRUE(graph.start());
    std::vector<FrameRef> frames;
    while (auto f = queue->pop(std::chrono::seconds(10)))
        frames.push_back(*f);
    graph.stop();
    ASSERT_EQ(frames.size(), 4u);
    for (size_t i = 0; i < frames.size(); ++i) {
        const FrameMetadata& m = frames[i].meta();
        EXPECT_EQ(m.stream, *id);
        EXPECT_EQ(m.sequence, 10 + i);
        EXPECT_EQ(m.host_stamp_ns, 1000 * static_cast<int64_t>(i + 1));
        EXPECT_EQ(m.device_stamp_ns, 1000 * static_cast<int64_t>(i + 1) + 5000);
        EXPECT_EQ(m.clock_domain, 7u);
        EXPECT_EQ(m.exposure_us, 250);
        EXPECT_EQ(m.status, i == 1 ? FrameStatus::kIncomplete : FrameStatus::kOk);
        EXPECT_EQ(frames[i].image().data[3], static_cast<uint8_t>(i * 8 + 3));
        // The very buffer the reader filled: no copy on the way.
        EXPECT_TRUE(fake->handed_out.count(frames[i].data())) << i;
    }
    EXPECT_TRUE(replay->finished());
    EXPECT_TRUE(replay->status());
    EXPECT_EQ(replay->publishedFrames(), 4u);
}

// A recording cut off: the frames before the cut are published, the streams end, and the
// device says why to whoever holds it as a Device (the AR pipeline, mixray play).
TEST(ReplayDevice, ACutOffRecordingIsSaidAsTheDevicesInputStatus) {
    auto reader = std::make_unique<FakeReader>(std::vector<int64_t>{1000, 2000, 3000, 4000});
    reader->cut_after = 2;
    auto device = openReplayDevice(std::move(reader), config({{"pace", "fast"}}));
    ASSERT_TRUE(device) << device.status().toString();
    Graph graph;
    const Device* replay = device->get();
    EXPECT_TRUE(replay->inputStatus());
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto queue = *graph.subscribe(*graph.findStream("rec/mono"), {8, QueuePolicy::kLossless, "t"});
    ASSERT_TRUE(graph.start());
    EXPECT_EQ(drain(*queue).size(), 2u);
    graph.stop();
    const Status input = replay->inputStatus();
    EXPECT_EQ(input.code(), ErrorCode::kCorruptData);
    EXPECT_TRUE(contains(input.message(),
                         "memory: file is cut off: it ends after 2 complete "
                         "frames"))
        << input.message();
}

TEST(ReplayDevice, RigModeRequestsMustDescribeTheRecording) {
    const std::vector<int64_t> stamps = {0, 33'333'333, 66'666'666};
    auto same =
        openReplayDevice(std::make_unique<FakeReader>(stamps), config({{"mono.width", "4"},
                                                                       {"mono.height", "2"},
                                                                       {"mono.format", "mono8"},
                                                                       {"mono.fps", "30"}}));
    EXPECT_TRUE(same) << same.status().toString();
    auto other =
        openReplayDevice(std::make_unique<FakeReader>(stamps), config({{"mono.width", "640"}}));
    ASSERT_FALSE(other);
    EXPECT_TRUE(contains(other.status().message(),
                         "the rig asks mono.width=640 but 'cam/mono' was recorded with width 4"))
        << other.status().message();
    auto missing =
        openReplayDevice(std::make_unique<FakeReader>(stamps), config({{"depth.width", "4"}}));
    ASSERT_FALSE(missing);
    EXPECT_TRUE(contains(missing.status().message(), "no stream 'depth'"));
}

TEST(ReplayDevice, WaitsWhileConsumersHoldEveryBuffer) {
    std::vector<int64_t> stamps;
    for (int i = 0; i < 40; ++i)
        stamps.push_back(i * 1000);
    auto device =
        openReplayDevice(std::make_unique<FakeReader>(stamps, 2), config({{"pace", "fast"}}));
    ASSERT_TRUE(device);
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto queue = *graph.subscribe(0, {16, QueuePolicy::kLossless, "slow"});
    ASSERT_TRUE(graph.start());
    std::vector<FrameRef> held;
    uint64_t expected = 10;
    while (auto f = queue->pop(std::chrono::seconds(10))) {
        EXPECT_EQ(f->meta().sequence, expected++);
        held.push_back(*f);
        if (held.size() == 2) {  // the reader's whole pool: it must wait for us
            std::this_thread::sleep_for(milliseconds(5));
            held.clear();
        }
    }
    graph.stop();
    EXPECT_EQ(expected, 50u);
}

TEST(ReplayDevice, LoopKeepsStampsAndSequencesIncreasing) {
    auto device =
        openReplayDevice(std::make_unique<FakeReader>(std::vector<int64_t>{100, 200, 300}),
                         config({{"pace", "fast"}, {"loop", "true"}}));
    ASSERT_TRUE(device);
    ReplayDevice* replay = device->get();
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto queue = *graph.subscribe(0, {4, QueuePolicy::kLossless, "test"});
    ASSERT_TRUE(graph.start());
    const auto frames = drain(*queue, 10);
    graph.stop();
    ASSERT_EQ(frames.size(), 10u);
    // One pass lasts 300 - 100 + one mean interval (100): the second pass starts at 400.
    for (size_t i = 0; i < frames.size(); ++i) {
        EXPECT_EQ(frames[i].meta.host_stamp_ns, 100 * static_cast<int64_t>(i + 1)) << i;
        EXPECT_EQ(frames[i].meta.device_stamp_ns, 100 * static_cast<int64_t>(i + 1) + 5000);
        EXPECT_EQ(frames[i].meta.sequence, 10 + i);
        // Pixels repeat each pass.
        EXPECT_EQ(frames[i].image.view().data[0], static_cast<uint8_t>((i % 3) * 8));
    }
    EXPECT_GE(replay->passes(), 3u);
}

TEST(ReplayDevice, StartSeeksAndPastTheEndIsAnError) {
    auto device = openReplayDevice(std::make_unique<FakeReader>(std::vector<int64_t>{
                                       1'000'000'000, 1'100'000'000, 1'200'000'000, 1'300'000'000}),
                                   config({{"pace", "fast"}, {"start", "0.15"}}));
    ASSERT_TRUE(device) << device.status().toString();
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto queue = *graph.subscribe(0, {8, QueuePolicy::kLossless, "test"});
    ASSERT_TRUE(graph.start());
    const auto frames = drain(*queue);
    graph.stop();
    ASSERT_EQ(frames.size(), 2u);  // 1.2 s and 1.3 s: the first at or after 1.0 + 0.15
    EXPECT_EQ(frames[0].meta.host_stamp_ns, 1'200'000'000);
    EXPECT_EQ(frames[0].meta.sequence, 12u);

    auto past = openReplayDevice(std::make_unique<FakeReader>(std::vector<int64_t>{0, 1000}),
                                 config({{"start", "2"}}));
    ASSERT_FALSE(past);
    EXPECT_EQ(past.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_TRUE(contains(past.status().message(), "start=2 s is past the last frame"));

    auto empty = openReplayDevice(std::make_unique<FakeReader>(std::vector<int64_t>{}), config({}));
    ASSERT_FALSE(empty);
    EXPECT_TRUE(contains(empty.status().message(), "no frames"));
}

TEST(ReplayDevice, OriginalPaceTakesTheRecordingsDuration) {
    // Five frames 50 ms apart: 200 ms at speed 1, 100 ms at speed 2.
    std::vector<int64_t> stamps;
    for (int i = 0; i < 5; ++i)
        stamps.push_back(7'000'000'000 + i * 50'000'000);
    for (const double speed : {1.0, 2.0}) {
        auto device = openReplayDevice(std::make_unique<FakeReader>(stamps),
                                       config({{"speed", std::to_string(speed)}}));
        ASSERT_TRUE(device) << device.status().toString();
        Graph graph;
        ASSERT_TRUE(graph.addNode(std::move(*device)));
        auto queue = *graph.subscribe(0, {8, QueuePolicy::kLossless, "test"});
        const auto t0 = Clock::now();
        ASSERT_TRUE(graph.start());
        const auto frames = drain(*queue);
        const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        graph.stop();
        ASSERT_EQ(frames.size(), 5u);
        const double expected = 0.2 / speed;
        EXPECT_GE(seconds, expected * 0.9) << "speed " << speed;
        EXPECT_LT(seconds, expected + 1.0) << "speed " << speed;  // loose: shared CI machines
    }
}

TEST(ReplayDevice, ArrivalStampsKeepTheRecordingsTimingWhenDeliveryIsLate) {
    // Two frames of one instant, then two 50 ms apart; a consumer that takes 300 ms per frame
    // makes the replay deliver late. The host stamps are still the recording's instants on the
    // host clock (frames of one instant keep one stamp); the lateness is in graph_stamp_ns.
    const std::vector<int64_t> stamps{7'000'000'000, 7'000'000'000, 7'050'000'000, 7'100'000'000};
    auto device =
        openReplayDevice(std::make_unique<FakeReader>(stamps), config({{"stamps", "arrival"}}));
    ASSERT_TRUE(device) << device.status().toString();
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto queue = *graph.subscribe(0, {1, QueuePolicy::kLossless, "slow"});
    const auto monotonicNs = [] {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
            .count();
    };
    const int64_t before = monotonicNs();
    ASSERT_TRUE(graph.start());
    std::vector<test::OwnedFrame> frames;
    while (auto frame = queue->pop(std::chrono::seconds(10))) {
        frames.push_back({frame->meta(), Image::copyOf(frame->image())});
        std::this_thread::sleep_for(milliseconds(300));
    }
    const int64_t after = monotonicNs();
    graph.stop();
    ASSERT_EQ(frames.size(), 4u);
    EXPECT_EQ(frames[0].meta.host_stamp_ns, frames[1].meta.host_stamp_ns);
    for (size_t i : {2, 3})
        EXPECT_NEAR(
            static_cast<double>(frames[i].meta.host_stamp_ns - frames[0].meta.host_stamp_ns),
            50e6 * static_cast<double>(i - 1), 1.0);
    for (const auto& f : frames) {
        EXPECT_GE(f.meta.host_stamp_ns, before);
        EXPECT_LE(f.meta.host_stamp_ns, after);
        EXPECT_GE(f.meta.graph_stamp_ns, f.meta.host_stamp_ns);
    }
    // The last frame waited behind the slow consumer (its predecessor's publish blocked until
    // the consumer took the second frame, at about 300 ms), well past its 100 ms.
    EXPECT_GT(frames[3].meta.graph_stamp_ns - frames[3].meta.host_stamp_ns, 100'000'000);
}

TEST(ReplayDevice, StopInterruptsPacingAndBlockedPublishes) {
    auto device = openReplayDevice(
        std::make_unique<FakeReader>(std::vector<int64_t>{0, 60'000'000'000}), config({}));
    ASSERT_TRUE(device);
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    auto never_read = *graph.subscribe(0, {1, QueuePolicy::kLossless, "stuck"});
    ASSERT_TRUE(graph.start());
    std::this_thread::sleep_for(milliseconds(20));
    const auto t0 = Clock::now();
    graph.stop();  // the device sleeps towards a frame a minute away
    EXPECT_LT(Clock::now() - t0, std::chrono::seconds(2));
}

TEST(ReplayDevice, TumDepthBecomesMillimetresUnlessRecordedUnitsAreAsked) {
    const auto dir = test::tempDir() / "tum";
    test::writeSyntheticTum(dir, 6);
    auto reference = openTum(dir);
    ASSERT_TRUE(reference);
    const auto expected = test::readAll(**reference);

    for (const bool recorded : {false, true}) {
        SCOPED_TRACE(recorded ? "depth_units=recorded" : "depth_units=mm");
        auto reader = openTum(dir);
        ASSERT_TRUE(reader);
        auto device = openReplayDevice(
            std::move(*reader),
            config({{"pace", "fast"}, {"depth_units", recorded ? "recorded" : "mm"}}));
        ASSERT_TRUE(device) << device.status().toString();
        Graph graph;
        ASSERT_TRUE(graph.addNode(std::move(*device)));
        const StreamId color = *graph.findStream("rec/color");
        const StreamId depth = *graph.findStream("rec/depth");
        EXPECT_EQ(graph.stream(depth).tags.count(kDepthScaleTag), recorded ? 1u : 0u);
        auto color_queue = *graph.subscribe(color, {4, QueuePolicy::kLossless, "c"});
        auto depth_queue = *graph.subscribe(depth, {4, QueuePolicy::kLossless, "d"});
        ASSERT_TRUE(graph.start());
        std::vector<test::OwnedFrame> colors;
        std::thread color_thread([&] { colors = drain(*color_queue); });
        const auto depths = drain(*depth_queue);
        color_thread.join();
        graph.stop();
        ASSERT_EQ(colors.size(), 6u);
        ASSERT_EQ(depths.size(), 6u);
        size_t c = 0, d = 0;
        for (const auto& e : expected) {
            const bool is_depth = e.meta.stream == 1;
            const test::OwnedFrame& got = is_depth ? depths[d++] : colors[c++];
            EXPECT_EQ(got.meta.host_stamp_ns, e.meta.host_stamp_ns);
            EXPECT_EQ(got.meta.device_stamp_ns, e.meta.device_stamp_ns);
            EXPECT_EQ(got.meta.sequence, e.meta.sequence);
            EXPECT_EQ(got.meta.stream, is_depth ? depth : color);
            if (!is_depth || recorded) {
                EXPECT_TRUE(sameImage(got.image.view(), e.image.view()));
            } else {
                Image mm(e.image.desc());
                ASSERT_TRUE(rescaleDepth(e.image.view(), 5000, mm.mutableView(), 1000));
                EXPECT_TRUE(sameImage(got.image.view(), mm.view()));
            }
        }
    }
}

TEST(ReplayDevice, StreamFilterDeclaresOnlyWhatIsAsked) {
    const auto dir = test::tempDir() / "tum";
    test::writeSyntheticTum(dir, 2);
    auto reader = openTum(dir);
    ASSERT_TRUE(reader);
    auto device = openReplayDevice(std::move(*reader), config({{"pace", "fast"}}, {"depth"}));
    ASSERT_TRUE(device) << device.status().toString();
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*device)));
    EXPECT_EQ(graph.streamCount(), 1u);
    EXPECT_EQ(graph.stream(0).name, "rec/depth");
    auto queue = *graph.subscribe(0, {8, QueuePolicy::kLossless, "d"});
    ASSERT_TRUE(graph.start());
    EXPECT_EQ(drain(*queue).size(), 2u);
    graph.stop();

    auto again = openTum(dir);
    auto unknown = openReplayDevice(std::move(*again), config({}, {"ir"}));
    ASSERT_FALSE(unknown);
    EXPECT_EQ(unknown.status().code(), ErrorCode::kNotFound);
    EXPECT_TRUE(contains(unknown.status().message(), "no stream 'ir' (it has: color, depth)"))
        << unknown.status().message();
}

}  // namespace
}  // namespace mixray::replay
