// The surfaces of many hits on one triangle mesh of one object at once, in SIMD lanes (Highway,
// the widest instruction set this CPU has): bit for bit what DifferentialIntegrator::surfaceAt()
// computes for each, the same operations in the same order and none fused. Internal to
// mixray::render.
#pragma once

#include <cstddef>
#include <cstdint>

#include "frame_context.h"

namespace mixray::render::detail {

struct Surface;

// Hits on one triangle mesh of one posed object: hits[samples[k]] for k < count, valid and
// naming `mesh` of `object`; their rays' origins and directions at the same indices.
struct MeshHits {
    const ObjectData* object = nullptr;
    const MaterialData* material = nullptr;
    const TriangleMesh* mesh = nullptr;
    const Hit* hits = nullptr;
    const Vec3* origins = nullptr;
    const Vec3* dirs = nullptr;
    const uint32_t* samples = nullptr;
    size_t count = 0;
};

// out[samples[k]] = the surface at hit samples[k], for every k < count. Reentrant.
void meshSurfaces(const MeshHits& hits, Surface* out);

}  // namespace mixray::render::detail
