// Decoding image files into linear-light float RGB: OpenCV for PNG/JPEG/TIFF/HDR, OpenEXR for
// EXR (OpenCV's own EXR reader is disabled by default in 4.x and cannot read every
// compression).
#include "image_file.h"

#include <ImathBox.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfRgbaFile.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <system_error>

namespace mixray::render::detail {

namespace {

std::string lowerExtension(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

Status missingFileStatus(const std::filesystem::path& path, std::string_view what) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
        return {ErrorCode::kNotFound, std::string(what) + " not found: " + path.string()};
    }
    if (std::filesystem::is_directory(path, ec)) {
        return {ErrorCode::kInvalidArgument,
                std::string(what) + " is a directory, not a file: " + path.string()};
    }
    return Status::ok();
}

// A table for 8-bit values, since 8-bit textures are by far the most common and the power
// function dominates decoding time otherwise.
const std::array<float, 256>& srgb8Table() {
    static const std::array<float, 256> table = [] {
        std::array<float, 256> t{};
        for (int i = 0; i < 256; ++i)
            t[i] = srgbToLinear(static_cast<float>(i) / 255.0f);
        return t;
    }();
    return table;
}

// Names of the three channels holding red, green and blue: "R","G","B", or the first layer
// that has all three ("diffuse.R", ...).
std::optional<std::array<std::string, 3>> findRgbChannels(const Imf::ChannelList& channels) {
    if (channels.findChannel("R") && channels.findChannel("G") && channels.findChannel("B")) {
        return std::array<std::string, 3>{"R", "G", "B"};
    }
    for (auto it = channels.begin(); it != channels.end(); ++it) {
        const std::string name = it.name();
        if (name.size() < 2 || name.compare(name.size() - 2, 2, ".R") != 0)
            continue;
        const std::string layer = name.substr(0, name.size() - 1);
        if (channels.findChannel(layer + "G") && channels.findChannel(layer + "B")) {
            return std::array<std::string, 3>{name, layer + "G", layer + "B"};
        }
    }
    return std::nullopt;
}

}  // namespace

float srgbToLinear(float encoded) {
    if (encoded <= 0.04045f)
        return encoded / 12.92f;
    return std::pow((encoded + 0.055f) / 1.055f, 2.4f);
}

Result<LinearImage> readExr(const std::filesystem::path& path) {
    MIXRAY_RETURN_IF_ERROR(missingFileStatus(path, "image file"));
    try {
        Imf::InputFile file(path.c_str());
        const Imath::Box2i window = file.header().dataWindow();
        const int width = window.max.x - window.min.x + 1;
        const int height = window.max.y - window.min.y + 1;
        if (width <= 0 || height <= 0) {
            return Result<LinearImage>(ErrorCode::kCorruptData,
                                       path.string() + ": empty EXR data window");
        }
        LinearImage image;
        image.width = width;
        image.height = height;
        image.texels.assign(static_cast<size_t>(width) * height, Rgb::Zero());

        const auto rgb = findRgbChannels(file.header().channels());
        if (rgb) {
            // InputFile converts half and uint channels to float, and reads the full-resolution
            // level of tiled mip-mapped files.
            Imf::FrameBuffer frame_buffer;
            const size_t x_stride = sizeof(Rgb);
            const size_t y_stride = sizeof(Rgb) * static_cast<size_t>(width);
            // OpenEXR addresses pixels by their data-window coordinates: shift the base so
            // that (min.x, min.y) lands on texels[0]. Computed in integers to avoid forming an
            // out-of-bounds pointer in C++ terms.
            const auto origin = reinterpret_cast<intptr_t>(image.texels.data()) -
                                static_cast<intptr_t>(window.min.x) * x_stride -
                                static_cast<intptr_t>(window.min.y) * y_stride;
            for (int c = 0; c < 3; ++c) {
                frame_buffer.insert(
                    (*rgb)[c],
                    Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(origin + c * sizeof(float)),
                               x_stride, y_stride, 1, 1, 0.0));
            }
            file.setFrameBuffer(frame_buffer);
            file.readPixels(window.min.y, window.max.y);
            return image;
        }
        if (!file.header().channels().findChannel("Y")) {
            return Result<LinearImage>(ErrorCode::kUnsupported,
                                       path.string() + ": EXR has neither R,G,B nor Y channels");
        }
        // Luminance(-chroma) images: the RGBA interface reconstructs RGB from Y, RY, BY.
        Imf::RgbaInputFile rgba_file(path.c_str());
        std::vector<Imf::Rgba> pixels(static_cast<size_t>(width) * height);
        rgba_file.setFrameBuffer(
            pixels.data() - window.min.x - static_cast<ptrdiff_t>(window.min.y) * width, 1,
            static_cast<size_t>(width));
        rgba_file.readPixels(window.min.y, window.max.y);
        for (size_t i = 0; i < pixels.size(); ++i) {
            image.texels[i] = Rgb(pixels[i].r, pixels[i].g, pixels[i].b);
        }
        return image;
    } catch (const std::exception& e) {
        return Result<LinearImage>(ErrorCode::kCorruptData,
                                   path.string() + ": cannot read EXR: " + e.what());
    }
}

Result<LinearImage> readLinearImage(const std::filesystem::path& path) {
    MIXRAY_RETURN_IF_ERROR(missingFileStatus(path, "image file"));
    if (lowerExtension(path) == ".exr")
        return readExr(path);

    cv::Mat mat;
    try {
        // IMREAD_UNCHANGED keeps 16-bit and float samples and ignores EXIF orientation, which
        // texture coordinates do not expect.
        mat = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
    } catch (const std::exception& e) {
        return Result<LinearImage>(ErrorCode::kCorruptData,
                                   path.string() + ": cannot decode image: " + e.what());
    }
    if (mat.empty()) {
        return Result<LinearImage>(ErrorCode::kCorruptData,
                                   path.string() +
                                       ": cannot decode image (unknown format or "
                                       "corrupt file)");
    }
    const int channels = mat.channels();
    const int depth = mat.depth();
    if (depth != CV_8U && depth != CV_16U && depth != CV_32F && depth != CV_16F &&
        depth != CV_64F) {
        return Result<LinearImage>(
            ErrorCode::kUnsupported,
            path.string() + ": unsupported sample type (depth " + std::to_string(depth) + ")");
    }
    if (channels < 1 || channels > 4) {
        return Result<LinearImage>(
            ErrorCode::kUnsupported,
            path.string() + ": unsupported channel count " + std::to_string(channels));
    }

    LinearImage image;
    image.width = mat.cols;
    image.height = mat.rows;
    image.texels.resize(static_cast<size_t>(mat.cols) * mat.rows);

    // Converts everything to float first; 8/16-bit values become [0,1] and are decoded.
    cv::Mat floats;
    bool srgb = true;
    if (depth == CV_8U) {
        floats = mat;  // decoded through the table below
    } else if (depth == CV_16U) {
        mat.convertTo(floats, CV_32F, 1.0 / 65535.0);
    } else {
        mat.convertTo(floats, CV_32F);
        srgb = false;
    }
    const auto& table = srgb8Table();
    // OpenCV stores colour as B,G,R(,A); grey images have one channel (two with alpha).
    const bool grey = channels <= 2;
    for (int y = 0; y < mat.rows; ++y) {
        Rgb* out = image.texels.data() + static_cast<size_t>(y) * mat.cols;
        if (depth == CV_8U) {
            const uint8_t* row = floats.ptr<uint8_t>(y);
            for (int x = 0; x < mat.cols; ++x) {
                const uint8_t* px = row + static_cast<size_t>(x) * channels;
                out[x] = grey ? Rgb::Constant(table[px[0]])
                              : Rgb(table[px[2]], table[px[1]], table[px[0]]);
            }
            continue;
        }
        const float* row = floats.ptr<float>(y);
        for (int x = 0; x < mat.cols; ++x) {
            const float* px = row + static_cast<size_t>(x) * channels;
            Rgb value = grey ? Rgb::Constant(px[0]) : Rgb(px[2], px[1], px[0]);
            if (srgb) {
                value =
                    Rgb(srgbToLinear(value.x()), srgbToLinear(value.y()), srgbToLinear(value.z()));
            }
            out[x] = value;
        }
    }
    return image;
}

}  // namespace mixray::render::detail
