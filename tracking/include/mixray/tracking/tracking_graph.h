// Tracking and light estimation as graph nodes: colour (and fish-eye environment) frames in;
// the camera's pose, the estimated lights and the environment map out as record streams, so a
// live rig, a replayed recording and an offline batch run are the same pipeline.
//
//   colour ──► MarkerTrackingNode ──► pose records ──┐
//   colour ─────────────────────────────────────────►├─► LightEstimationNode ──► light records
//   fish-eye ─► EnvironmentLightNode ──► environment light records ──┘   (one per colour frame)
//                                    └─► environment maps
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "mixray/graph/graph.h"
#include "mixray/tracking/pipeline.h"

namespace mixray::tracking {

// What the three nodes are built from; each takes the part it needs.
struct TrackingNodeOptions {
    std::string name = "tracking";  // the nodes are NAME/markers, NAME/lights, NAME/environment
    TrackingSetup setup;            // its camera.stream and environment->stream name graph streams
    PipelineOptions pipeline;
    // Offline (recordings as fast as the pipeline takes them): lossless edges, every colour
    // and environment frame estimated, and each colour frame's lights take the fish-eye
    // estimate of the newest environment image captured before it, so a run gives the same
    // answer every time. Live: live edges, the newest colour frame is tracked at once (older
    // ones waiting are skipped and counted), the probes are estimated beside the node (newest
    // frame wins) and the fish-eye on its own node's thread, newest image wins.
    bool lossless = true;
    // Output streams; the pose and light streams' records belong to the setup's camera stream,
    // the environment light records to the fish-eye stream.
    std::string pose_stream = "tracking/pose";
    std::string light_stream = "tracking/lights";
    std::string environment_light_stream = "tracking/environment_lights";
    std::string environment_map_stream = "tracking/environment_map";
    size_t queue_capacity = 8;  // per input edge
    size_t output_buffers = 8;  // per output stream's pool
    // Track this many colour frames, then end the pose and light streams as if the colour
    // stream had ended (0: all): what was tracked is exactly what was published, and recorded.
    uint64_t max_color_frames = 0;

    Status validate() const;
};

// The three nodes' figures together.
struct TrackingNodeStats {
    uint64_t color_frames = 0;         // colour frames tracked
    uint64_t color_skipped = 0;        // live: colour frames a newer one replaced before tracking
    uint64_t light_records = 0;        // light records published (one per tracked colour frame)
    uint64_t environment_frames = 0;   // environment frames estimated
    uint64_t environment_skipped = 0;  // live: environment frames a newer one replaced
    uint64_t environment_maps = 0;     // environment maps published (fish-eye or camera-built)
    uint64_t publish_failures = 0;     // records not published: their pool was exhausted
};

// Called before a colour frame's light record is published, once its pose and every light
// estimate are known (for reports, overlays, accuracy checks); on the light node's thread. Must
// not block for long: it holds up the lights (and, lossless, the whole pipeline).
using TrackedFrameCallback = std::function<void(const TrackedFrame& frame)>;

// What the three tracking nodes share: a thread of their own, started by start(), that runs
// until its inputs end or stop() closes them, and the error that ended it.
class TrackingGraphNode : public Node {
public:
    Status start() override;
    // Closes the inputs and joins the thread. Derived destructors call it.
    void stop() override;
    // Until the node's run ended (its inputs ended, or it failed); false on timeout.
    bool waitDone(std::chrono::nanoseconds timeout) const;
    // ok, or the error that stopped the node.
    Status status() const;

protected:
    TrackingGraphNode();
    ~TrackingGraphNode() override;
    // The node's loop, on its thread; ends by calling finish().
    virtual void run() = 0;
    // Ends the node's output streams and records how its run ended.
    void finish(Status status, std::initializer_list<StreamId> outputs);
    // An input edge stop() closes.
    void addInput(std::shared_ptr<FrameQueue> queue) { inputs_.push_back(std::move(queue)); }

    Graph* graph_ = nullptr;  // set by connect()
    std::atomic<bool> stop_{false};

private:
    struct RunState;
    std::vector<std::shared_ptr<FrameQueue>> inputs_;
    std::thread thread_;
    std::unique_ptr<RunState> run_state_;
};

class MarkerTrackingNode;
class LightEstimationNode;
class EnvironmentLightNode;

// Adds the tracking nodes to a graph that has the setup's camera stream (and, when the setup
// has one and the graph has it, its environment stream): the environment node first, then
// marker tracking, then light estimation. The nodes belong to the graph; this holds their
// addresses. Thread-safe: stats(), waitDone() and status() from any thread.
class TrackingNodes {
public:
    static Result<TrackingNodes> add(Graph& graph, TrackingNodeOptions options,
                                     TrackedFrameCallback on_frame = {});

    // Until the light stream ended (the colour stream did, or max_color_frames were tracked)
    // and its last record was published; false on timeout.
    bool waitDone(std::chrono::nanoseconds timeout) const;
    // ok, or the first error that stopped a node (a frame the tracker refused).
    Status status() const;
    TrackingNodeStats stats() const;
    // Upstream first, so that each record computed from a frame is published before its
    // consumers stop: environment and markers, then lights.
    void stop();

    const TrackingNodeOptions& options() const { return *options_; }
    bool hasEnvironment() const { return environment_ != nullptr; }
    // Whether options().environment_map_stream exists: the fish-eye's maps, or those the light
    // node builds from the colour frames.
    bool hasEnvironmentMaps() const;
    MarkerTrackingNode& markers() const { return *markers_; }
    LightEstimationNode& lights() const { return *lights_; }
    EnvironmentLightNode* environment() const { return environment_; }

private:
    std::shared_ptr<const TrackingNodeOptions> options_;
    MarkerTrackingNode* markers_ = nullptr;
    LightEstimationNode* lights_ = nullptr;
    EnvironmentLightNode* environment_ = nullptr;
};

}  // namespace mixray::tracking
