// Image files as the detectors take them (image_file.h).
#include "image_file.h"

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

namespace mixray::calibration::detail {

ImageView ImageFile::view() const {
    ImageView v;
    v.desc = ImageDesc{format, mat.cols, mat.rows, static_cast<int>(mat.step[0])};
    v.data = mat.data;
    v.size_bytes = mat.step[0] * static_cast<size_t>(mat.rows);
    return v;
}

ImageFile readImageFile(const std::filesystem::path& path) {
    ImageFile out;
    cv::Mat& img = out.mat;
    try {
        img = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
        if (!img.empty() && img.channels() == 4)
            cv::cvtColor(img, img,
                         img.depth() == CV_16U ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGRA2BGR);
        if (!img.empty() && img.depth() == CV_16U && img.channels() == 3)
            cv::cvtColor(img, img, cv::COLOR_BGR2GRAY);
    } catch (const cv::Exception&) {
        img.release();
    }
    if (!img.empty() && img.depth() == CV_8U)
        out.format = img.channels() == 1 ? PixelFormat::kMono8 : PixelFormat::kBGR8;
    else if (!img.empty() && img.depth() == CV_16U && img.channels() == 1)
        out.format = PixelFormat::kMono16;
    if (out.format == PixelFormat::kUnknown) {
        out.why = img.empty() ? "not an image OpenCV can read"
                              : "unsupported sample type (" + std::to_string(img.depth()) + ", " +
                                    std::to_string(img.channels()) + " channels)";
        img.release();
    }
    return out;
}

cv::Mat stretch16(const cv::Mat& src) {
    std::vector<uint16_t> values;
    values.reserve(src.total());
    for (int y = 0; y < src.rows; ++y) {
        const uint16_t* row = src.ptr<uint16_t>(y);
        values.insert(values.end(), row, row + src.cols);
    }
    const auto at = [&](double q) {
        auto k = static_cast<size_t>(q * static_cast<double>(values.size() - 1));
        std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
        return static_cast<double>(values[k]);
    };
    const double lo = at(0.005), hi = at(0.995);
    cv::Mat out;
    const double scale = hi > lo ? 255.0 / (hi - lo) : 1.0;
    src.convertTo(out, CV_8U, scale, -lo * scale);
    return out;
}

}  // namespace mixray::calibration::detail
