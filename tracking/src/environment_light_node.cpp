// Light estimation from the fish-eye as a graph node (mixray/tracking/environment_light_node.h).
#include "mixray/tracking/environment_light_node.h"

#include <mutex>

#include "mixray/graph/thread_priority.h"
#include "mixray/tracking/light_record.h"
#include "node_support.h"

namespace mixray::tracking {

Result<std::unique_ptr<EnvironmentLightNode>> EnvironmentLightNode::create(
    std::shared_ptr<const TrackingNodeOptions> options) {
    if (!options)
        return Status(ErrorCode::kInvalidArgument, "environment light node: no options");
    MIXRAY_RETURN_IF_ERROR(options->validate());
    if (!options->setup.environment)
        return Status(ErrorCode::kInvalidArgument,
                      options->name + ": the tracking setup has no environment camera");
    return std::unique_ptr<EnvironmentLightNode>(new EnvironmentLightNode(std::move(options)));
}

EnvironmentLightNode::EnvironmentLightNode(std::shared_ptr<const TrackingNodeOptions> options)
    : options_(std::move(options)),
      estimator_(options_->setup.environment->camera, options_->setup.environment->lights,
                 options_->setup.environment->map_width) {}

EnvironmentLightNode::~EnvironmentLightNode() {
    stop();
}

Status EnvironmentLightNode::connect(Graph& graph) {
    graph_ = &graph;
    const EnvironmentStream& setup = *options_->setup.environment;
    auto stream = detail::findStream(graph, setup.stream, "for the environment camera");
    if (!stream)
        return stream.status();
    const bool lossless = options_->lossless;
    // Live, the newest image wins: a queue of one replaces the image waiting.
    auto queue =
        graph.subscribe(*stream, {lossless ? options_->queue_capacity : 1,
                                  lossless ? QueuePolicy::kLossless : QueuePolicy::kLive, name()});
    if (!queue)
        return queue.status();
    queue_ = std::move(queue).value();
    addInput(queue_);

    const StreamInfo env = graph.stream(*stream);
    StreamInfo lights =
        makeLightStreamInfo(options_->environment_light_stream, env.name, env.nominal_fps);
    lights.device = options_->name;
    lights.clock_domain = env.clock_domain;
    // The light node keeps what it has not applied yet; the recorder and the view a few more.
    auto light_out = addPooledStream(graph, lights, options_->output_buffers);
    if (!light_out)
        return light_out.status();
    light_out_ = std::move(light_out).value();
    auto map_out = detail::addEnvironmentMapStream(graph, options_->environment_map_stream,
                                                   options_->name, env, setup.map_width);
    if (!map_out)
        return map_out.status();
    map_out_ = std::move(map_out).value();
    return Status::ok();
}

EnvironmentLightStats EnvironmentLightNode::stats() const {
    std::lock_guard lock(stats_mutex_);
    return stats_;
}

void EnvironmentLightNode::run() {
    // Live, a late estimate holds up no composite: the light node takes the newest there is.
    if (!options_->lossless)
        runAs(ThreadRole::kEstimator);
    while (auto next = detail::popUnlessStopped(*queue_, stop_)) {
        if (!options_->lossless) {
            const uint64_t skipped = detail::skipToNewest(*queue_, *next);
            std::lock_guard lock(stats_mutex_);
            stats_.environment_skipped += skipped;
        }
        estimate(*next);
    }
    finish(Status::ok(), {light_out_.id, map_out_.id});
}

void EnvironmentLightNode::estimate(const FrameRef& image) {
    const FrameMetadata& meta = image.meta();
    Estimate<EnvironmentEstimate> estimate = estimator_.latest();
    if (meta.status == FrameStatus::kCorrupt)
        estimate.keep("the environment image arrived corrupt", meta.host_stamp_ns);
    else
        estimate = estimator_.estimate(image.image(), meta.host_stamp_ns);
    publishMap(image, estimate);

    LightRecord record;
    record.frame_sequence = meta.sequence;
    record.frame_device_stamp_ns = meta.device_stamp_ns;
    record.groups.push_back(toLightGroup("environment", estimate));
    const bool published = detail::publishEncoded(*graph_, light_out_, encodeLightRecord(record),
                                                  meta, options_->lossless, stop_);
    std::lock_guard lock(stats_mutex_);
    ++stats_.environment_frames;
    if (!published)
        ++stats_.publish_failures;
}

void EnvironmentLightNode::publishMap(const FrameRef& image,
                                      const Estimate<EnvironmentEstimate>& estimate) {
    if (!estimate.value || !estimate.value->environment_map || estimate.good_stamp_ns <= 0 ||
        estimate.good_stamp_ns == published_map_stamp_ns_)
        return;
    FrameMetadata meta = image.meta();
    meta.sequence = maps_published_;
    if (!detail::publishEnvironmentMap(
            *graph_, map_out_, *estimate.value->environment_map,
            toEnvironmentMapHeader(image.meta().sequence, image.meta().device_stamp_ns, estimate),
            meta, options_->lossless, stop_)) {
        std::lock_guard lock(stats_mutex_);
        ++stats_.publish_failures;
        return;
    }
    ++maps_published_;
    published_map_stamp_ns_ = estimate.good_stamp_ns;
    std::lock_guard lock(stats_mutex_);
    ++stats_.environment_maps;
}

}  // namespace mixray::tracking
