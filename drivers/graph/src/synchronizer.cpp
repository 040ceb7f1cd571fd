// ApproximateTime matching over fixed per-stream rings, drop reporting, and the SyncNode thread.
#include "mixray/graph/synchronizer.h"

#include <algorithm>
#include <limits>

#include "mixray/graph/thread_priority.h"

namespace mixray {

std::string_view toString(SyncTimeBase base) {
    switch (base) {
        case SyncTimeBase::kCommon:
            return "common";
        case SyncTimeBase::kHost:
            return "host";
        case SyncTimeBase::kDevice:
            return "device";
    }
    return "unknown";
}

std::string_view toString(DropReason reason) {
    switch (reason) {
        case DropReason::kSuperseded:
            return "superseded";
        case DropReason::kSkewTooLarge:
            return "skew too large";
        case DropReason::kPartnerDropped:
            return "partner dropped";
        case DropReason::kQueueOverflow:
            return "queue overflow";
        case DropReason::kOutOfOrder:
            return "out of order";
        case DropReason::kNotPulled:
            return "not pulled";
        case DropReason::kFlushed:
            return "flushed";
    }
    return "unknown";
}

Status SyncOptions::validate(size_t stream_count) const {
    if (stream_count < 1) {
        return {ErrorCode::kInvalidArgument, "synchronizer: no streams to synchronise"};
    }
    if (max_skew_ns < 0) {
        return {ErrorCode::kInvalidArgument, "synchronizer: max_skew_ns must be >= 0"};
    }
    if (queue_size < 2) {
        return {ErrorCode::kInvalidArgument, "synchronizer: queue_size must be >= 2"};
    }
    if (!(age_penalty >= 0)) {
        return {ErrorCode::kInvalidArgument, "synchronizer: age_penalty must be >= 0"};
    }
    if (!min_period_ns.empty() && min_period_ns.size() != stream_count) {
        return {ErrorCode::kInvalidArgument,
                "synchronizer: min_period_ns has " + std::to_string(min_period_ns.size()) +
                    " entries for " + std::to_string(stream_count) + " streams"};
    }
    for (int64_t period : min_period_ns) {
        if (period < 0) {
            return {ErrorCode::kInvalidArgument, "synchronizer: min_period_ns must be >= 0"};
        }
    }
    if (ready_capacity < 1) {
        return {ErrorCode::kInvalidArgument, "synchronizer: ready_capacity must be >= 1"};
    }
    return Status::ok();
}

uint64_t SyncStats::framesDropped() const {
    uint64_t total = 0;
    for (uint64_t n : dropped_by_reason)
        total += n;
    return total;
}

Result<std::unique_ptr<Synchronizer>> Synchronizer::create(std::vector<StreamId> streams,
                                                           const SyncOptions& options,
                                                           ClockSync* clock) {
    MIXRAY_RETURN_IF_ERROR(options.validate(streams.size()));
    for (size_t i = 0; i < streams.size(); ++i) {
        for (size_t j = i + 1; j < streams.size(); ++j) {
            if (streams[i] == streams[j]) {
                return {ErrorCode::kInvalidArgument,
                        "synchronizer: stream " + std::to_string(streams[i]) + " listed twice"};
            }
        }
    }
    return std::unique_ptr<Synchronizer>(new Synchronizer(std::move(streams), options, clock));
}

Synchronizer::Synchronizer(std::vector<StreamId> streams, const SyncOptions& options,
                           ClockSync* clock)
    : ids_(std::move(streams)), options_(options), clock_(clock) {
    const size_t n = ids_.size();
    if (options_.time_base == SyncTimeBase::kCommon && !clock_) {
        own_clock_ = std::make_unique<ClockSync>();
        clock_ = own_clock_.get();
    }
    queues_.resize(n);
    for (size_t i = 0; i < n; ++i) {
        // One more than queue_size: a frame is added before the overflow check (as in ROS).
        queues_[i].ring.resize(options_.queue_size + 1);
        queues_[i].min_period_ns = options_.min_period_ns.empty() ? 0 : options_.min_period_ns[i];
    }
    virtual_moves_.resize(n);
    set_.frames.resize(n);
    set_.stamps_ns.resize(n);
    ready_.resize(options_.ready_capacity);
    for (SyncSet& s : ready_) {
        s.frames.resize(n);
        s.stamps_ns.resize(n);
    }
    stats_.dropped_per_stream.assign(n, 0);
}

// Frames still held are released without reports: the callbacks' owners may be gone already.
Synchronizer::~Synchronizer() = default;

int Synchronizer::indexOf(StreamId stream) const {
    for (size_t i = 0; i < ids_.size(); ++i) {
        if (ids_[i] == stream)
            return static_cast<int>(i);
    }
    return -1;
}

int Synchronizer::neededStream() const {
    int best = -1;
    for (size_t i = 0; i < queues_.size(); ++i) {
        const StreamQueue& q = queues_[i];
        if (!q.dequeEmpty())
            continue;
        if (best < 0) {
            best = static_cast<int>(i);
            continue;
        }
        // Of the streams with nothing left to examine, the one furthest behind holds up the
        // most: its next frame is the earliest any set can need. One never heard from first.
        const StreamQueue& b = queues_[static_cast<size_t>(best)];
        if (b.has_last && (!q.has_last || q.last_stamp_ns < b.last_stamp_ns)) {
            best = static_cast<int>(i);
        }
    }
    return best;
}

Status Synchronizer::add(FrameRef frame) {
    if (!frame)
        return {ErrorCode::kInvalidArgument, "synchronizer: empty frame"};
    const FrameMetadata& meta = frame.meta();
    int64_t stamp = meta.host_stamp_ns;
    switch (options_.time_base) {
        case SyncTimeBase::kCommon:
            if (indexOf(meta.stream) < 0)
                break;  // reported below, without feeding the clock
            stamp = clock_->observe(meta);
            break;
        case SyncTimeBase::kHost:
            stamp = meta.host_stamp_ns;
            break;
        case SyncTimeBase::kDevice:
            stamp = meta.device_stamp_ns;
            break;
    }
    return add(std::move(frame), stamp);
}

Status Synchronizer::add(FrameRef frame, int64_t stamp_ns) {
    if (!frame)
        return {ErrorCode::kInvalidArgument, "synchronizer: empty frame"};
    const int index = indexOf(frame.meta().stream);
    if (index < 0) {
        return {ErrorCode::kInvalidArgument, "synchronizer: frame of stream " +
                                                 std::to_string(frame.meta().stream) +
                                                 ", which is not synchronised"};
    }
    const auto i = static_cast<size_t>(index);
    {
        std::lock_guard lock(stats_mutex_);
        ++stats_.frames_added;
    }
    StreamQueue& q = queues_[i];
    if (q.has_last && stamp_ns < q.last_stamp_ns) {
        // The matching below assumes each stream's stamps never decrease.
        dropFrame(frame, i, DropReason::kOutOfOrder);
        return Status::ok();
    }
    q.has_last = true;
    q.last_stamp_ns = stamp_ns;

    const bool was_empty = q.dequeEmpty();
    q.at(q.size) = Entry{std::move(frame), stamp_ns};
    ++q.size;
    if (was_empty) {
        ++non_empty_;
        if (non_empty_ == queues_.size())
            process();
    }
    if (q.size > options_.queue_size) {
        // Abandon the candidate search (it may hold this stream's oldest frame), then make
        // room. The stream is no pivot until a set proves its drop cost nothing.
        recoverAll();
        dropFront(i, DropReason::kQueueOverflow);
        q.has_dropped = true;
        if (pivot_ != kNoPivot) {
            pivot_ = kNoPivot;
            process();
        }
    }
    return Status::ok();
}

void Synchronizer::countNonEmpty() {
    non_empty_ = 0;
    for (const StreamQueue& q : queues_)
        non_empty_ += q.dequeEmpty() ? 0 : 1;
}

void Synchronizer::recoverAll() {
    for (StreamQueue& q : queues_)
        q.past = 0;
    countNonEmpty();
}

void Synchronizer::dropFrame(const FrameRef& frame, size_t i, DropReason reason) {
    {
        std::lock_guard lock(stats_mutex_);
        ++stats_.dropped_per_stream[i];
        ++stats_.dropped_by_reason[static_cast<size_t>(reason)];
    }
    if (on_drop_)
        on_drop_(frame, reason);
}

void Synchronizer::dropFront(size_t i, DropReason reason) {
    StreamQueue& q = queues_[i];
    assert(q.past == 0 && q.size > 0);
    Entry& e = q.at(0);
    FrameRef frame = std::move(e.frame);
    q.begin = (q.begin + 1) % q.ring.size();
    --q.size;
    if (q.dequeEmpty())
        --non_empty_;
    dropFrame(frame, i, reason);
}

void Synchronizer::moveFrontToPast(size_t i) {
    StreamQueue& q = queues_[i];
    assert(!q.dequeEmpty());
    ++q.past;
    if (q.dequeEmpty())
        --non_empty_;
}

void Synchronizer::makeCandidate(int64_t start, int64_t end) {
    // The fronts become the candidate; what was examined before them can never be in a set
    // again, since sets come out in time order.
    for (size_t i = 0; i < queues_.size(); ++i) {
        StreamQueue& q = queues_[i];
        while (q.past > 0) {
            FrameRef frame = std::move(q.at(0).frame);
            q.begin = (q.begin + 1) % q.ring.size();
            --q.size;
            --q.past;
            dropFrame(frame, i, DropReason::kSuperseded);
        }
    }
    candidate_start_ = start;
    candidate_end_ = end;
}

void Synchronizer::publishCandidate() {
    emit();
    pivot_ = kNoPivot;
    countNonEmpty();
}

void Synchronizer::emit() {
    const size_t n = queues_.size();
    int64_t lo = std::numeric_limits<int64_t>::max();
    int64_t hi = std::numeric_limits<int64_t>::min();
    for (size_t i = 0; i < n; ++i) {
        StreamQueue& q = queues_[i];
        Entry& e = q.at(0);
        set_.frames[i] = std::move(e.frame);
        set_.stamps_ns[i] = e.stamp_ns;
        lo = std::min(lo, e.stamp_ns);
        hi = std::max(hi, e.stamp_ns);
        q.begin = (q.begin + 1) % q.ring.size();
        --q.size;
        q.past = 0;
    }
    set_.min_stamp_ns = lo;
    set_.max_stamp_ns = hi;
    set_.skew_ns = hi - lo;
    if (set_.skew_ns > options_.max_skew_ns) {
        // Unreachable by construction (every candidate is checked against the bound); kept so
        // that the bound holds even if that reasoning is ever broken by a change.
        assert(false && "synchronizer built a set wider than max_skew_ns");
        for (size_t i = 0; i < n; ++i) {
            FrameRef frame = std::move(set_.frames[i]);
            dropFrame(frame, i, DropReason::kSkewTooLarge);
        }
        return;
    }
    set_.index = next_index_++;
    {
        std::lock_guard lock(stats_mutex_);
        ++stats_.sets_emitted;
        stats_.skew_max_ns = std::max(stats_.skew_max_ns, set_.skew_ns);
        skew_sum_ns_ += static_cast<double>(set_.skew_ns);
        stats_.skew_mean_ns = skew_sum_ns_ / static_cast<double>(stats_.sets_emitted);
    }
    if (on_set_) {
        on_set_(set_);
        for (FrameRef& f : set_.frames)
            f.reset();
        return;
    }
    if (ready_size_ == ready_.size()) {
        // The puller fell behind: its oldest set goes, frames reported one by one.
        SyncSet& old = ready_[ready_begin_];
        for (size_t i = 0; i < n; ++i) {
            FrameRef frame = std::move(old.frames[i]);
            dropFrame(frame, i, DropReason::kNotPulled);
        }
        ready_begin_ = (ready_begin_ + 1) % ready_.size();
        --ready_size_;
    }
    SyncSet& slot = ready_[(ready_begin_ + ready_size_) % ready_.size()];
    for (size_t i = 0; i < n; ++i) {
        slot.frames[i] = std::move(set_.frames[i]);
        slot.stamps_ns[i] = set_.stamps_ns[i];
    }
    slot.index = set_.index;
    slot.min_stamp_ns = set_.min_stamp_ns;
    slot.max_stamp_ns = set_.max_stamp_ns;
    slot.skew_ns = set_.skew_ns;
    ++ready_size_;
}

bool Synchronizer::pop(SyncSet& out) {
    if (ready_size_ == 0)
        return false;
    SyncSet& slot = ready_[ready_begin_];
    const size_t n = queues_.size();
    out.frames.resize(n);
    out.stamps_ns.resize(n);
    for (size_t i = 0; i < n; ++i) {
        out.frames[i] = std::move(slot.frames[i]);
        out.stamps_ns[i] = slot.stamps_ns[i];
    }
    out.index = slot.index;
    out.min_stamp_ns = slot.min_stamp_ns;
    out.max_stamp_ns = slot.max_stamp_ns;
    out.skew_ns = slot.skew_ns;
    ready_begin_ = (ready_begin_ + 1) % ready_.size();
    --ready_size_;
    return true;
}

// The earliest (end = false) or latest (end = true) stamp among the fronts of the deques.
bool Synchronizer::boundary(bool end, size_t& index, int64_t& time) const {
    bool found = false;
    for (size_t i = 0; i < queues_.size(); ++i) {
        const int64_t t = queues_[i].front().stamp_ns;
        if (!found || (end ? t > time : t < time)) {
            time = t;
            index = i;
            found = true;
        }
    }
    return found;
}

// As boundary(), with an optimistic stamp for streams whose deque is empty: the earliest their
// next frame can have, given its minimum period (ROS's "virtual" candidate).
bool Synchronizer::virtualBoundary(bool end, size_t& index, int64_t& time) const {
    bool found = false;
    for (size_t i = 0; i < queues_.size(); ++i) {
        const StreamQueue& q = queues_[i];
        int64_t t = 0;
        if (q.dequeEmpty()) {
            assert(q.size > 0);  // a candidate exists, so every stream holds a frame
            t = std::max(q.at(q.size - 1).stamp_ns + q.min_period_ns, pivot_time_);
        } else {
            t = q.front().stamp_ns;
        }
        if (!found || (end ? t > time : t < time)) {
            time = t;
            index = i;
            found = true;
        }
    }
    return found;
}

void Synchronizer::process() {
    const size_t n = queues_.size();
    const double weight = 1.0 + options_.age_penalty;
    while (non_empty_ == n) {
        size_t end_index = 0;
        size_t start_index = 0;
        int64_t end_time = 0;
        int64_t start_time = 0;
        boundary(true, end_index, end_time);
        boundary(false, start_index, start_time);
        for (size_t i = 0; i < n; ++i) {
            // No dropped frame could have been a better partner than the ones at hand, so
            // those streams may serve as pivot again.
            if (i != end_index)
                queues_[i].has_dropped = false;
        }
        if (pivot_ == kNoPivot) {
            if (end_time - start_time > options_.max_skew_ns) {
                // Every other front is later still: nothing within the bound can include it.
                dropFront(start_index, DropReason::kSkewTooLarge);
                continue;
            }
            if (queues_[end_index].has_dropped) {
                // Its true partner on the pivot stream may be the frame that overflowed.
                dropFront(start_index, DropReason::kPartnerDropped);
                continue;
            }
            makeCandidate(start_time, end_time);
            pivot_ = end_index;
            pivot_time_ = end_time;
            moveFrontToPast(start_index);
        } else {
            const double later = static_cast<double>(end_time - candidate_end_) * weight;
            if (later >= static_cast<double>(start_time - candidate_start_)) {
                moveFrontToPast(start_index);  // not better than the candidate
            } else {
                makeCandidate(start_time, end_time);  // better; same pivot
                moveFrontToPast(start_index);
            }
        }

        const double age = static_cast<double>(end_time - candidate_end_) * weight;
        if (start_index == pivot_) {
            // Every candidate containing the pivot frame has been examined.
            publishCandidate();
        } else if (age >= static_cast<double>(pivot_time_ - candidate_start_)) {
            // Any later candidate spans [pivot_time_, end_time] at least: no better one exists.
            publishCandidate();
        } else if (non_empty_ < n) {
            // Try to prove optimality with the streams' minimum periods before waiting.
            std::fill(virtual_moves_.begin(), virtual_moves_.end(), 0);
            while (true) {
                size_t vend_index = 0;
                size_t vstart_index = 0;
                int64_t vend = 0;
                int64_t vstart = 0;
                virtualBoundary(true, vend_index, vend);
                virtualBoundary(false, vstart_index, vstart);
                const double vage = static_cast<double>(vend - candidate_end_) * weight;
                if (vage >= static_cast<double>(pivot_time_ - candidate_start_)) {
                    publishCandidate();  // also undoes the virtual moves
                    break;
                }
                if (vage < static_cast<double>(vstart - candidate_start_) ||
                    queues_[vstart_index].dequeEmpty() || vstart_index == pivot_) {
                    // An optimistic future candidate beats this one: wait for real frames.
                    for (size_t i = 0; i < n; ++i)
                        queues_[i].past -= virtual_moves_[i];
                    countNonEmpty();
                    break;
                }
                moveFrontToPast(vstart_index);
                ++virtual_moves_[vstart_index];
            }
        }
    }
}

void Synchronizer::flush() {
    // With no frame to come, the current candidate is the best its pivot will get; emitting it
    // may leave every stream with frames again, forming further sets.
    while (pivot_ != kNoPivot) {
        publishCandidate();
        process();
    }
    dropAllQueued();
}

void Synchronizer::dropAllQueued() {
    for (size_t i = 0; i < queues_.size(); ++i) {
        StreamQueue& q = queues_[i];
        q.past = 0;
        while (q.size > 0) {
            FrameRef frame = std::move(q.at(0).frame);
            q.begin = (q.begin + 1) % q.ring.size();
            --q.size;
            dropFrame(frame, i, DropReason::kFlushed);
        }
        q.has_dropped = false;
    }
    non_empty_ = 0;
}

void Synchronizer::clear() {
    pivot_ = kNoPivot;
    dropAllQueued();
    while (ready_size_ > 0) {
        SyncSet& old = ready_[ready_begin_];
        for (size_t i = 0; i < queues_.size(); ++i) {
            FrameRef frame = std::move(old.frames[i]);
            dropFrame(frame, i, DropReason::kFlushed);
        }
        ready_begin_ = (ready_begin_ + 1) % ready_.size();
        --ready_size_;
    }
}

SyncStats Synchronizer::stats() const {
    std::lock_guard lock(stats_mutex_);
    return stats_;
}

// ---------------------------------------------------------------------------------------------

Status SyncNodeOptions::validate() const {
    if (name.empty())
        return {ErrorCode::kInvalidArgument, "sync node: empty name"};
    if (streams.empty())
        return {ErrorCode::kInvalidArgument, "sync node '" + name + "': no streams"};
    for (size_t i = 0; i < streams.size(); ++i) {
        for (size_t j = i + 1; j < streams.size(); ++j) {
            if (streams[i] == streams[j]) {
                return {ErrorCode::kInvalidArgument,
                        "sync node '" + name + "': stream '" + streams[i] + "' listed twice"};
            }
        }
    }
    if (queue.capacity < 1) {
        return {ErrorCode::kInvalidArgument, "sync node '" + name + "': queue capacity is 0"};
    }
    if (poll_interval <= std::chrono::nanoseconds(0) || stall_timeout < poll_interval) {
        return {ErrorCode::kInvalidArgument, "sync node '" + name +
                                                 "': poll_interval must be > 0 and stall_timeout "
                                                 ">= poll_interval"};
    }
    MIXRAY_RETURN_IF_ERROR(sync.validate(streams.size()).withContext("sync node '" + name + "'"));
    MIXRAY_RETURN_IF_ERROR(clock.validate().withContext("sync node '" + name + "'"));
    return Status::ok();
}

SyncNode::SyncNode(SyncNodeOptions options, SetCallback on_set, DropCallback on_drop)
    : options_(std::move(options)),
      on_set_(std::move(on_set)),
      on_drop_(std::move(on_drop)),
      clock_(options_.clock) {}

SyncNode::~SyncNode() {
    stop();
}

Status SyncNode::connect(Graph& graph) {
    MIXRAY_RETURN_IF_ERROR(options_.validate());
    if (graph_)
        return {ErrorCode::kInvalidArgument, "sync node '" + name() + "' connected twice"};
    std::vector<StreamId> ids;
    std::vector<std::string> devices;
    device_of_.clear();
    for (const std::string& stream : options_.streams) {
        auto id = graph.findStream(stream);
        if (!id) {
            return {ErrorCode::kNotFound, "sync node '" + name() + "': no stream '" + stream +
                                              "' in the graph (add its device first)"};
        }
        ids.push_back(*id);
        const std::string device = graph.stream(*id).device;
        auto it = std::find(devices.begin(), devices.end(), device);
        device_of_.push_back(static_cast<size_t>(it - devices.begin()));
        if (it == devices.end())
            devices.push_back(device);
    }
    auto sync = Synchronizer::create(ids, options_.sync, &clock_);
    if (!sync)
        return sync.status().withContext("sync node '" + name() + "'");
    sync_ = std::move(sync).value();
    sync_->setSetCallback(on_set_);
    sync_->setDropCallback(on_drop_);
    QueueOptions queue = options_.queue;
    if (queue.name.empty())
        queue.name = options_.name;
    for (StreamId id : ids) {
        auto q = graph.subscribe(id, queue);
        if (!q)
            return q.status().withContext("sync node '" + name() + "'");
        queues_.push_back(std::move(q).value());
    }
    ids_ = std::move(ids);
    graph_ = &graph;
    return Status::ok();
}

Status SyncNode::start() {
    if (!sync_)
        return {ErrorCode::kInvalidArgument, "sync node '" + name() + "': not connected"};
    if (thread_.joinable())
        return Status::ok();
    stop_ = false;
    {
        std::lock_guard lock(done_mutex_);
        done_ = false;
    }
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void SyncNode::stop() {
    stop_ = true;
    if (thread_.joinable())
        thread_.join();
}

bool SyncNode::done() const {
    std::lock_guard lock(done_mutex_);
    return done_;
}

bool SyncNode::waitDone(std::chrono::nanoseconds timeout) const {
    std::unique_lock lock(done_mutex_);
    return done_cv_.wait_for(lock, timeout, [&] { return done_; });
}

SyncStats SyncNode::stats() const {
    return sync_ ? sync_->stats() : SyncStats{};
}

void SyncNode::run() {
    runAs(ThreadRole::kEstimator);  // matching: below capture and recording
    const size_t n = queues_.size();
    std::vector<bool> ended(n, false);
    size_t ended_count = 0;
    Synchronizer& sync = *sync_;

    auto feed = [&](FrameRef frame) {
        // A frame of another stream cannot reach these queues; add() only refuses those.
        (void)sync.add(std::move(frame));
    };
    // A closed queue may still hold frames; it has ended once a pop after the close finds none.
    auto pull = [&](size_t i) -> bool {
        if (auto frame = queues_[i]->tryPop()) {
            feed(std::move(*frame));
            return true;
        }
        if (queues_[i]->closed()) {
            if (auto frame = queues_[i]->tryPop()) {
                feed(std::move(*frame));
                return true;
            }
            ended[i] = true;
            ++ended_count;
        }
        return false;
    };

    using Clock = std::chrono::steady_clock;
    Clock::time_point last_frame = Clock::now();
    while (!stop_.load(std::memory_order_relaxed) && ended_count < n) {
        bool got = false;
        for (size_t i = 0; i < n; ++i) {
            if (ended[i])
                continue;
            // Back-pressure: leave frames in the graph queue while the synchronizer has no room
            // for them, unless a set waits for this very stream or no set needs back-pressure
            // anymore (a stream has ended).
            if (ended_count == 0 && !sync.hasRoom(i) && !sync.waitingFor(i))
                continue;
            got = pull(i) || got;
        }
        if (got) {
            last_frame = Clock::now();
            continue;
        }
        if (ended_count == n)
            break;

        int wait_on = sync.neededStream();
        if (wait_on < 0 || ended[static_cast<size_t>(wait_on)]) {
            wait_on = -1;
            for (size_t i = 0; i < n && wait_on < 0; ++i) {
                if (!ended[i])
                    wait_on = static_cast<int>(i);
            }
        }
        if (wait_on < 0)
            continue;
        if (auto frame = queues_[static_cast<size_t>(wait_on)]->pop(options_.poll_interval)) {
            feed(std::move(*frame));
            last_frame = Clock::now();
            continue;
        }
        // Nothing came. A held-back stream with a full queue may block its device's thread,
        // and with it the stream we wait for when that is the same device: take one frame.
        // Other devices have threads of their own; them we only force after a long stall.
        const bool stalled = Clock::now() - last_frame > options_.stall_timeout;
        for (size_t i = 0; i < n; ++i) {
            if (ended[i] || sync.hasRoom(i))
                continue;
            const bool same_device = device_of_[i] == device_of_[static_cast<size_t>(wait_on)];
            if (!same_device && !stalled)
                continue;
            if (queues_[i]->stats().size >= queues_[i]->options().capacity && pull(i)) {
                last_frame = Clock::now();
            }
        }
    }
    if (stop_.load()) {
        sync.clear();
    } else {
        sync.flush();
    }
    {
        std::lock_guard lock(done_mutex_);
        done_ = true;
    }
    done_cv_.notify_all();
}

}  // namespace mixray
