// Bounded queues: live drops the oldest, lossless blocks, close wakes everyone.
#include "mixray/graph/frame_queue.h"

#include <gtest/gtest.h>

#include <thread>

namespace mixray {
namespace {

using std::chrono::milliseconds;

FrameRef makeFrame(BufferPool& pool, uint64_t sequence) {
    WritableFrame w = pool.acquire();
    w.meta().sequence = sequence;
    return std::move(w).publish();
}

TEST(FrameQueue, LiveDropsOldestAndCounts) {
    auto pool = BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 8, 8), 0, 16, "q"});
    FrameQueue queue({3, QueuePolicy::kLive, "consumer"});
    for (uint64_t i = 0; i < 10; ++i)
        EXPECT_TRUE(queue.push(makeFrame(*pool, i)));
    auto stats = queue.stats();
    EXPECT_EQ(stats.pushed, 10u);
    EXPECT_EQ(stats.dropped, 7u);
    EXPECT_EQ(stats.skipped, 0u);
    EXPECT_EQ(stats.size, 3u);
    // Dropped frames went back to the pool: only the queued ones hold buffers.
    EXPECT_EQ(pool->inFlight(), 3u);
    for (uint64_t expected = 7; expected < 10; ++expected) {
        auto frame = queue.tryPop();
        ASSERT_TRUE(frame.has_value());
        EXPECT_EQ(frame->meta().sequence, expected);
    }
    EXPECT_FALSE(queue.tryPop().has_value());
}

// A recording's edge: a consumer behind by all the producer's frames it may hold gets copies
// instead, so the producer's pool is not starved and nothing is lost until the copies run out;
// then the oldest of the producer's frames goes, and the copies keep their order.
TEST(FrameQueue, SpillKeepsCopiesOnceTheProducersFramesAreAllHeld) {
    auto pool = BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 8, 8), 0, 4, "q"});
    FrameQueue queue(
        {.capacity = 2, .policy = QueuePolicy::kLive, .name = "recorder", .spill_capacity = 3});
    for (uint64_t i = 0; i < 5; ++i) {
        WritableFrame frame = pool->acquire();
        ASSERT_TRUE(frame) << "the producer's pool ran dry at frame " << i;
        frame.meta().sequence = i;
        frame.image().data[0] = static_cast<uint8_t>(i);
        EXPECT_TRUE(queue.push(std::move(frame).publish()));
    }
    QueueStats stats = queue.stats();
    EXPECT_EQ(stats.dropped, 0u);
    EXPECT_EQ(stats.spilled, 3u);
    EXPECT_EQ(stats.size, 5u);
    EXPECT_EQ(pool->inFlight(), 2u);  // only the first two are the producer's buffers

    // Full: the next frame costs the oldest of the producer's frames (0), not a copy.
    EXPECT_TRUE(queue.push(makeFrame(*pool, 5)));
    stats = queue.stats();
    EXPECT_EQ(stats.dropped, 1u);
    EXPECT_EQ(stats.size, 5u);
    EXPECT_EQ(pool->inFlight(), 2u);
    for (uint64_t expected : {1, 2, 3, 4, 5}) {
        auto frame = queue.tryPop();
        ASSERT_TRUE(frame.has_value());
        EXPECT_EQ(frame->meta().sequence, expected);
        if (expected < 5) {
            EXPECT_EQ(frame->image().data[0], expected) << "the copy differs from the frame";
        }
    }
    EXPECT_FALSE(queue.tryPop().has_value());
    EXPECT_EQ(pool->inFlight(), 0u);
}

// A consumer that samples at its own rate (a view) replaces frames on purpose: skipped, not
// dropped, so a status line's drops count only consumers that fell behind.
TEST(FrameQueue, NewestOnlyCountsReplacedFramesAsSkippedNotDropped) {
    auto pool = BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 8, 8), 0, 16, "q"});
    FrameQueue queue(
        {.capacity = 1, .policy = QueuePolicy::kLive, .name = "view", .newest_only = true});
    for (uint64_t i = 0; i < 10; ++i)
        EXPECT_TRUE(queue.push(makeFrame(*pool, i)));
    const QueueStats stats = queue.stats();
    EXPECT_EQ(stats.pushed, 10u);
    EXPECT_EQ(stats.skipped, 9u);
    EXPECT_EQ(stats.dropped, 0u);
    auto frame = queue.tryPop();
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->meta().sequence, 9u);
    EXPECT_EQ(pool->inFlight(), 1u);
}

TEST(FrameQueue, LosslessBlocksUntilConsumed) {
    auto pool = BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 8, 8), 0, 16, "q"});
    FrameQueue queue({2, QueuePolicy::kLossless, "recorder"});
    std::thread producer([&] {
        for (uint64_t i = 0; i < 12; ++i)
            ASSERT_TRUE(queue.push(makeFrame(*pool, i)));
    });
    for (uint64_t expected = 0; expected < 12; ++expected) {
        auto frame = queue.pop(std::chrono::seconds(5));
        ASSERT_TRUE(frame.has_value());
        EXPECT_EQ(frame->meta().sequence, expected);
        std::this_thread::sleep_for(milliseconds(1));
    }
    producer.join();
    EXPECT_EQ(queue.stats().dropped, 0u);
    EXPECT_LE(queue.stats().high_water, 2u);
}

TEST(FrameQueue, CloseReleasesBlockedProducerAndConsumer) {
    auto pool = BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 8, 8), 0, 4, "q"});
    FrameQueue queue({1, QueuePolicy::kLossless, "c"});
    ASSERT_TRUE(queue.push(makeFrame(*pool, 0)));
    bool pushed = true;
    std::thread producer([&] { pushed = queue.push(makeFrame(*pool, 1)); });
    std::this_thread::sleep_for(milliseconds(20));
    queue.close();
    producer.join();
    EXPECT_FALSE(pushed);
    EXPECT_TRUE(queue.pop(milliseconds(1)).has_value());  // queued data survives close
    EXPECT_FALSE(queue.pop(milliseconds(1)).has_value());
}

TEST(FrameQueue, PopTimesOut) {
    FrameQueue queue({2, QueuePolicy::kLive, "c"});
    auto start = std::chrono::steady_clock::now();
    EXPECT_FALSE(queue.pop(milliseconds(20)).has_value());
    EXPECT_GE(std::chrono::steady_clock::now() - start, milliseconds(19));
}

}  // namespace
}  // namespace mixray
