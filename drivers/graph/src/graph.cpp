// Stream registry, fan-out of published frames to subscribed queues, node lifecycle.
#include "mixray/graph/graph.h"

#include <algorithm>

#include "mixray/graph/device.h"

namespace mixray {

using QueueList = std::vector<std::shared_ptr<FrameQueue>>;

Graph::~Graph() {
    stop();
}

Result<StreamId> Graph::addStream(StreamInfo info) {
    if (info.name.empty())
        return {ErrorCode::kInvalidArgument, "stream without a name"};
    std::lock_guard lock(mutex_);
    for (const auto& s : streams_) {
        if (s->info.name == info.name) {
            return {ErrorCode::kInvalidArgument, "stream '" + info.name + "' declared twice"};
        }
    }
    auto state = std::make_unique<StreamState>();
    state->info = std::move(info);
    state->subscribers = std::make_shared<const QueueList>();
    streams_.push_back(std::move(state));
    return static_cast<StreamId>(streams_.size() - 1);
}

size_t Graph::streamCount() const {
    std::lock_guard lock(mutex_);
    return streams_.size();
}

StreamInfo Graph::stream(StreamId id) const {
    std::lock_guard lock(mutex_);
    return id < streams_.size() ? streams_[id]->info : StreamInfo{};
}

std::vector<StreamInfo> Graph::streams() const {
    std::lock_guard lock(mutex_);
    std::vector<StreamInfo> out;
    out.reserve(streams_.size());
    for (const auto& s : streams_)
        out.push_back(s->info);
    return out;
}

std::optional<StreamId> Graph::findStream(std::string_view name) const {
    std::lock_guard lock(mutex_);
    for (size_t i = 0; i < streams_.size(); ++i) {
        if (streams_[i]->info.name == name)
            return static_cast<StreamId>(i);
    }
    return std::nullopt;
}

Result<std::shared_ptr<FrameQueue>> Graph::subscribe(StreamId stream, const QueueOptions& options) {
    std::lock_guard lock(mutex_);
    if (stream >= streams_.size()) {
        return {ErrorCode::kNotFound, "subscribe: no stream with id " + std::to_string(stream)};
    }
    auto queue = std::make_shared<FrameQueue>(options);
    // Copy-on-write: publishers hold snapshots of the list and never wait for subscribers.
    auto list = std::make_shared<QueueList>(*streams_[stream]->subscribers);
    list->push_back(queue);
    streams_[stream]->subscribers = std::move(list);
    return queue;
}

void Graph::unsubscribe(const std::shared_ptr<FrameQueue>& queue) {
    if (!queue)
        return;
    queue->close();
    std::lock_guard lock(mutex_);
    for (auto& s : streams_) {
        const auto& current = *s->subscribers;
        if (std::find(current.begin(), current.end(), queue) == current.end())
            continue;
        auto list = std::make_shared<QueueList>();
        for (const auto& q : current) {
            if (q != queue)
                list->push_back(q);
        }
        s->subscribers = std::move(list);
    }
}

std::shared_ptr<const QueueList> Graph::subscribersOf(StreamId stream) const {
    std::lock_guard lock(mutex_);
    if (stream >= streams_.size())
        return nullptr;
    StreamState& state = *streams_[stream];
    state.published.fetch_add(1, std::memory_order_relaxed);
    state.last_published_ns.store(
        std::chrono::steady_clock::now().time_since_epoch() / std::chrono::nanoseconds(1),
        std::memory_order_relaxed);
    return state.subscribers;
}

void Graph::publish(const FrameRef& frame) {
    if (!frame)
        return;
    auto subscribers = subscribersOf(frame.meta().stream);
    if (!subscribers) {
        unknown_stream_frames_.fetch_add(1, std::memory_order_relaxed);
        return;
    }
    for (const auto& queue : *subscribers)
        queue->push(frame);
}

void Graph::endStream(StreamId stream) {
    std::shared_ptr<const QueueList> subscribers;
    {
        std::lock_guard lock(mutex_);
        if (stream >= streams_.size())
            return;
        subscribers = streams_[stream]->subscribers;
    }
    for (const auto& queue : *subscribers)
        queue->close();
}

Status Graph::addNode(std::unique_ptr<Node> node) {
    if (!node)
        return {ErrorCode::kInvalidArgument, "addNode: null node"};
    if (running_)
        return {ErrorCode::kInvalidArgument, "addNode: graph is running"};
    MIXRAY_RETURN_IF_ERROR(node->connect(*this).withContext("node '" + node->name() + "'"));
    nodes_.push_back(std::move(node));
    return Status::ok();
}

namespace {

// The order nodes start in: every consumer (sinks and filters) before any device, each group in
// the order it was added. A device publishes from its first instant; a consumer not yet
// started would let its queue overflow (the recorder's, while its encoders open: frames lost).
std::vector<Node*> startOrder(const std::vector<std::unique_ptr<Node>>& nodes) {
    std::vector<Node*> order;
    for (const auto& node : nodes)
        if (!dynamic_cast<const Device*>(node.get()))
            order.push_back(node.get());
    for (const auto& node : nodes)
        if (dynamic_cast<const Device*>(node.get()))
            order.push_back(node.get());
    return order;
}

}  // namespace

Status Graph::start() {
    if (running_)
        return Status::ok();
    running_ = true;
    const std::vector<Node*> order = startOrder(nodes_);
    for (started_nodes_ = 0; started_nodes_ < order.size(); ++started_nodes_) {
        Status status = order[started_nodes_]->start();
        if (!status.isOk()) {
            status = status.withContext("starting node '" + order[started_nodes_]->name() + "'");
            stop();
            return status;
        }
    }
    return Status::ok();
}

void Graph::stop() {
    if (!running_.exchange(false))
        return;
    // Close every queue first: nodes blocked on a lossless push or a pop wake up and see the
    // end, so stopping in reverse order cannot deadlock.
    std::vector<std::shared_ptr<const QueueList>> lists;
    {
        std::lock_guard lock(mutex_);
        for (const auto& s : streams_)
            lists.push_back(s->subscribers);
    }
    for (const auto& list : lists) {
        for (const auto& queue : *list)
            queue->close();
    }
    const std::vector<Node*> order = startOrder(nodes_);
    while (started_nodes_ > 0)
        order[--started_nodes_]->stop();
}

uint64_t Graph::publishedCount(StreamId stream) const {
    std::lock_guard lock(mutex_);
    return stream < streams_.size() ? streams_[stream]->published.load() : 0;
}

std::optional<std::chrono::steady_clock::time_point> Graph::lastPublished(StreamId stream) const {
    std::lock_guard lock(mutex_);
    const int64_t ns = stream < streams_.size() ? streams_[stream]->last_published_ns.load() : 0;
    if (ns == 0)
        return std::nullopt;
    return std::chrono::steady_clock::time_point(std::chrono::nanoseconds(ns));
}

void Graph::countLost(StreamId stream, uint64_t frames) {
    std::lock_guard lock(mutex_);
    if (stream < streams_.size())
        streams_[stream]->lost.fetch_add(frames);
}

uint64_t Graph::lostCount(StreamId stream) const {
    std::lock_guard lock(mutex_);
    return stream < streams_.size() ? streams_[stream]->lost.load() : 0;
}

std::vector<EdgeStats> Graph::edgeStats() const {
    std::lock_guard lock(mutex_);
    std::vector<EdgeStats> out;
    for (const auto& s : streams_) {
        for (const auto& queue : *s->subscribers) {
            out.push_back(
                {s->info.name, queue->options().name, queue->options().policy, queue->stats()});
        }
    }
    return out;
}

double Graph::recordingBacklog() const {
    std::lock_guard lock(mutex_);
    double fullest = 0;
    for (const auto& s : streams_) {
        for (const auto& queue : *s->subscribers) {
            if (!queue->options().feeds_recording || queue->options().capacity == 0)
                continue;
            fullest = std::max(fullest, static_cast<double>(queue->stats().size) /
                                            static_cast<double>(queue->options().capacity));
        }
    }
    return fullest;
}

Result<PooledStream> addPooledStream(Graph& graph, const StreamInfo& info, size_t buffer_count,
                                     size_t buffer_bytes) {
    auto id = graph.addStream(info);
    if (!id)
        return id.status();
    PooledStream out;
    out.id = *id;
    out.pool = BufferPool::create({info.format, buffer_bytes, buffer_count, info.name});
    if (!out.pool)
        return Status(ErrorCode::kInternal, "cannot create the pool of '" + info.name + "'");
    return out;
}

}  // namespace mixray
