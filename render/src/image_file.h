// Decoding image files into linear-light float RGB (OpenCV for PNG/JPEG/TIFF/HDR, OpenEXR for
// EXR), shared by Texture::load and EnvironmentMap::load.
#pragma once

#include <filesystem>
#include <vector>

#include "mixray/graph/result.h"
#include "mixray/render/scene.h"

namespace mixray::render::detail {

// A decoded image: row-major RGB texels in linear light, top row first. Plain value.
struct LinearImage {
    int width = 0;
    int height = 0;
    std::vector<Rgb> texels;
};

// sRGB transfer function decoded to linear (IEC 61966-2-1), for 8- and 16-bit images.
float srgbToLinear(float encoded);

// Reads `path`: 8/16-bit PNG/JPEG/TIFF are taken as sRGB-encoded and decoded to linear; float
// images (.hdr, float TIFF) and .exr are kept as they are. Grey images are replicated into R, G
// and B; alpha is dropped. kNotFound for a missing file, kCorruptData naming the file when it
// cannot be decoded, kUnsupported for sample types it does not handle. Reentrant.
Result<LinearImage> readLinearImage(const std::filesystem::path& path);

// Reads an OpenEXR file (any compression, scanline or tiled; tiled multi-resolution files give
// their full-resolution level) into linear RGB. R, G, B channels, or Y alone for grey images.
Result<LinearImage> readExr(const std::filesystem::path& path);

}  // namespace mixray::render::detail
