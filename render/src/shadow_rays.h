// Shadows by ray tracing: how much of a light a point sees in the mixed and the real scene (hard,
// uniform soft or RT²AR's adaptive soft shadows), and RT²AR's screen-space test against the
// depth map. Internal to mixray::render.
#pragma once

#include "frame_context.h"

namespace mixray::render::detail {

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

    // DepthSecondaryRays::kScreenSpace: whether the depth map's surface lies between `origin`
    // and a light `dist` away along `wi`.
    bool depthMapOccludes(const Frame& f, const Vec3& origin, const Vec3& wi, float dist) const;

private:
    const RenderOptions& options_;
    const EmbreeScene& scene_;
};

}  // namespace mixray::render::detail
