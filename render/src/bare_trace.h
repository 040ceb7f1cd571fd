// The benchmark's baseline: the rays of a RayLog (bench_seam.h) traced with nothing but Embree
// calls.
#pragma once

#include <embree3/rtcore.h>

#include "mixray/render/bench_seam.h"

namespace mixray::render::detail {

// Traces `log` in `all` / `ghosts` with `threads` TBB threads (0: all), `repeats` times per
// method: primaries as single rays and as 16-ray packets of consecutive log entries (the
// renderer logs them in 4x4-pixel blocks), secondary and shadow rays as single rays and as
// rtcIntersect1M / rtcOccluded1M streams, shadow rays also as 16-ray packets of consecutive
// entries (the renderer logs a point's soft-shadow samples together). Each kind keeps its
// fastest method.
bench::BareTraceTimes traceBareEmbree(RTCScene all, RTCScene ghosts, const bench::RayLog& log,
                                      int threads, int repeats);

}  // namespace mixray::render::detail
