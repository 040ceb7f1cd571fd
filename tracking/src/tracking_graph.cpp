// Tracking and light estimation as a graph node (mixray/tracking/tracking_node.h).
#include "mixray/tracking/tracking_node.h"

#include <algorithm>

#include "mixray/graph/pose.h"
#include "mixray/graph/record_codec.h"
#include "mixray/tracking/light_record.h"

namespace mixray::tracking {
namespace {

// Live, the probes are estimated about 5 times a second (PipelineOptions::probe_interval_ms).
constexpr int64_t kLiveProbeIntervalMs = 200;

constexpr auto kPollInterval = std::chrono::milliseconds(5);

}  // namespace

Status TrackingNodeOptions::validate() const {
    if (name.empty())
        return {ErrorCode::kInvalidArgument, "tracking node: empty name"};
    for (const std::string* s : {&pose_stream, &light_stream, &environment_map_stream})
        if (s->empty())
            return {ErrorCode::kInvalidArgument, "tracking node: an output stream has no name"};
    if (queue_capacity < 2 || output_buffers < 2)
        return {ErrorCode::kInvalidArgument,
                "tracking node: queue_capacity and output_buffers must be at least 2"};
    return setup.validate();
}

Result<std::unique_ptr<TrackingNode>> TrackingNode::create(TrackingNodeOptions options,
                                                           TrackedFrameCallback on_frame) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    return std::unique_ptr<TrackingNode>(new TrackingNode(std::move(options), std::move(on_frame)));
}

TrackingNode::TrackingNode(TrackingNodeOptions options, TrackedFrameCallback on_frame)
    : options_(std::move(options)), on_frame_(std::move(on_frame)) {}

TrackingNode::~TrackingNode() {
    stop();
}

Status TrackingNode::connect(Graph& graph) {
    graph_ = &graph;
    PipelineOptions pipeline_options = options_.pipeline;
    pipeline_options.wait_for_environment = options_.lossless;
    if (!options_.lossless && pipeline_options.probe_interval_ms == 0)
        pipeline_options.probe_interval_ms = kLiveProbeIntervalMs;
    // Live, tracking keeps the camera's rate while the probes are estimated beside it.
    pipeline_options.async_probes = !options_.lossless;
    auto pipeline = TrackingPipeline::create(options_.setup, graph.streams(), pipeline_options);
    if (!pipeline)
        return pipeline.status().withContext(options_.name);
    pipeline_ = std::move(pipeline).value();
    color_ = pipeline_->colorStream();
    environment_ = pipeline_->environmentStream();

    const QueuePolicy policy = options_.lossless ? QueuePolicy::kLossless : QueuePolicy::kLive;
    // Live, only the newest colour frame matters; one more lets the next arrive meanwhile.
    const size_t color_capacity = options_.lossless ? options_.queue_capacity : 2;
    auto color_queue = graph.subscribe(color_, {color_capacity, policy, options_.name});
    if (!color_queue)
        return color_queue.status();
    color_queue_ = std::move(color_queue).value();
    if (environment_ != kInvalidStream) {
        auto env_queue = graph.subscribe(
            environment_, {options_.lossless ? options_.queue_capacity : 1, policy, options_.name});
        if (!env_queue)
            return env_queue.status();
        environment_queue_ = std::move(env_queue).value();
    }

    const StreamInfo color = graph.stream(color_);
    const double fps = color.nominal_fps > 0 ? color.nominal_fps : 30;
    // Live, a pose or light record waits in the compositor's synchronizer for its colour frame
    // (up to half a second, 16 records) while the recorder and the view hold a few more: with
    // the colour frame's 8, one frame in four found the pool empty and went unpublished.
    // Records are small; a second and a half of them costs a few hundred kilobytes.
    const size_t record_buffers =
        options_.lossless ? options_.output_buffers
                          : std::max(options_.output_buffers, static_cast<size_t>(1.5 * fps));
    StreamInfo pose = makePoseStreamInfo(options_.pose_stream, color.name, fps, false);
    pose.device = options_.name;
    pose.clock_domain = color.clock_domain;
    auto pose_out = addPooledStream(graph, pose, record_buffers);
    if (!pose_out)
        return pose_out.status();
    pose_out_ = std::move(pose_out).value();
    StreamInfo lights = makeLightStreamInfo(options_.light_stream, color.name, fps);
    lights.device = options_.name;
    lights.clock_domain = color.clock_domain;
    auto light_out = addPooledStream(graph, lights, record_buffers);
    if (!light_out)
        return light_out.status();
    light_out_ = std::move(light_out).value();
    if (environment_ != kInvalidStream) {
        const StreamInfo env = graph.stream(environment_);
        const int width = options_.setup.environment->map_width;
        StreamInfo map = makeEnvironmentMapStreamInfo(options_.environment_map_stream, env.name,
                                                      width, width / 2);
        map.device = options_.name;
        map.clock_domain = env.clock_domain;
        map.nominal_fps = env.nominal_fps;
        // Maps are published rarely and held by the compositor until a newer one comes.
        auto map_out = addPooledStream(graph, map, 4);
        if (!map_out)
            return map_out.status();
        environment_map_out_ = std::move(map_out).value();
    }
    return Status::ok();
}

Status TrackingNode::start() {
    if (!graph_)
        return {ErrorCode::kInternal, options_.name + ": start() before connect()"};
    stop_ = false;
    thread_ = std::thread([this] { run(); });
    return Status::ok();
}

void TrackingNode::stop() {
    stop_ = true;
    if (color_queue_)
        color_queue_->close();
    if (environment_queue_)
        environment_queue_->close();
    if (thread_.joinable())
        thread_.join();
}

bool TrackingNode::waitDone(std::chrono::nanoseconds timeout) const {
    std::unique_lock lock(mutex_);
    return done_cv_.wait_for(lock, timeout, [this] { return done_; });
}

Status TrackingNode::status() const {
    std::lock_guard lock(mutex_);
    return status_;
}

TrackingNodeStats TrackingNode::stats() const {
    std::lock_guard lock(mutex_);
    return stats_;
}

void TrackingNode::finish(Status status) {
    // Consumers see the end of the records either way; an error stays in status().
    graph_->endStream(pose_out_.id);
    graph_->endStream(light_out_.id);
    if (environment_map_out_.pool)
        graph_->endStream(environment_map_out_.id);
    {
        std::lock_guard lock(mutex_);
        status_ = std::move(status);
        done_ = true;
    }
    done_cv_.notify_all();
}

void TrackingNode::submitEnvironment(const FrameRef& env) {
    if (env.meta().status == FrameStatus::kCorrupt)
        return;
    auto pushed = pipeline_->push(env);
    (void)pushed;  // environment frames give no tracked frame and no error
    std::lock_guard lock(mutex_);
    ++stats_.environment_frames;
}

void TrackingNode::run() {
    // Environment frames waiting now go to the estimator; lossless, every one of them in order.
    const auto drainEnvironment = [this] {
        if (!environment_queue_)
            return;
        while (auto env = environment_queue_->tryPop())
            submitEnvironment(*env);
    };
    FrameRef pending;  // lossless: the colour frame waiting for its successor
    while (!stop_) {
        auto next = color_queue_->pop(kPollInterval);
        if (!next) {
            // Lossless, an environment frame must not wait behind a colour frame that cannot
            // come before it is taken (the source publishes both from one thread).
            drainEnvironment();
            if (!color_queue_->closed())
                continue;
            // The last frame may have come between the timeout and the close.
            next = color_queue_->tryPop();
            if (!next)
                break;
        }
        if (!options_.lossless) {
            // Live: skip to the newest colour frame waiting.
            while (auto newer = color_queue_->tryPop()) {
                next = std::move(newer);
                std::lock_guard lock(mutex_);
                ++stats_.color_skipped;
            }
            drainEnvironment();
            if (!track(*next))
                return;
            continue;
        }
        // Everything published before this colour frame (its predecessor's environment frame)
        // is queued by now: estimate it, then track the predecessor.
        drainEnvironment();
        if (pending && !track(pending))
            return;
        pending = std::move(*next);
    }
    if (stop_) {
        finish(Status::ok());
        return;
    }
    drainEnvironment();
    if (pending && !track(pending))
        return;
    finish(Status::ok());
}

bool TrackingNode::track(const FrameRef& color) {
    if (color.meta().status == FrameStatus::kCorrupt)
        return true;
    auto tracked = pipeline_->push(color);
    if (!tracked) {
        finish(tracked.status().withContext(options_.name));
        return false;
    }
    if (!*tracked)
        return true;
    const TrackedFrame& f = **tracked;
    // Observers first: whoever consumes the records may then find the frame they came from.
    if (on_frame_)
        on_frame_(f);
    publishEnvironmentMap(f);
    publishPose(f);
    publishLights(f);
    {
        std::lock_guard lock(mutex_);
        ++stats_.color_frames;
        if (options_.max_color_frames == 0 || stats_.color_frames < options_.max_color_frames)
            return true;
    }
    finish(Status::ok());
    return false;
}

void TrackingNode::publishPose(const TrackedFrame& f) {
    PoseRecord record;
    record.frame_sequence = f.color.meta().sequence;
    record.frame_device_stamp_ns = f.color.meta().device_stamp_ns;
    record.anchor = "world";
    if (f.track.pose.value) {
        record.setTransform(*f.track.pose.value);
        record.status =
            f.track.state == TrackState::kTracking ? PoseStatus::kValid : PoseStatus::kStale;
    } else {
        record.status = PoseStatus::kLost;
    }
    if (record.status != PoseStatus::kValid)
        record.reason = record::printableText(f.track.pose.reason, kPoseReasonMaxBytes);
    if (!f.track.targets.empty())
        record.error = static_cast<float>(f.track.targets.front().rms_px);
    auto bytes = encodePoseRecord(record);
    WritableFrame out = acquire(*pose_out_.pool);
    if (!bytes || !out) {
        std::lock_guard lock(mutex_);
        ++stats_.publish_failures;
        graph_->countLost(pose_out_.id);
        return;
    }
    std::copy(bytes->begin(), bytes->end(), out.image().data);
    out.setPayloadBytes(bytes->size());
    out.meta() = f.color.meta();
    out.meta().stream = pose_out_.id;
    graph_->publish(std::move(out).publish());
}

void TrackingNode::publishLights(const TrackedFrame& f) {
    LightRecord record;
    record.frame_sequence = f.color.meta().sequence;
    record.frame_device_stamp_ns = f.color.meta().device_stamp_ns;
    const int64_t stamp = f.color.meta().host_stamp_ns;
    LightGroup render;
    render.name = "render";
    render.lights = pipeline_->renderLights(f);
    render.stale = render.lights.empty();
    if (render.stale)
        render.reason = "no light estimated yet";
    render.stamp_ns = stamp;
    render.good_stamp_ns = render.stale ? 0 : stamp;
    record.groups.push_back(std::move(render));
    for (size_t i = 0; i < f.probes.size(); ++i)
        record.groups.push_back(
            toLightGroup("probe:" + options_.setup.probes[i].name, f.probes[i]));
    if (options_.setup.environment && options_.pipeline.environment)
        record.groups.push_back(toLightGroup("environment", f.environment));
    if (f.sun.value || !f.sun.reason.empty())
        record.groups.push_back(toLightGroup("sun", f.sun));
    auto bytes = encodeLightRecord(record);
    WritableFrame out = acquire(*light_out_.pool);
    if (!bytes || !out || bytes->size() > out.capacityBytes()) {
        std::lock_guard lock(mutex_);
        ++stats_.publish_failures;
        graph_->countLost(light_out_.id);
        return;
    }
    std::copy(bytes->begin(), bytes->end(), out.image().data);
    out.setPayloadBytes(bytes->size());
    out.meta() = f.color.meta();
    out.meta().stream = light_out_.id;
    graph_->publish(std::move(out).publish());
}

void TrackingNode::publishEnvironmentMap(const TrackedFrame& f) {
    if (!environment_map_out_.pool || !f.environment.value ||
        !f.environment.value->environment_map || f.environment.good_stamp_ns <= 0 ||
        f.environment.good_stamp_ns == published_map_stamp_ns_)
        return;
    WritableFrame out = acquire(*environment_map_out_.pool);
    Result<size_t> bytes = Status(ErrorCode::kUnavailable, "no buffer");
    if (out) {
        bytes = encodeEnvironmentMapRecord(
            *f.environment.value->environment_map,
            toEnvironmentMapHeader(f.color.meta().sequence, f.color.meta().device_stamp_ns,
                                   f.environment),
            out.image().data, out.capacityBytes());
    }
    if (!bytes) {
        std::lock_guard lock(mutex_);
        ++stats_.publish_failures;
        graph_->countLost(environment_map_out_.id);
        return;
    }
    out.setPayloadBytes(*bytes);
    FrameMetadata meta;
    meta.stream = environment_map_out_.id;
    meta.sequence = static_cast<uint64_t>(stats().environment_maps);
    meta.host_stamp_ns = f.environment.good_stamp_ns;
    meta.device_stamp_ns = f.environment.good_stamp_ns;
    out.meta() = meta;
    graph_->publish(std::move(out).publish());
    published_map_stamp_ns_ = f.environment.good_stamp_ns;
    std::lock_guard lock(mutex_);
    ++stats_.environment_maps;
}

WritableFrame TrackingNode::acquire(BufferPool& pool) {
    // Lossless, a record waits for a consumer to return a buffer; live, it is dropped (counted).
    return options_.lossless ? acquireWaiting(pool, [this] { return stop_.load(); })
                             : pool.acquire();
}

}  // namespace mixray::tracking
