// The screen-space footprint of virtual content: which image tiles hold a pixel whose primary
// ray can meet a virtual object, its mirror image in a flat reflective ghost, or a ghost point
// whose light a virtual object can block. Conservative: tiles outside need no ray at all.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "mixray/calibration/camera_model.h"

namespace mixray::render::detail {

// Whether `c` lies within tol_a + (tol_b − tol_a)·t/length of the point a + t·dir for some t
// in [0, length]: a segment whose tolerance changes linearly along it, as the shadow rays from
// a point to a spherical light of radius R fan out by R over their length. A ray (length
// infinite) keeps tol_a. Exact: the distance minus the tolerance is convex in t, so its
// stationary point, clamped, is the minimum.
[[gnu::always_inline]] inline bool nearTaperedSegment(const Eigen::Vector3f& c,
                                                      const Eigen::Vector3f& a,
                                                      const Eigen::Vector3f& dir, float length,
                                                      float tol_a, float tol_b) {
    const Eigen::Vector3f q = c - a;
    const float along = q.dot(dir);
    if (!std::isfinite(length))
        return (a + std::max(0.f, along) * dir - c).norm() <= tol_a;
    const float k = (tol_b - tol_a) / length;
    if (!(std::abs(k) < 0.999f))
        return true;
    const float h = std::sqrt(std::max(0.f, q.squaredNorm() - along * along));
    const float t = std::clamp(along + k * h / std::sqrt(1 - k * k), 0.f, length);
    return (a + t * dir - c).norm() <= tol_a + k * t;
}

// The narrowest cone around one tile's camera-ray directions (camera frame).
struct TileCone {
    Eigen::Vector3f axis = Eigen::Vector3f::UnitZ();
    float half_angle = -1;  // radians; < 0: the tile has no rays
    // Undistorted pinhole cameras: rays through the corners of the tile's pixel area, which
    // span every sample's ray (unnormalised, z = 1).
    bool has_corners = false;
    std::array<Eigen::Vector3f, 4> corners;
};

// `directions`: ((y * width + x) * samples + s) unit camera-frame rays, NaN where none.
std::vector<TileCone> tileCones(const calibration::CameraModel& camera,
                                const std::vector<Eigen::Vector3f>& directions, int samples,
                                int tile_size);

struct BoundSphere {
    Eigen::Vector3f centre;
    float radius;
};

// A ghost as the footprint sees it (world frame).
struct FootprintGhost {
    BoundSphere bound;
    bool flat = false;  // a plane or disk: plane_point, plane_normal
    Eigen::Vector3f plane_point = Eigen::Vector3f::Zero();
    Eigen::Vector3f plane_normal = Eigen::Vector3f::UnitZ();
    bool always = false;    // anything virtual may change it anywhere (glass, unbounded mirrors)
    bool receives = false;  // Lambertian: virtual objects may shadow it
};

struct FootprintLight {
    bool directional = false;
    Eigen::Vector3f position = Eigen::Vector3f::Zero();    // point and sphere lights
    Eigen::Vector3f direction = Eigen::Vector3f::UnitZ();  // directional: travel direction
    float radius = 0;                                      // sphere lights
};

struct FootprintScene {
    Eigen::Matrix3f R_world_cam = Eigen::Matrix3f::Identity();
    Eigen::Vector3f t_world_cam = Eigen::Vector3f::Zero();
    std::vector<BoundSphere> virtual_bounds;
    std::vector<BoundSphere> mirrored_bounds;  // virtual bounds mirrored in the lone flat ghost
    std::vector<FootprintGhost> ghosts;
    std::vector<FootprintLight> lights;  // those that cast shadows
    // The depth mesh (DepthSecondaryRays::kMesh), per tile: the sphere around the measured
    // surface points the tile's rays see, widened by the mesh's distance from them (world frame;
    // radius < 0: no depth in the tile). Empty without a depth mesh.
    std::vector<BoundSphere> depth_regions;
    bool depth_reflects = false;  // the depth surface mirrors: every tile with depth counts
};

// mask[t] = 1 for tiles that may hold such a pixel. Runs in parallel over tiles (TBB).
void footprintMask(const FootprintScene& scene, const std::vector<TileCone>& cones,
                   const std::vector<Eigen::Vector3f>& directions, int width, int height,
                   int samples, int tile_size, std::vector<uint8_t>& mask);

}  // namespace mixray::render::detail
