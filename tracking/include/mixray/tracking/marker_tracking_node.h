// Marker tracking as a graph node: colour frames in, one pose record per colour frame out.
#pragma once

#include <functional>
#include <memory>
#include <mutex>
#include <string>

#include "mixray/graph/graph.h"
#include "mixray/graph/pose.h"
#include "mixray/tracking/markers.h"
#include "mixray/tracking/tracking_graph.h"

namespace mixray::tracking {

// One colour frame as the marker tracker saw it. Plain value.
struct TrackedColor {
    uint64_t index = 0;  // colour frames tracked so far, from 0
    FrameRef color;
    CameraTrack track;
    double track_ms = 0;
};

struct MarkerTrackingStats {
    uint64_t color_frames = 0;      // tracked
    uint64_t color_skipped = 0;     // live: replaced by a newer frame before tracking
    uint64_t publish_failures = 0;  // pose records not published: their pool was exhausted
};

// Tracks the setup's camera stream (the setup's targets and tracker options) and publishes,
// with each colour frame's metadata (sequence, stamps, clock domain), one pose record
// (mixray/graph/pose.h: valid, stale or lost, with the reason) on options.pose_stream. Lossless:
// every frame in order; live: the newest frame waiting, older ones skipped and counted. Ends
// its stream when the colour stream ends or max_color_frames were tracked. Thread-safe:
// stats(), waitDone() and status() from any thread.
class MarkerTrackingNode : public TrackingGraphNode {
public:
    // Called on the node's thread before the frame's pose record is published.
    using Callback = std::function<void(const TrackedColor& frame)>;

    static Result<std::unique_ptr<MarkerTrackingNode>> create(
        std::shared_ptr<const TrackingNodeOptions> options, Callback on_tracked = {});
    ~MarkerTrackingNode() override;

    std::string name() const override { return options_->name + "/markers"; }
    // The colour stream must exist, of the setup's camera model's size.
    Status connect(Graph& graph) override;
    MarkerTrackingStats stats() const;

private:
    MarkerTrackingNode(std::shared_ptr<const TrackingNodeOptions> options, Callback on_tracked);
    void run() override;
    // Tracks one colour frame and publishes its record; false when tracking failed. A frame
    // its driver marked corrupt is not tracked: its pose is lost, with the reason.
    bool track(const FrameRef& color);
    // Publishes `record` as color's pose; false once the node has finished (max_color_frames).
    bool publishPose(const FrameRef& color, const PoseRecord& record);

    std::shared_ptr<const TrackingNodeOptions> options_;
    Callback on_tracked_;
    std::unique_ptr<MarkerTracker> tracker_;
    std::shared_ptr<FrameQueue> color_queue_;
    PooledStream pose_out_;
    mutable std::mutex stats_mutex_;
    MarkerTrackingStats stats_;
};

}  // namespace mixray::tracking
