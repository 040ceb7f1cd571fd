// The tracking half of the AR pipeline, shared by mixray track, demo and bench: a recording's
// colour frames give the camera's pose (markers) and the probes' lights, its environment
// frames the fish-eye lights and environment map; every estimate keeps its last good value
// and says when it is stale.
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
#include "mixray/render/scene.h"
#include "mixray/tracking/estimate.h"
#include "mixray/tracking/light_intensity.h"
#include "mixray/tracking/lights.h"
#include "mixray/tracking/markers.h"
#include "mixray/tracking/setup.h"
#include "mixray/tracking/sun.h"

namespace mixray::cli {

// The setup to track `recording` with: `explicit_path` when given, else the recording's
// `tracking.yaml` attachment, else NAME.tracking.yaml beside it. kNotFound saying where it
// looked.
Result<tracking::TrackingSetup> findTrackingSetup(const std::filesystem::path& recording,
                                                  const RecordingReader& reader,
                                                  const std::string& explicit_path);

// Everything known after one colour frame. Plain value.
struct TrackedFrame {
    uint64_t index = 0;  // colour frames so far, from 0
    FrameRef color;
    tracking::CameraTrack track;
    // One per setup probe, in its order.
    std::vector<tracking::Estimate<tracking::ProbeResult>> probes;
    tracking::Estimate<tracking::EnvironmentEstimate> environment;
    // The sun (when the rig's site and the frame's UTC are known), for outdoor rigs.
    tracking::Estimate<tracking::EstimatedLight> sun;
    // Irradiance of the lights (directions from lights()) fitted to a diffuse probe.
    tracking::Estimate<tracking::IntensityFit> intensities;
    double track_ms = 0;  // marker tracking of this frame
    double probe_ms = 0;  // probe light estimation of this frame
};

struct PipelineOptions {
    bool probes = true;       // estimate lights from the setup's probes
    bool environment = true;  // and from the environment camera
    // Offline (recordings): wait for each environment frame's estimate, so a run is
    // reproducible. Live it would not wait.
    bool wait_for_environment = true;
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
    static Result<std::unique_ptr<TrackingPipeline>> create(tracking::TrackingSetup setup,
                                                            const std::vector<StreamInfo>& streams,
                                                            const PipelineOptions& options = {});
    ~TrackingPipeline();

    // Takes one frame of any stream; returns the tracked colour frame when it was one.
    Result<std::optional<TrackedFrame>> push(const FrameRef& frame);

    const tracking::TrackingSetup& setup() const { return setup_; }
    StreamId colorStream() const { return color_; }
    StreamId environmentStream() const { return environment_; }

    // The lights to render with: directions from the fish-eye (else the sun, else the
    // probes), strengths
    // from the diffuse probe's fit (else the estimates' own), as scene lights in the world
    // frame, plus the estimated environment map. Empty when nothing was estimated yet.
    std::vector<render::Light> lights(const TrackedFrame& frame) const;

private:
    TrackingPipeline() = default;
    std::vector<tracking::EstimatedLight> lightDirections(const TrackedFrame& frame) const;

    tracking::TrackingSetup setup_;
    PipelineOptions options_;
    StreamId color_ = kInvalidStream;
    StreamId environment_ = kInvalidStream;
    std::unique_ptr<tracking::MarkerTracker> tracker_;
    std::unique_ptr<tracking::AsyncEnvironmentEstimator> environment_estimator_;
    std::vector<tracking::Estimate<tracking::ProbeResult>> probes_;
    tracking::Estimate<tracking::IntensityFit> intensities_;
    tracking::Estimate<tracking::EstimatedLight> sun_;
    uint64_t frames_ = 0;
};

}  // namespace mixray::cli
