// The capture tests every backend must pass (compliance_suite.h): start/stop cycles,
// reconfiguration, slow consumers, stop with frames in flight, bad configurations.
#include "compliance_suite.h"

#include <chrono>
#include <cstring>
#include <set>
#include <thread>

#include "mixray/graph/graph.h"

namespace mixray::compliance {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using Clock = std::chrono::steady_clock;

// A device opened into its own graph, the subscribed stream found.
struct Capture {
    std::unique_ptr<Graph> graph = std::make_unique<Graph>();
    StreamId stream = kInvalidStream;
};

Status openInto(const CompliancePeer& peer, const DeviceConfig& config, Capture& capture) {
    auto backend = peer.backend();
    auto device = backend->open(config);
    if (!device)
        return device.status();
    MIXRAY_RETURN_IF_ERROR(capture.graph->addNode(std::move(*device)));
    const std::string name = config.name + "/" + peer.stream();
    auto id = capture.graph->findStream(name);
    if (!id)
        return {ErrorCode::kNotFound, "the device declared no stream '" + name + "'"};
    capture.stream = *id;
    return Status::ok();
}

std::vector<FrameRef> take(FrameQueue& queue, size_t n) {
    std::vector<FrameRef> frames;
    while (frames.size() < n) {
        auto frame = queue.pop(seconds(10));
        if (!frame)
            break;
        frames.push_back(std::move(*frame));
    }
    return frames;
}

// Waits until `done` holds: an upper bound against hangs, not a measurement.
template <typename F>
bool eventually(F done, int limit_s = 20) {
    const auto deadline = Clock::now() + seconds(limit_s);
    while (Clock::now() < deadline) {
        if (done())
            return true;
        std::this_thread::sleep_for(milliseconds(5));
    }
    return done();
}

std::vector<uint8_t> bytesOf(const FrameRef& frame) {
    const ImageView view = frame.image();
    return {frame.data(), frame.data() + view.size_bytes};
}

void expectIncreasing(const std::vector<FrameRef>& frames) {
    for (size_t i = 1; i < frames.size(); ++i) {
        const FrameMetadata& a = frames[i - 1].meta();
        const FrameMetadata& b = frames[i].meta();
        EXPECT_GT(b.sequence, a.sequence) << "frame " << i;
        EXPECT_GT(b.device_stamp_ns, a.device_stamp_ns) << "frame " << i;
        EXPECT_GE(b.host_stamp_ns, a.host_stamp_ns) << "frame " << i;
    }
}

}  // namespace

void Compliance::SetUp() {
    peer_ = GetParam().make();
    const std::string missing = peer_->missing();
    if (!missing.empty())
        GTEST_SKIP() << missing;
    const Status status = peer_->setUp();
    ASSERT_TRUE(status) << status.toString();
}

// Several start/stop cycles of one device: frames arrive in every run with increasing
// sequences and stamps, and each run can hold the whole pool at once, so no cycle leaked a
// buffer (a leak of one per cycle leaves the consumer short by the next).
TEST_P(Compliance, StartStopCycles) {
    Capture capture;
    ASSERT_TRUE(openInto(*peer_, peer_->config(), capture));
    const size_t pool = peer_->buffers();
    std::shared_ptr<FrameQueue> queue;
    for (int cycle = 0; cycle < 3; ++cycle) {
        SCOPED_TRACE("cycle " + std::to_string(cycle));
        capture.graph->unsubscribe(queue);
        auto q = capture.graph->subscribe(capture.stream, {pool, QueuePolicy::kLive, "cycles"});
        ASSERT_TRUE(q) << q.status().toString();
        queue = *q;
        ASSERT_TRUE(capture.graph->start());
        std::vector<FrameRef> frames = take(*queue, pool);
        ASSERT_EQ(frames.size(), pool) << "the pool did not come back full";
        expectIncreasing(frames);
        std::set<const uint8_t*> buffers;
        for (const FrameRef& f : frames) {
            EXPECT_EQ(f.meta().stream, capture.stream);
            EXPECT_EQ(f.meta().status, FrameStatus::kOk);
            buffers.insert(f.data());
        }
        EXPECT_EQ(buffers.size(), pool) << "a buffer was handed out twice";
        frames.clear();
        capture.graph->stop();
        EXPECT_FALSE(capture.graph->running());
    }
}

// Close and reopen in another mode: the frames have the new layout.
TEST_P(Compliance, Reconfigure) {
    const std::vector<PeerMode> modes = peer_->modes();
    if (modes.size() < 2)
        GTEST_SKIP() << "single mode: " << peer_->modesMissing();
    for (const PeerMode& mode : modes) {
        SCOPED_TRACE("mode " + std::to_string(mode.expected.width) + "x" +
                     std::to_string(mode.expected.height) + " " +
                     std::string(toString(mode.expected.format)));
        Capture capture;
        ASSERT_TRUE(openInto(*peer_, mode.config, capture));
        EXPECT_EQ(capture.graph->stream(capture.stream).format.width, mode.expected.width);
        EXPECT_EQ(capture.graph->stream(capture.stream).format.height, mode.expected.height);
        auto queue =
            capture.graph->subscribe(capture.stream, {2, QueuePolicy::kLive, "reconfigure"});
        ASSERT_TRUE(queue);
        ASSERT_TRUE(capture.graph->start());
        std::vector<FrameRef> frames = take(**queue, 2);
        capture.graph->stop();
        ASSERT_EQ(frames.size(), 2u);
        for (const FrameRef& f : frames) {
            const ImageDesc& d = f.image().desc;
            EXPECT_EQ(d.width, mode.expected.width);
            EXPECT_EQ(d.height, mode.expected.height);
            EXPECT_EQ(d.format, mode.expected.format);
            EXPECT_GT(f.image().size_bytes, 0u);
        }
    }
}

// A consumer that does not keep up with a live edge: the queue holds at most its capacity,
// the oldest frames are dropped and counted, and what is left are the newest frames.
TEST_P(Compliance, SlowConsumerOnLiveEdgeDropsOldest) {
    Capture capture;
    ASSERT_TRUE(openInto(*peer_, peer_->config(), capture));
    constexpr size_t kCapacity = 2;
    auto q = capture.graph->subscribe(capture.stream, {kCapacity, QueuePolicy::kLive, "slow"});
    ASSERT_TRUE(q);
    FrameQueue& queue = **q;
    ASSERT_TRUE(capture.graph->start());
    auto first = queue.pop(seconds(10));
    ASSERT_TRUE(first) << "no frame";
    const uint64_t first_sequence = first->meta().sequence;
    first->reset();
    // The consumer now sleeps through many frames.
    ASSERT_TRUE(eventually([&] { return queue.stats().pushed >= 12; }))
        << "the device published " << queue.stats().pushed << " frames";
    capture.graph->stop();
    const QueueStats stats = queue.stats();
    EXPECT_LE(stats.high_water, kCapacity);
    EXPECT_EQ(stats.size, kCapacity);
    EXPECT_EQ(stats.dropped, stats.pushed - 1 - stats.size);
    std::vector<FrameRef> left = take(queue, kCapacity);
    ASSERT_EQ(left.size(), kCapacity);
    expectIncreasing(left);
    // Every published frame advances the sequence by one at least: the newest frame is at
    // least pushed - 1 after the first one.
    EXPECT_GE(left.back().meta().sequence, first_sequence + stats.pushed - 1);
}

// A consumer slower than a file on a lossless edge: the device waits, nothing is lost.
TEST_P(Compliance, SlowConsumerOnLosslessEdgeLosesNothingFromFiles) {
    const std::optional<FiniteRun> run = peer_->finite();
    if (!run)
        GTEST_SKIP() << "a live source: a lossless edge cannot stop its sensor";
    Capture capture;
    ASSERT_TRUE(openInto(*peer_, run->config, capture));
    auto q = capture.graph->subscribe(capture.stream, {2, QueuePolicy::kLossless, "slow"});
    ASSERT_TRUE(q);
    FrameQueue& queue = **q;
    ASSERT_TRUE(capture.graph->start());
    std::vector<FrameRef> frames;
    for (;;) {
        auto frame = queue.pop(seconds(10));
        if (!frame)
            break;
        frames.push_back(std::move(*frame));
        // Slower than the device, which delivers as fast as the edge allows; frames are let go
        // so the pool is not what limits it.
        std::this_thread::sleep_for(milliseconds(2));
        frames.back() = FrameRef();
    }
    EXPECT_TRUE(queue.closed()) << "the stream did not end";
    capture.graph->stop();
    EXPECT_EQ(frames.size(), run->frames);
    EXPECT_EQ(queue.stats().dropped, 0u);
    EXPECT_EQ(queue.stats().popped, run->frames);
}

// The consumer holds every buffer of the pool (the device can publish nothing more) and the
// graph is stopped: stop() returns, and the held frames stay valid and unchanged after stop
// and after the device is destroyed.
TEST_P(Compliance, StopWithFramesInFlight) {
    Capture capture;
    ASSERT_TRUE(openInto(*peer_, peer_->config(), capture));
    const size_t pool = peer_->buffers();
    auto q = capture.graph->subscribe(capture.stream, {pool, QueuePolicy::kLive, "holder"});
    ASSERT_TRUE(q);
    ASSERT_TRUE(capture.graph->start());
    std::vector<FrameRef> held = take(**q, pool);
    ASSERT_EQ(held.size(), pool);
    std::vector<std::vector<uint8_t>> copies;
    std::vector<FrameMetadata> metas;
    for (const FrameRef& f : held) {
        copies.push_back(bytesOf(f));
        metas.push_back(f.meta());
    }
    // Let the device run into the empty pool before stopping it.
    std::this_thread::sleep_for(milliseconds(100));
    const auto before = Clock::now();
    capture.graph->stop();
    // A hang guard far above any expected figure, not a measurement.
    EXPECT_LT(Clock::now() - before, seconds(5)) << "stop() did not return promptly";
    for (size_t i = 0; i < held.size(); ++i) {
        EXPECT_EQ(bytesOf(held[i]), copies[i]) << "frame " << i << " changed after stop";
        EXPECT_EQ(held[i].meta().sequence, metas[i].sequence);
    }
    capture.graph.reset();
    for (size_t i = 0; i < held.size(); ++i) {
        EXPECT_EQ(bytesOf(held[i]), copies[i]) << "frame " << i << " changed after the device";
        EXPECT_EQ(held[i].meta().sequence, metas[i].sequence);
        EXPECT_EQ(held[i].meta().device_stamp_ns, metas[i].device_stamp_ns);
    }
}

// Bad configurations are refused with a Status that says what is wrong.
TEST_P(Compliance, BadConfigurationsAreReported) {
    auto backend = peer_->backend();
    DeviceConfig unknown_option = peer_->config();
    unknown_option.options["no_such_option"] = "1";
    auto opened = backend->open(unknown_option);
    ASSERT_FALSE(opened) << "an unknown option was accepted";
    EXPECT_EQ(opened.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(opened.status().message().find("no_such_option"), std::string::npos)
        << opened.status().toString();

    DeviceConfig bad_value = peer_->config();
    bad_value.options["buffers"] = "many";
    opened = backend->open(bad_value);
    ASSERT_FALSE(opened) << "buffers=many was accepted";
    EXPECT_EQ(opened.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(opened.status().message().find("many"), std::string::npos)
        << opened.status().toString();

    DeviceConfig missing = peer_->config();
    missing.id = peer_->missingId();
    opened = backend->open(missing);
    ASSERT_FALSE(opened) << "id '" << missing.id << "' was opened";
    EXPECT_NE(opened.status().code(), ErrorCode::kOk);
    EXPECT_NE(opened.status().message().find(missing.id), std::string::npos)
        << opened.status().toString();
}

}  // namespace mixray::compliance
