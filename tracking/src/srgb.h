// sRGB decoding shared by the marker edge fit and the light estimators.
#pragma once

#include <array>

namespace mixray::tracking::detail {

// sRGB code value (0..255) to linear [0, 1] (IEC 61966-2-1).
const std::array<float, 256>& srgbToLinearTable();

}  // namespace mixray::tracking::detail
