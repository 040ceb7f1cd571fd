// An environment map from the main camera's own frames (beyond the papers). Without a fish-eye
// camera or an HDR map a metal or glass virtual object reflects black; as ARKit's environment
// texturing does, this builds the surroundings from what the tracked camera sees as it moves:
// each frame's pixels land on a distance sphere around the scene and accumulate into an
// equirectangular map (the renderer's convention, lights.h), and directions no frame has seen
// are filled smoothly from those seen.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray::tracking {

struct CameraEnvironmentOptions {
    int width = 256;  // the map is width x width/2; even, 16 to 8192
    // Radius of the distance sphere the frames are projected onto, around `centre` (world
    // frame: the marker's middle for a tabletop). 0: at infinity, each pixel's direction from
    // the camera as it is; a room's walls a few metres away are better met by their distance,
    // which removes the parallax of a camera moving around the scene.
    double radius_m = 0;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();

    Status validate() const;  // kInvalidArgument naming the field
};

// Accumulates tracked frames into one map. Thread-bound.
class CameraEnvironment {
public:
    static Result<CameraEnvironment> create(const CameraEnvironmentOptions& options);

    // Adds a frame (kRGB8, kBGR8 or kMono8, sRGB-encoded, of the camera's size) seen from
    // T_world_cam: each texel whose direction the frame sees takes its linear radiance
    // (bilinear) into a running mean. kInvalidArgument for a bad image, model or pose.
    Status add(const ImageView& color, const calibration::CameraModel& camera,
               const Eigen::Isometry3d& T_world_cam);

    // The map (linear RGB, width x width/2): each seen texel the mean of the frames that saw
    // it, the others filled from the seen ones by a push-pull pyramid (coarser means,
    // bilinearly upsampled), so unseen directions take the light of the nearest seen ones and
    // no edge shows. All zero before any frame saw anything.
    FloatImage map() const;
    // Whether texel (x, y) was seen by some frame.
    bool seen(int x, int y) const { return weight_[static_cast<size_t>(y) * width_ + x] > 0; }
    // The fraction of the sphere's solid angle seen by some frame, 0 to 1.
    double coverage() const;
    uint64_t frames() const { return frames_; }
    int width() const { return width_; }
    int height() const { return width_ / 2; }

private:
    explicit CameraEnvironment(const CameraEnvironmentOptions& options);

    CameraEnvironmentOptions options_;
    int width_ = 0;
    std::vector<Eigen::Vector3d> directions_;  // per texel, world frame
    std::vector<double> sum_;                  // per texel: R, G, B
    std::vector<double> weight_;               // per texel: frames that saw it
    uint64_t frames_ = 0;
};

}  // namespace mixray::tracking
