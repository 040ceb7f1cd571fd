// Depth units of recorded streams: files keep their source's units exactly, the graph sees mm.
#pragma once

#include <cstdint>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray::replay {

// Stream tag naming how many depth units make one metre. mixray's own depth is millimetres
// (1000, also when the tag is absent); a TUM RGB-D folder stores 5000 units per metre (0.2 mm),
// and converting those to mm would lose information, so recordings made from TUM folders keep
// the raw PNG values and carry this tag. The replay device converts such streams to mm before
// they enter a graph unless asked for the recorded units.
inline constexpr const char* kDepthScaleTag = "depth_scale_per_m";
inline constexpr int kMillimetresPerMetre = 1000;
inline constexpr int kTumDepthPerMetre = 5000;

// The stream's depth units per metre: its kDepthScaleTag, else 1000. kCorruptData when the
// tag is not a positive integer.
Result<int> depthScalePerMetre(const StreamInfo& stream);

// Rescales a 16-bit depth image from `from_per_m` to `to_per_m` units per metre, rounding to
// nearest. 0 stays 0 (no measurement) and a measurement never becomes 0: it is at least 1
// unit. Exact when to_per_m is a multiple of from_per_m, and for values that are multiples of
// from_per_m / to_per_m. kInvalidArgument when a value does not fit in 16 bits (the message
// gives the first such pixel) or the layouts differ. `src` and `dst` may be the same memory.
Status rescaleDepth(const ImageView& src, int from_per_m, const MutableImageView& dst,
                    int to_per_m);

}  // namespace mixray::replay
