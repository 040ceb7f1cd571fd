// What every part of the renderer shares while it traces one frame: the frame's context (camera,
// depth, active lights, virtual bounds), the mixed/real radiance pair one-pass differential
// rendering carries, and the state of one sample. Internal to mixray::render.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "embree_scene.h"
#include "footprint.h"
#include "mixray/render/bench_seam.h"
#include "mixray/render/depth_occlusion.h"
#include "mixray/render/renderer.h"
#include "optics.h"

namespace mixray::render::detail {

using Vec3 = Eigen::Vector3f;
using Vec2 = Eigen::Vector2f;

constexpr float kInf = std::numeric_limits<float>::infinity();
// How far secondary rays look for depth-camera surfaces when nothing in the scene is nearer;
// beyond any Kinect's range.
constexpr float kFarDepth_m = 20;
constexpr float kDepthStart_m = 0.01f;

// Which radiances a ray carries: both (paths made of real surfaces so far), mixed only (after a
// virtual surface, where the real scene has no counterpart), or real only (the scene without
// virtual objects, for the I_r of rays a virtual object intercepted).
enum class Mode : uint8_t { kBoth, kMixed, kReal };

// Radiance in the mixed scene (I_m) and in the real-only scene (I_r).
struct Pair {
    Vec3 m = Vec3::Zero();
    Vec3 r = Vec3::Zero();
};

[[gnu::always_inline]] inline Pair scaled(const Pair& p, const Vec3& w) {
    return {p.m.cwiseProduct(w), p.r.cwiseProduct(w)};
}
[[gnu::always_inline]] inline Pair sum(const Pair& a, const Pair& b) {
    return {a.m + b.m, a.r + b.r};
}

struct Counters {
    uint64_t secondary = 0;
    uint64_t shadow = 0;
};

using RayList = std::vector<bench::RayLog::Ray>;

// What RT²AR's penumbra filter (Film::meanFilterPenumbra) needs of a sample's primary hit: the
// visible fraction of its direct light in the mixed and in the real scene, and how much the
// sample's I_m and I_r change with each. The filter averages the visibility, not the radiance,
// so that textures, highlights and reflections stay sharp where the shadow is smoothed.
struct PrimaryDirect {
    float unshadowed = 0;                // the lights' direct light, unoccluded (summed channels)
    float visible_m = 0, visible_r = 0;  // the same, times each light's visibility
    Vec3 dm_dvisible_m = Vec3::Zero();   // ∂I_m / ∂(visible fraction in the mixed scene)
    Vec3 dm_dvisible_r = Vec3::Zero();   // ∂I_m / ∂(visible fraction in the real scene)
    Vec3 dr_dvisible_r = Vec3::Zero();   // ∂I_r / ∂(visible fraction in the real scene)
    bool penumbra = false;               // an adaptive test found the light partly hidden

    float visibleFractionM() const { return unshadowed > 0 ? visible_m / unshadowed : 0.f; }
    float visibleFractionR() const { return unshadowed > 0 ? visible_r / unshadowed : 0.f; }
};

struct SampleState {
    optics::Rng rng;
    Counters* counters;
    RayList* log = nullptr;  // renderFrame() was given a log
    // Where the next shade() records its primary hit's direct light (taken by that call).
    PrimaryDirect* primary_direct = nullptr;
};

inline void logRay(RayList* log, bench::RayLog::Kind kind, RTCScene scene, RTCScene ghosts,
                   const Vec3& origin, const Vec3& d, float t_far) {
    if (log != nullptr)
        log->push_back({{origin.x(), origin.y(), origin.z()},
                        {d.x(), d.y(), d.z()},
                        t_far,
                        kind,
                        scene == ghosts});
}

// Per-frame tracing context: read-only during the parallel loop.
class CausticMaps;

struct Frame {
    const RenderInputs* inputs = nullptr;
    Eigen::Matrix3f R_world_cam;
    Vec3 t_world_cam;
    Eigen::Matrix3d R_cam_world;
    Eigen::Vector3d t_cam_world;
    std::vector<BoundSphere> virtual_bounds;
    std::vector<const LightData*> lights;  // active direct lights
    std::vector<const LightData*> environments;
    std::optional<DepthView> depth;
    bool depth_mesh = false;  // the depth surface is in the BVH this frame (kMesh)
    std::array<float, 256> srgb_lut{};
    // The only active ghost is a plane or disk: no ray leaving it can meet a ghost again.
    bool lone_flat_ghost = false;
    FootprintScene footprint;
    // Motion blur: the camera's pose at the shutter's opening and closing (RenderInputs::shutter),
    // the quaternions on the same side.
    struct Shutter {
        Eigen::Quaternionf q_open, q_close;
        Vec3 t_open, t_close;
    };
    std::optional<Shutter> shutter;
    const CausticMaps* caustics = nullptr;  // the scene's caustics, this frame's photons
};

inline uint64_t hashIndex(uint64_t seed, uint64_t a, uint64_t b) {
    optics::Rng rng(seed ^ (a * 0x9e3779b97f4a7c15ULL) ^ (b * 0xc2b2ae3d27d4eb4fULL));
    return rng.next();
}

// Distance from `c` to the segment a + s·(b - a), s in [0, s_max] (s_max = inf: a ray).
[[gnu::always_inline]] inline float distanceToSegment(const Vec3& c, const Vec3& a, const Vec3& dir,
                                                      float length) {
    const float s = std::clamp((c - a).dot(dir), 0.f, length);
    return (a + s * dir - c).norm();
}

// R·v spelled out: GCC at -O2 leaves Eigen's fixed-size product as an out-of-line call, which
// showed up in profiles of the per-hit code.
[[gnu::always_inline]] inline Vec3 rotate(const Eigen::Matrix3f& R, const Vec3& v) {
    return R.col(0) * v.x() + R.col(1) * v.y() + R.col(2) * v.z();
}

// How far a ray leaving a surface at `p` starts from it.
[[gnu::always_inline]] inline float offsetFor(const Vec3& p) {
    return 1e-4f * (1.f + p.cwiseAbs().maxCoeff());
}

}  // namespace mixray::render::detail
