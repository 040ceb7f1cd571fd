// Pooled frames: reference counting, recycling, exhaustion, pool lifetime.
#include "mixray/graph/frame.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

namespace mixray {
namespace {

std::shared_ptr<BufferPool> makePool(size_t count) {
    return BufferPool::create({ImageDesc::packed(PixelFormat::kDepth16, 64, 48), 0, count, "t"});
}

TEST(BufferPool, RejectsEmptyLayouts) {
    EXPECT_EQ(BufferPool::create({ImageDesc{}, 0, 4, "bad"}), nullptr);
    EXPECT_EQ(BufferPool::create({ImageDesc::packed(PixelFormat::kMono8, 4, 4), 0, 0, "bad"}),
              nullptr);
}

TEST(BufferPool, BufferReturnsOnLastRelease) {
    auto pool = makePool(2);
    WritableFrame w = pool->acquire();
    ASSERT_TRUE(w);
    w.meta().sequence = 42;
    w.image().row<uint16_t>(0)[0] = 1234;
    FrameRef a = std::move(w).publish();
    EXPECT_FALSE(w);  // NOLINT(bugprone-use-after-move): publish empties the writable frame
    FrameRef b = a;
    EXPECT_EQ(a.useCount(), 2u);
    EXPECT_EQ(a.data(), b.data());
    EXPECT_EQ(b.meta().sequence, 42u);
    EXPECT_EQ(b.image().row<uint16_t>(0)[0], 1234);
    EXPECT_EQ(pool->inFlight(), 1u);
    a.reset();
    EXPECT_EQ(pool->inFlight(), 1u);
    b.reset();
    EXPECT_EQ(pool->inFlight(), 0u);
}

TEST(BufferPool, ExhaustionIsCountedNotBlocking) {
    auto pool = makePool(2);
    FrameRef a = pool->acquire().publish();
    FrameRef b = pool->acquire().publish();
    EXPECT_FALSE(pool->acquire());
    EXPECT_EQ(pool->exhaustedCount(), 1u);
    a.reset();
    EXPECT_TRUE(pool->acquire());
}

TEST(BufferPool, UnpublishedFrameReturnsItsBuffer) {
    auto pool = makePool(1);
    { WritableFrame w = pool->acquire(); }
    EXPECT_EQ(pool->inFlight(), 0u);
    EXPECT_TRUE(pool->acquire());
}

TEST(BufferPool, FramesOutliveTheirPoolHandle) {
    auto pool = makePool(2);
    std::weak_ptr<BufferPool> weak = pool;
    WritableFrame w = pool->acquire();
    w.image().row<uint16_t>(3)[3] = 77;
    FrameRef frame = std::move(w).publish();
    pool.reset();
    EXPECT_FALSE(weak.expired());
    EXPECT_EQ(frame.image().row<uint16_t>(3)[3], 77);
    frame.reset();
    EXPECT_TRUE(weak.expired());
}

TEST(BufferPool, ConcurrentReleaseRecyclesEveryBuffer) {
    auto pool = makePool(4);
    for (int round = 0; round < 200; ++round) {
        FrameRef frame = pool->acquire().publish();
        ASSERT_TRUE(frame);
        std::vector<std::thread> threads;
        for (int t = 0; t < 4; ++t)
            threads.emplace_back([copy = frame]() mutable { copy.reset(); });
        frame.reset();
        for (auto& t : threads)
            t.join();
    }
    EXPECT_EQ(pool->inFlight(), 0u);
    EXPECT_EQ(pool->acquiredCount(), 200u);
}

TEST(CopyIntoPool, CopiesPayloadAndMetadata) {
    auto pool = BufferPool::create({ImageDesc::packed(PixelFormat::kMJPEG, 32, 32), 0, 2, "j"});
    std::vector<uint8_t> jpeg = {0xFF, 0xD8, 1, 2, 3, 0xFF, 0xD9};
    ImageView view{ImageDesc::packed(PixelFormat::kMJPEG, 32, 32), jpeg.data(), jpeg.size()};
    FrameMetadata meta;
    meta.sequence = 9;
    FrameRef frame = copyIntoPool(*pool, view, meta);
    ASSERT_TRUE(frame);
    EXPECT_EQ(frame.image().size_bytes, jpeg.size());
    EXPECT_TRUE(sameImage(frame.image(), view));
    EXPECT_EQ(frame.meta().sequence, 9u);
}

}  // namespace
}  // namespace mixray
