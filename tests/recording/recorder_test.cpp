// The recorder node: lossless and live recording from a graph, host-stamp order, stream
// subsets, drops under a slow disk, and a full disk that leaves a valid file.
#include "mixray/graph/recorder.h"

#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/resource.h>

#include <csignal>
#include <thread>

#include "recording_test_util.h"
#include "test_data.h"

namespace mixray {
namespace {

using std::chrono::milliseconds;
using test::ExpectedFrame;

class RecorderTest : public ::testing::Test {
protected:
    static void SetUpTestSuite() { setFfmpegLogging(false); }
};

StreamId addStream(Graph& graph, const StreamInfo& info) {
    auto id = graph.addStream(info);
    EXPECT_TRUE(id) << id.status().toString();
    return id ? *id : kInvalidStream;
}

// Publishes one synthetic frame of `stream` and returns it.
FrameRef publish(Graph& graph, StreamId stream, uint64_t sequence, int64_t host_ns) {
    FrameMetadata meta;
    meta.stream = stream;
    meta.sequence = sequence;
    meta.host_stamp_ns = host_ns;
    meta.device_stamp_ns = host_ns / 2 + 17;
    meta.exposure_us = 1000 + static_cast<int64_t>(sequence);
    FrameRef frame =
        test::makeFrame(graph.stream(stream), meta, static_cast<uint32_t>(sequence * 13 + stream));
    graph.publish(frame);
    return frame;
}

// Reads a whole recording; `end` gets the final status.
std::vector<FrameRef> readRecording(const std::filesystem::path& path, Status* end,
                                    std::vector<StreamInfo>* streams = nullptr) {
    auto reader = openMkv(path);
    EXPECT_TRUE(reader) << reader.status().toString();
    if (!reader)
        return {};
    if (streams)
        *streams = (*reader)->streams();
    return test::readAll(**reader, end);
}

TEST_F(RecorderTest, RecordsAllStreamsLosslesslyInHostStampOrder) {
    const auto path = test::tempDir() / "session.mkv";
    Graph graph;
    const StreamId depth =
        addStream(graph, test::makeStream("kinect/depth", PixelFormat::kDepth16, 16, 12));
    const StreamId imu =
        addStream(graph, test::makeStream("kinect/imu", PixelFormat::kBinary, 0, 1));
    RecorderOptions options;
    options.path = path;
    options.policy = QueuePolicy::kLossless;
    options.queue_capacity = 64;
    options.attachments = {{"rig.yaml", "application/x-yaml", {'r', 'i', 'g'}}};
    options.tags = {{"operator", "test"}};
    auto recorder = std::make_unique<Recorder>(options);
    Recorder* rec = recorder.get();
    ASSERT_TRUE(graph.addNode(std::move(recorder)));

    // Queued before the recorder starts: it sees every stream's head and merges by host time,
    // although depth frames were published first.
    std::vector<ExpectedFrame> expected;
    std::vector<FrameRef> depth_frames;
    std::vector<FrameRef> imu_frames;
    for (int i = 0; i < 10; ++i)
        depth_frames.push_back(publish(graph, depth, i, 1'000'000 + i * 10'000'000));
    for (int i = 0; i < 20; ++i)
        imu_frames.push_back(publish(graph, imu, i, 1'500'000 + i * 5'000'000));
    ASSERT_TRUE(graph.start());
    for (int i = 10; i < 15; ++i)
        depth_frames.push_back(publish(graph, depth, i, 1'000'000 + i * 10'000'000));
    graph.stop();

    const RecorderStats stats = rec->stats();
    EXPECT_TRUE(stats.error.isOk()) << stats.error.toString();
    EXPECT_FALSE(stats.writing);
    ASSERT_EQ(stats.streams.size(), 2u);
    EXPECT_EQ(stats.streams[0].stream, "kinect/depth");
    EXPECT_EQ(stats.streams[0].written, 15u);
    EXPECT_EQ(stats.streams[1].written, 20u);
    EXPECT_EQ(stats.frames_dropped, 0u);
    EXPECT_EQ(stats.bytes_written, std::filesystem::file_size(path));
    EXPECT_NE(stats.summary().find("recorded 35 frames"), std::string::npos) << stats.summary();

    for (const FrameRef& f : depth_frames)
        expected.push_back({f, f.meta()});
    for (const FrameRef& f : imu_frames)
        expected.push_back({f, f.meta()});
    std::stable_sort(expected.begin(), expected.end(), [](const auto& a, const auto& b) {
        return a.meta.host_stamp_ns < b.meta.host_stamp_ns;
    });
    Status end;
    std::vector<StreamInfo> streams;
    auto frames = readRecording(path, &end, &streams);
    EXPECT_EQ(end.code(), ErrorCode::kEndOfStream) << end.toString();
    test::expectSameStreams(streams, graph.streams());
    ASSERT_EQ(frames.size(), expected.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        test::expectSameFrame(frames[i], expected[i], "frame " + std::to_string(i));
    }
}

TEST_F(RecorderTest, ASlowStreamHoldsBackOnlyFramesWithinOneOfItsPeriods) {
    // A 30 fps camera and a 2 fps fish-eye. Once the fish-eye's frame at 0 is written, its
    // next cannot come before 0.4 s (80 % of its period): the camera's frames until then are
    // written at once, without waiting for the reorder window (here an hour); later ones wait
    // for the fish-eye's next frame, which puts them back in order.
    const auto path = test::tempDir() / "slow_stream.mkv";
    Graph graph;
    StreamInfo camera_info = test::makeStream("cam/color", PixelFormat::kRGB8, 8, 6);
    camera_info.nominal_fps = 30;
    StreamInfo fisheye_info = test::makeStream("env/color", PixelFormat::kRGB8, 8, 6);
    fisheye_info.nominal_fps = 2;
    const StreamId camera = addStream(graph, camera_info);
    const StreamId fisheye = addStream(graph, fisheye_info);
    RecorderOptions options;
    options.path = path;
    options.policy = QueuePolicy::kLossless;
    options.queue_capacity = 64;
    options.reorder_window = std::chrono::hours(1);
    auto recorder = std::make_unique<Recorder>(options);
    Recorder* rec = recorder.get();
    ASSERT_TRUE(graph.addNode(std::move(recorder)));
    ASSERT_TRUE(graph.start());
    const int64_t period = 33'333'333;
    publish(graph, fisheye, 0, 0);
    publish(graph, camera, 0, 1'000'000);  // after it: both heads there, the fish-eye's goes
    const auto written = [rec] {
        const RecorderStats stats = rec->stats();
        return stats.streams[0].written + stats.streams[1].written;
    };
    const auto waitWritten = [&](uint64_t n) {
        for (int i = 0; i < 1000 && written() < n; ++i)
            std::this_thread::sleep_for(milliseconds(10));
        return written();
    };
    // Camera frames 1..11 (up to 0.368 s) come before the fish-eye's next can.
    for (int i = 1; i < 12; ++i)
        publish(graph, camera, i, 1'000'000 + i * period);
    EXPECT_EQ(waitWritten(13), 13u);
    // 0.401 s and on: the fish-eye may bring an older frame, so they wait for it.
    for (int i = 12; i < 15; ++i)
        publish(graph, camera, i, 1'000'000 + i * period);
    std::this_thread::sleep_for(milliseconds(300));
    EXPECT_EQ(written(), 13u);
    // It brings one at 0.5 s: the three older camera frames go, it waits for the camera's next.
    publish(graph, fisheye, 1, 500'000'000);
    EXPECT_EQ(waitWritten(16), 16u);
    graph.stop();
    EXPECT_EQ(rec->stats().frames_dropped, 0u);

    Status end;
    auto frames = readRecording(path, &end);
    ASSERT_EQ(frames.size(), 17u);
    for (size_t i = 1; i < frames.size(); ++i)
        EXPECT_LE(frames[i - 1].meta().host_stamp_ns, frames[i].meta().host_stamp_ns) << i;
}

TEST_F(RecorderTest, AStreamThatHasNotStartedHoldsTheOthersBackOnlyOnce) {
    // A 30 fps camera records while the other camera of the rig has sent nothing yet (it is on
    // another host and starts later). The camera's first frame waits out the reorder window;
    // after that nobody waits for the silent stream until it brings a frame, so the camera is
    // written at its own rate, not one frame per window.
    const auto path = test::tempDir() / "late_stream.mkv";
    Graph graph;
    StreamInfo camera_info = test::makeStream("cam/color", PixelFormat::kRGB8, 8, 6);
    camera_info.nominal_fps = 30;
    StreamInfo late_info = test::makeStream("late/color", PixelFormat::kRGB8, 8, 6);
    late_info.nominal_fps = 30;
    const StreamId camera = addStream(graph, camera_info);
    const StreamId late = addStream(graph, late_info);
    RecorderOptions options;
    options.path = path;
    options.policy = QueuePolicy::kLossless;
    options.queue_capacity = 64;
    options.reorder_window = milliseconds(100);
    auto recorder = std::make_unique<Recorder>(options);
    Recorder* rec = recorder.get();
    ASSERT_TRUE(graph.addNode(std::move(recorder)));
    ASSERT_TRUE(graph.start());
    const auto written = [rec](size_t stream) { return rec->stats().streams[stream].written; };
    const int64_t period = 33'333'333;
    for (int i = 0; i < 30; ++i) {
        publish(graph, camera, i, 1'000'000 + i * period);
        std::this_thread::sleep_for(milliseconds(33));
    }
    for (int i = 0; i < 100 && written(0) < 30; ++i)
        std::this_thread::sleep_for(milliseconds(10));
    // One window per frame would have written about ten in the second.
    EXPECT_EQ(written(0), 30u);
    // The late stream starts: written in order with what comes after.
    publish(graph, late, 0, 1'000'000 + 30 * period);
    publish(graph, camera, 30, 1'000'000 + 31 * period);
    graph.stop();
    EXPECT_EQ(written(1), 1u);
    EXPECT_EQ(written(0), 31u);
    EXPECT_EQ(rec->stats().frames_dropped, 0u);
}

TEST_F(RecorderTest, RecordsAChosenSubsetWithItsOwnStreamIds) {
    const auto path = test::tempDir() / "subset.mkv";
    Graph graph;
    const StreamId a = addStream(graph, test::makeStream("cam/a", PixelFormat::kMono8, 8, 8));
    const StreamId b = addStream(graph, test::makeStream("cam/b", PixelFormat::kRGB8, 8, 8));
    const StreamId c = addStream(graph, test::makeStream("cam/c", PixelFormat::kMono16, 8, 8));
    RecorderOptions options;
    options.path = path;
    options.policy = QueuePolicy::kLossless;
    options.streams = {"cam/c", "cam/a"};
    auto recorder = std::make_unique<Recorder>(options);
    Recorder* rec = recorder.get();
    ASSERT_TRUE(graph.addNode(std::move(recorder)));
    ASSERT_TRUE(graph.start());
    std::vector<ExpectedFrame> expected;
    for (int i = 0; i < 4; ++i) {
        FrameRef fa = publish(graph, a, i, 100 + i * 3);
        publish(graph, b, i, 101 + i * 3);
        FrameRef fc = publish(graph, c, i, 102 + i * 3);
        FrameMetadata ma = fa.meta();
        ma.stream = 1;  // cam/a is the recording's second stream
        FrameMetadata mc = fc.meta();
        mc.stream = 0;
        expected.push_back({fa, ma});
        expected.push_back({fc, mc});
    }
    graph.stop();
    EXPECT_TRUE(rec->stats().error.isOk()) << rec->stats().error.toString();
    ASSERT_EQ(rec->header().streams.size(), 2u);
    EXPECT_EQ(rec->header().streams[0].name, "cam/c");

    Status end;
    std::vector<StreamInfo> streams;
    auto frames = readRecording(path, &end, &streams);
    ASSERT_EQ(streams.size(), 2u);
    EXPECT_EQ(streams[0].name, "cam/c");
    EXPECT_EQ(streams[1].name, "cam/a");
    ASSERT_EQ(frames.size(), expected.size());
    for (size_t i = 0; i < frames.size(); ++i) {
        test::expectSameFrame(frames[i], expected[i], "frame " + std::to_string(i));
    }
}

TEST_F(RecorderTest, ConnectRefusesUnknownStreamsAndBadOptions) {
    Graph graph;
    addStream(graph, test::makeStream("cam/a", PixelFormat::kMono8, 8, 8));
    RecorderOptions options;
    options.path = test::tempDir() / "x.mkv";
    options.streams = {"cam/nope"};
    Status unknown = graph.addNode(std::make_unique<Recorder>(options));
    EXPECT_EQ(unknown.code(), ErrorCode::kNotFound);
    EXPECT_NE(unknown.message().find("cam/nope"), std::string::npos) << unknown.message();
    EXPECT_NE(unknown.message().find("cam/a"), std::string::npos) << unknown.message();

    RecorderOptions no_path;
    EXPECT_EQ(graph.addNode(std::make_unique<Recorder>(no_path)).code(),
              ErrorCode::kInvalidArgument);
    RecorderOptions zero_queue;
    zero_queue.path = options.path;
    zero_queue.queue_capacity = 0;
    EXPECT_EQ(graph.addNode(std::make_unique<Recorder>(zero_queue)).code(),
              ErrorCode::kInvalidArgument);
}

// A writer that takes its time, like a slow disk.
class SlowWriter : public RecordingWriter {
public:
    SlowWriter(std::unique_ptr<RecordingWriter> inner, milliseconds delay)
        : inner_(std::move(inner)), delay_(delay) {}
    Status write(const FrameRef& frame) override {
        std::this_thread::sleep_for(delay_);
        return inner_->write(frame);
    }
    Status writeAs(StreamId stream, const FrameRef& frame) override {
        std::this_thread::sleep_for(delay_);
        return inner_->writeAs(stream, frame);
    }
    Status close() override { return inner_->close(); }
    uint64_t bytesWritten() const override { return inner_->bytesWritten(); }

private:
    std::unique_ptr<RecordingWriter> inner_;
    milliseconds delay_;
};

// A recorder of `path` whose writer takes `delay` per frame: a disk too slow for its streams.
// It may fall `backlog` behind before it drops (none by default).
RecorderOptions slowDiskRecorder(const std::filesystem::path& path, QueuePolicy policy,
                                 size_t queue_capacity, milliseconds delay,
                                 milliseconds backlog = milliseconds(0)) {
    RecorderOptions options;
    options.path = path;
    options.policy = policy;
    options.queue_capacity = queue_capacity;
    options.backlog = backlog;
    options.writer_factory =
        [path, delay](const RecordingHeader& header) -> Result<std::unique_ptr<RecordingWriter>> {
        auto writer = createMkvWriter(path, header);
        if (!writer)
            return writer.status();
        return std::unique_ptr<RecordingWriter>(
            std::make_unique<SlowWriter>(std::move(*writer), delay));
    };
    return options;
}

// 60 frames of a 16x16 depth stream published at once into `options`' recorder, the way a
// driver would: what was published, how long publishing took, and the recorder's figures.
struct BurstOutcome {
    std::map<uint64_t, FrameRef> published;
    std::chrono::steady_clock::duration publishing{};
    RecorderStats stats;
};

BurstOutcome publishBurst(RecorderOptions options) {
    BurstOutcome out;
    Graph graph;
    const StreamId depth =
        addStream(graph, test::makeStream("cam/depth", PixelFormat::kDepth16, 16, 16));
    auto recorder = std::make_unique<Recorder>(std::move(options));
    Recorder* rec = recorder.get();
    EXPECT_TRUE(graph.addNode(std::move(recorder)));
    EXPECT_TRUE(graph.start());
    const auto begin = std::chrono::steady_clock::now();
    for (uint64_t i = 0; i < 60; ++i)
        out.published[i] = publish(graph, depth, i, 1'000'000 * static_cast<int64_t>(i + 1));
    out.publishing = std::chrono::steady_clock::now() - begin;
    graph.stop();
    out.stats = rec->stats();
    return out;
}

// The file at `path` reads to its end and holds `count` frames, each exactly as published.
void expectFileHoldsPublishedFrames(const std::filesystem::path& path,
                                    const std::map<uint64_t, FrameRef>& published, size_t count) {
    Status end;
    auto frames = readRecording(path, &end);
    EXPECT_EQ(end.code(), ErrorCode::kEndOfStream) << end.toString();
    ASSERT_EQ(frames.size(), count);
    for (const FrameRef& f : frames) {
        const FrameRef& original = published.at(f.meta().sequence);
        EXPECT_TRUE(test::sameFrame(f, {original, original.meta()})) << f.meta().sequence;
    }
}

TEST_F(RecorderTest, LivePolicyDropsAndCountsInsteadOfBlockingTheDriver) {
    const auto path = test::tempDir() / "slow.mkv";
    const BurstOutcome burst =
        publishBurst(slowDiskRecorder(path, QueuePolicy::kLive, 4, milliseconds(30)));
    // A lossless queue would have held the driver for about 60 x 30 ms.
    EXPECT_LT(burst.publishing, milliseconds(600));
    const RecorderStats& stats = burst.stats;
    EXPECT_TRUE(stats.error.isOk()) << stats.error.toString();
    ASSERT_EQ(stats.streams.size(), 1u);
    EXPECT_GT(stats.streams[0].dropped, 0u);
    EXPECT_EQ(stats.streams[0].written + stats.streams[0].dropped, 60u);
    EXPECT_NE(stats.summary().find("dropped"), std::string::npos) << stats.summary();
    // What was written is valid and exact.
    expectFileHoldsPublishedFrames(path, burst.published, stats.streams[0].written);
}

// A writer held up for a while (here 60 frames at 30 ms against frames published at once) costs
// no frame while its backlog lasts: the frames beyond queue_capacity wait as copies, the driver
// is never held up, and the file has every frame, exact.
TEST_F(RecorderTest, LivePolicyKeepsEveryFrameWhileTheWriterIsBehindByLessThanItsBacklog) {
    const auto path = test::tempDir() / "behind.mkv";
    // Three seconds of the 30 fps stream (90 frames) may wait, beyond the four queued.
    const BurstOutcome burst = publishBurst(
        slowDiskRecorder(path, QueuePolicy::kLive, 4, milliseconds(30), milliseconds(3000)));
    EXPECT_LT(burst.publishing, milliseconds(600));
    const RecorderStats& stats = burst.stats;
    EXPECT_TRUE(stats.error.isOk()) << stats.error.toString();
    EXPECT_EQ(stats.frames_dropped, 0u) << stats.summary();
    EXPECT_EQ(stats.frames_written, 60u);
    EXPECT_GT(stats.frames_spilled, 0u);
    EXPECT_NE(stats.summary().find("waited in memory"), std::string::npos) << stats.summary();
    expectFileHoldsPublishedFrames(path, burst.published, 60);
}

TEST_F(RecorderTest, LosslessPolicyHoldsTheDriverAndSaysForHowLong) {
    const auto path = test::tempDir() / "slow_lossless.mkv";
    Graph graph;
    const StreamId depth =
        addStream(graph, test::makeStream("cam/depth", PixelFormat::kDepth16, 16, 16));
    auto recorder = std::make_unique<Recorder>(
        slowDiskRecorder(path, QueuePolicy::kLossless, 2, milliseconds(20)));
    Recorder* rec = recorder.get();
    ASSERT_TRUE(graph.addNode(std::move(recorder)));
    ASSERT_TRUE(graph.start());
    constexpr int kFrames = 12;
    for (int i = 0; i < kFrames; ++i)
        publish(graph, depth, i, 1'000'000 * (i + 1));
    graph.stop();

    const RecorderStats stats = rec->stats();
    EXPECT_TRUE(stats.error.isOk()) << stats.error.toString();
    EXPECT_EQ(stats.frames_written, static_cast<uint64_t>(kFrames));
    EXPECT_EQ(stats.frames_dropped, 0u);
    // Twelve frames into two slots at 20 ms a frame: the driver waited most of the time.
    EXPECT_GT(stats.producer_waits, 0u);
    EXPECT_GT(stats.producer_waited_s, 0.05);
    EXPECT_NE(stats.summary().find("waited for the disk"), std::string::npos) << stats.summary();
}

// Lowers this process's file size limit (and ignores SIGXFSZ, so writes fail with EFBIG like
// on a full disk) for its lifetime.
class FileSizeLimit {
public:
    explicit FileSizeLimit(rlim_t bytes) {
        getrlimit(RLIMIT_FSIZE, &saved_);
        old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
        rlimit limit = saved_;
        limit.rlim_cur = bytes;
        ok_ = setrlimit(RLIMIT_FSIZE, &limit) == 0;
    }
    ~FileSizeLimit() {
        setrlimit(RLIMIT_FSIZE, &saved_);
        std::signal(SIGXFSZ, old_handler_);
    }
    bool ok() const { return ok_; }

private:
    rlimit saved_{};
    void (*old_handler_)(int) = SIG_DFL;
    bool ok_ = false;
};

TEST_F(RecorderTest, FullDiskStopsWritingReportsAndLeavesAValidFile) {
    const auto path = test::tempDir() / "full.mkv";
    Graph graph;
    const StreamId depth =
        addStream(graph, test::makeStream("cam/depth", PixelFormat::kDepth16, 64, 48));
    RecorderOptions options;
    options.path = path;
    options.policy = QueuePolicy::kLossless;
    options.queue_capacity = 8;
    auto recorder = std::make_unique<Recorder>(options);
    Recorder* rec = recorder.get();
    ASSERT_TRUE(graph.addNode(std::move(recorder)));

    constexpr int kFrames = 40;
    std::map<uint64_t, FrameRef> published;
    constexpr rlim_t kLimit = 48 * 1024;  // room for the header and a few noisy frames
    {
        FileSizeLimit limit(kLimit);
        ASSERT_TRUE(limit.ok());
        ASSERT_TRUE(graph.start());
        // Lossless, yet the driver is never stuck: after the error the recorder drains.
        for (int i = 0; i < kFrames; ++i)
            published[i] = publish(graph, depth, i, 1'000'000 * (i + 1));
        graph.stop();
    }

    const RecorderStats stats = rec->stats();
    ASSERT_FALSE(stats.error.isOk()) << "the file size limit was never hit";
    EXPECT_EQ(stats.error.code(), ErrorCode::kIoError) << stats.error.toString();
    EXPECT_NE(stats.error.message().find(path.string()), std::string::npos)
        << stats.error.toString();
    EXPECT_NE(stats.summary().find("stopped"), std::string::npos) << stats.summary();
    ASSERT_EQ(stats.streams.size(), 1u);
    EXPECT_GT(stats.streams[0].written, 0u);
    EXPECT_GT(stats.streams[0].discarded, 0u);
    EXPECT_EQ(stats.streams[0].written + stats.streams[0].discarded,
              static_cast<uint64_t>(kFrames));
    EXPECT_LE(std::filesystem::file_size(path), kLimit);

    // Every frame reported written reads back exactly; then the cut is reported.
    Status end;
    auto frames = readRecording(path, &end);
    EXPECT_EQ(end.code(), ErrorCode::kCorruptData) << end.toString();
    ASSERT_EQ(frames.size(), stats.streams[0].written);
    for (size_t i = 0; i < frames.size(); ++i) {
        const FrameRef& original = published.at(i);
        EXPECT_TRUE(test::sameFrame(frames[i], {original, original.meta()})) << i;
    }
}

// A real full disk: a 256 KiB tmpfs mounted for the test (root only; skipped elsewhere).
class SmallTmpfs {
public:
    explicit SmallTmpfs(const std::filesystem::path& where) : path_(where) {
        std::filesystem::create_directories(where);
        mounted_ = ::mount("tmpfs", where.c_str(), "tmpfs", 0, "size=256k") == 0;
    }
    ~SmallTmpfs() {
        if (mounted_)
            ::umount2(path_.c_str(), MNT_DETACH);
    }
    bool mounted() const { return mounted_; }

private:
    std::filesystem::path path_;
    bool mounted_ = false;
};

TEST_F(RecorderTest, ARealFullDiskStopsWritingSaysSoAndLeavesAValidFile) {
    const auto dir = test::tempDir() / "small_disk";
    SmallTmpfs disk(dir);
    if (!disk.mounted())
        GTEST_SKIP() << "cannot mount a tmpfs here (needs root): the file size limit test "
                        "covers the same path";
    const auto path = dir / "full.mkv";
    Graph graph;
    const StreamId depth =
        addStream(graph, test::makeStream("cam/depth", PixelFormat::kDepth16, 64, 48));
    RecorderOptions options;
    options.path = path;
    options.policy = QueuePolicy::kLive;
    options.queue_capacity = 4;
    auto recorder = std::make_unique<Recorder>(options);
    Recorder* rec = recorder.get();
    ASSERT_TRUE(graph.addNode(std::move(recorder)));
    ASSERT_TRUE(graph.start());
    // Noisy 64x48 depth frames hardly compress: 200 of them do not fit in 256 KiB.
    constexpr int kFrames = 200;
    std::map<uint64_t, FrameRef> published;
    for (int i = 0; i < kFrames; ++i) {
        published[i] = publish(graph, depth, i, 1'000'000 * (i + 1));
        std::this_thread::sleep_for(milliseconds(1));
    }
    graph.stop();

    const RecorderStats stats = rec->stats();
    ASSERT_FALSE(stats.error.isOk()) << "the disk never filled";
    EXPECT_EQ(stats.error.code(), ErrorCode::kIoError) << stats.error.toString();
    EXPECT_NE(stats.error.message().find(path.string()), std::string::npos)
        << stats.error.toString();
    EXPECT_NE(stats.summary().find("stopped"), std::string::npos) << stats.summary();
    EXPECT_EQ(stats.frames_written + stats.frames_dropped + stats.frames_discarded,
              static_cast<uint64_t>(kFrames));
    Status end;
    auto frames = readRecording(path, &end);
    EXPECT_EQ(end.code(), ErrorCode::kCorruptData) << end.toString();
    EXPECT_GT(frames.size(), 0u);
    EXPECT_LE(frames.size(), stats.frames_written);
    for (const FrameRef& f : frames) {
        const FrameRef& original = published.at(f.meta().sequence);
        EXPECT_TRUE(test::sameFrame(f, {original, original.meta()})) << f.meta().sequence;
    }
}

}  // namespace
}  // namespace mixray
