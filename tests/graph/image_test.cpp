// Pixel format table and image layout.
#include "mixray/graph/image.h"

#include <gtest/gtest.h>

namespace mixray {
namespace {

TEST(PixelFormat, NamesRoundTrip) {
    for (int i = 1; i <= static_cast<int>(PixelFormat::kBinary); ++i) {
        auto format = static_cast<PixelFormat>(i);
        auto parsed = pixelFormatFromString(toString(format));
        ASSERT_TRUE(parsed.has_value()) << toString(format);
        EXPECT_EQ(*parsed, format);
    }
    EXPECT_FALSE(pixelFormatFromString("rgb9").has_value());
}

TEST(ImageDesc, PackedStridesAndSizes) {
    EXPECT_EQ(ImageDesc::packed(PixelFormat::kRGB8, 640, 480).bufferBytes(), 640u * 480 * 3);
    EXPECT_EQ(ImageDesc::packed(PixelFormat::kDepth16, 640, 480).stride_bytes, 1280);
    EXPECT_EQ(ImageDesc::packed(PixelFormat::kYUYV, 640, 480).stride_bytes, 1280);
    EXPECT_EQ(ImageDesc::packed(PixelFormat::kNV12, 1280, 720).bufferBytes(), 1280u * 720 * 3 / 2);
    EXPECT_EQ(ImageDesc::packed(PixelFormat::kMJPEG, 640, 480).stride_bytes, 0);
    EXPECT_GT(ImageDesc::packed(PixelFormat::kMJPEG, 640, 480).bufferBytes(), 640u * 480 * 3);
    EXPECT_EQ(ImageDesc::packed(PixelFormat::kMono8, 0, 480).bufferBytes(), 0u);
}

TEST(Image, SameImageIgnoresRowPadding) {
    Image a(ImageDesc::packed(PixelFormat::kMono16, 5, 3));
    Image b(ImageDesc{PixelFormat::kMono16, 5, 3, 16});
    for (int y = 0; y < 3; ++y) {
        for (int x = 0; x < 5; ++x) {
            a.mutableView().row<uint16_t>(y)[x] = static_cast<uint16_t>(y * 100 + x);
            b.mutableView().row<uint16_t>(y)[x] = static_cast<uint16_t>(y * 100 + x);
        }
    }
    EXPECT_TRUE(sameImage(a.view(), b.view()));
    b.mutableView().row<uint16_t>(2)[4] = 7;
    EXPECT_FALSE(sameImage(a.view(), b.view()));
}

}  // namespace
}  // namespace mixray
