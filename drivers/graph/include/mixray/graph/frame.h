// Frames and their per-stream buffer pools: immutable, reference counted, never copied in flight.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "mixray/graph/image.h"
#include "mixray/graph/stream.h"

namespace mixray {

// Whether a frame's payload can be trusted.
enum class FrameStatus : uint8_t {
    kOk = 0,
    kIncomplete,  // the device delivered part of the frame (lost packets); payload partly stale
    kCorrupt,     // the payload failed a check; keep it for the record, do not process it
};

std::string_view toString(FrameStatus status);

// Everything known about a frame besides its pixels (libcamera's FrameMetadata).
struct FrameMetadata {
    StreamId stream = kInvalidStream;
    uint64_t sequence = 0;        // per stream, from the device when it counts, else by the driver
    int64_t device_stamp_ns = 0;  // in the device clock `clock_domain`
    int64_t host_stamp_ns = 0;    // host CLOCK_MONOTONIC when the frame arrived
    // Host CLOCK_MONOTONIC when a replayed frame entered this graph (its recorded
    // host_stamp_ns is another session's clock); 0 for live devices, whose host_stamp_ns is it.
    // Pipeline latency counts from here. Not recorded.
    int64_t graph_stamp_ns = 0;
    ClockDomainId clock_domain = kHostClockDomain;
    int64_t exposure_us = -1;  // -1 when unknown
    FrameStatus status = FrameStatus::kOk;
};

class BufferPool;

namespace detail {
// One pooled buffer with its metadata and reference count. Internal to frame.cpp.
struct FrameSlot {
    std::atomic<uint32_t> refs{0};
    FrameMetadata meta;
    ImageDesc desc;
    size_t payload_bytes = 0;
    size_t capacity_bytes = 0;
    uint8_t* data = nullptr;
    std::shared_ptr<BufferPool> owner;  // keeps the pool alive while the slot is out
};

// Frees pool storage allocated with the pool's alignment.
struct AlignedBytesDelete {
    void operator()(uint8_t* p) const;
};
}  // namespace detail

// Shared handle to an immutable published frame. Copying it costs one atomic increment; the
// buffer returns to its pool when the last handle goes. Thread-safe: handles to the same frame
// may be copied and released on any thread.
class FrameRef {
public:
    FrameRef() = default;
    FrameRef(const FrameRef& other);
    FrameRef(FrameRef&& other) noexcept : slot_(other.slot_) { other.slot_ = nullptr; }
    FrameRef& operator=(const FrameRef& other);
    FrameRef& operator=(FrameRef&& other) noexcept;
    ~FrameRef() { reset(); }

    explicit operator bool() const { return slot_ != nullptr; }
    const FrameMetadata& meta() const { return slot_->meta; }
    ImageView image() const { return {slot_->desc, slot_->data, slot_->payload_bytes}; }
    // Address of the payload: equal addresses mean the very same buffer (no copy was made).
    const uint8_t* data() const { return slot_->data; }
    uint32_t useCount() const { return slot_ ? slot_->refs.load(std::memory_order_relaxed) : 0; }
    void reset();

private:
    friend class WritableFrame;
    explicit FrameRef(detail::FrameSlot* slot) : slot_(slot) {}
    detail::FrameSlot* slot_ = nullptr;
};

// A frame being filled by its producer: exclusive, writable, not yet visible to anyone.
// publish() turns it into an immutable FrameRef; dropping it unpublished returns the buffer.
// Thread-bound to the producer.
class WritableFrame {
public:
    WritableFrame() = default;
    WritableFrame(WritableFrame&& other) noexcept : slot_(other.slot_) { other.slot_ = nullptr; }
    WritableFrame& operator=(WritableFrame&& other) noexcept;
    WritableFrame(const WritableFrame&) = delete;
    WritableFrame& operator=(const WritableFrame&) = delete;
    ~WritableFrame();

    explicit operator bool() const { return slot_ != nullptr; }
    FrameMetadata& meta() { return slot_->meta; }
    MutableImageView image() { return {slot_->desc, slot_->data, slot_->capacity_bytes}; }
    size_t capacityBytes() const { return slot_->capacity_bytes; }
    // For compressed or binary payloads: how many bytes of the buffer are payload. Defaults to
    // the full image size for uncompressed formats. Must not exceed capacityBytes().
    void setPayloadBytes(size_t bytes);
    // Changes width/height/stride for this frame (binary records of varying length); the
    // buffer must still hold it.
    void setDesc(const ImageDesc& desc);

    // Makes the frame immutable and shareable. The WritableFrame is empty afterwards.
    FrameRef publish() &&;

    // Turns the only handle of a published frame back into a writable frame, so a producer
    // that forwards frames (the replay device renumbering streams, shifting stamps on a loop)
    // can amend the metadata without copying the payload. When other handles exist the frame
    // is shared and must stay immutable: returns an empty WritableFrame, `frame` untouched.
    static WritableFrame reclaim(FrameRef& frame);

private:
    friend class BufferPool;
    explicit WritableFrame(detail::FrameSlot* slot) : slot_(slot) {}
    detail::FrameSlot* slot_ = nullptr;
};

// Options of a BufferPool.
struct BufferPoolOptions {
    ImageDesc desc;           // layout of every buffer
    size_t buffer_bytes = 0;  // 0: desc.bufferBytes()
    size_t buffer_count = 8;  // buffers allocated up front; the pool never grows
    std::string name;         // for statistics and errors, usually the stream name

    bool validate(std::string* why) const;
};

// Fixed set of equally sized buffers for one stream, allocated once. Frames come from
// acquire() without heap allocation; a buffer comes back when its last FrameRef goes.
// Thread-safe. Held by shared_ptr: outstanding frames keep their pool alive.
class BufferPool : public std::enable_shared_from_this<BufferPool> {
public:
    static std::shared_ptr<BufferPool> create(const BufferPoolOptions& options);
    ~BufferPool();
    BufferPool(const BufferPool&) = delete;
    BufferPool& operator=(const BufferPool&) = delete;

    // A free buffer, or an empty WritableFrame when all are in flight (counted in
    // exhaustedCount(); the producer drops the frame — a pool never blocks a capture thread).
    WritableFrame acquire();

    const BufferPoolOptions& options() const { return options_; }
    size_t inFlight() const;
    uint64_t exhaustedCount() const { return exhausted_.load(std::memory_order_relaxed); }
    uint64_t acquiredCount() const { return acquired_.load(std::memory_order_relaxed); }

private:
    friend class FrameRef;
    friend class WritableFrame;
    explicit BufferPool(const BufferPoolOptions& options);
    static void recycle(detail::FrameSlot* slot);

    BufferPoolOptions options_;
    std::vector<detail::FrameSlot> slots_;
    std::unique_ptr<uint8_t[], detail::AlignedBytesDelete> storage_;
    mutable std::mutex mutex_;
    std::vector<detail::FrameSlot*> free_;
    std::atomic<uint64_t> exhausted_{0};
    std::atomic<uint64_t> acquired_{0};
};

// A free buffer of `pool` for a producer that must not drop (a lossless pipeline stage): while
// consumers hold every buffer it waits, polling each millisecond, until one comes back or
// `give_up` says to stop (then the frame is empty).
WritableFrame acquireWaiting(BufferPool& pool, const std::function<bool()>& give_up);

// Copies `view` into a fresh frame from `pool` with the given metadata (for producers whose
// source memory cannot be handed over: files, libraries with their own buffers). Returns an
// empty FrameRef when the pool is exhausted or the view does not fit.
FrameRef copyIntoPool(BufferPool& pool, const ImageView& view, const FrameMetadata& meta);

}  // namespace mixray
