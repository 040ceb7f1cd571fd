// The device graph: nodes publish frames into typed streams; bounded queues carry them to
// consumers.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/frame_queue.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray {

class Graph;

// A participant in a graph: a source (device), a filter or a sink. The graph calls connect()
// once when the node is added (declare output streams, subscribe to inputs), then start() and
// stop(). A node that needs a thread owns it: start() launches it, stop() joins it.
class Node {
public:
    virtual ~Node() = default;
    virtual std::string name() const = 0;
    virtual Status connect(Graph& graph) = 0;
    virtual Status start() = 0;
    // Must return promptly, also when the node's input queues are closed or its device hangs.
    virtual void stop() = 0;
};

// Statistics of one edge: a stream feeding one consumer's queue.
struct EdgeStats {
    std::string stream;
    std::string consumer;
    QueuePolicy policy = QueuePolicy::kLive;
    QueueStats queue;
};

// Owns nodes and routes published frames to every subscribed queue without copying them.
// Thread-safe: publish() is called from capture threads; subscribe() may be called at any
// time. Nodes are started in the order they were added, every consumer before any device (so
// no queue fills before its consumer runs), and stopped in reverse.
class Graph {
public:
    Graph() = default;
    ~Graph();
    Graph(const Graph&) = delete;
    Graph& operator=(const Graph&) = delete;

    // Declares a stream. Names are unique; the returned id indexes stream().
    Result<StreamId> addStream(StreamInfo info);
    size_t streamCount() const;
    StreamInfo stream(StreamId id) const;
    std::vector<StreamInfo> streams() const;
    std::optional<StreamId> findStream(std::string_view name) const;

    // Creates an edge from `stream` to a new queue for one consumer. The graph keeps a
    // reference until unsubscribe() or the graph dies; the consumer keeps the other.
    Result<std::shared_ptr<FrameQueue>> subscribe(StreamId stream, const QueueOptions& options);
    void unsubscribe(const std::shared_ptr<FrameQueue>& queue);

    // Hands `frame` to every queue subscribed to frame.meta().stream. Live edges never block;
    // lossless edges block until they have room. Frames of undeclared streams are counted
    // and discarded.
    void publish(const FrameRef& frame);

    // Publishes to all subscribers, then ends them: each subscribed queue of `stream` is
    // closed so consumers see the end of data.
    void endStream(StreamId stream);

    // Takes ownership of `node` and calls its connect().
    Status addNode(std::unique_ptr<Node> node);
    const std::vector<std::unique_ptr<Node>>& nodes() const { return nodes_; }

    // Starts every node in order; on a failure stops those already started and returns it.
    Status start();
    // Stops every node in reverse order and closes every queue. Idempotent.
    void stop();
    bool running() const { return running_.load(); }

    uint64_t publishedCount(StreamId stream) const;
    // When the last frame of `stream` was published (steady clock); nullopt before the first.
    // A device that says it streams but has published nothing for a few frame periods is
    // stalled (render::ArPipelineStats).
    std::optional<std::chrono::steady_clock::time_point> lastPublished(StreamId stream) const;
    // Frames a source made or read but could not publish on `stream` (a full pool, a frame a
    // player skipped): sources count them here so commands report them beside the consumers'
    // drops (edgeStats). Unknown streams are ignored.
    void countLost(StreamId stream, uint64_t frames = 1);
    uint64_t lostCount(StreamId stream) const;
    std::vector<EdgeStats> edgeStats() const;
    // How far behind the recording is: the fullest edge with QueueOptions::feeds_recording,
    // as the fraction of its capacity queued now (0: none is backed up or there is none).
    double recordingBacklog() const;

private:
    struct StreamState {
        StreamInfo info;
        std::shared_ptr<const std::vector<std::shared_ptr<FrameQueue>>> subscribers;
        std::atomic<uint64_t> published{0};
        std::atomic<int64_t> last_published_ns{0};  // steady clock; 0: nothing yet
        std::atomic<uint64_t> lost{0};
    };
    std::shared_ptr<const std::vector<std::shared_ptr<FrameQueue>>> subscribersOf(
        StreamId stream) const;

    mutable std::mutex mutex_;
    std::vector<std::unique_ptr<StreamState>> streams_;
    std::vector<std::unique_ptr<Node>> nodes_;
    size_t started_nodes_ = 0;
    std::atomic<bool> running_{false};
    std::atomic<uint64_t> unknown_stream_frames_{0};
};

// A stream a device publishes from a pool of its own: declared in the graph, its pool allocated.
struct PooledStream {
    StreamId id = kInvalidStream;
    std::shared_ptr<BufferPool> pool;
};

// Declares `info` and creates its pool of `buffer_count` buffers of `buffer_bytes` (0: what the
// stream's format needs), named after the stream. The graph's error for a bad stream; kInternal
// naming the stream when the pool cannot be created.
Result<PooledStream> addPooledStream(Graph& graph, const StreamInfo& info, size_t buffer_count,
                                     size_t buffer_bytes = 0);

}  // namespace mixray
