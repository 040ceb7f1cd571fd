// The recorder node: merges its input queues in host-stamp order into a RecordingWriter on one
// thread, and keeps draining after a write error so live drivers are never held up.
#include "mixray/graph/recorder.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "mixray/graph/thread_priority.h"

namespace mixray {

using Clock = std::chrono::steady_clock;

bool RecorderOptions::validate(std::string* why) const {
    auto fail = [&](const char* text) {
        if (why)
            *why = text;
        return false;
    };
    if (path.empty() && !writer_factory)
        return fail("recorder: no output path");
    if (queue_capacity == 0)
        return fail("recorder: queue_capacity must be at least 1");
    if (reorder_window.count() < 0)
        return fail("recorder: negative reorder_window");
    if (backlog.count() < 0)
        return fail("recorder: negative backlog");
    if (name.empty())
        return fail("recorder: empty name");
    return writer.validate(why);
}

std::string RecorderStats::summary() const {
    char text[160];
    std::snprintf(text, sizeof(text), "recorded %llu frames, %.1f MB at %.1f MB/s",
                  static_cast<unsigned long long>(frames_written), bytes_written / 1e6,
                  bytes_per_second / 1e6);
    std::string out = text;
    if (frames_dropped > 0) {
        out += "; dropped " + std::to_string(frames_dropped) + " (";
        bool first = true;
        for (const auto& s : streams) {
            if (s.dropped == 0)
                continue;
            out += (first ? "" : ", ") + s.stream + " " + std::to_string(s.dropped);
            first = false;
        }
        out += ")";
    }
    if (frames_spilled > 0) {
        out +=
            "; " + std::to_string(frames_spilled) + " waited in memory while the writer caught up";
    }
    if (producer_waits > 0) {
        std::snprintf(text, sizeof(text), "; the drivers waited for the disk %llu times (%.2f s)",
                      static_cast<unsigned long long>(producer_waits), producer_waited_s);
        out += text;
    }
    if (frames_discarded > 0) {
        out += "; not written after the error: " + std::to_string(frames_discarded);
    }
    if (!error.isOk())
        out += "; stopped: " + error.toString();
    return out;
}

Recorder::Recorder(RecorderOptions options) : options_(std::move(options)) {}

Recorder::~Recorder() {
    stop();
}

Status Recorder::connect(Graph& graph) {
    std::string why;
    if (!options_.validate(&why))
        return {ErrorCode::kInvalidArgument, why};
    graph_ = &graph;
    std::vector<std::string> names = options_.streams;
    if (names.empty()) {
        for (const StreamInfo& info : graph.streams())
            names.push_back(info.name);
    }
    if (names.empty())
        return {ErrorCode::kInvalidArgument, "recorder: the graph has no streams"};
    header_ = RecordingHeader{};
    inputs_.clear();
    counts_.clear();
    for (const std::string& name : names) {
        if (std::count(names.begin(), names.end(), name) > 1) {
            return {ErrorCode::kInvalidArgument, "recorder: stream '" + name + "' listed twice"};
        }
        auto id = graph.findStream(name);
        if (!id) {
            std::string known;
            for (const StreamInfo& info : graph.streams())
                known += " " + info.name;
            return {ErrorCode::kNotFound,
                    "recorder: no stream '" + name + "' in the graph (it has:" + known + ")"};
        }
        Input input;
        input.graph_id = *id;
        input.min_period_ns = minFramePeriodNs(graph.stream(*id));
        header_.streams.push_back(graph.stream(*id));
        inputs_.push_back(std::move(input));
        RecorderStreamStats stats;
        stats.stream = name;
        counts_.push_back(stats);
    }
    header_.attachments = options_.attachments;
    header_.tags = options_.tags;
    for (Input& input : inputs_) {
        const double fps = graph.stream(input.graph_id).nominal_fps;
        const double backlog_s = std::chrono::duration<double>(options_.backlog).count();
        const auto spill = static_cast<size_t>(std::ceil(backlog_s * (fps > 0 ? fps : 60.0)));
        auto queue =
            graph.subscribe(input.graph_id, QueueOptions{.capacity = options_.queue_capacity,
                                                         .policy = options_.policy,
                                                         .name = options_.name,
                                                         .feeds_recording = true,
                                                         .spill_capacity = spill});
        if (!queue)
            return queue.status();
        input.queue = *queue;
    }
    return Status::ok();
}

Status Recorder::start() {
    if (thread_.joinable())
        return Status::ok();
    if (inputs_.empty())
        return {ErrorCode::kInvalidArgument, "recorder: not connected to a graph"};
    // The encoders' threads start here and keep this thread's priority: the recorder's.
    const ScopedThreadRole role(ThreadRole::kRecorder);
    auto writer = options_.writer_factory
                      ? options_.writer_factory(header_)
                      : createMkvWriter(options_.path, header_, options_.writer);
    if (!writer)
        return writer.status();
    writer_ = std::move(*writer);
    stopping_ = false;
    {
        std::lock_guard lock(stats_mutex_);
        error_ = Status::ok();
        running_ = true;
        finished_ = false;
        started_at_ = Clock::now();
        bytes_written_ = writer_->bytesWritten();
    }
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void Recorder::stop() {
    stopping_ = true;
    // Closing the queues ends the thread's loop once they are drained; producers pushing to a
    // closed queue are refused at once instead of waiting.
    for (Input& input : inputs_) {
        if (input.queue)
            input.queue->close();
    }
    if (thread_.joinable())
        thread_.join();
    std::lock_guard lock(stats_mutex_);
    running_ = false;
}

bool Recorder::pullHeads(bool wait) {
    bool got = false;
    bool waited = !wait;
    for (Input& input : inputs_) {
        if (input.head || input.finished)
            continue;
        std::optional<FrameRef> frame;
        if (!waited) {
            // Sleep on one empty queue only: bounded latency for the others.
            frame = input.queue->pop(std::chrono::milliseconds(5));
            waited = true;
        } else {
            frame = input.queue->tryPop();
        }
        if (!frame && input.queue->closed()) {
            // Pushes stop at close(), so an empty queue seen after it stays empty.
            frame = input.queue->tryPop();
            if (!frame)
                input.finished = true;
        }
        if (frame) {
            input.head = std::move(*frame);
            input.head_since = Clock::now();
            input.last_stamp_ns = input.head.meta().host_stamp_ns;
            input.overdue = false;
            got = true;
        }
    }
    return got;
}

void Recorder::writeFrame(size_t index, FrameRef frame) {
    bool failed = false;
    {
        std::lock_guard lock(stats_mutex_);
        failed = !error_.isOk();
    }
    if (failed) {
        std::lock_guard lock(stats_mutex_);
        ++counts_[index].discarded;
        return;
    }
    Status status = writer_->writeAs(static_cast<StreamId>(index), frame);
    frame.reset();  // back to the driver's pool before the bookkeeping
    const uint64_t bytes = writer_->bytesWritten();
    std::lock_guard lock(stats_mutex_);
    bytes_written_ = bytes;
    if (status.isOk()) {
        ++counts_[index].written;
    } else {
        error_ = status.withContext("recorder '" + options_.name + "'");
        ++counts_[index].discarded;
    }
}

void Recorder::run() {
    // Its queues hold the drivers' pool buffers: when it falls behind, frames are lost for
    // good. So it runs above everything but capture; the renderer gives way instead.
    runAs(ThreadRole::kRecorder);
    while (true) {
        pullHeads(false);
        size_t best = inputs_.size();
        bool all_finished = true;
        for (size_t i = 0; i < inputs_.size(); ++i) {
            const Input& input = inputs_[i];
            if (input.head) {
                all_finished = false;
                if (best == inputs_.size() ||
                    input.head.meta().host_stamp_ns < inputs_[best].head.meta().host_stamp_ns) {
                    best = i;
                }
            } else if (!input.finished) {
                all_finished = false;
            }
        }
        if (all_finished)
            break;
        if (best < inputs_.size()) {
            // Every stream without a head either ended or cannot bring an older frame (a
            // slow stream, such as a fish-eye at 2 fps, holds the others back only for frames
            // within one of its periods).
            const int64_t best_stamp = inputs_[best].head.meta().host_stamp_ns;
            const bool all_present =
                std::all_of(inputs_.begin(), inputs_.end(), [best_stamp](const Input& input) {
                    return input.head || input.finished || input.overdue ||
                           !input.mayPrecede(best_stamp);
                });
            bool failed = false;
            {
                std::lock_guard lock(stats_mutex_);
                failed = !error_.isOk();
            }
            // Write the oldest head once no stream can still deliver an older frame: every
            // stream has a head, or it waited out the reorder window, or we are draining. Order
            // never costs a frame: once any queue is half full (a stream's records come late,
            // such as tracking's on a starved machine), the oldest head is written at once.
            const bool waited = Clock::now() - inputs_[best].head_since >= options_.reorder_window;
            const bool pressed =
                std::any_of(inputs_.begin(), inputs_.end(), [this](const Input& input) {
                    return input.queue->stats().size * 2 >= options_.queue_capacity;
                });
            if (all_present || waited || pressed || stopping_ || failed) {
                if (!all_present && waited) {
                    for (Input& input : inputs_)
                        input.overdue = input.overdue || (!input.head && !input.finished &&
                                                          input.mayPrecede(best_stamp));
                }
                writeFrame(best, std::move(inputs_[best].head));
                inputs_[best].head.reset();
                continue;
            }
        }
        pullHeads(true);
    }
    finish();
}

void Recorder::finish() {
    Status closed = writer_->close();
    const uint64_t bytes = writer_->bytesWritten();
    std::lock_guard lock(stats_mutex_);
    bytes_written_ = bytes;
    if (error_.isOk() && !closed.isOk()) {
        error_ = closed.withContext("recorder '" + options_.name + "'");
    }
    finished_ = true;
    finished_at_ = Clock::now();
}

RecorderStats Recorder::stats() const {
    RecorderStats stats;
    std::lock_guard lock(stats_mutex_);
    stats.streams = counts_;
    for (size_t i = 0; i < inputs_.size() && i < stats.streams.size(); ++i) {
        if (!inputs_[i].queue)
            continue;
        const QueueStats queue = inputs_[i].queue->stats();
        stats.streams[i].dropped = queue.dropped;
        stats.streams[i].spilled = queue.spilled;
        stats.streams[i].queue_high_water = queue.high_water;
        stats.streams[i].producer_waits = queue.waits;
        stats.streams[i].producer_waited_s = static_cast<double>(queue.waited_ns) * 1e-9;
    }
    for (const auto& s : stats.streams) {
        stats.producer_waits += s.producer_waits;
        stats.producer_waited_s += s.producer_waited_s;
        stats.frames_written += s.written;
        stats.frames_dropped += s.dropped;
        stats.frames_discarded += s.discarded;
        stats.frames_spilled += s.spilled;
    }
    stats.bytes_written = bytes_written_;
    if (started_at_ != Clock::time_point{}) {
        const auto end = finished_ ? finished_at_ : Clock::now();
        stats.seconds = std::chrono::duration<double>(end - started_at_).count();
    }
    stats.bytes_per_second = stats.seconds > 0 ? bytes_written_ / stats.seconds : 0;
    stats.writing = running_ && !finished_ && error_.isOk();
    stats.error = error_;
    return stats;
}

}  // namespace mixray
