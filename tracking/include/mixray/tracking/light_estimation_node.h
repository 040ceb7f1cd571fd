// Light estimation as a graph node: colour frames and their pose records (and the fish-eye's
// environment light records) in, one light record per colour frame out.
#pragma once

#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "mixray/graph/graph.h"
#include "mixray/graph/pose.h"
#include "mixray/tracking/tracking_graph.h"

namespace mixray::tracking {

struct LightEstimationStats {
    uint64_t light_records = 0;            // published
    uint64_t publish_failures = 0;         // light records not published: their pool was exhausted
    uint64_t camera_environment_maps = 0;  // camera-built environment maps published
};

// For each pose record of options.pose_stream (MarkerTrackingNode's), matched to its colour
// frame by sequence: the probes' lights from the colour image seen from that pose, the sun's
// direction from the frame's time, the fish-eye's lights from options.environment_light_stream
// (EnvironmentLightNode's), and the strengths fit to the diffuse probe; published as one light
// record (light_record.h: a group per estimator and the "render" group the compositor renders
// with) with the colour frame's metadata. Every group keeps its stale flag and reason.
//
// Lossless, a colour frame's fish-eye estimate is the one of the newest environment image
// stamped at or before it: the node also listens to the environment stream, to know which
// images were captured before the frame, and waits until their records came. Live, the newest
// environment record wins, and the probes are estimated on a thread beside the node
// (at most every PipelineOptions::probe_interval_ms), so the records keep the
// colour rate. Without a fish-eye stream, and with PipelineOptions::camera_environment, it also
// builds the environment from the colour frames it has fresh poses for and publishes its maps. Ends
// its streams when the pose stream ends. Thread-safe: stats(), waitDone() and status() from any
// thread.
class LightEstimationNode : public TrackingGraphNode {
public:
    // Called on the node's thread before the record of colour frame `color_sequence` is
    // published, with the frame's estimates (probes, environment, sun, intensities, probe_ms;
    // color when the node had the frame).
    using Callback = std::function<void(uint64_t color_sequence, TrackedFrame& frame)>;

    static Result<std::unique_ptr<LightEstimationNode>> create(
        std::shared_ptr<const TrackingNodeOptions> options, Callback on_lights = {});
    ~LightEstimationNode() override;

    std::string name() const override { return options_->name + "/lights"; }
    // The colour and pose streams must exist; the environment streams are used when they do.
    Status connect(Graph& graph) override;
    LightEstimationStats stats() const;
    // After connect(): whether this node publishes camera-built environment maps.
    bool buildsCameraEnvironment() const { return camera_environment_.has_value(); }

private:
    class ProbeWorker;
    LightEstimationNode(std::shared_ptr<const TrackingNodeOptions> options, Callback on_lights);
    void run() override;
    void runLossless();
    void runLive();
    // Drains the environment queues into environment_stamps_ and environment_records_.
    void takeEnvironment();
    // Lossless: applies the environment records of images stamped at or before `stamp`, once
    // every such image's record came; false when stopped first.
    bool environmentUpTo(int64_t stamp);
    // Estimates and publishes the lights of the frame a pose record belongs to (`color` when
    // known): `pose_frame` carries the record `pose` decoded from it.
    void estimate(const FrameRef& pose_frame, const Result<PoseRecord>& pose,
                  const FrameRef& color);
    // Adds a colour frame with a fresh pose to the camera environment and publishes the map
    // when one is due.
    void addToCameraEnvironment(const FrameRef& color, const PoseRecord& pose,
                                const FrameMetadata& meta);

    std::shared_ptr<const TrackingNodeOptions> options_;
    PipelineOptions pipeline_;  // options_->pipeline as this node runs it
    Callback on_lights_;
    std::shared_ptr<FrameQueue> color_queue_;
    std::shared_ptr<FrameQueue> pose_queue_;
    std::shared_ptr<FrameQueue> environment_image_queue_;   // lossless: when images were taken
    std::shared_ptr<FrameQueue> environment_record_queue_;  // their estimates
    bool has_environment_stream_ = false;  // the setup's environment stream is in the graph
    PooledStream light_out_;
    std::optional<CameraEnvironment> camera_environment_;  // without a fish-eye, when asked
    PooledStream camera_map_out_;

    // Run state, touched by the node's thread only.
    std::deque<int64_t> environment_stamps_;    // lossless: images whose records are awaited
    std::deque<FrameRef> environment_records_;  // records not yet applied
    bool environment_ended_ = false;
    Estimate<EnvironmentEstimate> environment_;
    Estimate<EstimatedLight> sun_;
    std::vector<Estimate<ProbeResult>> probes_;
    Estimate<IntensityFit> intensities_;
    std::unique_ptr<ProbeWorker> probe_worker_;                  // live
    Estimate<EnvironmentEstimate> camera_environment_estimate_;  // the map last published
    uint32_t camera_frames_since_map_ = 0;
    int64_t last_probe_stamp_ns_ = 0;
    bool probed_ = false;

    mutable std::mutex stats_mutex_;
    LightEstimationStats stats_;
};

}  // namespace mixray::tracking
