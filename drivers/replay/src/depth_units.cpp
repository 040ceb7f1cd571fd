// Depth unit tags and exact integer rescaling of 16-bit depth images.
#include "mixray/replay/depth_units.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <string>

namespace mixray::replay {

Result<int> depthScalePerMetre(const StreamInfo& stream) {
    auto it = stream.tags.find(kDepthScaleTag);
    if (it == stream.tags.end())
        return kMillimetresPerMetre;
    const std::string& text = it->second;
    int value = 0;
    auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || end != text.data() + text.size() || value <= 0) {
        return {ErrorCode::kCorruptData, "stream '" + stream.name + "': tag " + kDepthScaleTag +
                                             "='" + text + "' is not a positive integer"};
    }
    return value;
}

Status rescaleDepth(const ImageView& src, int from_per_m, const MutableImageView& dst,
                    int to_per_m) {
    if (from_per_m <= 0 || to_per_m <= 0) {
        return {ErrorCode::kInvalidArgument, "depth scales must be positive"};
    }
    const auto& src_info = pixelFormatInfo(src.desc.format);
    const auto& dst_info = pixelFormatInfo(dst.desc.format);
    if (src_info.bits_per_pixel != 16 || dst_info.bits_per_pixel != 16 || src_info.channels != 1 ||
        dst_info.channels != 1 || src.desc.width != dst.desc.width ||
        src.desc.height != dst.desc.height) {
        return {ErrorCode::kInvalidArgument,
                "rescaleDepth: source and destination must be "
                "16-bit single-channel images of the same size"};
    }
    const auto from = static_cast<uint64_t>(from_per_m);
    const auto to = static_cast<uint64_t>(to_per_m);
    for (int y = 0; y < src.desc.height; ++y) {
        const uint16_t* in = src.row<uint16_t>(y);
        uint16_t* out = dst.row<uint16_t>(y);
        for (int x = 0; x < src.desc.width; ++x) {
            const uint64_t v = in[x];
            if (v == 0) {
                out[x] = 0;
                continue;
            }
            uint64_t scaled = (v * to + from / 2) / from;
            // Rounding must not turn a measurement into "no measurement".
            if (scaled == 0)
                scaled = 1;
            if (scaled > UINT16_MAX) {
                return {ErrorCode::kInvalidArgument,
                        "depth " + std::to_string(v) + " at pixel (" + std::to_string(x) + "," +
                            std::to_string(y) + ") is " + std::to_string(scaled) + " in " +
                            std::to_string(to_per_m) + " units per metre, beyond 16 bits"};
            }
            out[x] = static_cast<uint16_t>(scaled);
        }
    }
    return Status::ok();
}

uint16_t nyuRawToMm(uint16_t raw) {
    if (raw == 0 || raw >= kNyuDepthParam2)
        return 0;
    const double metres = kNyuDepthParam1 / (kNyuDepthParam2 - raw);
    if (metres > kNyuMaxDepthM)
        return 0;
    return static_cast<uint16_t>(std::lround(metres * 1000.0));
}

Status convertNyuRawToMm(const MutableImageView& image, std::string_view where) {
    if (pixelFormatInfo(image.desc.format).bits_per_pixel != 16) {
        return {ErrorCode::kInvalidArgument, std::string(where) + ": NYU raw depth must be 16-bit"};
    }
    const auto swap = [](uint16_t v) { return static_cast<uint16_t>((v >> 8) | (v << 8)); };
    uint16_t max_stored = 0, max_swapped = 0;
    for (int y = 0; y < image.desc.height; ++y) {
        const uint16_t* row = image.row<uint16_t>(y);
        for (int x = 0; x < image.desc.width; ++x) {
            max_stored = std::max(max_stored, row[x]);
            max_swapped = std::max(max_swapped, swap(row[x]));
        }
    }
    bool swapped = false;
    if (max_stored > kNyuRawMax) {
        if (max_swapped > kNyuRawMax) {
            return {ErrorCode::kCorruptData,
                    std::string(where) +
                        ": not NYU raw Kinect depth: values exceed 11 bits in "
                        "either byte order (largest " +
                        std::to_string(max_stored) + ")"};
        }
        swapped = true;
    }
    for (int y = 0; y < image.desc.height; ++y) {
        uint16_t* row = image.row<uint16_t>(y);
        for (int x = 0; x < image.desc.width; ++x)
            row[x] = nyuRawToMm(swapped ? swap(row[x]) : row[x]);
    }
    return Status::ok();
}

double sunRotatedShare(const ImageView& image) {
    uint64_t nonzero = 0, rotated = 0;
    for (int y = 0; y < image.desc.height; ++y) {
        const uint16_t* row = image.row<uint16_t>(y);
        for (int x = 0; x < image.desc.width; ++x) {
            if (row[x] == 0)
                continue;
            ++nonzero;
            rotated += (row[x] & 7u) == 0 ? 1 : 0;
        }
    }
    return nonzero == 0 ? 1.0 : static_cast<double>(rotated) / static_cast<double>(nonzero);
}

void convertSunDepthToMm(const MutableImageView& image) {
    for (int y = 0; y < image.desc.height; ++y) {
        uint16_t* row = image.row<uint16_t>(y);
        for (int x = 0; x < image.desc.width; ++x)
            row[x] = sunDepthToMm(row[x]);
    }
}

}  // namespace mixray::replay
