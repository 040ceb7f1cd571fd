// Depth units of recorded streams: files keep their source's units exactly, the graph sees mm.
#pragma once

#include <cstdint>
#include <string_view>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/graph/stream.h"

namespace mixray::replay {

// Stream tag naming how many depth units make one metre. mixray's own depth is millimetres
// (1000, also when the tag is absent); a TUM RGB-D folder stores 5000 units per metre (0.2 mm),
// and converting those to mm would lose information, so recordings made from TUM folders keep
// the raw PNG values and carry this tag. The replay device converts such streams to mm before
// they enter a graph unless asked for the recorded units.
inline constexpr const char* kDepthScaleTag = "depth_scale_per_m";
inline constexpr int kMillimetresPerMetre = 1000;
inline constexpr int kTumDepthPerMetre = 5000;

// The stream's depth units per metre: its kDepthScaleTag, else 1000. kCorruptData when the
// tag is not a positive integer.
Result<int> depthScalePerMetre(const StreamInfo& stream);

// Rescales a 16-bit depth image from `from_per_m` to `to_per_m` units per metre, rounding to
// nearest. 0 stays 0 (no measurement) and a measurement never becomes 0: it is at least 1
// unit. Exact when to_per_m is a multiple of from_per_m, and for values that are multiples of
// from_per_m / to_per_m. kInvalidArgument when a value does not fit in 16 bits (the message
// gives the first such pixel) or the layouts differ. `src` and `dst` may be the same memory.
Status rescaleDepth(const ImageView& src, int from_per_m, const MutableImageView& dst,
                    int to_per_m);

// NYU Depth V2 raw depth (the dataset's d-*.pgm files): the Kinect's 11-bit disparity-like
// values, not distances. The NYU toolbox (camera_params.m, depth_rel2depth_abs.m) converts them
// with depth_m = 351.3 / (1092.5 - raw), clamping at 10 m. 2047 is the Kinect's "no reading".
inline constexpr double kNyuDepthParam1 = 351.3;
inline constexpr double kNyuDepthParam2 = 1092.5;
inline constexpr int kNyuRawMax = 2047;
inline constexpr double kNyuMaxDepthM = 10.0;

// One NYU raw value to mm, rounded to nearest: 0 for 0, for values the formula makes negative
// or infinite (raw >= 1092.5, which includes 2047) and for depths beyond 10 m (where the
// toolbox clamps to 10 m, a distance nothing measured; here it is "no measurement").
uint16_t nyuRawToMm(uint16_t raw);

// Converts a decoded NYU raw depth image (16-bit, values as the PGM header's big-endian order
// gives them) to mm in place. The dataset's files hold little-endian words despite PGM's rule
// (the toolbox swaps bytes after imread), and other copies are re-encoded properly, so the
// order is decided by content, per image: when every value fits 11 bits as decoded, they are
// used as they are; when they do not but every byte-swapped value does, the bytes are swapped;
// otherwise kCorruptData naming `where` (not Kinect raw depth in either order).
Status convertNyuRawToMm(const MutableImageView& image, std::string_view where);

// SUN RGB-D depth PNGs hold millimetres rotated left by 3 bits in 16 bits (its toolbox's
// read3dPoints.m: depth = bitor(bitshift(v, -3), bitshift(v, 16 - 3))).
inline constexpr uint16_t sunDepthToMm(uint16_t v) {
    return static_cast<uint16_t>((v >> 3) | (v << 13));
}
// The share of non-zero pixels whose low 3 bits are 0: about 1 for SUN RGB-D's rotated values
// (any depth below 8.192 m), about 1/8 for plain millimetres. 1 for an image without depth.
double sunRotatedShare(const ImageView& image);
// The least sunRotatedShare() a SUN RGB-D depth image must have (content check of the reader).
inline constexpr double kSunMinRotatedShare = 0.95;
// Rotates a decoded SUN RGB-D depth image back to mm in place.
void convertSunDepthToMm(const MutableImageView& image);

}  // namespace mixray::replay
