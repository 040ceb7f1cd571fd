// Frame -> tile JPEG: colour conversion, false colour, normalisation, subsampling, libturbojpeg.
#include "image_to_jpeg.h"

#include <turbojpeg.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

namespace mixray::liveview {
namespace {

uint8_t clamp8(int v) {
    return static_cast<uint8_t>(std::clamp(v, 0, 255));
}

// BT.601 limited range, as UVC cameras and the Azure Kinect deliver it.
void yuvToRgb(int y, int u, int v, uint8_t* rgb) {
    const int c = y - 16;
    const int d = u - 128;
    const int e = v - 128;
    rgb[0] = clamp8((298 * c + 409 * e + 128) >> 8);
    rgb[1] = clamp8((298 * c - 100 * d - 208 * e + 128) >> 8);
    rgb[2] = clamp8((298 * c + 516 * d + 128) >> 8);
}

bool isBayer(PixelFormat f) {
    return f == PixelFormat::kBayerRGGB8 || f == PixelFormat::kBayerGRBG8 ||
           f == PixelFormat::kBayerGBRG8 || f == PixelFormat::kBayerBGGR8;
}

// Bytes the payload must hold for `desc` with its stride (the last row need not be padded).
size_t neededBytes(const ImageDesc& desc) {
    const size_t rows = desc.format == PixelFormat::kNV12 ? static_cast<size_t>(desc.height) * 3 / 2
                                                          : static_cast<size_t>(desc.height);
    const size_t row_bytes =
        desc.format == PixelFormat::kNV12
            ? static_cast<size_t>(desc.width)
            : static_cast<size_t>(desc.width) * pixelFormatInfo(desc.format).bits_per_pixel / 8;
    return rows == 0 ? 0 : (rows - 1) * static_cast<size_t>(desc.stride_bytes) + row_bytes;
}

const std::array<std::array<uint8_t, 3>, 256>& turboLut() {
    static const auto lut = [] {
        std::array<std::array<uint8_t, 3>, 256> t{};
        for (int i = 0; i < 256; ++i)
            turboColor(i / 255.0, t[i].data());
        return t;
    }();
    return lut;
}

}  // namespace

bool isTileFormat(PixelFormat format) {
    switch (format) {
        case PixelFormat::kMono8:
        case PixelFormat::kMono16:
        case PixelFormat::kRGB8:
        case PixelFormat::kBGR8:
        case PixelFormat::kBayerRGGB8:
        case PixelFormat::kBayerGRBG8:
        case PixelFormat::kBayerGBRG8:
        case PixelFormat::kBayerBGGR8:
        case PixelFormat::kYUYV:
        case PixelFormat::kNV12:
        case PixelFormat::kMJPEG:
        case PixelFormat::kDepth16:
        case PixelFormat::kIR16:
            return true;
        case PixelFormat::kUnknown:
        case PixelFormat::kBinary:
            return false;
    }
    return false;
}

void turboColor(double t, uint8_t rgb[3]) {
    // Anton Mikhailov's turbo map as Ruofei Du's degree-5 polynomial fit.
    const double x = std::clamp(t, 0.0, 1.0);
    const double x2 = x * x, x3 = x2 * x, x4 = x3 * x, x5 = x4 * x;
    const double r = 0.13572138 + 4.61539260 * x - 42.66032258 * x2 + 132.13108234 * x3 -
                     152.94239396 * x4 + 59.28637943 * x5;
    const double g = 0.09140261 + 2.19418839 * x + 4.84296658 * x2 - 14.18503333 * x3 +
                     4.27729857 * x4 + 2.82956604 * x5;
    const double b = 0.10667330 + 12.64194608 * x - 60.58204836 * x2 + 110.36276771 * x3 -
                     89.90310912 * x4 + 27.34824973 * x5;
    rgb[0] = clamp8(static_cast<int>(std::lround(std::clamp(r, 0.0, 1.0) * 255)));
    rgb[1] = clamp8(static_cast<int>(std::lround(std::clamp(g, 0.0, 1.0) * 255)));
    rgb[2] = clamp8(static_cast<int>(std::lround(std::clamp(b, 0.0, 1.0) * 255)));
}

namespace {
int subsampleFactor(const ImageDesc& desc, int max_width) {
    const int w = isBayer(desc.format) ? desc.width / 2 : desc.width;  // one RGB pixel per cell
    return std::max(1, (w + max_width - 1) / std::max(1, max_width));
}
}  // namespace

void tileSize(const ImageDesc& desc, int max_width, int* width, int* height) {
    const int bayer = isBayer(desc.format) ? 2 : 1;
    const int w = desc.width / bayer;
    const int h = desc.height / bayer;
    const int factor = subsampleFactor(desc, max_width);
    *width = std::max(1, w / factor);
    *height = std::max(1, h / factor);
    if (desc.format == PixelFormat::kMJPEG) {  // passed through as it is
        *width = desc.width;
        *height = desc.height;
    }
}

size_t JpegEncoder::maxJpegBytes(int width, int height) {
    return static_cast<size_t>(tjBufSize(std::max(width, 1), std::max(height, 1), TJSAMP_444));
}

JpegEncoder::JpegEncoder() : tj_(tjInitCompress()) {}

JpegEncoder::~JpegEncoder() {
    if (tj_ != nullptr)
        tjDestroy(tj_);
}

Status JpegEncoder::encode(const ImageView& image, const TileRenderOptions& options,
                           EncodedTile* out) {
    const ImageDesc& desc = image.desc;
    if (!isTileFormat(desc.format)) {
        return {ErrorCode::kUnsupported,
                "a " + std::string(toString(desc.format)) + " frame cannot be shown as an image"};
    }
    if (desc.width <= 0 || desc.height <= 0 || image.data == nullptr) {
        return {ErrorCode::kCorruptData, "empty image"};
    }
    out->range_lo = out->range_hi = 0;
    if (desc.format == PixelFormat::kMJPEG) {
        if (image.size_bytes < 4 || image.data[0] != 0xFF || image.data[1] != 0xD8) {
            return {ErrorCode::kCorruptData, "the MJPEG frame does not start with a JPEG marker"};
        }
        out->jpeg.assign(reinterpret_cast<const char*>(image.data), image.size_bytes);
        out->width = desc.width;
        out->height = desc.height;
        return Status::ok();
    }
    if (desc.stride_bytes <= 0 || image.size_bytes < neededBytes(desc)) {
        return {ErrorCode::kCorruptData,
                "a " + std::string(toString(desc.format)) + " frame of " +
                    std::to_string(desc.width) + "x" + std::to_string(desc.height) + " holds " +
                    std::to_string(image.size_bytes) + " bytes, fewer than its layout needs"};
    }
    int w = 0;
    int h = 0;
    tileSize(desc, options.max_width, &w, &h);
    const int bayer = isBayer(desc.format) ? 2 : 1;
    const int factor = subsampleFactor(desc, options.max_width);
    const bool grey = desc.format == PixelFormat::kMono8 || desc.format == PixelFormat::kMono16 ||
                      desc.format == PixelFormat::kIR16;
    const int channels = grey ? 1 : 3;
    pixels_.resize(static_cast<size_t>(w) * h * channels);
    uint8_t* dst = pixels_.data();

    if (desc.format == PixelFormat::kMono16 || desc.format == PixelFormat::kIR16) {
        // Normalised between the frame's own 1st and 99th percentiles, so a dim infrared image
        // is visible and a few saturated speckles do not turn the rest black.
        // The percentiles from about 16k samples on a grid: as good for a display, and a
        // fraction of the cost of partitioning every pixel.
        values_.clear();
        const int step =
            std::max(1, static_cast<int>(std::sqrt(static_cast<double>(w) * h / 16384)));
        for (int y = 0; y < h; y += step) {
            const uint16_t* row = image.row<uint16_t>(y * factor);
            for (int x = 0; x < w; x += step)
                values_.push_back(row[x * factor]);
        }
        const size_t lo_at = values_.size() / 100;
        const size_t hi_at = values_.size() - 1 - values_.size() / 100;
        std::nth_element(values_.begin(), values_.begin() + static_cast<std::ptrdiff_t>(lo_at),
                         values_.end());
        const uint16_t lo = values_[lo_at];
        std::nth_element(values_.begin(), values_.begin() + static_cast<std::ptrdiff_t>(hi_at),
                         values_.end());
        const uint16_t hi = values_[hi_at];
        const double scale = hi > lo ? 255.0 / (hi - lo) : 0.0;
        for (int y = 0; y < h; ++y) {
            const uint16_t* row = image.row<uint16_t>(y * factor);
            for (int x = 0; x < w; ++x)
                *dst++ = clamp8(static_cast<int>((row[x * factor] - lo) * scale));
        }
        out->range_lo = lo;
        out->range_hi = hi;
    } else if (desc.format == PixelFormat::kDepth16) {
        double lo_mm = options.depth_min_m * 1000.0;
        double hi_mm = options.depth_max_m * 1000.0;
        if (options.depth_auto_range) {
            uint16_t mn = std::numeric_limits<uint16_t>::max();
            uint16_t mx = 0;
            for (int y = 0; y < h; ++y) {
                const uint16_t* row = image.row<uint16_t>(y * factor);
                for (int x = 0; x < w; ++x) {
                    const uint16_t d = row[x * factor];
                    if (d == 0)
                        continue;
                    mn = std::min(mn, d);
                    mx = std::max(mx, d);
                }
            }
            if (mx > mn) {
                lo_mm = mn;
                hi_mm = mx;
            }
        }
        const auto& lut = turboLut();
        const double scale = 255.0 / std::max(1.0, hi_mm - lo_mm);
        for (int y = 0; y < h; ++y) {
            const uint16_t* row = image.row<uint16_t>(y * factor);
            for (int x = 0; x < w; ++x, dst += 3) {
                const uint16_t d = row[x * factor];
                if (d == 0) {  // no measurement: black, outside the colour map
                    dst[0] = dst[1] = dst[2] = 0;
                    continue;
                }
                const auto& c = lut[clamp8(static_cast<int>((d - lo_mm) * scale))];
                std::memcpy(dst, c.data(), 3);
            }
        }
        out->range_lo = lo_mm / 1000.0;
        out->range_hi = hi_mm / 1000.0;
    } else {
        for (int y = 0; y < h; ++y) {
            const int sy = y * factor * bayer;
            const uint8_t* row = image.row<uint8_t>(sy);
            for (int x = 0; x < w; ++x) {
                const int sx = x * factor * bayer;
                switch (desc.format) {
                    case PixelFormat::kMono8:
                        *dst++ = row[sx];
                        break;
                    case PixelFormat::kRGB8:
                        std::memcpy(dst, row + 3 * sx, 3);
                        dst += 3;
                        break;
                    case PixelFormat::kBGR8:
                        dst[0] = row[3 * sx + 2];
                        dst[1] = row[3 * sx + 1];
                        dst[2] = row[3 * sx];
                        dst += 3;
                        break;
                    case PixelFormat::kYUYV: {
                        const uint8_t* pair = row + 4 * (sx / 2);
                        yuvToRgb(pair[(sx & 1) * 2], pair[1], pair[3], dst);
                        dst += 3;
                        break;
                    }
                    case PixelFormat::kNV12: {
                        const uint8_t* uv = image.data +
                                            static_cast<size_t>(desc.height) * desc.stride_bytes +
                                            static_cast<size_t>(sy / 2) * desc.stride_bytes;
                        yuvToRgb(row[sx], uv[sx & ~1], uv[(sx & ~1) + 1], dst);
                        dst += 3;
                        break;
                    }
                    default: {  // Bayer: one RGB pixel from each 2x2 cell
                        const uint8_t* next = image.row<uint8_t>(sy + 1);
                        const uint8_t cell[4] = {row[sx], row[sx + 1], next[sx], next[sx + 1]};
                        // Index of R and B in the cell; the other two are green.
                        int r = 0;
                        if (desc.format == PixelFormat::kBayerGRBG8)
                            r = 1;
                        if (desc.format == PixelFormat::kBayerGBRG8)
                            r = 2;
                        if (desc.format == PixelFormat::kBayerBGGR8)
                            r = 3;
                        const int b = 3 - r;
                        dst[0] = cell[r];
                        // Red and blue sit on one diagonal, the greens on the other.
                        dst[1] = static_cast<uint8_t>((r == 0 || r == 3) ? (cell[1] + cell[2]) / 2
                                                                         : (cell[0] + cell[3]) / 2);
                        dst[2] = cell[b];
                        dst += 3;
                        break;
                    }
                }
            }
        }
    }

    if (tj_ == nullptr)
        return {ErrorCode::kInternal, "libturbojpeg did not initialise"};
    unsigned char* jpeg = nullptr;
    unsigned long jpeg_bytes = 0;  // NOLINT(google-runtime-int): libturbojpeg's type
    const int rc = tjCompress2(tj_, pixels_.data(), w, w * channels, h, grey ? TJPF_GRAY : TJPF_RGB,
                               &jpeg, &jpeg_bytes, grey ? TJSAMP_GRAY : TJSAMP_420,
                               std::clamp(options.quality, 1, 100), TJFLAG_FASTDCT);
    if (rc != 0) {
        if (jpeg != nullptr)
            tjFree(jpeg);
        return {ErrorCode::kInternal, std::string("libturbojpeg: ") + tjGetErrorStr2(tj_)};
    }
    out->jpeg.assign(reinterpret_cast<const char*>(jpeg), jpeg_bytes);
    tjFree(jpeg);
    out->width = w;
    out->height = h;
    return Status::ok();
}

}  // namespace mixray::liveview
