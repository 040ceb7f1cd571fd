// libFuzzer target for the RGB-D dataset inputs: NYU raw file names and depth words, SUN RGB-D
// intrinsics.txt and depth words. Any input gives a value or a clean kCorruptData error.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>

#include "mixray/replay/depth_units.h"
#include "mixray/replay/rgbd_datasets.h"

namespace {

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "depth_dataset_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace mixray;
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    auto stamp = replay::parseNyuFileName(text);
    if (!stamp.isOk() && stamp.status().code() != ErrorCode::kCorruptData)
        broken("unexpected NYU name code", stamp.status().toString());
    auto k = replay::parseSunIntrinsics(text, "fuzz/intrinsics.txt");
    if (k.isOk() && !k->validate().isOk())
        broken("accepted SUN intrinsics fail validate()", std::string(text));
    if (!k.isOk() && (k.status().code() != ErrorCode::kCorruptData ||
                      k.status().message().rfind("fuzz/intrinsics.txt", 0) != 0))
        broken("bad SUN intrinsics error", k.status().toString());

    // The bytes as a 16-bit depth image, 8 pixels wide.
    const int width = 8;
    const int height = static_cast<int>(size / (2 * width));
    if (height == 0)
        return 0;
    Image image(ImageDesc::packed(PixelFormat::kDepth16, width, height));
    std::memcpy(image.bytes().data(), data, static_cast<size_t>(width * height * 2));
    const double share = replay::sunRotatedShare(image.view());
    if (!(share >= 0 && share <= 1))
        broken("rotated share out of range", std::to_string(share));
    Image sun = image;
    replay::convertSunDepthToMm(sun.mutableView());
    Status nyu = replay::convertNyuRawToMm(image.mutableView(), "fuzz.pgm");
    if (nyu.isOk()) {
        for (int y = 0; y < height; ++y) {
            for (int x = 0; x < width; ++x) {
                const uint16_t mm = image.view().row<uint16_t>(y)[x];
                if (mm != 0 && (mm < 321 || mm > 10000))
                    broken("NYU depth outside the Kinect's range", std::to_string(mm));
            }
        }
    } else if (nyu.code() != ErrorCode::kCorruptData) {
        broken("unexpected NYU depth code", nyu.toString());
    }
    return 0;
}
