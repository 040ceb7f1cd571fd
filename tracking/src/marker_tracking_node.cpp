// Marker tracking as a graph node (mixray/tracking/marker_tracking_node.h).
#include "mixray/tracking/marker_tracking_node.h"

#include <algorithm>

#include "mixray/graph/pose.h"
#include "mixray/graph/record_codec.h"
#include "node_support.h"

namespace mixray::tracking {

Result<std::unique_ptr<MarkerTrackingNode>> MarkerTrackingNode::create(
    std::shared_ptr<const TrackingNodeOptions> options, Callback on_tracked) {
    if (!options)
        return Status(ErrorCode::kInvalidArgument, "marker tracking node: no options");
    MIXRAY_RETURN_IF_ERROR(options->validate());
    return std::unique_ptr<MarkerTrackingNode>(
        new MarkerTrackingNode(std::move(options), std::move(on_tracked)));
}

MarkerTrackingNode::MarkerTrackingNode(std::shared_ptr<const TrackingNodeOptions> options,
                                       Callback on_tracked)
    : options_(std::move(options)), on_tracked_(std::move(on_tracked)) {}

MarkerTrackingNode::~MarkerTrackingNode() {
    stop();
}

Status MarkerTrackingNode::connect(Graph& graph) {
    graph_ = &graph;
    const TrackingSetup& setup = options_->setup;
    auto color = detail::findStream(graph, setup.camera.stream, "to track");
    if (!color)
        return color.status();
    const StreamInfo info = graph.stream(*color);
    if (info.format.width != setup.camera.model.width ||
        info.format.height != setup.camera.model.height) {
        return Status(ErrorCode::kInvalidArgument,
                      setup.camera.stream + " is " + std::to_string(info.format.width) + "x" +
                          std::to_string(info.format.height) + " but the setup's camera model is " +
                          std::to_string(setup.camera.model.width) + "x" +
                          std::to_string(setup.camera.model.height));
    }
    auto tracker = MarkerTracker::create(setup.camera.model, setup.targets, setup.tracker);
    if (!tracker)
        return tracker.status();
    tracker_ = std::move(tracker).value();

    const bool lossless = options_->lossless;
    // Live, only the newest colour frame matters; one more lets the next arrive meanwhile.
    auto queue =
        graph.subscribe(*color, {lossless ? options_->queue_capacity : 2,
                                 lossless ? QueuePolicy::kLossless : QueuePolicy::kLive, name()});
    if (!queue)
        return queue.status();
    color_queue_ = std::move(queue).value();
    addInput(color_queue_);

    const double fps = info.nominal_fps > 0 ? info.nominal_fps : 30;
    // Live, a pose record waits in the compositor's synchronizer for its colour frame (up to
    // half a second, 16 records) while the light node, the recorder and the view hold a few
    // more: with the colour frame's 8, one frame in four found the pool empty and went
    // unpublished. Records are small; a second and a half of them costs a few hundred kilobytes.
    const size_t buffers = lossless
                               ? options_->output_buffers
                               : std::max(options_->output_buffers, static_cast<size_t>(1.5 * fps));
    StreamInfo pose = makePoseStreamInfo(options_->pose_stream, info.name, fps, false);
    pose.device = options_->name;
    pose.clock_domain = info.clock_domain;
    auto out = addPooledStream(graph, pose, buffers);
    if (!out)
        return out.status();
    pose_out_ = std::move(out).value();
    return Status::ok();
}

MarkerTrackingStats MarkerTrackingNode::stats() const {
    std::lock_guard lock(stats_mutex_);
    return stats_;
}

void MarkerTrackingNode::run() {
    while (auto next = detail::popUnlessStopped(*color_queue_, stop_)) {
        if (!options_->lossless) {
            const uint64_t skipped = detail::skipToNewest(*color_queue_, *next);
            std::lock_guard lock(stats_mutex_);
            stats_.color_skipped += skipped;
        }
        if (!track(*next))
            return;
    }
    finish(Status::ok(), {pose_out_.id});
}

bool MarkerTrackingNode::track(const FrameRef& color) {
    PoseRecord record;
    record.frame_sequence = color.meta().sequence;
    record.frame_device_stamp_ns = color.meta().device_stamp_ns;
    record.anchor = "world";
    if (color.meta().status == FrameStatus::kCorrupt) {
        // Not tracked (its pixels are broken), but not passed over in silence either: its pose
        // is lost with the reason, so the compositor still gets the frame's set and says why
        // it made no composite of it.
        record.status = PoseStatus::kLost;
        record.reason = "the colour frame is marked corrupt by its driver";
        return publishPose(color, record);
    }
    TrackedColor f;
    f.color = color;
    const auto start = std::chrono::steady_clock::now();
    auto track = tracker_->track(color.image(), color.meta().host_stamp_ns);
    if (!track) {
        finish(track.status().withContext(name() + ": " + options_->setup.camera.stream +
                                          " frame " + std::to_string(color.meta().sequence)),
               {pose_out_.id});
        return false;
    }
    f.track = std::move(track).value();
    f.track_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    {
        std::lock_guard lock(stats_mutex_);
        f.index = stats_.color_frames;
    }
    // Observers first: whoever consumes the record may then find the frame it came from.
    if (on_tracked_)
        on_tracked_(f);

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
    return publishPose(color, record);
}

bool MarkerTrackingNode::publishPose(const FrameRef& color, const PoseRecord& record) {
    const bool published = detail::publishEncoded(*graph_, pose_out_, encodePoseRecord(record),
                                                  color.meta(), options_->lossless, stop_);
    {
        std::lock_guard lock(stats_mutex_);
        if (!published)
            ++stats_.publish_failures;
        ++stats_.color_frames;
        if (options_->max_color_frames == 0 || stats_.color_frames < options_->max_color_frames)
            return true;
    }
    finish(Status::ok(), {pose_out_.id});
    return false;
}

}  // namespace mixray::tracking
