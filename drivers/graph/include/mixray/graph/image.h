// Pixel formats and non-owning image views: the layout vocabulary every module shares.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace mixray {

// Memory layout of a frame's payload. Sizes in names are bytes unless a suffix says otherwise.
enum class PixelFormat : uint8_t {
    kUnknown = 0,
    kMono8,       // 8-bit grey
    kMono16,      // 16-bit grey, native endian
    kRGB8,        // 8-bit R,G,B interleaved
    kBGR8,        // 8-bit B,G,R interleaved
    kBayerRGGB8,  // raw Bayer mosaics, 8 bits per sample; the name is the top-left 2x2 order
    kBayerGRBG8,
    kBayerGBRG8,
    kBayerBGGR8,
    kYUYV,     // YUV 4:2:2 packed, Y0 U Y1 V, 2 bytes per pixel (UVC)
    kNV12,     // YUV 4:2:0, Y plane then interleaved UV plane (Azure Kinect)
    kMJPEG,    // one JPEG image per frame, compressed: size varies, stride is 0
    kDepth16,  // uint16 depth in millimetres; 0 means no measurement
    kIR16,     // uint16 infrared intensity
    kBinary,   // opaque bytes (IMU samples, poses); width is the byte count, height 1
};

// Static facts about a pixel format.
struct PixelFormatInfo {
    std::string_view name;    // stable lowercase name used in files: "rgb8", "depth16"
    uint32_t bits_per_pixel;  // average bits per pixel; 0 for compressed formats
    uint32_t channels;        // colour channels after decoding
    bool compressed;          // payload size varies frame to frame
};

const PixelFormatInfo& pixelFormatInfo(PixelFormat format);
std::string_view toString(PixelFormat format);
std::optional<PixelFormat> pixelFormatFromString(std::string_view name);

// Geometry and layout of one image. stride_bytes is the distance between rows of the first
// plane; 0 for compressed formats.
struct ImageDesc {
    PixelFormat format = PixelFormat::kUnknown;
    int width = 0;
    int height = 0;
    int stride_bytes = 0;

    // A tightly packed description (stride = width * bytes per pixel).
    static ImageDesc packed(PixelFormat format, int width, int height);

    // Bytes a buffer needs for this image; for compressed formats a generous upper bound.
    size_t bufferBytes() const;
    bool operator==(const ImageDesc&) const = default;
};

// Read-only view of an image in memory it does not own.
struct ImageView {
    ImageDesc desc;
    const uint8_t* data = nullptr;
    size_t size_bytes = 0;  // bytes of payload; for compressed formats the actual size

    template <typename T>
    const T* row(int y) const {
        return reinterpret_cast<const T*>(data + static_cast<size_t>(y) * desc.stride_bytes);
    }
};

// Writable view of an image in memory it does not own.
struct MutableImageView {
    ImageDesc desc;
    uint8_t* data = nullptr;
    size_t capacity_bytes = 0;

    template <typename T>
    T* row(int y) const {
        return reinterpret_cast<T*>(data + static_cast<size_t>(y) * desc.stride_bytes);
    }
    operator ImageView() const { return {desc, data, capacity_bytes}; }  // NOLINT
};

// An image that owns its pixels: for tests, converters and offline tools, not the capture path
// (which uses pooled frames).
class Image {
public:
    Image() = default;
    explicit Image(ImageDesc desc) : desc_(desc), bytes_(desc.bufferBytes()) {}
    // Copies `view` (for compressed formats only its size_bytes).
    static Image copyOf(const ImageView& view);

    const ImageDesc& desc() const { return desc_; }
    ImageView view() const { return {desc_, bytes_.data(), bytes_.size()}; }
    MutableImageView mutableView() { return {desc_, bytes_.data(), bytes_.size()}; }
    std::vector<uint8_t>& bytes() { return bytes_; }
    const std::vector<uint8_t>& bytes() const { return bytes_; }

private:
    ImageDesc desc_;
    std::vector<uint8_t> bytes_;
};

// True when both views have the same layout and identical pixel bytes (rows only, not padding).
bool sameImage(const ImageView& a, const ImageView& b);

// A float image of linear values (renders, environment maps), row-major, `channels` per
// pixel. Plain value.
struct FloatImage {
    int width = 0;
    int height = 0;
    int channels = 3;
    std::vector<float> pixels;
    float* at(int x, int y) {
        return pixels.data() + (static_cast<size_t>(y) * width + x) * channels;
    }
    const float* at(int x, int y) const {
        return pixels.data() + (static_cast<size_t>(y) * width + x) * channels;
    }
};

}  // namespace mixray
