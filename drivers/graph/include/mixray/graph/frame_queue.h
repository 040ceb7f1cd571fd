// Bounded frame queues: the edges of the device graph, each with a declared overflow policy.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "mixray/graph/frame.h"

namespace mixray {

// What an edge does when its consumer falls behind.
enum class QueuePolicy : uint8_t {
    kLive,      // never blocks the producer: the oldest queued frame is dropped and counted
    kLossless,  // blocks the producer until the consumer makes room: nothing is dropped
};

std::string_view toString(QueuePolicy policy);

struct QueueOptions {
    size_t capacity = 4;  // producer's frames held at most (each holds one of its pool's buffers)
    QueuePolicy policy = QueuePolicy::kLive;
    std::string name;  // consumer name, for statistics
    // The edge feeds a recording: its frames are the ones a user cannot get back. While such
    // an edge is backed up, work that may be skipped (the live compositor) gives way to it
    // (Graph::recordingBacklog()).
    bool feeds_recording = false;
    // Live only: the consumer samples the stream at its own rate (a view, a watch counting
    // frames) and wants only the newest frame. Frames replaced before its turn are its choice,
    // counted as QueueStats::skipped, not as drops.
    bool newest_only = false;
    // Live only: frames that find `capacity` of the producer's frames queued are copied into
    // the queue's own memory, up to this many more, instead of dropping the oldest. For edges
    // whose frames cannot be got back (a recording): the producer gets its buffers back as
    // before, and a consumer held up for a moment (a burst of CPU elsewhere) catches up later.
    // The memory (spill_capacity buffers of the stream's frame size) is allocated on the
    // first copy, once.
    size_t spill_capacity = 0;
};

struct QueueStats {
    uint64_t pushed = 0;    // frames offered by the producer
    uint64_t popped = 0;    // frames taken by the consumer
    uint64_t dropped = 0;   // frames discarded under the live policy: the consumer was behind
    uint64_t skipped = 0;   // newest_only: frames replaced by newer ones before the consumer's turn
    uint64_t spilled = 0;   // spill_capacity: frames copied into the queue's memory (not lost)
    size_t size = 0;        // frames queued now
    size_t high_water = 0;  // most frames ever queued at once
    // Lossless: pushes that found the queue full and held their producer up, and for how long.
    uint64_t waits = 0;
    int64_t waited_ns = 0;
};

// Fixed-capacity FIFO of FrameRefs between one producer side and one consumer. Storage is
// allocated once (the spill memory on its first use); push and pop never allocate otherwise.
// Thread-safe.
class FrameQueue {
public:
    explicit FrameQueue(const QueueOptions& options);
    FrameQueue(const FrameQueue&) = delete;
    FrameQueue& operator=(const FrameQueue&) = delete;

    // Offers a frame. Live: always returns true at once. Lossless: waits for room; returns
    // false when the queue was closed meanwhile.
    bool push(FrameRef frame);

    // Takes the oldest frame, waiting up to `timeout`; nullopt on timeout or when closed and
    // empty.
    std::optional<FrameRef> pop(std::chrono::nanoseconds timeout);
    std::optional<FrameRef> tryPop();

    // Wakes everyone; further pushes are refused, queued frames may still be popped.
    void close();
    bool closed() const;

    const QueueOptions& options() const { return options_; }
    QueueStats stats() const;

private:
    // A copy of `frame` in the spill memory, or an empty frame when it is all in use.
    FrameRef spill(const FrameRef& frame);

    QueueOptions options_;
    mutable std::mutex mutex_;
    std::condition_variable not_empty_;
    std::condition_variable not_full_;
    std::vector<FrameRef> ring_;      // capacity + spill_capacity entries
    std::vector<bool> ring_spilled_;  // the entry is a copy in spill_pool_, not the producer's
    size_t held_ = 0;                 // entries that hold the producer's buffers
    std::shared_ptr<BufferPool> spill_pool_;
    size_t head_ = 0;
    size_t size_ = 0;
    bool closed_ = false;
    QueueStats stats_;
};

}  // namespace mixray
