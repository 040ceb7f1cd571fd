// Tracking and light estimation as a graph node: colour (and fish-eye environment) frames in;
// the camera's pose, the estimated lights and the environment map out as record streams, so a
// live rig, a replayed recording and an offline batch run are the same pipeline.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "mixray/graph/graph.h"
#include "mixray/tracking/pipeline.h"

namespace mixray::tracking {

struct TrackingNodeOptions {
    std::string name = "tracking";
    TrackingSetup setup;  // its camera.stream and environment->stream name graph streams
    PipelineOptions pipeline;
    // Offline (recordings as fast as the pipeline takes them): lossless edges, and each colour
    // frame is tracked once the next one (or the end) has arrived, after every environment
    // frame published before it was estimated, so a run gives the same answer every time.
    // Live: live edges, the newest colour frame is tracked at once (older ones waiting are
    // skipped and counted) and the fish-eye is estimated on its own thread, newest image wins.
    bool lossless = true;
    // Output streams; the pose stream's records belong to (pose_of) the setup's camera stream.
    std::string pose_stream = "tracking/pose";
    std::string light_stream = "tracking/lights";
    std::string environment_map_stream = "tracking/environment_map";
    size_t queue_capacity = 8;  // per input edge
    size_t output_buffers = 8;  // per output stream's pool
    // Track this many colour frames, then end the output streams as if the colour stream had
    // ended (0: all): what was tracked is exactly what was published, and recorded.
    uint64_t max_color_frames = 0;

    Status validate() const;
};

struct TrackingNodeStats {
    uint64_t color_frames = 0;        // colour frames tracked
    uint64_t color_skipped = 0;       // live: colour frames a newer one replaced before tracking
    uint64_t environment_frames = 0;  // environment frames handed to the estimator
    uint64_t environment_maps = 0;    // environment maps published
    uint64_t publish_failures = 0;    // records not published: their pool was exhausted
};

// Called on the node's thread before a colour frame's records are published; the frame holds
// every estimate (for reports, overlays, accuracy checks). Must not block for long: it holds up
// tracking (and, lossless, the whole pipeline).
using TrackedFrameCallback = std::function<void(const TrackedFrame& frame)>;

// Owns one TrackingPipeline and its thread. Publishes, per colour frame and with that frame's
// metadata (sequence, stamps, clock domain), one pose record (mixray/graph/pose.h: valid,
// stale or lost, with the reason) and one light record (light_record.h: a group per estimator
// and the "render" group the compositor renders with); and an environment-map record whenever
// the fish-eye gave a new map (stamped with its environment frame). When the colour stream
// ends, it ends its own streams. Thread-safe: stats(), waitDone() and status() from any thread.
class TrackingNode : public Node {
public:
    static Result<std::unique_ptr<TrackingNode>> create(TrackingNodeOptions options,
                                                        TrackedFrameCallback on_frame = {});
    ~TrackingNode() override;

    std::string name() const override { return options_.name; }
    // The setup's camera stream (and environment stream, when the setup has one and the graph
    // has it) must exist: add the devices first.
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    // Until the colour stream ended and its last frame was published; false on timeout.
    bool waitDone(std::chrono::nanoseconds timeout) const;
    // ok, or the error that stopped tracking (a frame the tracker refused).
    Status status() const;
    TrackingNodeStats stats() const;
    const TrackingNodeOptions& options() const { return options_; }
    bool hasEnvironment() const { return environment_ != kInvalidStream; }

private:
    TrackingNode(TrackingNodeOptions options, TrackedFrameCallback on_frame);
    void run();
    // Tracks one colour frame and publishes its records; false when tracking failed.
    bool track(const FrameRef& color);
    void submitEnvironment(const FrameRef& env);
    void publishPose(const TrackedFrame& f);
    void publishLights(const TrackedFrame& f);
    void publishEnvironmentMap(const TrackedFrame& f);
    void finish(Status status);
    WritableFrame acquire(BufferPool& pool);

    TrackingNodeOptions options_;
    TrackedFrameCallback on_frame_;
    std::unique_ptr<TrackingPipeline> pipeline_;
    Graph* graph_ = nullptr;
    StreamId color_ = kInvalidStream;
    StreamId environment_ = kInvalidStream;
    std::shared_ptr<FrameQueue> color_queue_;
    std::shared_ptr<FrameQueue> environment_queue_;
    PooledStream pose_out_;
    PooledStream light_out_;
    PooledStream environment_map_out_;
    int64_t published_map_stamp_ns_ = 0;

    std::thread thread_;
    std::atomic<bool> stop_{false};
    mutable std::mutex mutex_;
    mutable std::condition_variable done_cv_;
    bool done_ = false;
    Status status_;
    TrackingNodeStats stats_;
};

}  // namespace mixray::tracking
