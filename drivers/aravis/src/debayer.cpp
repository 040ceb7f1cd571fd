// Bayer demosaicing with OpenCV, for cameras whose raw mosaic is wanted as colour.
#include <opencv2/imgproc.hpp>

#include "mixray/aravis/aravis_backend.h"

namespace mixray::aravis {

Status debayer(const ImageView& bayer, const MutableImageView& rgb) {
    // OpenCV names a mosaic by the second row's second and third samples, so GenICam's
    // (and mixray's) RGGB, whose top-left 2x2 is R G / G B, is OpenCV's "BG".
    int code = -1;
    switch (bayer.desc.format) {
        case PixelFormat::kBayerRGGB8:
            code = cv::COLOR_BayerBG2RGB;
            break;
        case PixelFormat::kBayerGRBG8:
            code = cv::COLOR_BayerGB2RGB;
            break;
        case PixelFormat::kBayerGBRG8:
            code = cv::COLOR_BayerGR2RGB;
            break;
        case PixelFormat::kBayerBGGR8:
            code = cv::COLOR_BayerRG2RGB;
            break;
        default:
            return {ErrorCode::kInvalidArgument,
                    "debayer: " + std::string(toString(bayer.desc.format)) +
                        " is not an 8-bit Bayer format"};
    }
    if (rgb.desc.format != PixelFormat::kRGB8 || rgb.desc.width != bayer.desc.width ||
        rgb.desc.height != bayer.desc.height) {
        return {ErrorCode::kInvalidArgument, "debayer: the output must be rgb8 of the same size"};
    }
    if (bayer.desc.width < 2 || bayer.desc.height < 2)
        return {ErrorCode::kInvalidArgument, "debayer: the mosaic is smaller than 2x2"};
    try {
        const cv::Mat in(bayer.desc.height, bayer.desc.width, CV_8UC1,
                         const_cast<uint8_t*>(bayer.data),
                         static_cast<size_t>(bayer.desc.stride_bytes));
        cv::Mat out(rgb.desc.height, rgb.desc.width, CV_8UC3, rgb.data,
                    static_cast<size_t>(rgb.desc.stride_bytes));
        cv::cvtColor(in, out, code);
    } catch (const cv::Exception& e) {
        return {ErrorCode::kInternal, std::string("debayer: OpenCV: ") + e.what()};
    }
    return Status::ok();
}

}  // namespace mixray::aravis
