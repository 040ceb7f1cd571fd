// Depth unit tags and exact integer rescaling of 16-bit depth images.
#include "mixray/replay/depth_units.h"

#include <charconv>
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

}  // namespace mixray::replay
