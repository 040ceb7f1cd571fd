// Image files as the detectors take them (internal to calibration): read with OpenCV, alpha
// dropped, 16-bit colour made grey, 16-bit grey stretched to 8 bits when 8 are needed.
#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "mixray/graph/image.h"

namespace mixray::calibration::detail {

// One image file: `mat` in `format` (kMono8, kBGR8 or kMono16) sharing `view`'s pixels, or
// format kUnknown and `why` ("not an image OpenCV can read").
struct ImageFile {
    cv::Mat mat;
    PixelFormat format = PixelFormat::kUnknown;
    std::string why;
    ImageView view() const;
};

ImageFile readImageFile(const std::filesystem::path& path);

// 16-bit images (IR, mono) hold their signal in a small, camera-dependent part of the range;
// a percentile stretch puts the board's black and white at the ends of 8 bits whatever it is.
cv::Mat stretch16(const cv::Mat& src);

}  // namespace mixray::calibration::detail
