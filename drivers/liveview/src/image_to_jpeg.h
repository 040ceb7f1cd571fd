// Turns one frame of any image format into the JPEG a tile shows (false colour for depth,
// normalised grey for 16-bit images, MJPEG passed through).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray::liveview {

// True for the formats a tile can show; binary records and unknown formats are no tile.
bool isTileFormat(PixelFormat format);

// How a tile's image is made.
struct TileRenderOptions {
    int max_width = 640;  // images wider than this are subsampled by an integer factor
    int quality = 80;     // JPEG quality 1..100
    double depth_min_m = 0.3;
    double depth_max_m = 5.0;
    bool depth_auto_range = false;
};

// One encoded tile image and what the page needs to label it.
struct EncodedTile {
    std::string jpeg;
    int width = 0;  // of the JPEG
    int height = 0;
    // The values black..white (grey) or the ends of the colour map (depth, in metres) span;
    // both 0 when the image is shown as it is.
    double range_lo = 0;
    double range_hi = 0;
};

// Width and height of the JPEG encode() makes from an image of this size (the page scales
// overlays from the stream's size to it).
void tileSize(const ImageDesc& desc, int max_width, int* width, int* height);

// The turbo colour map (Google's polynomial fit), t in [0, 1] -> RGB.
void turboColor(double t, uint8_t rgb[3]);

// Converts and encodes frames; keeps its scratch buffers and libturbojpeg handle between frames.
// Thread-bound.
class JpegEncoder {
public:
    JpegEncoder();
    ~JpegEncoder();
    JpegEncoder(const JpegEncoder&) = delete;
    JpegEncoder& operator=(const JpegEncoder&) = delete;

    // kUnsupported for a format that is no tile; kCorruptData when the payload is smaller than
    // the layout says or an MJPEG frame is not a JPEG; kInternal when libturbojpeg fails.
    Status encode(const ImageView& image, const TileRenderOptions& options, EncodedTile* out);

    // The largest JPEG libturbojpeg can make of a tile of this size.
    static size_t maxJpegBytes(int width, int height);

private:
    void* tj_ = nullptr;
    std::vector<uint8_t> pixels_;   // the converted, subsampled 8-bit image
    std::vector<uint16_t> values_;  // a 16-bit grey frame's samples, for its percentiles
};

}  // namespace mixray::liveview
