// MJPEG frames (one JPEG per frame, as UVC cameras send them) decoded to RGB with libjpeg-turbo.
#pragma once

#include <cstddef>
#include <cstdint>

#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray::v4l2 {

// Width and height from the JPEG's frame header; kCorruptData when it is not a JPEG.
Result<ImageDesc> mjpegSize(const uint8_t* data, size_t size);

// Decodes `size` bytes of JPEG into `out` (kRGB8, the JPEG's size; rows at out.desc's stride).
// UVC frames often omit the Huffman tables: libjpeg-turbo supplies the standard ones.
// kCorruptData for a broken stream, kInvalidArgument when `out` has another size or format.
// Reentrant; allocates only libjpeg's per-call state.
Status decodeMjpegToRgb(const uint8_t* data, size_t size, const MutableImageView& out);

}  // namespace mixray::v4l2
