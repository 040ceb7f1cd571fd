// Rendering of the pattern streams: integer arithmetic only, so every platform gets the same bits.
#include "mixray/pattern/pattern_image.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cstring>

namespace mixray::pattern {
namespace {

constexpr std::array<std::string_view, kPatternStreamCount> kNames = {"color", "depth", "ir",
                                                                      "mono"};

// A well-mixed 32-bit hash of a pixel position and frame, for holes and speckle.
uint32_t hash3(uint32_t x, uint32_t y, uint32_t z) {
    uint32_t h =
        x * 0x9E3779B1u ^ (y + 0x7F4A7C15u) * 0x85EBCA77u ^ (z + 0x165667B1u) * 0xC2B2AE3Du;
    h ^= h >> 16;
    h *= 0x7FEB352Du;
    h ^= h >> 15;
    h *= 0x846CA68Bu;
    h ^= h >> 16;
    return h;
}

// Rows are built from per-column tables on the stack (widths are at most kMaxWidth): no
// division per pixel and no heap allocation per frame.
constexpr int kMaxWidth = kMaxPatternSide;

void renderColor(uint64_t seq, const MutableImageView& out) {
    const int w = std::min(out.desc.width, kMaxWidth);
    const int h = out.desc.height;
    const auto s = static_cast<uint32_t>(seq);
    const int cell_x = std::max(4, w / 16);
    const int cell_y = std::max(4, h / 12);
    std::array<uint8_t, kMaxWidth> red;
    std::array<uint8_t, kMaxWidth> column_parity;
    for (int x = 0; x < w; ++x) {
        red[x] = static_cast<uint8_t>(static_cast<uint32_t>(x * 255 / w) + s * 3);
        column_parity[x] = static_cast<uint8_t>(
            ((static_cast<uint32_t>(x) + s * 2) / static_cast<uint32_t>(cell_x)) & 1u);
    }
    for (int y = 0; y < h; ++y) {
        uint8_t* row = out.row<uint8_t>(y);
        const auto g = static_cast<uint8_t>(static_cast<uint32_t>(y * 255 / h) + s * 5);
        const auto row_parity = static_cast<uint8_t>((y / cell_y) & 1);
        for (int x = 0; x < w; ++x) {
            row[3 * x + 0] = red[x];
            row[3 * x + 1] = g;
            row[3 * x + 2] = (column_parity[x] ^ row_parity) ? 35 : 220;
        }
    }
}

void renderMono(uint64_t seq, const MutableImageView& out) {
    const int w = std::min(out.desc.width, kMaxWidth);
    const int h = out.desc.height;
    const auto s = static_cast<uint32_t>(seq);
    const auto cell = static_cast<uint32_t>(std::max(4, w / 16));
    std::array<uint8_t, kMaxWidth> dark;   // value where the square is dark
    std::array<uint8_t, kMaxWidth> light;  // and where it is light
    std::array<uint8_t, kMaxWidth> column_parity;
    for (int x = 0; x < w; ++x) {
        const auto shade = static_cast<uint32_t>(x * 24 / w);
        dark[x] = static_cast<uint8_t>(20 + shade);
        light[x] = static_cast<uint8_t>(200 + shade);
        column_parity[x] = static_cast<uint8_t>(((static_cast<uint32_t>(x) + s * 3) / cell) & 1u);
    }
    for (int y = 0; y < h; ++y) {
        uint8_t* row = out.row<uint8_t>(y);
        const auto row_parity = static_cast<uint8_t>(((static_cast<uint32_t>(y) + s) / cell) & 1u);
        for (int x = 0; x < w; ++x)
            row[x] = (column_parity[x] ^ row_parity) ? light[x] : dark[x];
    }
}

// A wall 1.8–2.5 m away, tilted in x and y, and a box 1.2 m away sliding left to right. Like a
// structured-light sensor there is no depth in the box's shadow (a band left of it), along the
// right border and at scattered pixels.
void renderDepth(uint64_t seq, const MutableImageView& out) {
    const int w = std::min(out.desc.width, kMaxWidth);
    const int h = out.desc.height;
    const auto s = static_cast<uint32_t>(seq);
    const int travel = std::max(1, w / 2);
    const int box_cx = w / 4 + static_cast<int>((seq * 4) % static_cast<uint64_t>(travel));
    const int box_cy = h / 2 + h / 8;
    const int box_hw = std::max(2, w / 8);
    const int box_hh = std::max(2, h / 6);
    const int shadow = std::max(1, w / 100 + 2);
    const int border = std::max(1, w / 80);
    // The wall's and the box rows' depth for each column; 0 where there is none.
    std::array<uint16_t, kMaxWidth> wall;
    std::array<uint16_t, kMaxWidth> box_row;
    for (int x = 0; x < w; ++x) {
        const int wall_mm = 2000 + (x - w / 2) * 400 / w;
        int box_mm = wall_mm;
        if (x >= box_cx - box_hw && x < box_cx + box_hw) {
            box_mm = 1200 + (x - box_cx) * 100 / w;
        } else if (x >= box_cx - box_hw - shadow && x < box_cx - box_hw) {
            box_mm = 0;
        }
        const bool edge = x >= w - border;
        wall[x] = static_cast<uint16_t>(edge ? 0 : wall_mm);
        box_row[x] = static_cast<uint16_t>(edge ? 0 : box_mm);
    }
    for (int y = 0; y < h; ++y) {
        auto* row = out.row<uint16_t>(y);
        const bool box_rows = y >= box_cy - box_hh && y < box_cy + box_hh;
        const std::array<uint16_t, kMaxWidth>& base = box_rows ? box_row : wall;
        const int tilt = y * 300 / h;
        for (int x = 0; x < w; ++x) {
            const int d = base[x];
            const bool box = box_rows && d != 0 && d < 1500;
            const bool hole =
                hash3(static_cast<uint32_t>(x), static_cast<uint32_t>(y), s) % 211 == 0;
            row[x] = static_cast<uint16_t>(d == 0 || hole ? 0 : (box ? d : d + tilt));
        }
    }
}

void renderInfrared(uint64_t seq, const MutableImageView& out) {
    const int w = out.desc.width;
    const int h = out.desc.height;
    const auto level = static_cast<uint32_t>((seq * 7) & 255);
    for (int y = 0; y < h; ++y) {
        auto* row = out.row<uint16_t>(y);
        for (int x = 0; x < w; ++x) {
            uint32_t v =
                300 + (hash3(static_cast<uint32_t>(x), static_cast<uint32_t>(y), 0) & 1023u);
            if (x % 8 == 4 && y % 8 == 4)
                v += 2000;  // projector dots
            row[x] = static_cast<uint16_t>(v + level);
        }
    }
}

}  // namespace

std::string_view toString(PatternStream stream) {
    const auto index = static_cast<size_t>(stream);
    return index < kNames.size() ? kNames[index] : "unknown";
}

std::optional<PatternStream> patternStreamFromString(std::string_view name) {
    for (size_t i = 0; i < kNames.size(); ++i) {
        if (kNames[i] == name)
            return static_cast<PatternStream>(i);
    }
    return std::nullopt;
}

PixelFormat formatOf(PatternStream stream) {
    switch (stream) {
        case PatternStream::kColor:
            return PixelFormat::kRGB8;
        case PatternStream::kDepth:
            return PixelFormat::kDepth16;
        case PatternStream::kInfrared:
            return PixelFormat::kIR16;
        case PatternStream::kMono:
            return PixelFormat::kMono8;
    }
    return PixelFormat::kUnknown;
}

StreamKind kindOf(PatternStream stream) {
    switch (stream) {
        case PatternStream::kColor:
            return StreamKind::kColor;
        case PatternStream::kDepth:
            return StreamKind::kDepth;
        case PatternStream::kInfrared:
            return StreamKind::kInfrared;
        case PatternStream::kMono:
            return StreamKind::kMono;
    }
    return StreamKind::kData;
}

// Depth images carry each stamp byte as one pixel of kDepthStampBaseMm + byte millimetres:
// plausible depths (1.000 to 1.255 m) that every depth format and tool can hold, where raw
// bytes would read as depths up to 65.5 m (beyond TUM's 16-bit 0.2 mm units, for one).
constexpr uint16_t kDepthStampBaseMm = 1000;

void stampSequence(uint64_t sequence, const MutableImageView& out) {
    std::array<uint8_t, kSequenceBytes> bytes{};
    for (size_t i = 0; i < 8; ++i) {
        bytes[i] = static_cast<uint8_t>(sequence >> (8 * i));
        bytes[8 + i] = static_cast<uint8_t>(~bytes[i]);
    }
    if (out.desc.format == PixelFormat::kDepth16) {
        assert(out.data && out.capacity_bytes >= kSequenceBytes * sizeof(uint16_t));
        uint16_t* row = out.row<uint16_t>(0);
        for (size_t i = 0; i < bytes.size(); ++i) {
            row[i] = static_cast<uint16_t>(kDepthStampBaseMm + bytes[i]);
        }
        return;
    }
    assert(out.data && out.capacity_bytes >= kSequenceBytes);
    std::memcpy(out.data, bytes.data(), bytes.size());
}

std::optional<uint64_t> readSequence(const ImageView& image) {
    const bool depth = image.desc.format == PixelFormat::kDepth16;
    const size_t bytes_needed = depth ? kSequenceBytes * sizeof(uint16_t) : kSequenceBytes;
    if (!image.data || image.size_bytes < bytes_needed ||
        static_cast<size_t>(image.desc.stride_bytes) < bytes_needed) {
        return std::nullopt;
    }
    std::array<uint8_t, kSequenceBytes> bytes{};
    for (size_t i = 0; i < bytes.size(); ++i) {
        if (depth) {
            const uint16_t v = image.row<uint16_t>(0)[i];
            if (v < kDepthStampBaseMm || v > kDepthStampBaseMm + 255)
                return std::nullopt;
            bytes[i] = static_cast<uint8_t>(v - kDepthStampBaseMm);
        } else {
            bytes[i] = image.data[i];
        }
    }
    uint64_t sequence = 0;
    for (size_t i = 0; i < 8; ++i) {
        if (static_cast<uint8_t>(~bytes[i]) != bytes[8 + i])
            return std::nullopt;
        sequence |= static_cast<uint64_t>(bytes[i]) << (8 * i);
    }
    return sequence;
}

void renderPattern(PatternStream stream, uint64_t sequence, const MutableImageView& out) {
    assert(out.desc.format == formatOf(stream));
    assert(out.desc.width >= kMinPatternWidth && out.desc.height >= kMinPatternHeight &&
           out.desc.width <= kMaxPatternSide);
    switch (stream) {
        case PatternStream::kColor:
            renderColor(sequence, out);
            break;
        case PatternStream::kDepth:
            renderDepth(sequence, out);
            break;
        case PatternStream::kInfrared:
            renderInfrared(sequence, out);
            break;
        case PatternStream::kMono:
            renderMono(sequence, out);
            break;
    }
    stampSequence(sequence, out);
}

Image renderPattern(PatternStream stream, int width, int height, uint64_t sequence) {
    Image image(ImageDesc::packed(formatOf(stream), width, height));
    renderPattern(stream, sequence, image.mutableView());
    return image;
}

}  // namespace mixray::pattern
