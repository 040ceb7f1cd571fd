// Bounded ring of FrameRefs with live (drop oldest) and lossless (block) policies.
#include "mixray/graph/frame_queue.h"

#include <algorithm>

#include "mixray/graph/image.h"

namespace mixray {

std::string_view toString(QueuePolicy policy) {
    return policy == QueuePolicy::kLive ? "live" : "lossless";
}

FrameQueue::FrameQueue(const QueueOptions& options) : options_(options) {
    options_.capacity = std::max<size_t>(options_.capacity, 1);
    if (options_.policy != QueuePolicy::kLive || options_.newest_only)
        options_.spill_capacity = 0;
    ring_.resize(options_.capacity + options_.spill_capacity);
    ring_spilled_.resize(ring_.size(), false);
}

FrameRef FrameQueue::spill(const FrameRef& frame) {
    const ImageView view = frame.image();
    const size_t bytes =
        pixelFormatInfo(view.desc.format).compressed ? view.size_bytes : view.desc.bufferBytes();
    if (!spill_pool_ || spill_pool_->options().buffer_bytes < bytes) {
        // Sized by the first frame that needs it (a larger one later, such as a longer record,
        // gets a new pool; copies in the old one keep it alive until they are written).
        const size_t buffer_bytes =
            spill_pool_ ? std::max(bytes, 2 * spill_pool_->options().buffer_bytes) : bytes;
        spill_pool_ = BufferPool::create({view.desc, std::max<size_t>(buffer_bytes, 1),
                                          options_.spill_capacity, options_.name + " (spill)"});
        if (!spill_pool_)
            return {};
    }
    return copyIntoPool(*spill_pool_, view, frame.meta());
}

bool FrameQueue::push(FrameRef frame) {
    std::unique_lock lock(mutex_);
    if (closed_)
        return false;
    ++stats_.pushed;
    if (held_ == options_.capacity && size_ < ring_.size()) {
        // The consumer is behind by all the producer's frames it may hold: keep a copy instead,
        // so the producer's buffer goes back to it now and nothing is lost yet.
        if (FrameRef copy = spill(frame)) {
            ring_[(head_ + size_) % ring_.size()] = std::move(copy);
            ring_spilled_[(head_ + size_) % ring_.size()] = true;
            ++size_;
            ++stats_.spilled;
            stats_.high_water = std::max(stats_.high_water, size_);
            lock.unlock();
            frame.reset();
            not_empty_.notify_one();
            return true;
        }
    }
    // Every entry beyond `capacity` is a copy, so a full ring always holds `capacity` of the
    // producer's frames.
    if (held_ == options_.capacity) {
        if (options_.policy == QueuePolicy::kLive) {
            // Drop the oldest of the producer's frames (copies, older or not, wait their turn):
            // the consumer wants the freshest frames, and the producer must never wait on it.
            const size_t n = ring_.size();
            size_t k = 0;
            while (ring_spilled_[(head_ + k) % n])
                ++k;
            FrameRef dropped = std::move(ring_[(head_ + k) % n]);
            if (k == 0) {
                head_ = (head_ + 1) % n;
            } else {
                for (size_t j = k; j + 1 < size_; ++j) {
                    ring_[(head_ + j) % n] = std::move(ring_[(head_ + j + 1) % n]);
                    ring_spilled_[(head_ + j) % n] = ring_spilled_[(head_ + j + 1) % n];
                }
            }
            ring_spilled_[(head_ + size_ - 1) % n] = false;
            --size_;
            --held_;
            ++(options_.newest_only ? stats_.skipped : stats_.dropped);
            lock.unlock();
            dropped.reset();  // recycling takes the pool's lock: not under ours
            lock.lock();
            if (closed_)
                return false;
        } else {
            const auto since = std::chrono::steady_clock::now();
            not_full_.wait(lock, [&] { return closed_ || held_ < options_.capacity; });
            ++stats_.waits;
            stats_.waited_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::steady_clock::now() - since)
                                    .count();
            if (closed_)
                return false;
        }
    }
    ring_[(head_ + size_) % ring_.size()] = std::move(frame);
    ring_spilled_[(head_ + size_) % ring_.size()] = false;
    ++size_;
    ++held_;
    stats_.high_water = std::max(stats_.high_water, size_);
    lock.unlock();
    not_empty_.notify_one();
    return true;
}

std::optional<FrameRef> FrameQueue::pop(std::chrono::nanoseconds timeout) {
    std::unique_lock lock(mutex_);
    if (!not_empty_.wait_for(lock, timeout, [&] { return closed_ || size_ > 0; })) {
        return std::nullopt;
    }
    if (size_ == 0)
        return std::nullopt;
    FrameRef frame = std::move(ring_[head_]);
    if (!ring_spilled_[head_])
        --held_;
    ring_spilled_[head_] = false;
    head_ = (head_ + 1) % ring_.size();
    --size_;
    ++stats_.popped;
    lock.unlock();
    not_full_.notify_one();
    return frame;
}

std::optional<FrameRef> FrameQueue::tryPop() {
    return pop(std::chrono::nanoseconds(0));
}

void FrameQueue::close() {
    {
        std::lock_guard lock(mutex_);
        closed_ = true;
    }
    not_empty_.notify_all();
    not_full_.notify_all();
}

bool FrameQueue::closed() const {
    std::lock_guard lock(mutex_);
    return closed_;
}

QueueStats FrameQueue::stats() const {
    std::lock_guard lock(mutex_);
    QueueStats stats = stats_;
    stats.size = size_;
    return stats;
}

}  // namespace mixray
