// JPEG decoding through libjpeg's C API, its longjmp error handling kept inside one function.
#include "mixray/v4l2/mjpeg.h"

#include <csetjmp>
#include <cstdio>
#include <string>

// clang-format off
#include <jpeglib.h>
// clang-format on

namespace mixray::v4l2 {
namespace {

struct ErrorManager {
    jpeg_error_mgr base;
    std::jmp_buf jump;
    char message[JMSG_LENGTH_MAX];
};

// libjpeg's default error_exit calls exit(): jump back to the caller instead.
[[noreturn]] void onError(j_common_ptr cinfo) {
    auto* err = reinterpret_cast<ErrorManager*>(cinfo->err);
    (*cinfo->err->format_message)(cinfo, err->message);
    std::longjmp(err->jump, 1);
}

// Warnings (corrupt data that libjpeg skips over) would otherwise go to stderr per frame.
void onMessage(j_common_ptr /*cinfo*/, int /*level*/) {}

// Only trivially destructible objects live in this frame, so longjmp out of libjpeg skips no
// destructor. Returns false with `err.message` set when libjpeg failed.
bool decode(jpeg_decompress_struct& cinfo, ErrorManager& err, const uint8_t* data, size_t size,
            bool header_only, const MutableImageView* out) {
    cinfo.err = jpeg_std_error(&err.base);
    err.base.error_exit = onError;
    err.base.emit_message = onMessage;
    err.message[0] = '\0';
    if (setjmp(err.jump)) {
        jpeg_destroy_decompress(&cinfo);
        return false;
    }
    jpeg_create_decompress(&cinfo);
    jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
    jpeg_read_header(&cinfo, TRUE);
    if (header_only || !out) {
        jpeg_destroy_decompress(&cinfo);
        return true;
    }
    if (static_cast<int>(cinfo.image_width) != out->desc.width ||
        static_cast<int>(cinfo.image_height) != out->desc.height) {
        std::snprintf(err.message, sizeof(err.message), "JPEG is %ux%u, the frame %dx%d",
                      cinfo.image_width, cinfo.image_height, out->desc.width, out->desc.height);
        jpeg_destroy_decompress(&cinfo);
        return false;
    }
    cinfo.out_color_space = JCS_RGB;
    jpeg_start_decompress(&cinfo);
    while (cinfo.output_scanline < cinfo.output_height) {
        JSAMPROW row = out->row<JSAMPLE>(static_cast<int>(cinfo.output_scanline));
        jpeg_read_scanlines(&cinfo, &row, 1);
    }
    jpeg_finish_decompress(&cinfo);
    jpeg_destroy_decompress(&cinfo);
    return true;
}

}  // namespace

Result<ImageDesc> mjpegSize(const uint8_t* data, size_t size) {
    if (!data || size < 4)
        return {ErrorCode::kCorruptData, "MJPEG frame of " + std::to_string(size) + " bytes"};
    jpeg_decompress_struct cinfo{};
    ErrorManager err{};
    if (!decode(cinfo, err, data, size, true, nullptr))
        return {ErrorCode::kCorruptData, std::string("MJPEG frame: ") + err.message};
    return ImageDesc::packed(PixelFormat::kRGB8, static_cast<int>(cinfo.image_width),
                             static_cast<int>(cinfo.image_height));
}

Status decodeMjpegToRgb(const uint8_t* data, size_t size, const MutableImageView& out) {
    if (out.desc.format != PixelFormat::kRGB8 || !out.data ||
        out.desc.stride_bytes < out.desc.width * 3 ||
        out.capacity_bytes < static_cast<size_t>(out.desc.stride_bytes) * out.desc.height) {
        return {ErrorCode::kInvalidArgument, "MJPEG decoding needs an rgb8 image that holds it"};
    }
    if (!data || size < 4)
        return {ErrorCode::kCorruptData, "MJPEG frame of " + std::to_string(size) + " bytes"};
    jpeg_decompress_struct cinfo{};
    ErrorManager err{};
    if (!decode(cinfo, err, data, size, false, &out))
        return {ErrorCode::kCorruptData, std::string("MJPEG frame: ") + err.message};
    return Status::ok();
}

}  // namespace mixray::v4l2
