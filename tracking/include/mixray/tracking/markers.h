// Fiducial markers: target poses (IPPE for single markers, all corners for boards) from the
// detections of mixray/calibration/marker_detection.h, several targets each binding scene
// objects, and a camera tracker with One-Euro smoothing, loss and re-acquisition.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/marker_detection.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/tracking/estimate.h"

namespace mixray::tracking {

// Marker detection lives in calibration (mixray/calibration/marker_detection.h), shared with
// the calibration targets; these names keep tracking's vocabulary.
using calibration::detectMarkers;
using calibration::DetectorOptions;
using calibration::isKnownDictionary;
using calibration::MarkerDetection;

enum class TargetKind : uint8_t {
    kMarker,        // one square marker; its frame: centre, +x right, +y up, +z out
    kCharucoBoard,  // OpenCV CharucoBoard; its frame: top-left corner, +x right, +y down, +z in
    kGridBoard,     // OpenCV 4.6 GridBoard; its frame: top-left corner, +x right, +y down, +z in
};

// Something tracked, placed in the world (marker) frame. Plain value.
struct MarkerTarget {
    std::string name;
    TargetKind kind = TargetKind::kMarker;
    std::string dictionary = "DICT_6X6_250";
    int id = 0;                        // kMarker; boards: the first marker id
    double size_m = 0.1;               // kMarker: black square's side; boards: each marker's side
    int squares_x = 0, squares_y = 0;  // kCharucoBoard squares; kGridBoard markers
    double square_m = 0;               // kCharucoBoard square side
    double separation_m = 0;           // kGridBoard gap between markers
    Eigen::Isometry3d T_world_target = Eigen::Isometry3d::Identity();
    // Scene objects that move with this target (RT²AR binds virtual objects to markers).
    std::vector<std::string> bound_objects;

    Status validate() const;
    // The target's corner points in its own frame, keyed by (marker id, corner 0..3) for
    // markers and grid boards, by ChArUco corner id (marker id -1) for ChArUco boards.
    struct Point {
        int marker_id = 0;
        int corner = 0;
        Eigen::Vector3d p_target;
    };
    std::vector<Point> points() const;
};

// The pose of one target seen in one image. Plain value.
struct TargetObservation {
    std::string target;
    Eigen::Isometry3d T_camera_target = Eigen::Isometry3d::Identity();
    int points = 0;     // 2D-3D correspondences used
    double rms_px = 0;  // reprojection error of those
};

// One-Euro filter settings (Casiez, Roussel, Vogel, CHI 2012): a low-pass whose cutoff rises
// with speed, so a still pose stops jittering and a fast one does not lag.
struct SmoothingOptions {
    bool enabled = true;
    double min_cutoff_hz = 1.0;  // cutoff at rest: lower removes more jitter
    double beta = 100.0;         // cutoff increase per unit speed (m/s, rad/s): higher lags less
    double d_cutoff_hz = 1.0;    // cutoff of the speed estimate

    Status validate() const;
};

// Smooths a pose stream: translation and rotation (on the rotation's tangent space) each with a
// One-Euro filter. Thread-bound.
class PoseFilter {
public:
    explicit PoseFilter(const SmoothingOptions& options = {});
    // The smoothed pose for `raw` at `stamp_ns` (later than the previous call's; otherwise, or
    // after reset(), the filter restarts at `raw`).
    Eigen::Isometry3d filter(const Eigen::Isometry3d& raw, int64_t stamp_ns);
    void reset();

private:
    SmoothingOptions options_;
    bool primed_ = false;
    int64_t last_stamp_ns_ = 0;
    Eigen::Vector3d t_{0, 0, 0}, dt_{0, 0, 0};
    Eigen::Quaterniond q_{1, 0, 0, 0};
    Eigen::Vector3d dq_{0, 0, 0};
};

// How the tracker behaves. Every field has a working default.
struct TrackerOptions {
    DetectorOptions detector;
    SmoothingOptions smoothing;
    double max_rms_px = 2.0;  // target poses fitting worse than this are rejected
    // A frame without a good pose makes the tracker kLost. When a pose comes back after a gap
    // longer than this, the smoothing restarts (the pose jumps to the fresh one instead of
    // sliding from the old); shorter gaps (a missed detection) keep filtering.
    int64_t reacquire_after_ns = 200'000'000;

    Status validate() const;
};

enum class TrackState : uint8_t {
    kSearching,  // no target seen yet
    kTracking,   // a fresh pose this frame
    kLost,       // targets gone: the last good pose is kept, stale
};

std::string_view toString(TrackState state);

// The camera's pose for one image. Plain value.
struct CameraTrack {
    TrackState state = TrackState::kSearching;
    bool reacquired = false;  // first fresh pose after kLost
    // T_world_camera, smoothed; stale (the last good one) unless state == kTracking.
    Estimate<Eigen::Isometry3d> pose;
    std::optional<Eigen::Isometry3d> raw_T_world_camera;  // this frame's unsmoothed pose
    std::vector<MarkerDetection> detections;
    std::vector<TargetObservation> targets;  // targets seen this frame
};

// Follows the camera through a video from the targets it sees: every target seen votes for the
// camera's pose through its known T_world_target (all their corners in one fit). Thread-bound.
class MarkerTracker {
public:
    // kInvalidArgument for a bad camera model, target or option (naming it), or no targets.
    static Result<std::unique_ptr<MarkerTracker>> create(const calibration::CameraModel& camera,
                                                         std::vector<MarkerTarget> targets,
                                                         const TrackerOptions& options = {});
    virtual ~MarkerTracker() = default;

    // Tracks one image (its size must match the camera model's); `stamp_ns` increasing.
    virtual Result<CameraTrack> track(const ImageView& image, int64_t stamp_ns) = 0;
    virtual const std::vector<MarkerTarget>& targets() const = 0;
    // Forgets the history (the next frame starts from scratch).
    virtual void reset() = 0;
};

}  // namespace mixray::tracking
