// sRGB decoding: camera images are sRGB-encoded (docs/conventions.md), and fits on intensity
// (marker edges, light estimation) need it linear.
#pragma once

#include <array>

namespace mixray {

// An 8-bit sRGB code value (0..255) to linear intensity in [0, 1] (IEC 61966-2-1).
const std::array<float, 256>& srgbToLinearTable();

}  // namespace mixray
