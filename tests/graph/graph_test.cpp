// The device graph: stream registry, zero-copy fan-out, back-pressure policies, lifecycle.
#include "mixray/graph/graph.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "mixray/graph/device.h"

namespace mixray {
namespace {

using std::chrono::milliseconds;

StreamInfo depthStream(const std::string& name) {
    StreamInfo info;
    info.name = name;
    info.device = "test";
    info.kind = StreamKind::kDepth;
    info.format = ImageDesc::packed(PixelFormat::kDepth16, 64, 48);
    return info;
}

TEST(Graph, StreamNamesAreUnique) {
    Graph graph;
    auto a = graph.addStream(depthStream("cam/depth"));
    ASSERT_TRUE(a);
    EXPECT_EQ(*a, 0u);
    auto dup = graph.addStream(depthStream("cam/depth"));
    ASSERT_FALSE(dup);
    EXPECT_EQ(dup.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_EQ(graph.findStream("cam/depth"), std::optional<StreamId>(0));
    EXPECT_FALSE(graph.findStream("cam/color").has_value());
    EXPECT_FALSE(graph.subscribe(7, {}));
}

TEST(Graph, FanOutSharesOneBuffer) {
    Graph graph;
    StreamId id = *graph.addStream(depthStream("cam/depth"));
    auto q1 = *graph.subscribe(id, {4, QueuePolicy::kLive, "a"});
    auto q2 = *graph.subscribe(id, {4, QueuePolicy::kLossless, "b"});
    auto pool = BufferPool::create({depthStream("").format, 0, 4, "cam/depth"});
    WritableFrame w = pool->acquire();
    w.meta().stream = id;
    FrameRef frame = std::move(w).publish();
    graph.publish(frame);
    auto f1 = q1->tryPop();
    auto f2 = q2->tryPop();
    ASSERT_TRUE(f1 && f2);
    EXPECT_EQ(f1->data(), frame.data());
    EXPECT_EQ(f2->data(), frame.data());
    EXPECT_EQ(frame.useCount(), 3u);
    EXPECT_EQ(graph.publishedCount(id), 1u);
}

// When each stream last published: what tells a stalled device from a streaming one.
TEST(Graph, RemembersWhenEachStreamLastPublished) {
    Graph graph;
    StreamId a = *graph.addStream(depthStream("cam/depth"));
    StreamId b = *graph.addStream(depthStream("cam/other"));
    EXPECT_FALSE(graph.lastPublished(a).has_value());
    EXPECT_FALSE(graph.lastPublished(99).has_value());
    auto pool = BufferPool::create({depthStream("").format, 0, 4, "cam/depth"});
    const auto before = std::chrono::steady_clock::now();
    for (int i = 0; i < 2; ++i) {
        WritableFrame w = pool->acquire();
        w.meta().stream = a;
        graph.publish(std::move(w).publish());
    }
    const auto first = graph.lastPublished(a);
    ASSERT_TRUE(first.has_value());
    EXPECT_GE(*first, before);
    EXPECT_LE(*first, std::chrono::steady_clock::now());
    EXPECT_FALSE(graph.lastPublished(b).has_value());
    std::this_thread::sleep_for(milliseconds(2));
    WritableFrame w = pool->acquire();
    w.meta().stream = a;
    graph.publish(std::move(w).publish());
    EXPECT_GT(*graph.lastPublished(a), *first);
}

TEST(Graph, UnsubscribedQueueGetsNothingMore) {
    Graph graph;
    StreamId id = *graph.addStream(depthStream("cam/depth"));
    auto q = *graph.subscribe(id, {4, QueuePolicy::kLive, "a"});
    graph.unsubscribe(q);
    auto pool = BufferPool::create({depthStream("").format, 0, 4, "p"});
    WritableFrame w = pool->acquire();
    w.meta().stream = id;
    graph.publish(std::move(w).publish());
    EXPECT_FALSE(q->tryPop().has_value());
    EXPECT_TRUE(graph.edgeStats().empty());
}

// A source that publishes `count` frames as fast as its pool allows.
class BurstSource : public Node {
public:
    explicit BurstSource(int count) : count_(count) {}
    std::string name() const override { return "burst"; }
    Status connect(Graph& graph) override {
        graph_ = &graph;
        auto id = graph.addStream(depthStream("burst/depth"));
        if (!id)
            return id.status();
        stream_ = *id;
        pool_ = BufferPool::create({depthStream("").format, 0, 16, "burst/depth"});
        return Status::ok();
    }
    Status start() override {
        thread_ = std::thread([this] {
            for (int i = 0; i < count_ && graph_->running(); ++i) {
                WritableFrame w = pool_->acquire();
                if (!w) {
                    ++pool_empty_;
                    std::this_thread::yield();
                    --i;
                    continue;
                }
                w.meta().stream = stream_;
                w.meta().sequence = static_cast<uint64_t>(i);
                graph_->publish(std::move(w).publish());
            }
            graph_->endStream(stream_);
        });
        return Status::ok();
    }
    void stop() override {
        if (thread_.joinable())
            thread_.join();
    }
    std::shared_ptr<BufferPool> pool() const { return pool_; }
    int poolEmpty() const { return pool_empty_; }

private:
    int count_;
    Graph* graph_ = nullptr;
    StreamId stream_ = kInvalidStream;
    std::shared_ptr<BufferPool> pool_;
    std::thread thread_;
    std::atomic<int> pool_empty_{0};
};

TEST(Graph, SlowLiveConsumerNeitherGrowsMemoryNorSlowsOthers) {
    constexpr int kFrames = 2000;
    Graph graph;
    auto source = std::make_unique<BurstSource>(kFrames);
    BurstSource* src = source.get();
    ASSERT_TRUE(graph.addNode(std::move(source)));
    StreamId id = *graph.findStream("burst/depth");
    auto fast = *graph.subscribe(id, {8, QueuePolicy::kLossless, "fast"});
    auto slow = *graph.subscribe(id, {2, QueuePolicy::kLive, "slow"});

    std::atomic<size_t> max_in_flight{0};
    std::thread slow_consumer([&] {
        while (auto frame = slow->pop(std::chrono::seconds(5))) {
            std::this_thread::sleep_for(milliseconds(2));  // far slower than the source
        }
    });
    ASSERT_TRUE(graph.start());
    int fast_count = 0;
    uint64_t expected = 0;
    while (auto frame = fast->pop(std::chrono::seconds(5))) {
        EXPECT_EQ(frame->meta().sequence, expected++);
        ++fast_count;
        size_t now = src->pool()->inFlight();
        if (now > max_in_flight)
            max_in_flight = now;
    }
    graph.stop();
    slow_consumer.join();

    EXPECT_EQ(fast_count, kFrames);  // the fast consumer saw every frame
    EXPECT_EQ(fast->stats().dropped, 0u);
    EXPECT_GT(slow->stats().dropped, kFrames / 2u);  // the slow one lost most of them...
    EXPECT_LE(slow->stats().high_water, 2u);         // ...while holding at most its capacity
    // Memory is flat: never more buffers out than both queues plus the frames being handled.
    EXPECT_LE(max_in_flight.load(), 8u + 2u + 2u);
    EXPECT_EQ(src->pool()->inFlight(), 0u);
}

TEST(Graph, LosslessConsumerGetsEveryFrameInOrder) {
    constexpr int kFrames = 500;
    Graph graph;
    auto source = std::make_unique<BurstSource>(kFrames);
    ASSERT_TRUE(graph.addNode(std::move(source)));
    auto recorder = *graph.subscribe(0, {3, QueuePolicy::kLossless, "recorder"});
    ASSERT_TRUE(graph.start());
    uint64_t expected = 0;
    while (auto frame = recorder->pop(std::chrono::seconds(5))) {
        ASSERT_EQ(frame->meta().sequence, expected++);
        if (expected % 50 == 0)
            std::this_thread::sleep_for(milliseconds(3));
    }
    graph.stop();
    EXPECT_EQ(expected, static_cast<uint64_t>(kFrames));
    EXPECT_EQ(recorder->stats().dropped, 0u);
}

TEST(Graph, StopUnblocksAProducerStuckOnALosslessEdge) {
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::make_unique<BurstSource>(1000000)));
    auto never_read = *graph.subscribe(0, {1, QueuePolicy::kLossless, "stuck"});
    ASSERT_TRUE(graph.start());
    std::this_thread::sleep_for(milliseconds(20));
    graph.stop();  // must return: closing the queue releases the blocked publish
    EXPECT_FALSE(graph.running());
}

class FailingNode : public Node {
public:
    std::string name() const override { return "broken"; }
    Status connect(Graph&) override { return Status::ok(); }
    Status start() override { return {ErrorCode::kUnavailable, "device unplugged"}; }
    void stop() override {}
};

TEST(Graph, StartFailureNamesTheNodeAndStopsTheOthers) {
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::make_unique<BurstSource>(10)));
    ASSERT_TRUE(graph.addNode(std::make_unique<FailingNode>()));
    Status status = graph.start();
    EXPECT_EQ(status.code(), ErrorCode::kUnavailable);
    EXPECT_NE(status.message().find("broken"), std::string::npos);
    EXPECT_FALSE(graph.running());
}

class NullBackend : public DeviceBackend {
public:
    std::string_view name() const override { return "null"; }
    Result<std::vector<DeviceDescriptor>> enumerate() override {
        return std::vector<DeviceDescriptor>{};
    }
    Result<std::unique_ptr<Device>> open(const DeviceConfig&) override {
        return {ErrorCode::kNotFound, "no such device"};
    }
};

TEST(BackendRegistry, UnknownDriverListsKnownOnes) {
    BackendRegistry registry;
    ASSERT_TRUE(registry.add(std::make_unique<NullBackend>()));
    EXPECT_FALSE(registry.add(std::make_unique<NullBackend>()));
    auto device = registry.open({"kinect", "openni3", "", {}, {}});
    ASSERT_FALSE(device);
    EXPECT_NE(device.status().message().find("known: null"), std::string::npos);
    auto missing = registry.open({"cam", "null", "", {}, {}});
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(missing.status().message().find("device 'cam'"), std::string::npos);
}

}  // namespace
}  // namespace mixray
