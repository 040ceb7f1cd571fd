// Bounded ring of FrameRefs with live (drop oldest) and lossless (block) policies.
#include "mixray/graph/frame_queue.h"

#include <algorithm>

namespace mixray {

std::string_view toString(QueuePolicy policy) {
    return policy == QueuePolicy::kLive ? "live" : "lossless";
}

FrameQueue::FrameQueue(const QueueOptions& options)
    : options_(options), ring_(std::max<size_t>(options.capacity, 1)) {
    options_.capacity = ring_.size();
}

bool FrameQueue::push(FrameRef frame) {
    std::unique_lock lock(mutex_);
    if (closed_)
        return false;
    ++stats_.pushed;
    if (size_ == ring_.size()) {
        if (options_.policy == QueuePolicy::kLive) {
            // Drop the oldest: the consumer wants the freshest frames, and the producer must
            // never wait on it.
            FrameRef dropped = std::move(ring_[head_]);
            head_ = (head_ + 1) % ring_.size();
            --size_;
            ++(options_.newest_only ? stats_.skipped : stats_.dropped);
            lock.unlock();
            dropped.reset();  // recycling takes the pool's lock: not under ours
            lock.lock();
            if (closed_)
                return false;
        } else {
            const auto since = std::chrono::steady_clock::now();
            not_full_.wait(lock, [&] { return closed_ || size_ < ring_.size(); });
            ++stats_.waits;
            stats_.waited_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::steady_clock::now() - since)
                                    .count();
            if (closed_)
                return false;
        }
    }
    ring_[(head_ + size_) % ring_.size()] = std::move(frame);
    ++size_;
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
