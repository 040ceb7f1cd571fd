// Light estimation from the fish-eye environment camera as a graph node: environment images
// in; the lights and the environment map out.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "mixray/graph/graph.h"
#include "mixray/tracking/lights.h"
#include "mixray/tracking/tracking_graph.h"

namespace mixray::tracking {

struct EnvironmentLightStats {
    uint64_t environment_frames = 0;   // estimated
    uint64_t environment_skipped = 0;  // live: replaced by a newer image before estimation
    uint64_t environment_maps = 0;     // published
    uint64_t publish_failures = 0;     // records not published: their pool was exhausted
};

// Estimates the setup's environment camera (its stream, lens, light options and map width) on
// the node's own thread and publishes, for each image it estimates, one light record on
// options.environment_light_stream with the image's metadata (one group, "environment": the
// lights, or the last good ones marked stale with the reason), and, whenever an image gave a
// new map, an environment-map record on options.environment_map_stream stamped with that
// image. Lossless: every image in order (a corrupt one gives a stale record); live: the newest
// image waiting, older ones skipped and counted. Ends its streams when the environment stream
// ends. Thread-safe: stats(), waitDone() and status() from any thread.
class EnvironmentLightNode : public TrackingGraphNode {
public:
    // kInvalidArgument for a setup without an environment camera.
    static Result<std::unique_ptr<EnvironmentLightNode>> create(
        std::shared_ptr<const TrackingNodeOptions> options);
    ~EnvironmentLightNode() override;

    std::string name() const override { return options_->name + "/environment"; }
    // The environment stream must exist.
    Status connect(Graph& graph) override;
    EnvironmentLightStats stats() const;

private:
    explicit EnvironmentLightNode(std::shared_ptr<const TrackingNodeOptions> options);
    void run() override;
    void estimate(const FrameRef& image);
    void publishMap(const FrameRef& image, const Estimate<EnvironmentEstimate>& estimate);

    std::shared_ptr<const TrackingNodeOptions> options_;
    EnvironmentEstimator estimator_;
    std::shared_ptr<FrameQueue> queue_;
    PooledStream light_out_;
    PooledStream map_out_;
    int64_t published_map_stamp_ns_ = 0;
    uint64_t maps_published_ = 0;
    mutable std::mutex stats_mutex_;
    EnvironmentLightStats stats_;
};

}  // namespace mixray::tracking
