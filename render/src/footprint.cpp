// The tile mask of the screen-space footprint: cones of camera rays per tile against bounding
// spheres, and against the ghost regions whose light virtual bounding spheres can block.
#include "footprint.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace mixray::render::detail {
namespace {

using Vec3 = Eigen::Vector3f;

// acos near 1 loses ~3e-4 rad in float; cones and tests widen by more than that.
constexpr float kAngleSlack = 2e-3f;
// Metres added to every distance test: float error of hit points and shadow-ray offsets.
constexpr float kDistanceSlack = 1e-3f;

bool coneMeetsSphere(const TileCone& cone, const Vec3& centre_cam, float radius) {
    const float d = centre_cam.norm();
    if (d <= radius)
        return true;
    const float beta = std::acos(std::clamp(cone.axis.dot(centre_cam) / d, -1.f, 1.f));
    return beta <= cone.half_angle + std::asin(std::min(1.f, radius / d)) + kAngleSlack;
}

// Whether any point within `rho` of `q` can have a virtual bounding sphere on its way to a
// light: at a fraction s of the way, the segment from such a point x to a point within R of
// the light's centre stays within (1 − s)·rho + s·R of the one from q to the centre (for a
// directional light the segments are parallel: rho all along).
bool regionShadowable(const FootprintScene& scene, const Vec3& q, float rho) {
    for (const FootprintLight& light : scene.lights) {
        Vec3 dir;
        float length = std::numeric_limits<float>::infinity();
        if (light.directional) {
            dir = -light.direction;
        } else {
            const Vec3 delta = light.position - q;
            length = delta.norm();
            if (length <= rho + light.radius)
                return true;
            dir = delta / length;
        }
        const float slack = kDistanceSlack * (1 + q.cwiseAbs().maxCoeff());
        for (const BoundSphere& b : scene.virtual_bounds)
            if (nearTaperedSegment(b.centre, q, dir, length, b.radius + rho + slack,
                                   b.radius + light.radius + slack))
                return true;
    }
    return false;
}

// The sphere around the points where the tile's rays meet a flat ghost's plane inside its
// bound; false when none does.
bool planeHitsBound(const FootprintScene& scene, const FootprintGhost& ghost, const TileCone& cone,
                    const std::vector<Vec3>& directions, int width, int samples, int x0, int y0,
                    int x1, int y1, BoundSphere& out) {
    const Eigen::Matrix3f R_cam_world = scene.R_world_cam.transpose();
    const Vec3 n_cam = R_cam_world * ghost.plane_normal;
    const float h = ghost.plane_normal.dot(ghost.plane_point - scene.t_world_cam);
    const Vec3 g_cam = R_cam_world * (ghost.bound.centre - scene.t_world_cam);
    const float g_r = ghost.bound.radius * 1.001f + kDistanceSlack;
    Vec3 lo = Vec3::Constant(std::numeric_limits<float>::infinity());
    Vec3 hi = -lo;
    bool any = false;
    // A pinhole maps the tile's rectangle onto the plane projectively: when all four corners
    // land in front, so does the whole rectangle, inside the quadrilateral of the corners.
    bool corners_in_front = cone.has_corners;
    for (const Vec3& c : cone.corners) {
        if (!corners_in_front)
            break;
        const float t = h / n_cam.dot(c);
        corners_in_front = t > 0 && std::isfinite(t);
        if (corners_in_front) {
            lo = lo.cwiseMin(t * c);
            hi = hi.cwiseMax(t * c);
        }
    }
    if (corners_in_front) {
        any = ((0.5f * (lo + hi) - g_cam).norm() <= 0.5f * (hi - lo).norm() + g_r);
        y1 = y0;  // no need to look at the samples
    } else {
        lo = Vec3::Constant(std::numeric_limits<float>::infinity());
        hi = -lo;
    }
    for (int y = y0; y < y1; ++y) {
        const Vec3* d = directions.data() + (static_cast<size_t>(y) * width + x0) * samples;
        const int n = (x1 - x0) * samples;
        for (int i = 0; i < n; ++i) {
            const float denom = n_cam.dot(d[i]);
            const float t = h / denom;
            if (!(t > 0) || !std::isfinite(t))
                continue;
            const Vec3 x = t * d[i];
            if ((x - g_cam).squaredNorm() > g_r * g_r)
                continue;
            lo = lo.cwiseMin(x);
            hi = hi.cwiseMax(x);
            any = true;
        }
    }
    if (!any)
        return false;
    const Vec3 centre_cam = 0.5f * (lo + hi);
    out.centre = scene.R_world_cam * centre_cam + scene.t_world_cam;
    out.radius = 0.5f * (hi - lo).norm() + kDistanceSlack * (1 + centre_cam.norm());
    if (out.radius > ghost.bound.radius)
        out = ghost.bound;
    return true;
}

}  // namespace

std::vector<TileCone> tileCones(const calibration::CameraModel& camera,
                                const std::vector<Vec3>& directions, int samples, int tile_size) {
    const int width = camera.width, height = camera.height;
    const bool pinhole = camera.lens == calibration::LensModel::kPinhole &&
                         std::all_of(camera.distortion.begin(), camera.distortion.end(),
                                     [](double k) { return k == 0; });
    const int tiles_x = (width + tile_size - 1) / tile_size;
    const int tiles_y = (height + tile_size - 1) / tile_size;
    std::vector<TileCone> cones(static_cast<size_t>(tiles_x) * tiles_y);
    tbb::parallel_for(0, tiles_x * tiles_y, [&](int t) {
        const int x0 = (t % tiles_x) * tile_size, y0 = (t / tiles_x) * tile_size;
        const int x1 = std::min(width, x0 + tile_size), y1 = std::min(height, y0 + tile_size);
        Vec3 sum = Vec3::Zero();
        for (int y = y0; y < y1; ++y)
            for (int i = (y * width + x0) * samples; i < (y * width + x1) * samples; ++i)
                if (directions[static_cast<size_t>(i)].allFinite())
                    sum += directions[static_cast<size_t>(i)];
        TileCone& cone = cones[static_cast<size_t>(t)];
        if (sum.squaredNorm() <= 0)
            return;
        if (pinhole) {
            // Samples lie within half a pixel of their pixel centre.
            const auto corner = [&](double u, double v) {
                return Vec3(static_cast<float>((u - camera.cx) / camera.fx),
                            static_cast<float>((v - camera.cy) / camera.fy), 1.f);
            };
            cone.has_corners = true;
            cone.corners = {corner(x0 - 0.5, y0 - 0.5), corner(x1 - 0.5, y0 - 0.5),
                            corner(x0 - 0.5, y1 - 0.5), corner(x1 - 0.5, y1 - 0.5)};
        }
        cone.axis = sum.normalized();
        float min_dot = 1;
        for (int y = y0; y < y1; ++y)
            for (int i = (y * width + x0) * samples; i < (y * width + x1) * samples; ++i)
                if (directions[static_cast<size_t>(i)].allFinite())
                    min_dot = std::min(min_dot, cone.axis.dot(directions[static_cast<size_t>(i)]));
        cone.half_angle = std::acos(std::clamp(min_dot, -1.f, 1.f)) + kAngleSlack;
    });
    return cones;
}

void footprintMask(const FootprintScene& scene, const std::vector<TileCone>& cones,
                   const std::vector<Vec3>& directions, int width, int height, int samples,
                   int tile_size, std::vector<uint8_t>& mask) {
    const int tiles_x = (width + tile_size - 1) / tile_size;
    const int tiles = static_cast<int>(cones.size());
    mask.assign(cones.size(), 0);
    if (scene.virtual_bounds.empty())
        return;
    const Eigen::Matrix3f R_cam_world = scene.R_world_cam.transpose();
    const auto toCam = [&](const BoundSphere& b) {
        return BoundSphere{R_cam_world * (b.centre - scene.t_world_cam), b.radius};
    };
    std::vector<BoundSphere> direct;  // seen directly or mirrored: camera frame
    for (const BoundSphere& b : scene.virtual_bounds)
        direct.push_back(toCam(b));
    for (const BoundSphere& b : scene.mirrored_bounds) {
        BoundSphere c = toCam(b);
        c.radius += kDistanceSlack * (1 + b.centre.cwiseAbs().maxCoeff());
        direct.push_back(c);
    }
    std::vector<BoundSphere> ghost_bounds;
    for (const FootprintGhost& g : scene.ghosts)
        ghost_bounds.push_back(toCam(g.bound));

    tbb::parallel_for(0, tiles, [&](int t) {
        const TileCone& cone = cones[static_cast<size_t>(t)];
        if (cone.half_angle < 0)
            return;
        const auto inTile = [&] {
            for (const BoundSphere& b : direct)
                if (coneMeetsSphere(cone, b.centre, b.radius))
                    return true;
            for (size_t g = 0; g < scene.ghosts.size(); ++g) {
                const FootprintGhost& ghost = scene.ghosts[g];
                if (!coneMeetsSphere(cone, ghost_bounds[g].centre, ghost_bounds[g].radius))
                    continue;
                if (!ghost.always && (!ghost.receives || scene.lights.empty()))
                    continue;
                // Where the tile's rays can meet the ghost.
                BoundSphere region = ghost.bound;
                if (ghost.flat) {
                    const int x0 = (t % tiles_x) * tile_size, y0 = (t / tiles_x) * tile_size;
                    if (!planeHitsBound(scene, ghost, cone, directions, width, samples, x0, y0,
                                        std::min(width, x0 + tile_size),
                                        std::min(height, y0 + tile_size), region))
                        continue;
                }
                if (ghost.always || regionShadowable(scene, region.centre, region.radius))
                    return true;
            }
            if (!scene.depth_regions.empty() && !scene.virtual_bounds.empty()) {
                const BoundSphere& r = scene.depth_regions[static_cast<size_t>(t)];
                if (r.radius >= 0 &&
                    (scene.depth_reflects || regionShadowable(scene, r.centre, r.radius)))
                    return true;
            }
            return false;
        };
        mask[static_cast<size_t>(t)] = inTile() ? 1 : 0;
    });
}

}  // namespace mixray::render::detail
