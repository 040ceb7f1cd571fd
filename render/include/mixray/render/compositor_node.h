// The compositor as a graph node: a synchronized set of colour, depth, pose and lights in, the
// composite out as an ordinary rgb8 stream, so the recorder, the live view and remote hosts
// consume it like any camera's.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

#include "mixray/calibration/depth_registration.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/pose.h"
#include "mixray/graph/synchronizer.h"
#include "mixray/render/renderer.h"
#include "mixray/render/scene.h"
#include "mixray/tracking/light_record.h"

namespace mixray::render {

// Scene lights from estimated ones (a light record's "render" group): a light with a position
// and an apparent size becomes a sphere of that size (soft shadows as the real light casts
// them, intensity E·d² for the same irradiance at the scene), else a directional light; plus
// the environment map, when there is one, as an environment light. The others take
// `settings`' shadow map.
std::vector<Light> lightsFromEstimates(const std::vector<tracking::EstimatedLight>& estimates,
                                       std::shared_ptr<const FloatImage> environment_map,
                                       const EstimatedLightSettings& settings = {});

// One rung of the quality ladder: what the renderer may give up to hold a frame rate.
struct QualityStep {
    int samples_per_pixel = 1;
    int shadow_samples = 20;
    int max_depth = 3;
    SoftShadowMethod soft_shadows = SoftShadowMethod::kAdaptive;
    std::string label() const;  // "spp 4, shadows adaptive/20, depth 3"
    // `options` (the best, what was asked for) as this rung renders it.
    RenderOptions applied(RenderOptions options) const;
};

// The ladder from `best` (index 0, what was asked for) down to one sample, few shadow rays,
// hard shadows and no bounces; rungs that would change nothing are left out. Every rung draws
// every material: where it cuts a path's bounces, the path takes the environment.
std::vector<QualityStep> qualityLadder(const RenderOptions& best);

// How people and files number a ladder position: rungs count from 1 (full quality) to the
// ladder's length, "rung 2 of 5 (spp 1, shadows adaptive/8, depth 3)" in text and "rung": 2 in
// JSON. `step` is the index into qualityLadder(), from 0, as the code holds it
// (QualityController::step(), CompositorStats::quality_step, CompositeFrame::quality_step).
std::string rungText(int step, int steps, const std::string& label);

// Picks the ladder rung that holds a frame rate from the render times it is told: down a rung
// when frames take more than 90 % of the period (averaged, after 3 frames on a rung), up a rung
// after 2 s worth of frames below 45 % of it. Plain value; thread-bound.
class QualityController {
public:
    // `steps` rungs (rung 0 the best); target_fps <= 0: always rung 0.
    QualityController(int steps, double target_fps);
    // One frame at step() took `render_seconds`; returns the rung for the next frame.
    int update(double render_seconds);
    int step() const { return step_; }

private:
    int steps_ = 1;
    double target_fps_ = 0;
    int step_ = 0;
    double ema_s_ = 0;
    int frames_at_step_ = 0;
    int frames_fast_ = 0;
};

// Live, a set is skipped instead of rendered while a recording edge is at least this full:
// the recorder is behind, and a composite is the one thing that may give way.
inline constexpr double kRecordingBacklogToSkip = 0.5;

struct CompositorOptions {
    std::string name = "compositor";
    std::string color_stream;  // rgb8 or bgr8; required
    std::string depth_stream;  // depth16 that occludes; empty: none
    std::string pose_stream;   // pose records placing the camera; empty: fixed pose
    std::string light_stream;  // light records; empty: the scene's own lights
    // Environment-map records (the fish-eye's or the camera-built), rendered while the light
    // records' "environment" or "camera_environment" group names them; empty: none.
    std::string environment_map_stream;
    std::string output_stream = "composite/color";

    calibration::CameraModel camera;                                      // the colour camera
    Eigen::Isometry3d fixed_T_world_cam = Eigen::Isometry3d::Identity();  // without poses
    // Depth in the depth camera's own image, registered into the colour camera per frame.
    std::optional<calibration::DepthRegistration> depth_registration;
    // Poses of anchors that tracking does not give ("marker:3" -> T_world_marker).
    std::map<std::string, Eigen::Isometry3d> T_world_anchor;
    RenderOptions render;

    // Offline: lossless edges and every set rendered, so a run gives the same composites each
    // time. Live: live edges, and the compositor takes the newest complete set; the sets it
    // had no time for are counted (superseded).
    bool lossless = true;
    // Live only: lower quality along qualityLadder() to hold this rate; 0: never lower it.
    double target_fps = 0;
    // A frame without a valid or stale pose: false passes the camera image through (the
    // composite stream has a frame for every colour frame), true publishes nothing for it.
    bool skip_without_pose = false;
    // How colour and depth are matched (kHost for recordings replayed as fast as possible,
    // kCommon for live devices); pose and light records carry their colour frame's stamps.
    SyncTimeBase time_base = SyncTimeBase::kHost;
    size_t queue_capacity = 8;   // per input edge
    size_t output_buffers = 12;  // live: the recorder and the view hold some too

    Status validate() const;
};

// What a composite observer sees: everything the frame was made from, and how it went.
struct CompositeFrame {
    uint64_t index = 0;  // composites so far, from 0
    FrameRef color;
    FrameRef depth;      // empty without a depth stream
    FrameRef composite;  // the published frame (the colour frame itself when passed through)
    std::optional<PoseRecord> pose;
    std::optional<tracking::LightRecord> lights;
    bool rendered = false;  // false: the camera image passed through (no pose)
    // The lights the renderer used, from the light stream; null when there is none (the scene's
    // own lights). Valid during the callback only.
    const std::vector<Light>* lights_used = nullptr;
    // The renderer's layers of a rendered frame (I_m, I_r, M with RenderOptions::keep_layers);
    // valid during the callback only.
    const RenderLayers* layers = nullptr;
    RenderStats stats;
    int quality_step = 0;  // index into qualityLadder(), from 0 (rungText() numbers it)
    // From the colour frame's capture (host stamp; for a replayed frame, when it entered the
    // graph: FrameMetadata::graph_stamp_ns) to the composite's publication.
    double latency_ms = 0;
};

// Called on the compositor's thread after a composite was published; holding it up holds up
// the compositor (lossless: the whole pipeline).
using CompositeCallback = std::function<void(const CompositeFrame& frame)>;

struct LatencyPercentiles {
    double p50_ms = 0, p95_ms = 0, p99_ms = 0, max_ms = 0;
    uint64_t count = 0;
};

struct CompositorStats {
    uint64_t sets = 0;                // complete sets the synchronizer gave
    uint64_t composites = 0;          // published
    uint64_t rendered = 0;            // of them ray traced
    uint64_t passed_through = 0;      // of them the camera image (no pose)
    uint64_t skipped_superseded = 0;  // live: a newer set came before this one was started
    // Live: the recording was backed up (Graph::recordingBacklog() at or above
    // kRecordingBacklogToSkip) when this set's turn came, so its cores went to the recorder.
    uint64_t skipped_for_recording = 0;
    uint64_t skipped_without_pose = 0;  // skip_without_pose
    // The colour frame's driver marked it corrupt (FrameStatus::kCorrupt): kept in the
    // recording, never composited (virtual objects over a broken image would be a wrong picture).
    uint64_t skipped_corrupt = 0;
    uint64_t publish_failures = 0;  // no free output buffer
    uint64_t skipped_at_stop = 0;   // waiting or being rendered when stop() came
    // Every set is accounted for: sets == composites + skipped_superseded +
    // skipped_for_recording + skipped_without_pose + skipped_corrupt + publish_failures +
    // skipped_at_stop (once stopped or done).
    // Pose and light records that did not decode (damaged, a NaN or non-unit rotation): the set
    // is composited as if the pose were lost, or with the lights it had; the first one's reason.
    uint64_t damaged_records = 0;
    std::string first_damaged_record;
    SyncStats sync;              // frames the synchronizer could not match, and why
    LatencyPercentiles latency;  // over the last 1024 composites
    double render_ms_mean = 0;
    // Lights from the estimates (and the estimated environment map) the last rendered composite
    // was lit by: 0 until the first light record with lights arrives.
    size_t estimated_lights = 0;
    int quality_step = 0;  // index into qualityLadder(), from 0 (rungText() numbers it)
    int quality_steps = 1;
    std::string quality_label;

    int qualityRung() const { return quality_step + 1; }  // as people and JSON number it
    std::string qualityText() const { return rungText(quality_step, quality_steps, quality_label); }
    // Each virtual object of the scene, in scene order, and the rendered composites it was
    // drawn in: posed, since the camera and its anchor had a pose (in view or not).
    struct ObjectDrawn {
        std::string name;
        std::string anchor;  // "world", "marker:0"
        uint64_t frames = 0;
    };
    std::vector<ObjectDrawn> objects;

    // One line per virtual object drawn in no composite, with why: "object 'teapot' (anchor
    // marker:0) was never drawn: marker 0 had no pose in any of 36 composites". Empty before
    // the first composite.
    std::vector<std::string> neverDrawn() const;
    // One line each for corrupt colour frames skipped and damaged records composited past;
    // empty when there were none.
    std::vector<std::string> damage() const;
};

// Runs a SyncNode over its inputs and renders on a thread of its own, so matching never waits
// for the renderer. Live, it renders as ThreadRole::kRenderer (RenderOptions::yield_to_capture)
// and skips sets while the recording is backed up, so it never costs a captured frame. Light
// records change the renderer's lights only when they change. With target_fps it keeps a renderer
// per ladder rung it used and moves down a rung when frames take more than 90 % of the period, up
// again after 2 s below 45 %. Thread-safe: stats(), status() and waitDone() from any thread.
class CompositorNode : public Node {
public:
    static Result<std::unique_ptr<CompositorNode>> create(CompositorOptions options,
                                                          SceneDescription scene,
                                                          CompositeCallback on_composite = {});
    ~CompositorNode() override;

    std::string name() const override { return options_.name; }
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    // Until every input ended and the last composite was published; false on timeout.
    bool waitDone(std::chrono::nanoseconds timeout) const;
    Status status() const;
    CompositorStats stats() const;
    StreamId outputStream() const { return output_.id; }
    const CompositorOptions& options() const { return options_; }

private:
    struct Pending {
        FrameRef color, depth, pose, lights;
    };
    CompositorNode(CompositorOptions options, SceneDescription scene,
                   CompositeCallback on_composite);
    void onSet(const SyncSet& set);
    void run();
    Status composite(const Pending& set);
    // Motion blur's shutter poses for this colour frame and its pose, from the motion since the
    // last measured one; remembers this one.
    std::optional<RenderInputs::ShutterPoses> shutterFor(const FrameMetadata& color,
                                                         const PoseRecord& pose);
    Result<Renderer*> renderer(int step);
    Status warmUp();
    void drainEnvironmentMaps();
    void finish(Status status);
    WritableFrame acquire(BufferPool& pool);

    CompositorOptions options_;
    SceneDescription scene_;
    // The last composite's measured camera pose and its frame's stamp: the motion the next
    // frame's motion blur extrapolates (camera_matching.motion_blur).
    std::optional<Eigen::Isometry3d> last_T_world_cam_;
    int64_t last_pose_stamp_ns_ = 0;
    CompositeCallback on_composite_;
    std::vector<QualityStep> ladder_;
    std::vector<std::unique_ptr<Renderer>> renderers_;  // per rung, made when first used
    std::vector<uint64_t> renderer_lights_version_;
    std::vector<Light> lights_;
    uint64_t lights_version_ = 0;
    int64_t last_map_stamp_ns_ = -1;
    std::map<int64_t, std::shared_ptr<const FloatImage>> environment_maps_;  // by stamp
    RenderLayers layers_;

    Graph* graph_ = nullptr;
    std::unique_ptr<SyncNode> sync_;
    int depth_index_ = -1, pose_index_ = -1, light_index_ = -1;
    std::shared_ptr<FrameQueue> map_queue_;
    PooledStream output_;

    std::thread thread_;
    std::atomic<bool> stop_{false};
    std::stop_source stop_render_;
    mutable std::mutex mutex_;
    std::condition_variable mailbox_cv_;
    std::optional<Pending> mailbox_;
    mutable std::condition_variable done_cv_;
    bool done_ = false;
    Status status_;
    CompositorStats stats_;
    std::vector<double> latencies_ms_;  // ring of the last kLatencyWindow
    size_t latency_next_ = 0;
    double render_ms_sum_ = 0;
    QualityController quality_;
};

}  // namespace mixray::render
