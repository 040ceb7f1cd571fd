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
