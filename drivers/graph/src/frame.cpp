// Reference counting of pooled frames and the pools themselves.
#include "mixray/graph/frame.h"

#include <cassert>
#include <chrono>
#include <cstring>
#include <new>
#include <thread>

namespace mixray {
namespace {
constexpr std::align_val_t kPoolAlignment{64};
}  // namespace

void detail::AlignedBytesDelete::operator()(uint8_t* p) const {
    ::operator delete[](p, kPoolAlignment);
}

std::string_view toString(FrameStatus status) {
    switch (status) {
        case FrameStatus::kOk:
            return "ok";
        case FrameStatus::kIncomplete:
            return "incomplete";
        case FrameStatus::kCorrupt:
            return "corrupt";
    }
    return "unknown";
}

FrameRef::FrameRef(const FrameRef& other) : slot_(other.slot_) {
    if (slot_)
        slot_->refs.fetch_add(1, std::memory_order_relaxed);
}

FrameRef& FrameRef::operator=(const FrameRef& other) {
    if (this != &other) {
        if (other.slot_)
            other.slot_->refs.fetch_add(1, std::memory_order_relaxed);
        reset();
        slot_ = other.slot_;
    }
    return *this;
}

FrameRef& FrameRef::operator=(FrameRef&& other) noexcept {
    if (this != &other) {
        reset();
        slot_ = other.slot_;
        other.slot_ = nullptr;
    }
    return *this;
}

void FrameRef::reset() {
    if (slot_ && slot_->refs.fetch_sub(1, std::memory_order_acq_rel) == 1) {
        BufferPool::recycle(slot_);
    }
    slot_ = nullptr;
}

WritableFrame& WritableFrame::operator=(WritableFrame&& other) noexcept {
    if (this != &other) {
        if (slot_)
            BufferPool::recycle(slot_);
        slot_ = other.slot_;
        other.slot_ = nullptr;
    }
    return *this;
}

WritableFrame::~WritableFrame() {
    if (slot_)
        BufferPool::recycle(slot_);
}

void WritableFrame::setPayloadBytes(size_t bytes) {
    assert(bytes <= slot_->capacity_bytes);
    slot_->payload_bytes = bytes <= slot_->capacity_bytes ? bytes : slot_->capacity_bytes;
}

void WritableFrame::setDesc(const ImageDesc& desc) {
    assert(desc.bufferBytes() <= slot_->capacity_bytes);
    slot_->desc = desc;
    if (!pixelFormatInfo(desc.format).compressed)
        slot_->payload_bytes = desc.bufferBytes();
}

FrameRef WritableFrame::publish() && {
    detail::FrameSlot* slot = slot_;
    slot_ = nullptr;
    slot->refs.store(1, std::memory_order_release);
    return FrameRef(slot);
}

WritableFrame WritableFrame::reclaim(FrameRef& frame) {
    detail::FrameSlot* slot = frame.slot_;
    // With a single handle nobody else can take a new reference, so the check cannot race.
    if (!slot || slot->refs.load(std::memory_order_acquire) != 1)
        return {};
    frame.slot_ = nullptr;
    slot->refs.store(0, std::memory_order_relaxed);
    return WritableFrame(slot);
}

bool BufferPoolOptions::validate(std::string* why) const {
    const size_t bytes = buffer_bytes ? buffer_bytes : desc.bufferBytes();
    if (bytes == 0) {
        if (why)
            *why = "buffer pool '" + name + "': zero-sized buffers (bad image layout)";
        return false;
    }
    if (buffer_bytes && buffer_bytes < desc.bufferBytes() &&
        !pixelFormatInfo(desc.format).compressed) {
        if (why)
            *why = "buffer pool '" + name + "': buffer_bytes smaller than one image";
        return false;
    }
    if (buffer_count == 0) {
        if (why)
            *why = "buffer pool '" + name + "': buffer_count is 0";
        return false;
    }
    return true;
}

std::shared_ptr<BufferPool> BufferPool::create(const BufferPoolOptions& options) {
    if (!options.validate(nullptr))
        return nullptr;
    return std::shared_ptr<BufferPool>(new BufferPool(options));
}

BufferPool::BufferPool(const BufferPoolOptions& options)
    : options_(options), slots_(options.buffer_count) {
    constexpr auto kAlign = static_cast<size_t>(kPoolAlignment);
    size_t bytes = options_.buffer_bytes ? options_.buffer_bytes : options_.desc.bufferBytes();
    bytes = (bytes + kAlign - 1) / kAlign * kAlign;
    options_.buffer_bytes = bytes;
    storage_.reset(static_cast<uint8_t*>(::operator new[](bytes* slots_.size(), kPoolAlignment)));
    free_.reserve(slots_.size());
    for (size_t i = 0; i < slots_.size(); ++i) {
        slots_[i].data = storage_.get() + i * bytes;
        slots_[i].capacity_bytes = bytes;
        free_.push_back(&slots_[i]);
    }
}

BufferPool::~BufferPool() = default;

WritableFrame BufferPool::acquire() {
    detail::FrameSlot* slot = nullptr;
    {
        std::lock_guard lock(mutex_);
        if (free_.empty()) {
            exhausted_.fetch_add(1, std::memory_order_relaxed);
            return {};
        }
        slot = free_.back();
        free_.pop_back();
    }
    acquired_.fetch_add(1, std::memory_order_relaxed);
    slot->meta = FrameMetadata{};
    slot->desc = options_.desc;
    slot->payload_bytes =
        pixelFormatInfo(options_.desc.format).compressed ? 0 : options_.desc.bufferBytes();
    slot->owner = shared_from_this();
    return WritableFrame(slot);
}

size_t BufferPool::inFlight() const {
    std::lock_guard lock(mutex_);
    return slots_.size() - free_.size();
}

void BufferPool::recycle(detail::FrameSlot* slot) {
    // The slot's own reference may be the pool's last one: move it out before returning the
    // slot, so the pool dies (if it must) only after the free list is no longer touched.
    std::shared_ptr<BufferPool> pool = std::move(slot->owner);
    {
        std::lock_guard lock(pool->mutex_);
        pool->free_.push_back(slot);
    }
}

WritableFrame acquireWaiting(BufferPool& pool, const std::function<bool()>& give_up) {
    while (true) {
        WritableFrame frame = pool.acquire();
        if (frame || give_up())
            return frame;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
}

FrameRef copyIntoPool(BufferPool& pool, const ImageView& view, const FrameMetadata& meta) {
    WritableFrame frame = pool.acquire();
    if (!frame)
        return {};
    const bool compressed = pixelFormatInfo(view.desc.format).compressed;
    const size_t bytes = compressed ? view.size_bytes : view.desc.bufferBytes();
    if (bytes > frame.capacityBytes())
        return {};
    frame.setDesc(view.desc);
    std::memcpy(frame.image().data, view.data, bytes);
    frame.setPayloadBytes(bytes);
    frame.meta() = meta;
    return std::move(frame).publish();
}

}  // namespace mixray
