// The pattern devices' images: a deterministic function of (stream, sequence), for exact checks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>

#include "mixray/graph/image.h"
#include "mixray/graph/stream.h"

namespace mixray::pattern {

// The streams a pattern device can publish.
enum class PatternStream : uint8_t {
    kColor,     // rgb8: moving colour gradients over a drifting checkerboard
    kDepth,     // depth16 mm: a tilted wall and a box sliding in front of it, with holes
    kInfrared,  // ir16: a fixed speckle field with a dot grid, brightness varying over time
    kMono,      // mono8: a moving checkerboard over a horizontal gradient
};
inline constexpr size_t kPatternStreamCount = 4;

// "color", "depth", "ir", "mono".
std::string_view toString(PatternStream stream);
std::optional<PatternStream> patternStreamFromString(std::string_view name);
PixelFormat formatOf(PatternStream stream);
StreamKind kindOf(PatternStream stream);

// Smallest image a pattern stream may have: the sequence stamp needs kSequenceBytes of row 0.
inline constexpr int kMinPatternWidth = 16;
inline constexpr int kMinPatternHeight = 8;
inline constexpr int kMaxPatternSide = 16384;
// Row 0 starts with the sequence (8 bytes, little-endian) and its bitwise complement (8 more),
// so readSequence() can tell a pattern image from any other. Depth images hold each of those
// 16 bytes as one pixel of 1000 + byte millimetres, so the stamp is a plausible depth.
inline constexpr size_t kSequenceBytes = 16;

// Fills `out` with frame `sequence` of `stream`. out.desc must be the stream's format with a
// size from kMinPatternWidth x kMinPatternHeight to kMaxPatternSide square; any stride >= the
// packed one works. No heap allocation.
// The result depends on nothing else (not on the device, its clock or its options), so tests
// can regenerate a frame after recording and replay and compare bit for bit.
void renderPattern(PatternStream stream, uint64_t sequence, const MutableImageView& out);
// The same into a new packed image (tests and tools; the capture path renders into pool
// buffers).
Image renderPattern(PatternStream stream, int width, int height, uint64_t sequence);

// Writes only the sequence stamp of row 0 (for benchmarks that measure the graph, not the
// renderer). The other pixels are left as they were.
void stampSequence(uint64_t sequence, const MutableImageView& out);
// The sequence a pattern image carries; nullopt when the stamp is absent or damaged.
std::optional<uint64_t> readSequence(const ImageView& image);

}  // namespace mixray::pattern
