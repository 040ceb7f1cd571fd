// The tracking half of the AR pipeline, frame by frame: colour frames give the camera's pose
// (markers) and the probes' lights, environment frames the fish-eye lights and environment map;
// every estimate keeps its last good value and says when it is stale. TrackingNode
// (tracking_node.h) runs it in the device graph.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/recording.h"
#include "mixray/graph/result.h"
#include "mixray/graph/rig.h"
#include "mixray/tracking/estimate.h"
#include "mixray/tracking/light_intensity.h"
#include "mixray/tracking/lights.h"
#include "mixray/tracking/markers.h"
#include "mixray/tracking/setup.h"
#include "mixray/tracking/sun.h"

namespace mixray::tracking {

// The setup to track `recording` with: `explicit_path` when given, else the recording's
// `tracking.yaml` attachment, else NAME.tracking.yaml beside it. kNotFound saying where it
// looked.
Result<TrackingSetup> findTrackingSetup(const std::filesystem::path& recording,
                                        const RecordingReader& reader,
                                        const std::string& explicit_path);

// Everything known after one colour frame. Plain value.
struct TrackedFrame {
    uint64_t index = 0;  // colour frames so far, from 0
    FrameRef color;
    CameraTrack track;
    // One per setup probe, in its order.
    std::vector<Estimate<ProbeResult>> probes;
    Estimate<EnvironmentEstimate> environment;
    // The sun (when the rig's site and the frame's UTC are known), for outdoor rigs.
    Estimate<EstimatedLight> sun;
    // Irradiance of the lights (directions from lights()) fitted to a diffuse probe.
    Estimate<IntensityFit> intensities;
    double track_ms = 0;  // marker tracking of this frame
    double probe_ms = 0;  // probe light estimation of this frame (async: handing it over)
};

struct PipelineOptions {
    bool probes = true;       // estimate lights from the setup's probes
    bool environment = true;  // and from the environment camera
    // Offline (recordings): wait for each environment frame's estimate, so a run is
    // reproducible. Live it would not wait.
    bool wait_for_environment = true;
    // The environment estimate is marked stale, with the reason, once its camera has sent no
    // image for this long before a colour frame (the camera died or was unplugged: its last
    // lights are kept but no longer claimed as current). 0: never (default 1000).
    int64_t environment_max_age_ms = 1000;
    // Estimate the probes' lights and fit the light strengths at most this often, keeping the
    // last estimates in between: lights change slowly and the probes cost several times the
    // marker tracking, so live this keeps tracking at the camera's rate. 0: every colour frame
    // (offline, the default). TrackingNode sets 200 ms when it runs live unless told otherwise.
    int64_t probe_interval_ms = 0;
    // Estimate the probes' lights (and fit the strengths) on a thread of their own, newest
    // frame wins, instead of in push(): push() then returns the latest finished estimates, and
    // tracking never waits for the probes. Live only: what a frame gets then depends on
    // timing. TrackingNode sets it when it runs live.
    bool async_probes = false;
    // Where the rig stands (its rig file's site:) and UTC minus the host clock: with both, each
    // colour frame also gets the sun's direction.
    std::optional<RigSite> site;
    std::optional<int64_t> utc_minus_host_ns;
    // Or the UTC of the first colour frame (ns since the Unix epoch), which fixes the offset.
    std::optional<int64_t> utc_first_frame_ns;
};

// The site of the recording's rig (its rig.yaml attachment, or `rig_path`), if it has one.
Result<std::optional<RigSite>> findRigSite(const RecordingReader& reader,
                                           const std::string& rig_path);
// The recording's UTC minus host clock tag (kUtcMinusHostTag), if it has one.
Result<std::optional<int64_t>> recordingUtcOffset(const RecordingReader& reader);
// "2026-06-21T12:00:00Z" (seconds may have a fraction) as ns since the Unix epoch.
Result<int64_t> parseUtc(const std::string& text);

// Pulls frames through tracking. Thread-bound.
class TrackingPipeline {
public:
    static Result<std::unique_ptr<TrackingPipeline>> create(TrackingSetup setup,
                                                            const std::vector<StreamInfo>& streams,
                                                            const PipelineOptions& options = {});
    ~TrackingPipeline();

    // Takes one frame of any stream; returns the tracked colour frame when it was one.
    Result<std::optional<TrackedFrame>> push(const FrameRef& frame);

    const TrackingSetup& setup() const { return setup_; }
    StreamId colorStream() const { return color_; }
    StreamId environmentStream() const { return environment_; }

    // The lights to render with: directions from the fish-eye (else the sun, else the
    // probes), strengths from the diffuse probe's fit (else the estimates' own), in the world
    // frame; lights with no strength are left out. Empty when nothing was estimated yet.
    // render::lightsFromEstimates() turns them, and the environment map, into scene lights.
    std::vector<EstimatedLight> renderLights(const TrackedFrame& frame) const;

private:
    class ProbeWorker;
    TrackingPipeline();
    std::vector<EstimatedLight> lightDirections(const TrackedFrame& frame) const;
    // The probes' lights and the strengths fit from the colour image of a frame with a fresh
    // pose; `frame` brings the environment and sun estimates the fit takes directions from.
    void estimateProbes(const ImageView& color, const Eigen::Isometry3d& T_world_camera,
                        int64_t stamp, TrackedFrame& frame) const;

    TrackingSetup setup_;
    PipelineOptions options_;
    StreamId color_ = kInvalidStream;
    StreamId environment_ = kInvalidStream;
    std::unique_ptr<MarkerTracker> tracker_;
    std::unique_ptr<AsyncEnvironmentEstimator> environment_estimator_;
    std::vector<Estimate<ProbeResult>> probes_;
    Estimate<IntensityFit> intensities_;
    std::unique_ptr<ProbeWorker> probe_worker_;  // async_probes
    Estimate<EstimatedLight> sun_;
    uint64_t frames_ = 0;
    int64_t last_probe_stamp_ns_ = 0;
    bool probed_ = false;
};

}  // namespace mixray::tracking
