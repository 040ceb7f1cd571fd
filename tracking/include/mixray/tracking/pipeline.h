// The tracking half of the AR pipeline, frame by frame: colour frames give the camera's pose
// (markers) and the probes' lights, environment frames the fish-eye lights and environment map;
// every estimate keeps its last good value and says when it is stale. The graph nodes of
// tracking_graph.h run it.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/recording.h"
#include "mixray/graph/result.h"
#include "mixray/graph/rig.h"
#include "mixray/tracking/camera_environment.h"
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
    // The environment estimate is marked stale, with the reason, once its camera has sent no
    // image for this long before a colour frame (the camera died or was unplugged: its last
    // lights are kept but no longer claimed as current). 0: never (default 1000).
    int64_t environment_max_age_ms = 1000;
    // Estimate the probes' lights and fit the light strengths at most this often, keeping the
    // last estimates in between: lights change slowly and the probes cost several times the
    // marker tracking, so live this keeps tracking at the camera's rate. 0: every colour frame
    // (offline, the default). LightEstimationNode sets 200 ms when it runs live unless told
    // otherwise; live it also estimates them on a thread beside it, newest frame wins.
    int64_t probe_interval_ms = 0;
    // Where the rig stands (its rig file's site:) and UTC minus the host clock: with both, each
    // colour frame also gets the sun's direction.
    std::optional<RigSite> site;
    std::optional<int64_t> utc_minus_host_ns;
    // Or the UTC of the first colour frame (ns since the Unix epoch), which fixes the offset.
    std::optional<int64_t> utc_first_frame_ns;
    // Without a fish-eye in the graph (the setup has none, the recording lacks its stream, or
    // `environment` is off), LightEstimationNode builds the environment from the tracked colour
    // frames themselves (CameraEnvironment) and publishes its map on the environment-map stream
    // after the first frame with a fresh pose and then after every camera_environment_interval
    // more; each light record's "camera_environment" group names the map in use by its
    // good_stamp_ns, and the compositor renders it as an environment light, so metal and glass
    // reflect the room instead of black. nullopt: none.
    std::optional<CameraEnvironmentOptions> camera_environment;
    uint32_t camera_environment_interval = 10;
};

// The site of the recording's rig (its rig.yaml attachment, or `rig_path`), if it has one.
Result<std::optional<RigSite>> findRigSite(const RecordingReader& reader,
                                           const std::string& rig_path);
// The recording's UTC minus host clock tag (kUtcMinusHostTag), if it has one.
Result<std::optional<int64_t>> recordingUtcOffset(const RecordingReader& reader);
// "2026-06-21T12:00:00Z" (seconds may have a fraction) as ns since the Unix epoch.
Result<int64_t> parseUtc(const std::string& text);

// The probes' lights from a colour image seen from T_world_camera at `stamp` (frame.probes: one
// estimate per setup probe, updated, or kept stale with the reason), then the strengths of the
// lights whose directions lightDirections() gives, fit to the setup's diffuse probe
// (frame.intensities). frame.environment and frame.sun must be this frame's.
void estimateFrameProbes(const TrackingSetup& setup, const ImageView& color,
                         const Eigen::Isometry3d& T_world_camera, int64_t stamp,
                         TrackedFrame& frame);

// The directions of the frame's lights: the fish-eye's, else the sun's, else a mirror probe's
// highlights (sharp), else a diffuse probe's. Empty when nothing was estimated yet.
std::vector<EstimatedLight> lightDirections(const TrackingSetup& setup, const TrackedFrame& frame);

// The lights to render with: lightDirections(), strengths from the diffuse probe's fit (else
// the estimates' own), in the world frame; lights with no strength are left out.
// render::lightsFromEstimates() turns them, and the environment map, into scene lights.
std::vector<EstimatedLight> renderLights(const TrackingSetup& setup, const TrackedFrame& frame);

}  // namespace mixray::tracking
