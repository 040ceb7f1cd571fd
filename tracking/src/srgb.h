// sRGB decoding shared by the light estimators (the marker edge fit, now in calibration, has its
// own table).
#pragma once

#include <array>

namespace mixray::tracking::detail {

// sRGB code value (0..255) to linear [0, 1] (IEC 61966-2-1).
const std::array<float, 256>& srgbToLinearTable();

}  // namespace mixray::tracking::detail
