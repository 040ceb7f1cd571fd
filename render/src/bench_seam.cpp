// bench_seam.h: the benchmark's ray log and bare-Embree baseline, on the one Renderer
// implementation there is.
#include "mixray/render/bench_seam.h"

#include <algorithm>
#include <cassert>

#include "embree_renderer.h"

namespace mixray::render::bench {

uint64_t RayLog::count(Kind kind) const {
    return static_cast<uint64_t>(
        std::count_if(rays.begin(), rays.end(), [kind](const Ray& r) { return r.kind == kind; }));
}

// Renderer::create() makes nothing else; a Renderer from elsewhere (a test double) has no BVH
// to measure against.
static detail::EmbreeRenderer& embreeRenderer(const Renderer& renderer) {
    auto* embree = dynamic_cast<const detail::EmbreeRenderer*>(&renderer);
    assert(embree != nullptr);
    return const_cast<detail::EmbreeRenderer&>(*embree);
}

Status renderLoggingRays(Renderer& renderer, const RenderInputs& inputs, RenderLayers& out,
                         RenderStats* stats, RayLog& log) {
    return embreeRenderer(renderer).renderFrame(inputs, out, stats, &log);
}

CreationTimes creationTimes(const Renderer& renderer) {
    return embreeRenderer(renderer).creationTimes();
}

BareTraceTimes traceBare(const Renderer& renderer, const RayLog& log, int repeats) {
    return embreeRenderer(renderer).traceBare(log, repeats);
}

}  // namespace mixray::render::bench
