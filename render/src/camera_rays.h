// The camera: the ray of every (sub)pixel sample through the calibrated lens, cached per camera
// model, and the primary hits of a tile traced as packets. Internal to mixray::render.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "frame_context.h"
#include "mixray/calibration/camera_model.h"

namespace mixray::render::detail {

bool sameModel(const calibration::CameraModel& a, const calibration::CameraModel& b);

// Camera directions of every (sub)pixel sample, computed once per camera model through its
// unproject(), so rays follow the lens distortion exactly. NaN marks samples without a ray.
struct RayCache {
    calibration::CameraModel model;
    int samples = 0;
    uint64_t seed = 0;
    std::vector<Vec3> directions;  // ((y * width + x) * samples + s)
    std::vector<TileCone> cones;   // per tile of options.tile_size
    // The z of the unit ray through each pixel's centre (y * width + x), exactly as
    // rayDistanceAt() computes it; NaN where it has none in front of the camera.
    std::vector<double> centre_cos;

    // rayDistanceAt(depth, x, y) for a depth image registered to `model`, from the cache:
    // the same value, without a lens unprojection per pixel per frame.
    std::optional<float> rayDistanceAt(const DepthView& depth, int x, int y) const {
        const std::optional<float> z = depth.zAt(x, y);
        if (!z)
            return std::nullopt;
        const double c = centre_cos[static_cast<size_t>(y) * model.width + x];
        if (!(c > 0))
            return std::nullopt;
        return static_cast<float>(*z / c);
    }
};

// Fills `rays` for `camera` with `spp` stratified jittered samples per pixel (a square number;
// one sits on the pixel centre) drawn from `seed`, and the cones of tiles of `tile_size`; keeps
// it as it is when nothing changed.
void updateRayCache(RayCache& rays, const calibration::CameraModel& camera, int spp, uint64_t seed,
                    int tile_size);

// The primary hits and world directions of the samples of the tile [x0, x1) x [y0, y1) of
// frame `f`, in `hits` and `dirs` ((y - y0) * (x1 - x0) + (x - x0)) * samples + s).
void primaryHits(const EmbreeScene& scene, const RayCache& rays, const Frame& f, int x0, int y0,
                 int x1, int y1, std::vector<Hit>& hits, std::vector<Vec3>& dirs, RayList* log);

}  // namespace mixray::render::detail
