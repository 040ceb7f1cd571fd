// Shadows by ray tracing: how much of a light a point sees in the mixed and the real scene (hard,
// uniform soft or RT²AR's adaptive soft shadows), and RT²AR's screen-space test against the
// depth map. Internal to mixray::render.
#pragma once

#include <cmath>

#include "frame_context.h"

namespace mixray::render::detail {

// One point's hard shadow test: visibility()'s single ray, towards a point light, a directional
// light or a spherical light's centre, `length` long (infinite: a direction).
struct HardShadowQuery {
    Vec3 origin;
    Vec3 dir;
    float length = kInf;
    Mode mode = Mode::kBoth;
};

class ShadowRays {
public:
    // Both are kept by reference and must outlive this.
    ShadowRays(const RenderOptions& options, const EmbreeScene& scene)
        : options_(options), scene_(scene) {}

    // Fractions of `light`'s visible area seen from `origin` (towards `to_light`, `dist` away;
    // infinite for directional lights) in the mixed and the real scene, as `mode` asks. Both
    // use the same sample points, so they agree bit for bit where no virtual object interferes.
    // `penumbra` (may be null) is set when RT²AR's adaptive test rays disagreed.
    Pair visibility(const LightData& light, const Vec3& origin, const Vec3& to_light, float dist,
                    Mode mode, SampleState& st, bool* penumbra = nullptr) const;

    // Whether visibility() of `light` at `dist` traces one ray (hard shadows).
    bool hard(const LightData& light, float dist) const {
        return light.light.type != LightType::kSphere ||
               options_.soft_shadows == SoftShadowMethod::kHard || dist <= light.light.radius;
    }
    // The hard test visibility() makes from `origin` to a light `dist` along `to_light`.
    static HardShadowQuery hardQuery(const Vec3& origin, const Vec3& to_light, float dist,
                                     Mode mode) {
        return {origin, to_light, std::isfinite(dist) ? dist * kShorten : kInf, mode};
    }
    // visibility()'s answers to `count` hard tests (shadows on), into visible[i]: the same rays,
    // counted in `counters` and logged in `log` (may be null), traced as 16-wide occlusion
    // packets: each ray in the mixed scene, then in the real scene where that was blocked.
    void hardVisibilities(const HardShadowQuery* queries, size_t count, Counters& counters,
                          RayList* log, Pair* visible) const;

    // DepthSecondaryRays::kScreenSpace: whether the depth map's surface lies between `origin`
    // and a light `dist` away along `wi`.
    bool depthMapOccludes(const Frame& f, const Vec3& origin, const Vec3& wi, float dist) const;

private:
    // Shadow rays stop this much short of the light, so that they do not hit its own geometry.
    static constexpr float kShorten = 1.f - 1e-4f;

    const RenderOptions& options_;
    const EmbreeScene& scene_;
};

}  // namespace mixray::render::detail
