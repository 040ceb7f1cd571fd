// The recorder: a graph sink that writes a chosen set of streams into one recording on its own
// thread, never blocking live drivers, and reports what it wrote, dropped and why it stopped.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mixray/graph/graph.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/recording.h"

namespace mixray {

// Creates the writer once the recorder knows its streams. The default writes Matroska.
using RecordingWriterFactory =
    std::function<Result<std::unique_ptr<RecordingWriter>>(const RecordingHeader& header)>;

struct RecorderOptions {
    std::filesystem::path path;        // the file to create (required unless writer_factory)
    std::vector<std::string> streams;  // stream names to record; empty: every stream the graph
                                       // has when the recorder is added
    // kLive: drivers never wait for the disk; when it falls behind, the oldest queued frames
    // are dropped and counted. kLossless: drivers wait, nothing is dropped.
    QueuePolicy policy = QueuePolicy::kLive;
    // Frames queued per stream. Each holds one of its driver's pool buffers, so keep it below
    // the drivers' pool sizes: a longer queue starves the driver instead of dropping here.
    size_t queue_capacity = 4;
    // kLive: how far the writer may fall behind a stream before its frames are dropped. Frames
    // beyond queue_capacity are copied into the recorder's own memory, up to this much of each
    // stream (at its nominal rate; 60 fps where it has none), so a moment without CPU or disk
    // (a browser starting, a compiler) costs no frame. Memory: at most this long of each
    // stream, allocated the first time it is needed. Zero: drop at queue_capacity.
    std::chrono::milliseconds backlog{2000};
    // How long a frame may wait for other streams' older frames before it is written anyway.
    // Frames are written in host-stamp order within this window, and at once when any queue is
    // half full: ordering never costs a frame.
    std::chrono::milliseconds reorder_window{100};
    std::vector<Attachment> attachments;      // rig description, calibration, ...
    std::map<std::string, std::string> tags;  // recording tags
    MkvWriterOptions writer;                  // used by the default (Matroska) writer
    RecordingWriterFactory writer_factory;    // empty: createMkvWriter(path, header, writer)
    std::string name = "recorder";            // node and queue name

    bool validate(std::string* why) const;
};

struct RecorderStreamStats {
    std::string stream;
    uint64_t written = 0;    // frames stored in the recording
    uint64_t dropped = 0;    // frames the live queue dropped because the writer fell behind
    uint64_t discarded = 0;  // frames drained and not written after a write error
    uint64_t spilled = 0;    // frames that waited in the recorder's memory (backlog), all kept
    size_t queue_high_water = 0;
    // Lossless: times the stream's driver waited for the writer (a slow disk), and how long.
    uint64_t producer_waits = 0;
    double producer_waited_s = 0;
};

struct RecorderStats {
    std::vector<RecorderStreamStats> streams;  // in RecorderOptions::streams order
    uint64_t frames_written = 0;
    uint64_t frames_dropped = 0;
    uint64_t frames_discarded = 0;
    uint64_t frames_spilled = 0;
    uint64_t producer_waits = 0;
    double producer_waited_s = 0;
    uint64_t bytes_written = 0;
    double seconds = 0;           // since start() (until the writer closed)
    double bytes_per_second = 0;  // average over `seconds`
    bool writing = false;         // started, not stopped, no error
    Status error;                 // the first error; nothing was written after it

    // One line for logs: "recorded 300 frames, 12.1 MB at 3.2 MB/s; dropped 4 (cam/depth 4)";
    // under the lossless policy, how long the drivers waited for the disk.
    std::string summary() const;
};

// A sink node: subscribes to its streams in connect(), creates the recording in start(),
// writes on its own thread, and finishes the file in stop(). After the first write error
// (disk full, file size limit) it writes nothing more but keeps draining its queues, so live
// drivers never block and the file stays readable up to its last complete frame.
// Thread-safe: stats() may be called from any thread at any time; the Node methods are
// called by the graph.
class Recorder : public Node {
public:
    explicit Recorder(RecorderOptions options);
    ~Recorder() override;
    Recorder(const Recorder&) = delete;
    Recorder& operator=(const Recorder&) = delete;

    std::string name() const override { return options_.name; }
    Status connect(Graph& graph) override;
    Status start() override;
    // Drains what is queued, finishes the file and joins the thread.
    void stop() override;

    RecorderStats stats() const;
    // The recording's header as given to the writer (valid after connect()).
    const RecordingHeader& header() const { return header_; }

private:
    struct Input {
        StreamId graph_id = kInvalidStream;
        std::shared_ptr<FrameQueue> queue;
        FrameRef head;  // popped, waiting for its turn
        std::chrono::steady_clock::time_point head_since;
        bool finished = false;
        // It held another stream's frame for the whole reorder window: nobody waits for it again
        // until it brings a frame (a camera that starts late would otherwise slow every other
        // stream to one frame per window, and their pools would run dry).
        bool overdue = false;
        // The stream's frames come at least this far apart (minFramePeriodNs()), and the last
        // one popped had this host stamp: until then plus the period,
        // the stream cannot bring a frame that should be written before another stream's.
        int64_t min_period_ns = 0;
        std::optional<int64_t> last_stamp_ns;
        // Whether its next frame may be older than `stamp_ns` (host time base).
        bool mayPrecede(int64_t stamp_ns) const {
            return !last_stamp_ns || min_period_ns == 0 ||
                   *last_stamp_ns + min_period_ns <= stamp_ns;
        }
    };

    void run();
    bool pullHeads(bool wait);
    void writeFrame(size_t input, FrameRef frame);
    void finish();

    RecorderOptions options_;
    Graph* graph_ = nullptr;
    RecordingHeader header_;
    std::vector<Input> inputs_;  // thread-bound to the writing thread while it runs
    std::unique_ptr<RecordingWriter> writer_;
    std::thread thread_;
    std::atomic<bool> stopping_{false};

    mutable std::mutex stats_mutex_;
    std::vector<RecorderStreamStats> counts_;  // written / discarded per input
    uint64_t bytes_written_ = 0;
    Status error_;
    bool running_ = false;
    std::chrono::steady_clock::time_point started_at_;
    std::chrono::steady_clock::time_point finished_at_;
    bool finished_ = false;
};

}  // namespace mixray
