// The camera's rays (camera_rays.h).
#include "camera_rays.h"

#include <tbb/parallel_for.h>

#include <array>
#include <cmath>

namespace mixray::render::detail {

bool sameModel(const calibration::CameraModel& a, const calibration::CameraModel& b) {
    return a.lens == b.lens && a.width == b.width && a.height == b.height && a.fx == b.fx &&
           a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

void updateRayCache(RayCache& rays, const calibration::CameraModel& camera, int spp, uint64_t seed,
                    int tile_size) {
    if (!rays.directions.empty() && sameModel(rays.model, camera) && rays.samples == spp &&
        rays.seed == seed)
        return;
    rays = {camera, spp, seed, {}, {}, {}};
    const int n = static_cast<int>(std::lround(std::sqrt(spp)));
    const int w = camera.width;
    rays.directions.resize(static_cast<size_t>(w) * camera.height * spp);
    rays.centre_cos.resize(static_cast<size_t>(w) * camera.height);
    tbb::parallel_for(0, camera.height, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const size_t pixel = static_cast<size_t>(y) * w + x;
            const auto centre = camera.unproject(Eigen::Vector2d(x, y));
            rays.centre_cos[pixel] = centre ? centre->z() : NAN;
            optics::Rng rng(hashIndex(seed, pixel, 0x5eed));
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
    rays.cones = detail::tileCones(camera, rays.directions, spp, tile_size);
}

// The primary hits of the tile [x0, x1) x [y0, y1) in 16-ray packets of 4x4-pixel blocks,
// logged in that order.
void primaryHits(const EmbreeScene& scene, const RayCache& rays, const Frame& f, int x0, int y0,
                 int x1, int y1, std::vector<Hit>& hits, std::vector<Vec3>& dirs, RayList* log) {
    const int spp = rays.samples;
    const int w = f.inputs->camera.width, tw = x1 - x0;
    const size_t n = static_cast<size_t>(tw) * (y1 - y0) * spp;
    hits.assign(n, Hit{});
    dirs.resize(n);
    std::array<size_t, 16> lane_index;
    std::array<Vec3, 16> lane_dir;
    std::array<Hit, 16> lane_hit;
    // The depth mesh is resolved per pixel in finishPrimaryHit().
    const unsigned object_mask = f.depth_mesh ? detail::kObjectMask : detail::kAnyMask;
    int lanes = 0;
    const auto flush = [&] {
        if (lanes == 0)
            return;
        EmbreeScene::intersect16(scene.all(), f.t_world_cam, lane_dir.data(), lanes,
                                 lane_hit.data(), object_mask);
        for (int i = 0; i < lanes; ++i) {
            hits[lane_index[i]] = lane_hit[i];
            logRay(log, RayLog::Kind::kPrimary, scene.all(), scene.ghosts(), f.t_world_cam,
                   lane_dir[i], kInf);
        }
        lanes = 0;
    };
    for (int by = y0; by < y1; by += 4)
        for (int bx = x0; bx < x1; bx += 4) {
            for (int y = by; y < std::min(y1, by + 4); ++y)
                for (int x = bx; x < std::min(x1, bx + 4); ++x)
                    for (int k = 0; k < spp; ++k) {
                        const size_t i = (static_cast<size_t>(y - y0) * tw + (x - x0)) * spp + k;
                        const Vec3& dir_cam =
                            rays.directions[(static_cast<size_t>(y) * w + x) * spp + k];
                        if (!dir_cam.allFinite())
                            continue;
                        dirs[i] = rotate(f.R_world_cam, dir_cam);
                        lane_index[lanes] = i;
                        lane_dir[lanes] = dirs[i];
                        if (++lanes == 16)
                            flush();
                    }
            flush();
        }
}

}  // namespace mixray::render::detail
