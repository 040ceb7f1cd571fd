// The camera's rays (camera_rays.h).
#include "camera_rays.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace mixray::render::detail {

bool sameModel(const calibration::CameraModel& a, const calibration::CameraModel& b) {
    return a.lens == b.lens && a.width == b.width && a.height == b.height && a.fx == b.fx &&
           a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

float ThinLens::blurRadiusPx(double f_px, float nearest_m) const {
    if (radius_m <= 0)
        return 0;
    // |1/d − 1/focus| over d in [nearest, ∞) is largest at one end.
    const float spread = std::max(1 / focus_m, std::abs(1 / nearest_m - 1 / focus_m));
    return static_cast<float>(f_px) * radius_m * spread;
}

namespace {

// Shirley and Chiu's concentric map of the unit square onto the unit disk: strata stay compact.
Vec2 concentricDisk(float u, float v) {
    const float a = 2 * u - 1, b = 2 * v - 1;
    if (a == 0 && b == 0)
        return Vec2::Zero();
    constexpr float kQuarterPi = 0.78539816f;
    const bool wide = std::abs(a) > std::abs(b);
    const float r = wide ? a : b;
    const float phi = wide ? kQuarterPi * (b / a) : 2 * kQuarterPi - kQuarterPi * (a / b);
    return {r * std::cos(phi), r * std::sin(phi)};
}

}  // namespace

bool updateRayCache(RayCache& rays, const calibration::CameraModel& camera, int spp, uint64_t seed,
                    int tile_size, const ThinLens& lens, bool timed, const std::stop_token& stop) {
    if (!rays.directions.empty() && sameModel(rays.model, camera) && rays.samples == spp &&
        rays.seed == seed && rays.lens == lens && (!timed || !rays.times.empty()))
        return true;
    rays = {camera, spp, seed, lens, {}, {}, {}, {}, {}};
    const int n = static_cast<int>(std::lround(std::sqrt(spp)));
    const int w = camera.width;
    rays.directions.resize(static_cast<size_t>(w) * camera.height * spp);
    rays.centre_cos.resize(static_cast<size_t>(w) * camera.height);
    if (lens.radius_m > 0)
        rays.lens_points.resize(rays.directions.size());
    if (timed)
        rays.times.resize(rays.directions.size());
    tbb::parallel_for(0, camera.height, [&](int y) {
        if (stop.stop_requested())
            return;
        std::vector<int> strata(static_cast<size_t>(spp));
        // A fresh shuffle of the pixel's strata into `strata`.
        const auto shuffle = [&](optics::Rng& rng) {
            for (int k = 0; k < spp; ++k)
                strata[static_cast<size_t>(k)] = k;
            for (int k = spp - 1; k > 0; --k)
                std::swap(strata[static_cast<size_t>(k)],
                          strata[static_cast<size_t>(rng.next() % static_cast<uint64_t>(k + 1))]);
        };
        for (int x = 0; x < w; ++x) {
            const size_t pixel = static_cast<size_t>(y) * w + x;
            const auto centre = camera.unproject(Eigen::Vector2d(x, y));
            rays.centre_cos[pixel] = centre ? centre->z() : NAN;
            optics::Rng rng(hashIndex(seed, pixel, 0x5eed));
            if (!rays.lens_points.empty()) {
                // Pixel stratum k takes aperture stratum strata[k], shuffled per pixel, so the
                // two are stratified each and uncorrelated together.
                optics::Rng lens_rng(hashIndex(seed, pixel, 0x1e25));
                shuffle(lens_rng);
                for (int k = 0; k < spp; ++k) {
                    const int j = strata[static_cast<size_t>(k)];
                    const float u = ((j % n) + lens_rng.uniform()) / n;
                    const float v = ((j / n) + lens_rng.uniform()) / n;
                    rays.lens_points[pixel * spp + k] = lens.radius_m * concentricDisk(u, v);
                }
            }
            if (timed) {
                // The exposure in spp strata, paired with the pixel samples by a shuffle.
                optics::Rng time_rng(hashIndex(seed, pixel, 0x7173));
                shuffle(time_rng);
                for (int k = 0; k < spp; ++k)
                    rays.times[pixel * spp + k] =
                        (strata[static_cast<size_t>(k)] + time_rng.uniform()) /
                        static_cast<float>(spp);
            }
            for (int k = 0; k < spp; ++k) {
                // Stratified jitter; one sample sits exactly on the pixel centre.
                double dx = 0, dy = 0;
                if (spp > 1) {
                    dx = ((k % n) + rng.uniform()) / n - 0.5;
                    dy = ((k / n) + rng.uniform()) / n - 0.5;
                }
                const auto dir = camera.unproject({x + dx, y + dy});
                rays.directions[pixel * spp + k] =
                    dir ? Vec3(dir->cast<float>().normalized()) : Vec3::Constant(NAN);
            }
        }
    });
    if (stop.stop_requested()) {
        rays = {};  // part-built: the next frame builds it again
        return false;
    }
    rays.cones = detail::tileCones(camera, rays.directions, spp, tile_size);
    return true;
}

// The primary hits of the tile [x0, x1) x [y0, y1) in 16-ray packets of 4x4-pixel blocks,
// logged in that order.
void primaryHits(const EmbreeScene& scene, const RayCache& rays, const Frame& f, int x0, int y0,
                 int x1, int y1, PrimarySamples& out, RayList* log) {
    const int spp = rays.samples;
    const int w = f.inputs->camera.width, tw = x1 - x0;
    const size_t n = static_cast<size_t>(tw) * (y1 - y0) * spp;
    out.hits.resize(n);
    out.dirs.resize(n);
    out.origins.resize(n);
    out.live.resize(n);
    Hit* const hits = out.hits.data();
    Vec3* const dirs = out.dirs.data();
    Vec3* const origins = out.origins.data();
    uint8_t* const live = out.live.data();
    const bool lens = !rays.lens_points.empty();
    const bool moving = f.shutter && !rays.times.empty();
    // The depth mesh is resolved per pixel in finishPrimaryHit().
    const unsigned object_mask = f.depth_mesh ? detail::kObjectMask : detail::kAnyMask;
    IntersectPacket16 packet;
    const auto flush = [&] {
        if (log != nullptr)
            for (int i = 0; i < packet.size(); ++i) {
                const uint32_t slot = packet.slot(i);
                logRay(log, bench::RayLog::Kind::kPrimary, scene.all(), scene.ghosts(),
                       origins[slot], dirs[slot], kInf);
            }
        packet.trace(scene.all(), object_mask, hits);
    };
    for (int by = y0; by < y1; by += 4)
        for (int bx = x0; bx < x1; bx += 4) {
            for (int y = by; y < std::min(y1, by + 4); ++y)
                for (int x = bx; x < std::min(x1, bx + 4); ++x)
                    for (int k = 0; k < spp; ++k) {
                        const size_t i = (static_cast<size_t>(y - y0) * tw + (x - x0)) * spp + k;
                        const size_t sample = (static_cast<size_t>(y) * w + x) * spp + k;
                        const Vec3& dir_cam = rays.directions[sample];
                        live[i] = dir_cam.allFinite();
                        if (!live[i]) {
                            hits[i] = Hit{};
                            origins[i] = f.t_world_cam;
                            dirs[i] = dir_cam;
                            continue;
                        }
                        // The ray in the camera frame: from the centre of projection, or, through
                        // a lens, from the aperture point through where the pinhole ray meets the
                        // plane of focus (a ray at or beyond 90° keeps the pinhole's).
                        if (moving || lens) {
                            Vec3 start = Vec3::Zero(), dir = dir_cam;
                            if (lens && dir_cam.z() > 0) {
                                const Vec2& a = rays.lens_points[sample];
                                start = Vec3(a.x(), a.y(), 0);
                                dir = (dir_cam * (rays.lens.focus_m / dir_cam.z()) - start)
                                          .normalized();
                            }
                            if (moving) {
                                // The camera where it was at the sample's time in the exposure.
                                const float tau = rays.times[sample];
                                // nlerp: over one exposure the turn is small, and there nlerp
                                // is slerp within 1e-6, without trigonometry per sample.
                                const Eigen::Quaternionf q(((1 - tau) * f.shutter->q_open.coeffs() +
                                                            tau * f.shutter->q_close.coeffs())
                                                               .normalized());
                                origins[i] = q * start + (1 - tau) * f.shutter->t_open +
                                             tau * f.shutter->t_close;
                                dirs[i] = q * dir;
                            } else {
                                origins[i] = rotate(f.R_world_cam, start) + f.t_world_cam;
                                dirs[i] = rotate(f.R_world_cam, dir);
                            }
                        } else {
                            origins[i] = f.t_world_cam;
                            dirs[i] = rotate(f.R_world_cam, dir_cam);
                        }
                        packet.add(origins[i], dirs[i], static_cast<uint32_t>(i));
                        if (packet.full())
                            flush();
                    }
            flush();
        }
}

void dilateTileMask(std::vector<uint8_t>& mask, int tiles_x, int tile_size, float radius_px) {
    const int reach = static_cast<int>(std::ceil(radius_px / static_cast<float>(tile_size)));
    if (reach <= 0 || mask.empty())
        return;
    const int tiles_y = static_cast<int>(mask.size()) / tiles_x;
    const std::vector<uint8_t> seed = mask;
    for (int ty = 0; ty < tiles_y; ++ty)
        for (int tx = 0; tx < tiles_x; ++tx) {
            if (!seed[static_cast<size_t>(ty) * tiles_x + tx])
                continue;
            for (int y = std::max(0, ty - reach); y <= std::min(tiles_y - 1, ty + reach); ++y)
                std::fill_n(
                    mask.begin() + static_cast<std::ptrdiff_t>(static_cast<size_t>(y) * tiles_x +
                                                               std::max(0, tx - reach)),
                    std::min(tiles_x - 1, tx + reach) - std::max(0, tx - reach) + 1, 1);
        }
}

}  // namespace mixray::render::detail
