// Pixel format table, image sizes and comparisons.
#include "mixray/graph/image.h"

#include <array>
#include <cstring>

namespace mixray {
namespace {

constexpr std::array<PixelFormatInfo, 15> kFormats = {{
    {"unknown", 0, 0, false},
    {"mono8", 8, 1, false},
    {"mono16", 16, 1, false},
    {"rgb8", 24, 3, false},
    {"bgr8", 24, 3, false},
    {"bayer_rggb8", 8, 3, false},
    {"bayer_grbg8", 8, 3, false},
    {"bayer_gbrg8", 8, 3, false},
    {"bayer_bggr8", 8, 3, false},
    {"yuyv", 16, 3, false},
    {"nv12", 12, 3, false},
    {"mjpeg", 0, 3, true},
    {"depth16", 16, 1, false},
    {"ir16", 16, 1, false},
    {"binary", 8, 0, true},
}};

}  // namespace

const PixelFormatInfo& pixelFormatInfo(PixelFormat format) {
    auto index = static_cast<size_t>(format);
    return index < kFormats.size() ? kFormats[index] : kFormats[0];
}

std::string_view toString(PixelFormat format) {
    return pixelFormatInfo(format).name;
}

std::optional<PixelFormat> pixelFormatFromString(std::string_view name) {
    for (size_t i = 1; i < kFormats.size(); ++i) {
        if (kFormats[i].name == name)
            return static_cast<PixelFormat>(i);
    }
    return std::nullopt;
}

ImageDesc ImageDesc::packed(PixelFormat format, int width, int height) {
    ImageDesc desc{format, width, height, 0};
    const auto& info = pixelFormatInfo(format);
    if (format == PixelFormat::kNV12) {
        desc.stride_bytes = width;
    } else if (format == PixelFormat::kBinary) {
        desc.stride_bytes = width;
    } else if (!info.compressed) {
        desc.stride_bytes = width * static_cast<int>(info.bits_per_pixel / 8);
    }
    return desc;
}

size_t ImageDesc::bufferBytes() const {
    if (width <= 0 || height <= 0)
        return 0;
    const auto w = static_cast<size_t>(width);
    const auto h = static_cast<size_t>(height);
    switch (format) {
        case PixelFormat::kUnknown:
            return 0;
        case PixelFormat::kMJPEG:
            // A JPEG of any sane quality stays below 4 bytes per pixel plus headers.
            return w * h * 4 + 65536;
        case PixelFormat::kNV12:
            return static_cast<size_t>(stride_bytes) * h * 3 / 2;
        case PixelFormat::kBinary:
            return w * h;
        default:
            return static_cast<size_t>(stride_bytes) * h;
    }
}

Image Image::copyOf(const ImageView& view) {
    Image image;
    image.desc_ = view.desc;
    const size_t bytes =
        pixelFormatInfo(view.desc.format).compressed ? view.size_bytes : view.desc.bufferBytes();
    image.bytes_.assign(view.data, view.data + bytes);
    return image;
}

bool sameImage(const ImageView& a, const ImageView& b) {
    if (a.desc.format != b.desc.format || a.desc.width != b.desc.width ||
        a.desc.height != b.desc.height) {
        return false;
    }
    const auto& info = pixelFormatInfo(a.desc.format);
    if (info.compressed) {
        return a.size_bytes == b.size_bytes && std::memcmp(a.data, b.data, a.size_bytes) == 0;
    }
    const size_t row_bytes = static_cast<size_t>(a.desc.width) * info.bits_per_pixel / 8;
    const int rows = a.desc.format == PixelFormat::kNV12 ? a.desc.height * 3 / 2 : a.desc.height;
    for (int y = 0; y < rows; ++y) {
        if (std::memcmp(a.row<uint8_t>(y), b.row<uint8_t>(y),
                        a.desc.format == PixelFormat::kNV12 ? static_cast<size_t>(a.desc.width)
                                                            : row_bytes) != 0) {
            return false;
        }
    }
    return true;
}

}  // namespace mixray
