// The whole AR pipeline as one device graph: devices (a rig, or a recording replayed as its
// rig) → tracking and light estimation → compositor → composite stream, recorder and observers.
// mixray run, demo, track and render are configurations of it.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mixray/calibration/calibration_file.h"
#include "mixray/graph/device.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/recorder.h"
#include "mixray/graph/rig.h"
#include "mixray/render/compositor_node.h"
#include "mixray/render/scene.h"
#include "mixray/tracking/tracking_graph.h"

namespace mixray::render {

// The scene's camera takes the calibrated lens's settings (CalibratedCamera::lens) as its
// aperture where the scene gives none, so virtual objects blur as the lens was set; the
// scene's own aperture wins. The pose stays tracking's.
void applyCalibratedLens(const calibration::CalibratedCamera& camera, SceneDescription& scene);

// Where frames come from.
struct ArSource {
    enum class Pace {
        kReal,  // live devices, or a recording at its own pace, stamped as it is published
        kFast,  // a recording as fast as the pipeline takes it; every frame processed
    };
    // Exactly one of: a rig's devices, or a recording (any format the "replay" backend opens),
    // replayed with its recorded stream names so that setups written for the rig apply.
    std::optional<RigDescription> rig;
    std::filesystem::path recording;
    Pace pace = Pace::kReal;
    bool loop = false;  // recordings: play again from the start at the end
};

struct ArPipelineOptions {
    // Track markers and estimate lights with this setup; none: poses come from pose_stream
    // (or the scene's fixed camera) and lights from the scene.
    std::optional<tracking::TrackingSetup> setup;
    tracking::PipelineOptions tracking;
    // Composite this scene's virtual objects; none: no compositor (tracking only, or a monitor
    // of the devices).
    std::optional<SceneDescription> scene;
    // The colour camera's model (wins over the scene's and the setup's) and depth registration.
    std::optional<calibration::CalibrationFile> calibration;
    RenderOptions render;
    // Which streams: empty picks as described at ArPipeline.
    std::string color_stream;
    std::string pose_stream;  // a recorded pose stream placing the camera, instead of tracking
    bool use_depth = true;    // let the depth stream hide virtual objects
    // Real pace only: the quality ladder holds this rate (0: full quality always; below 0: the
    // colour stream's nominal rate).
    double target_fps = 0;
    bool skip_without_pose = false;
    // Record raw streams, poses, lights and the composite into one recording. Live, every
    // frame a device published on a recorded stream reaches the file: the recorder runs above
    // tracking and the renderer, and the compositor skips sets while it is behind.
    std::filesystem::path record;
    // How the recording stores images. Default: at real pace ffvhuff, a tenth of FFV1's CPU,
    // which live belongs to capture first; at fast pace FFV1, the smallest files (offline its
    // CPU costs only time).
    std::optional<MkvCompression> record_compression;
    std::vector<Attachment> record_attachments;
    std::map<std::string, std::string> record_tags;
    std::map<std::string, Eigen::Isometry3d> T_world_anchor;
    tracking::TrackedFrameCallback on_tracked;
    // Track this many colour frames and no more (0: all; TrackingNodeOptions::max_color_frames).
    uint64_t max_color_frames = 0;
    CompositeCallback on_composite;
};

// What the pipeline has done so far, for status lines, the live view and summary.json.
struct ArPipelineStats {
    struct Stream {
        std::string name;
        std::string device;
        uint64_t published = 0;
        uint64_t lost = 0;      // lost by the source (full pool, dropped by the device)
        bool captured = false;  // a device's stream (raw frames), not a pipeline node's
        double fps = 0;         // over the last second
    };
    struct Device {
        std::string name;
        // What the device says (Device::state(): "streaming", "reconnecting", "lost",
        // "ended"); for devices that do not say, judged from their streams: "streaming",
        // "waiting" (nothing yet), "ended" (every stream ended). Either way, at real pace,
        // "stalled" as soon as a stream that delivered is silent for 5 of its frame periods
        // (and 0.5 s): before a driver's loss timeout says "reconnecting" or "lost".
        std::string state;
        double silent_s = 0;  // stalled: how long its quietest stream has been silent
        std::string clock;    // Device::clockReport(): another host's clock, when it has one
    };
    std::vector<Stream> streams;
    std::vector<Device> devices;
    // Frames live edges dropped because their consumer was behind. Not the frames a view or a
    // watch skips by its own rate (QueueOptions::newest_only): those are not losses.
    uint64_t edge_drops = 0;
    // Frames waiting on every edge now: bounded by the edges' capacities, whatever the run's
    // length (scripts/soak watches it).
    uint64_t queued_frames = 0;
    std::optional<tracking::TrackingNodeStats> tracking;
    std::optional<CompositorStats> compositor;
    std::optional<RecorderStats> recorder;
    double seconds = 0;  // since start()
    // ArPipeline::inputStatus() when it was taken: a replayed recording cut off or damaged.
    Status input;

    // What a user must be told besides the figures, one line each: the input's damage, then
    // each virtual object never drawn (CompositorStats::neverDrawn()).
    std::vector<std::string> warnings() const;

    // The live view's status object (docs/live-view.md): devices, streams, latency, sync,
    // ladder, messages.
    std::string json() const;
};

// Builds and runs the graph. Stream choice: the colour stream is the setup's camera stream,
// else `color_stream`, else the first rgb8 colour stream; the depth stream is one the
// calibration registers into it, else the first depth16 stream of its size that is not tagged
// aligned_with an IR camera; the pose stream is the tracking node's, else `pose_stream`, else
// the only recorded pose stream when the scene's camera has no pose.
// Thread-safety: start/stop/wait from one thread; stats() from any.
class ArPipeline {
public:
    // Opens the source's devices through `backends` (a recording needs the "replay" backend)
    // and connects every node. Errors name the device, stream or file.
    static Result<std::unique_ptr<ArPipeline>> create(const BackendRegistry& backends,
                                                      const ArSource& source,
                                                      ArPipelineOptions options);
    ~ArPipeline();

    Status start();
    // Until the source ended and everything downstream finished (recordings without loop);
    // false on timeout.
    bool waitDone(std::chrono::nanoseconds timeout) const;
    // Stops every node (the recording is closed with what reached it). Idempotent.
    void stop();
    // The first error of a node (tracking, compositor, recorder), else ok.
    Status status() const;
    // The first device's Device::inputStatus() that is not ok: a replayed recording cut off or
    // damaged (kCorruptData naming the file, what is missing and the frames read). The
    // pipeline then ran on the frames that were readable; it is not an error of status().
    Status inputStatus() const;
    ArPipelineStats stats() const;

    Graph& graph() { return *graph_; }
    const tracking::TrackingNodes* tracking() const { return tracking_ ? &*tracking_ : nullptr; }
    const CompositorNode* compositor() const { return compositor_; }
    const std::string& colorStream() const { return color_stream_; }
    // The composite stream's name, empty without a scene.
    std::string compositeStream() const;
    // The camera model the compositor renders with (valid with a scene).
    const calibration::CameraModel& camera() const { return camera_; }

private:
    ArPipeline() = default;

    std::unique_ptr<Graph> graph_;
    std::vector<Device*> devices_;
    std::optional<tracking::TrackingNodes> tracking_;
    CompositorNode* compositor_ = nullptr;
    Recorder* recorder_ = nullptr;
    bool live_ = false;  // real pace: live edges
    std::string color_stream_;
    calibration::CameraModel camera_;
    std::chrono::steady_clock::time_point started_;
    struct RateWindow;
    std::unique_ptr<RateWindow> rates_;
};

}  // namespace mixray::render
