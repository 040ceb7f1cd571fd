// The benchmark's seam into the renderer (`mixray bench render`, its tests): every ray of a
// frame logged, and the same rays traced again by bare Embree on the renderer's BVH, the
// baseline the renderer's efficiency is measured against. Not for applications: it reaches
// behind Renderer's interface into the one implementation Renderer::create() makes.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mixray/graph/result.h"
#include "mixray/render/renderer.h"

namespace mixray::render::bench {

// Every ray one frame traced, in a deterministic order, so a benchmark can trace the same rays
// with bare Embree on the same BVH.
struct RayLog {
    enum class Kind : uint8_t { kPrimary, kSecondary, kShadow };
    struct Ray {
        float origin[3];
        float direction[3];
        float t_far;
        Kind kind;
        bool ghosts_only;  // traced in the scene of ghosts (real-only radiance), else all objects
    };
    std::vector<Ray> rays;

    uint64_t count(Kind kind) const;
};

// Seconds bare Embree took to trace a RayLog on the renderer's BVH with its threads: the best
// of the ways tried for each kind (single rays, 16-ray packets, streams), as wall-clock time
// and as the process's CPU time (which other programs on the machine disturb less).
struct BareTraceTimes {
    double primary_s = 0;
    double secondary_s = 0;
    double shadow_s = 0;
    double primary_cpu_s = 0, secondary_cpu_s = 0, shadow_cpu_s = 0;
    std::string primary_method, secondary_method, shadow_method;
    // Every way tried, per kind, in the order tried: what a wavefront's batches could gain over
    // the single rays a recursive integrator traces.
    struct Method {
        RayLog::Kind kind;
        std::string name;  // rtcIntersect1, rtcIntersect16, rtcIntersect1M, rtcOccluded1, …
        double wall_s = 0, cpu_s = 0;
    };
    std::vector<Method> tried;
    double total() const { return primary_s + secondary_s + shadow_s; }
    double totalCpu() const { return primary_cpu_s + secondary_cpu_s + shadow_cpu_s; }
};

// How long Renderer::create() took, in its two parts, and what it built.
struct CreationTimes {
    double load_s = 0;  // meshes (assimp), textures and environment maps read and prepared
    double bvh_s = 0;   // Embree's BVHs built
    uint64_t triangles_built = 0;  // a mesh several objects instance counts once
};
CreationTimes creationTimes(const Renderer& renderer);

// Renderer::render(), appending every ray of the frame to `log` (cleared first). Slower than
// render(); the image and stats are the same.
Status renderLoggingRays(Renderer& renderer, const RenderInputs& inputs, RenderLayers& out,
                         RenderStats* stats, RayLog& log);

// Traces `log` (from the renderer's last frame) with bare Embree on the renderer's BVH and
// poses, with its options().threads, `repeats` times; the fastest run per ray kind counts.
BareTraceTimes traceBare(const Renderer& renderer, const RayLog& log, int repeats);

}  // namespace mixray::render::bench
