// The camera: the ray of every (sub)pixel sample through the calibrated lens, cached per camera
// model, and the primary hits of a tile traced as packets. Internal to mixray::render.
#pragma once

#include <cstdint>
#include <optional>
#include <stop_token>
#include <vector>

#include "frame_context.h"
#include "mixray/calibration/camera_model.h"

namespace mixray::render::detail {

bool sameModel(const calibration::CameraModel& a, const calibration::CameraModel& b);

// A thin lens at the centre of projection (Kán & Kaufmann §3.1, after Cook's distributed ray
// tracing): a sample's ray leaves a point of the aperture disk and passes through the point
// where its pinhole ray meets the plane of focus z = focus_m, so that plane stays sharp and a
// point at depth d spreads over fx · 2·radius_m · |1/d − 1/focus_m| pixels. radius_m = 0: a
// pinhole.
struct ThinLens {
    float radius_m = 0;
    float focus_m = 1;

    bool operator==(const ThinLens&) const = default;
    // How far, in pixels, a point at depth of at least `nearest_m` can spread from its pinhole
    // image (half the largest circle of confusion) for a focal length of `f_px`.
    float blurRadiusPx(double f_px, float nearest_m) const;
};

// Camera directions of every (sub)pixel sample, computed once per camera model through its
// unproject(), so rays follow the lens distortion exactly. NaN marks samples without a ray.
struct RayCache {
    calibration::CameraModel model;
    int samples = 0;
    uint64_t seed = 0;
    ThinLens lens;
    // Pinhole directions: a sample's ray without the lens, which the footprint and the depth
    // map use; with a lens, where it meets the plane of focus.
    std::vector<Vec3> directions;  // ((y * width + x) * samples + s)
    // With a lens, each sample's point on the aperture (camera frame, z = 0), stratified
    // jointly with the pixel samples; empty for a pinhole.
    std::vector<Vec2> lens_points;
    // For motion blur, each sample's time in the exposure, 0 (shutter open) to 1 (closed),
    // stratified over the pixel's samples and paired with them by a shuffle; empty: none.
    std::vector<float> times;
    std::vector<TileCone> cones;  // per tile of options.tile_size
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
// one sits on the pixel centre) drawn from `seed`, their points on `lens`'s aperture, their
// times in the exposure when `timed` (kept once made, so a pipeline that blurs some frames and
// not others does not rebuild it), and the cones of tiles of `tile_size`; keeps it as it is
// when nothing changed. Building it unprojects every sample through the lens model (seconds
// at 64 samples per pixel under the sanitizers), so it checks `stop` row by row: false, and
// the cache left empty, when a stop was requested before it was done.
bool updateRayCache(RayCache& rays, const calibration::CameraModel& camera, int spp, uint64_t seed,
                    int tile_size, const ThinLens& lens = {}, bool timed = false,
                    const std::stop_token& stop = {});

// A tile's primary samples, ((y - y0) * (x1 - x0) + (x - x0)) * samples + s: reused by the
// thread that traces them, so the tile loop never allocates.
struct PrimarySamples {
    std::vector<Hit> hits;      // the nearest hit among the scene's objects; invalid when not live
    std::vector<Vec3> origins;  // world
    std::vector<Vec3> dirs;     // world, unit
    std::vector<uint8_t> live;  // the sample has a ray (RayCache::directions is finite)
};

// The primary hits, world origins and world directions of the samples of the tile
// [x0, x1) x [y0, y1) of frame `f`, into `out`. Without a lens every origin is the camera's;
// with f.shutter each sample's pose is interpolated at its time.
void primaryHits(const EmbreeScene& scene, const RayCache& rays, const Frame& f, int x0, int y0,
                 int x1, int y1, PrimarySamples& out, RayList* log);

// Grows `mask` (tiles_x wide, 1 where a tile may hold virtual content) by `radius_px` pixels of
// tiles `tile_size` wide: with a lens, content spreads that far from where a pinhole shows it.
void dilateTileMask(std::vector<uint8_t>& mask, int tiles_x, int tile_size, float radius_px);

}  // namespace mixray::render::detail
