// Tracking and light estimation as graph nodes (mixray/tracking/tracking_graph.h).
#include "mixray/tracking/tracking_graph.h"

#include <condition_variable>
#include <map>
#include <mutex>

#include "mixray/graph/thread_priority.h"
#include "mixray/tracking/environment_light_node.h"
#include "mixray/tracking/light_estimation_node.h"
#include "mixray/tracking/marker_tracking_node.h"

namespace mixray::tracking {
namespace {

// Joins what the marker node saw of a colour frame with the lights the light node estimated
// for it, into the TrackedFrame observers get. The light node's part always comes second: it
// needs the frame's pose record, which the marker node publishes after its callback.
class TrackedFrameJoiner {
public:
    explicit TrackedFrameJoiner(TrackedFrameCallback on_frame) : on_frame_(std::move(on_frame)) {}

    void tracked(const TrackedColor& c) {
        std::lock_guard lock(mutex_);
        waiting_[c.color.meta().sequence] = c;
        // Live, the light node may fall behind; a second's frames are plenty to wait for.
        while (waiting_.size() > 64)
            waiting_.erase(waiting_.begin());
    }
    void lit(uint64_t sequence, TrackedFrame& frame) {
        std::optional<TrackedColor> c;
        {
            std::lock_guard lock(mutex_);
            const auto it = waiting_.find(sequence);
            if (it != waiting_.end())
                c = std::move(it->second);
            waiting_.erase(waiting_.begin(), waiting_.upper_bound(sequence));
        }
        if (!c)
            return;
        frame.index = c->index;
        frame.color = std::move(c->color);
        frame.track = std::move(c->track);
        frame.track_ms = c->track_ms;
        on_frame_(frame);
    }

private:
    TrackedFrameCallback on_frame_;
    std::mutex mutex_;
    std::map<uint64_t, TrackedColor> waiting_;
};

}  // namespace

struct TrackingGraphNode::RunState {
    mutable std::mutex mutex;
    mutable std::condition_variable cv;
    bool done = false;
    Status status;
};

TrackingGraphNode::TrackingGraphNode() : run_state_(std::make_unique<RunState>()) {}

TrackingGraphNode::~TrackingGraphNode() = default;

Status TrackingGraphNode::start() {
    if (!graph_)
        return {ErrorCode::kInternal, name() + ": start() before connect()"};
    stop_ = false;
    thread_ = std::thread([this] {
        // Tracking and light estimation: below capture, the recorder and the publishers,
        // above the renderer (mixray/graph/thread_priority.h).
        runAs(ThreadRole::kEstimator);
        run();
    });
    return Status::ok();
}

void TrackingGraphNode::stop() {
    stop_ = true;
    for (const auto& queue : inputs_)
        queue->close();
    if (thread_.joinable())
        thread_.join();
}

bool TrackingGraphNode::waitDone(std::chrono::nanoseconds timeout) const {
    std::unique_lock lock(run_state_->mutex);
    return run_state_->cv.wait_for(lock, timeout, [this] { return run_state_->done; });
}

Status TrackingGraphNode::status() const {
    std::lock_guard lock(run_state_->mutex);
    return run_state_->status;
}

void TrackingGraphNode::finish(Status status, std::initializer_list<StreamId> outputs) {
    // Consumers see the end of the records either way; an error stays in status().
    for (StreamId id : outputs)
        graph_->endStream(id);
    {
        std::lock_guard lock(run_state_->mutex);
        run_state_->status = std::move(status);
        run_state_->done = true;
    }
    run_state_->cv.notify_all();
}

Status TrackingNodeOptions::validate() const {
    if (name.empty())
        return {ErrorCode::kInvalidArgument, "tracking nodes: empty name"};
    for (const std::string* s :
         {&pose_stream, &light_stream, &environment_light_stream, &environment_map_stream})
        if (s->empty())
            return {ErrorCode::kInvalidArgument, "tracking nodes: an output stream has no name"};
    if (queue_capacity < 2 || output_buffers < 2)
        return {ErrorCode::kInvalidArgument,
                "tracking nodes: queue_capacity and output_buffers must be at least 2"};
    if (pipeline.camera_environment) {
        MIXRAY_RETURN_IF_ERROR(
            pipeline.camera_environment->validate().withContext("camera_environment"));
        if (pipeline.camera_environment_interval < 1)
            return {ErrorCode::kInvalidArgument,
                    "tracking nodes: camera_environment_interval must be at least 1"};
    }
    return setup.validate();
}

Result<TrackingNodes> TrackingNodes::add(Graph& graph, TrackingNodeOptions options,
                                         TrackedFrameCallback on_frame) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    TrackingNodes nodes;
    nodes.options_ = std::make_shared<const TrackingNodeOptions>(std::move(options));
    const TrackingNodeOptions& o = *nodes.options_;
    if (o.pipeline.environment && o.setup.environment &&
        graph.findStream(o.setup.environment->stream)) {
        auto environment = EnvironmentLightNode::create(nodes.options_);
        if (!environment)
            return environment.status();
        nodes.environment_ = environment->get();
        MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(environment).value()));
    }
    std::shared_ptr<TrackedFrameJoiner> joiner;
    if (on_frame)
        joiner = std::make_shared<TrackedFrameJoiner>(std::move(on_frame));
    MarkerTrackingNode::Callback on_tracked;
    LightEstimationNode::Callback on_lights;
    if (joiner) {
        on_tracked = [joiner](const TrackedColor& c) { joiner->tracked(c); };
        on_lights = [joiner](uint64_t sequence, TrackedFrame& f) { joiner->lit(sequence, f); };
    }
    auto markers = MarkerTrackingNode::create(nodes.options_, std::move(on_tracked));
    if (!markers)
        return markers.status();
    nodes.markers_ = markers->get();
    MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(markers).value()));
    auto lights = LightEstimationNode::create(nodes.options_, std::move(on_lights));
    if (!lights)
        return lights.status();
    nodes.lights_ = lights->get();
    MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(lights).value()));
    return nodes;
}

bool TrackingNodes::hasEnvironmentMaps() const {
    return environment_ || lights_->buildsCameraEnvironment();
}

bool TrackingNodes::waitDone(std::chrono::nanoseconds timeout) const {
    return lights_->waitDone(timeout);
}

Status TrackingNodes::status() const {
    if (environment_)
        MIXRAY_RETURN_IF_ERROR(environment_->status());
    MIXRAY_RETURN_IF_ERROR(markers_->status());
    return lights_->status();
}

TrackingNodeStats TrackingNodes::stats() const {
    TrackingNodeStats s;
    const MarkerTrackingStats m = markers_->stats();
    const LightEstimationStats l = lights_->stats();
    s.color_frames = m.color_frames;
    s.color_skipped = m.color_skipped;
    s.light_records = l.light_records;
    s.publish_failures = m.publish_failures + l.publish_failures;
    s.environment_maps = l.camera_environment_maps;
    if (environment_) {
        const EnvironmentLightStats e = environment_->stats();
        s.environment_frames = e.environment_frames;
        s.environment_skipped = e.environment_skipped;
        s.environment_maps += e.environment_maps;
        s.publish_failures += e.publish_failures;
    }
    return s;
}

void TrackingNodes::stop() {
    if (environment_)
        environment_->stop();
    markers_->stop();
    lights_->stop();
}

}  // namespace mixray::tracking
