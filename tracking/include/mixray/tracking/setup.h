// Tracking setup files: which camera stream is tracked and its lens, the markers and boards in
// the world with the objects they bind, the smoothing, the light probes and the fish-eye
// environment camera (docs/tracking.md#setup-files). Parsed into plain structs.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/result.h"
#include "mixray/tracking/lights.h"
#include "mixray/tracking/markers.h"

namespace mixray::tracking {

// The colour camera whose pose is tracked. Plain value.
struct TrackedCamera {
    std::string stream = "kinect/color";  // the recording's "device/stream"
    calibration::CameraModel model;
};

// The fish-eye environment camera's stream and how its images are turned into light. Plain
// value.
struct EnvironmentStream {
    std::string stream = "env/color";
    EnvironmentCamera camera;
    EnvironmentLightOptions lights;
    int map_width = 512;  // equirectangular environment map, width x width/2
};

// A whole setup file. Plain value.
struct TrackingSetup {
    int version = 1;
    TrackedCamera camera;
    std::vector<MarkerTarget> targets;
    TrackerOptions tracker;
    std::vector<LightProbe> probes;
    ProbeOptions probe_options;
    std::optional<EnvironmentStream> environment;
    std::string source_path;

    // Cross-entry checks (also run by the parser): a valid camera model, at least one target,
    // unique names, every option valid. kCorruptData / kInvalidArgument naming the entry.
    Status validate() const;
};

inline constexpr size_t kMaxTrackingSetupBytes = 1 << 20;

// Parses a setup file's text; errors read "FILE:LINE:COLUMN: FIELD.PATH: what is wrong".
// Never throws.
Result<TrackingSetup> parseTrackingSetup(std::string_view text, std::string_view source_name);
// kNotFound / kIoError for the file, else as parseTrackingSetup().
Result<TrackingSetup> loadTrackingSetup(const std::filesystem::path& path);

// The setup as a file parseTrackingSetup() reads back to the same values.
std::string trackingSetupYaml(const TrackingSetup& setup);

}  // namespace mixray::tracking
