// Groups frames of several streams into time-matched sets (ROS ApproximateTime, with a skew
// bound, drop reporting and statistics), and the graph node that runs it on its own thread.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "mixray/graph/clock.h"
#include "mixray/graph/frame.h"
#include "mixray/graph/frame_queue.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray {

// Which stamp of a frame the synchronizer matches on.
enum class SyncTimeBase : uint8_t {
    kCommon,  // device stamp mapped to host time by a ClockSync: immune to arrival jitter
    kHost,    // host arrival stamp: for devices without a usable clock
    kDevice,  // raw device stamp: only when all streams share one clock (hardware sync)
};

std::string_view toString(SyncTimeBase base);

// Why a frame will never be part of a set.
enum class DropReason : uint8_t {
    kSuperseded,      // a frame of the same stream closer in time to the others was chosen
    kSkewTooLarge,    // no frame of some other stream is within max_skew_ns of it
    kPartnerDropped,  // the frame it would pair with was lost to a queue overflow
    kQueueOverflow,   // its stream had queue_size frames waiting already
    kOutOfOrder,      // its stamp is older than an earlier frame of the same stream
    kNotPulled,       // its set was completed but never pulled before the set queue filled
    kFlushed,         // still waiting when the synchronizer was flushed or cleared
};
inline constexpr size_t kDropReasonCount = 7;

std::string_view toString(DropReason reason);

struct SyncOptions {
    // A set whose stamps spread over more than this is never emitted. Keep it under half the
    // frame period so that neighbouring captures cannot be mistaken for one instant.
    int64_t max_skew_ns = 10'000'000;
    // Frames per stream the synchronizer holds while looking for the best set (ROS queue_size).
    // At least 2; a stream that gets further ahead than this loses its oldest frames.
    uint32_t queue_size = 8;
    SyncTimeBase time_base = SyncTimeBase::kCommon;
    // How much older a better set may be than the current candidate before it stops being
    // preferred (ROS age_penalty): 0 picks the tightest set, larger values emit sooner.
    double age_penalty = 0.1;
    // Optional per stream (empty, or one entry per stream): the least time between two frames
    // of the stream, 0 when unknown. With it a set can be proven optimal and emitted as soon
    // as its last frame arrives, instead of when every stream has sent a later one.
    std::vector<int64_t> min_period_ns;
    // Completed sets kept for pop() when no set callback is given.
    uint32_t ready_capacity = 8;

    Status validate(size_t stream_count) const;
};

// One matched set: a frame of every stream, no pixel copied. Frames are in the order of the
// synchronizer's stream list.
struct SyncSet {
    uint64_t index = 0;              // 0, 1, 2, ... in emission order
    std::vector<FrameRef> frames;    // one per stream
    std::vector<int64_t> stamps_ns;  // the stamp (in the time base) each frame was matched on
    int64_t min_stamp_ns = 0;
    int64_t max_stamp_ns = 0;
    int64_t skew_ns = 0;  // max_stamp_ns − min_stamp_ns, never above max_skew_ns

    // The instant the set stands for: the middle of its stamps.
    int64_t stampNs() const { return min_stamp_ns + skew_ns / 2; }
};

struct SyncStats {
    uint64_t frames_added = 0;
    uint64_t sets_emitted = 0;
    std::vector<uint64_t> dropped_per_stream;  // indexed like the stream list
    std::array<uint64_t, kDropReasonCount> dropped_by_reason{};
    int64_t skew_max_ns = 0;
    double skew_mean_ns = 0;

    uint64_t framesDropped() const;
};

// Called with each completed set. The set and its storage are reused after the call returns:
// copy the FrameRefs to keep frames (a copy is an atomic increment, not a pixel copy).
using SetCallback = std::function<void(const SyncSet& set)>;
// Called once for every frame that will never be part of a set.
using DropCallback = std::function<void(const FrameRef& frame, DropReason reason)>;

// Matches frames of N streams into sets by approximate time, with the semantics of ROS
// message_filters' ApproximateTime: each emitted set holds one frame per stream, sets come out
// in time order, no frame is in two sets, and among the possible sets the ones with the
// smallest spread are chosen (a set is emitted once no later frame could make it tighter).
// Added to that: a hard max_skew_ns bound, a drop callback for every frame that can no longer
// be matched (with the reason), the skew of each set, and statistics.
//
// Frames are stamped on arrival in the chosen time base; for kCommon the synchronizer feeds
// each frame to a ClockSync (its own, or one given to create(), which it does not own and
// which nothing else may feed). Steady state does no heap allocation: the per-stream queues,
// the set and the ready queue are allocated once.
//
// Thread-bound: add(), flush(), clear(), pop() and the callbacks run on one thread at a time;
// callbacks must not call back into the synchronizer. stats() is thread-safe.
class Synchronizer {
public:
    // `streams` are the graph StreamIds to match, in the order sets list them. `clock` is used
    // for SyncTimeBase::kCommon (nullptr: an internal ClockSync) and must outlive the
    // synchronizer.
    static Result<std::unique_ptr<Synchronizer>> create(std::vector<StreamId> streams,
                                                        const SyncOptions& options,
                                                        ClockSync* clock = nullptr);
    ~Synchronizer();
    Synchronizer(const Synchronizer&) = delete;
    Synchronizer& operator=(const Synchronizer&) = delete;

    // Set before the first add(). Without a set callback, completed sets wait for pop().
    void setSetCallback(SetCallback callback) { on_set_ = std::move(callback); }
    void setDropCallback(DropCallback callback) { on_drop_ = std::move(callback); }

    // Offers a frame of one of the streams, stamped in the configured time base. Completed sets
    // and drops are reported before it returns. InvalidArgument for an empty frame or a stream
    // that is not synchronised (the frame is not counted).
    Status add(FrameRef frame);
    // The same with a stamp chosen by the caller (replayed or simulated time).
    Status add(FrameRef frame, int64_t stamp_ns);

    // Declares that no more frames will come: emits every set the waiting frames still form,
    // then drops the rest (kFlushed). The synchronizer may be used again afterwards.
    void flush();
    // Drops every waiting frame and completed-but-unpulled set (kFlushed) without emitting.
    void clear();

    // Moves the oldest completed set into `out` (reusing out's storage); false when none.
    bool pop(SyncSet& out);
    size_t readyCount() const { return ready_size_; }

    // Frames of stream `index` waiting to be matched, and whether another fits without forcing
    // the oldest out (back-pressure for callers that can wait).
    size_t pending(size_t index) const { return queues_[index].size; }
    bool hasRoom(size_t index) const { return queues_[index].size < options_.queue_size; }
    // Whether stream `index` has no frame left to examine: a set cannot complete without it.
    bool waitingFor(size_t index) const { return queues_[index].dequeEmpty(); }
    // Index of `stream` in the stream list, or -1.
    int indexOf(StreamId stream) const;
    // The stream a set is waiting for: one with no frame left to examine (-1 when none).
    int neededStream() const;

    const std::vector<StreamId>& streams() const { return ids_; }
    const SyncOptions& options() const { return options_; }
    ClockSync* clock() const { return clock_; }
    SyncStats stats() const;

private:
    struct Entry {
        FrameRef frame;
        int64_t stamp_ns = 0;
    };
    // One stream's frames in arrival order, in a fixed ring. The first `past` entries have been
    // examined for the current candidate (ROS keeps them in a separate "past" vector; a prefix
    // of one ring is the same thing without moving anything).
    struct StreamQueue {
        std::vector<Entry> ring;
        size_t begin = 0;
        size_t size = 0;
        size_t past = 0;
        bool has_dropped = false;
        bool has_last = false;
        int64_t last_stamp_ns = 0;
        int64_t min_period_ns = 0;

        Entry& at(size_t i) { return ring[(begin + i) % ring.size()]; }
        const Entry& at(size_t i) const { return ring[(begin + i) % ring.size()]; }
        bool dequeEmpty() const { return past == size; }
        const Entry& front() const { return at(past); }
    };

    Synchronizer(std::vector<StreamId> streams, const SyncOptions& options, ClockSync* clock);

    void process();
    void dropFront(size_t i, DropReason reason);
    void dropFrame(const FrameRef& frame, size_t i, DropReason reason);
    void moveFrontToPast(size_t i);
    void recoverAll();
    // Drops every frame still queued (reason kFlushed) and empties the queues.
    void dropAllQueued();
    void makeCandidate(int64_t start, int64_t end);
    void publishCandidate();
    void countNonEmpty();
    bool boundary(bool end, size_t& index, int64_t& time) const;
    bool virtualBoundary(bool end, size_t& index, int64_t& time) const;
    void emit();

    std::vector<StreamId> ids_;
    SyncOptions options_;
    std::unique_ptr<ClockSync> own_clock_;
    ClockSync* clock_ = nullptr;
    SetCallback on_set_;
    DropCallback on_drop_;

    std::vector<StreamQueue> queues_;
    size_t non_empty_ = 0;
    static constexpr size_t kNoPivot = SIZE_MAX;
    size_t pivot_ = kNoPivot;
    int64_t pivot_time_ = 0;
    int64_t candidate_start_ = 0;
    int64_t candidate_end_ = 0;
    std::vector<size_t> virtual_moves_;

    SyncSet set_;
    uint64_t next_index_ = 0;
    std::vector<SyncSet> ready_;
    size_t ready_begin_ = 0;
    size_t ready_size_ = 0;

    mutable std::mutex stats_mutex_;
    SyncStats stats_;
    double skew_sum_ns_ = 0;
};

struct SyncNodeOptions {
    std::string name = "sync";         // node name, and the name of its input queues
    std::vector<std::string> streams;  // graph stream names to match, in set order
    // The edges from the streams to the node. Lossless edges with back-pressure give every
    // set a source can produce; live edges keep the sources free-running.
    QueueOptions queue{8, QueuePolicy::kLossless, ""};
    SyncOptions sync;
    ClockModelOptions clock;
    // How long the node's thread waits on the stream it needs before polling the others.
    std::chrono::nanoseconds poll_interval = std::chrono::milliseconds(2);
    // With no frame at all for this long, held-back streams are pulled anyway (their oldest
    // frames overflow): a source that died must not stall the others behind lossless edges.
    std::chrono::nanoseconds stall_timeout = std::chrono::milliseconds(500);

    Status validate() const;
};

// A graph node that subscribes to N streams, runs a Synchronizer (with its own ClockSync) on
// its own thread and hands every set to a callback, on that thread. Frames are pulled from a
// stream only while the synchronizer has room for them, so lossless edges carry back-pressure
// to the sources. A device publishes all its streams from one thread, so holding back one of
// its streams can block the very stream a set waits for: then (its queue full, nothing else
// arriving for poll_interval) the held-back stream is pulled anyway and the synchronizer drops
// its oldest frame, which had no partner. When every input stream has ended it flushes the
// synchronizer and is done.
// Thread-safe: stats(), clock estimates and waitDone() may be called from any thread.
class SyncNode : public Node {
public:
    SyncNode(SyncNodeOptions options, SetCallback on_set, DropCallback on_drop = {});
    ~SyncNode() override;

    std::string name() const override { return options_.name; }
    // Resolves the stream names and subscribes to them; the streams must already exist
    // (add the devices to the graph first).
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    // Waits until every input stream has ended and the last set was delivered; false on
    // timeout.
    bool waitDone(std::chrono::nanoseconds timeout) const;
    bool done() const;

    SyncStats stats() const;
    std::optional<ClockEstimate> clockEstimate(ClockDomainId domain) const {
        return clock_.estimate(domain);
    }
    const std::vector<StreamId>& streamIds() const { return ids_; }

private:
    void run();

    SyncNodeOptions options_;
    SetCallback on_set_;
    DropCallback on_drop_;
    ClockSync clock_;
    std::unique_ptr<Synchronizer> sync_;
    std::vector<StreamId> ids_;
    std::vector<size_t> device_of_;  // per stream: index of its device among the inputs'
    std::vector<std::shared_ptr<FrameQueue>> queues_;
    Graph* graph_ = nullptr;

    std::thread thread_;
    std::atomic<bool> stop_{false};
    mutable std::mutex done_mutex_;
    mutable std::condition_variable done_cv_;
    bool done_ = false;
};

}  // namespace mixray
