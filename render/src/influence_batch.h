// The footprint test of many ghost hits at once, in SIMD lanes (Highway, the widest instruction
// set this CPU has): for each, what DifferentialIntegrator::ghostInfluenced() answers, the same
// operations in the same order. Internal to mixray::render.
#pragma once

#include <cstddef>
#include <cstdint>

#include "frame_context.h"

namespace mixray::render::detail {

struct Surface;

// Ghost hits surfaces[samples[k]] seen along dirs[samples[k]], k < count, in frame `f` (its
// virtual bounds, lights and lone flat ghost); `shadows`: RenderOptions::shadows. Without
// caustics (CausticMaps::near() is the integrator's, hit by hit).
struct GhostHits {
    const Frame* f = nullptr;
    bool shadows = true;
    const Surface* surfaces = nullptr;
    const Vec3* dirs = nullptr;
    const uint32_t* samples = nullptr;
    size_t count = 0;
};

// influenced[samples[k]] = whether virtual objects can change the shading of hit samples[k],
// for every k < count. Reentrant.
void ghostsInfluenced(const GhostHits& hits, uint8_t* influenced);

}  // namespace mixray::render::detail
