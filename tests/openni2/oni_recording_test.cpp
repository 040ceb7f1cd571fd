// .oni recordings as RecordingReaders: the real Kinect v1 recording, and one OpenNI2 refuses.
#include "mixray/openni2/oni_recording.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "test_data.h"

namespace mixray::openni2 {
namespace {

TEST(OniRecording, RecognisesOniFilesByTheirMagic) {
    const auto oni = test::kinectV1Oni();
    MIXRAY_REQUIRE_SHARED_DATA(oni);
    EXPECT_TRUE(looksLikeOni(oni));
    const auto dir = test::tempDir();
    test::writeText(dir / "fake.oni", "not an oni file");
    EXPECT_FALSE(looksLikeOni(dir / "fake.oni"));
    auto reader = openOniRecording(dir / "fake.oni");
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kCorruptData);
}

// The Kinect v1 recording: 12 depth (mm) + 12 colour frames, in recorded-time order, the depth
// intrinsics from the recorded field of view (≈ 575.8 px, what ZPD / (2 ZPPS) gives).
TEST(OniRecording, ReadsEveryFrameOfTheKinectRecordingInTimeOrder) {
    const auto oni = test::kinectV1Oni();
    MIXRAY_REQUIRE_SHARED_DATA(oni);
    auto reader = openOniRecording(oni);
    ASSERT_TRUE(reader) << reader.status().toString();
    EXPECT_EQ((*reader)->format(), "oni");
    const auto& streams = (*reader)->streams();
    ASSERT_EQ(streams.size(), 2u);
    int depth = -1;
    for (size_t i = 0; i < streams.size(); ++i) {
        if (streams[i].kind == StreamKind::kDepth)
            depth = static_cast<int>(i);
    }
    ASSERT_GE(depth, 0);
    const StreamInfo& d = streams[static_cast<size_t>(depth)];
    EXPECT_EQ(d.name, "oni/depth");
    EXPECT_EQ(d.format.format, PixelFormat::kDepth16);
    EXPECT_EQ(d.format.width, 640);
    ASSERT_EQ(d.tags.count(kOniIntrinsicsTag), 1u);
    double fx = 0, fy = 0, cx = 0, cy = 0;
    ASSERT_EQ(
        std::sscanf(d.tags.at(kOniIntrinsicsTag).c_str(), "%lf,%lf,%lf,%lf", &fx, &fy, &cx, &cy),
        4);
    EXPECT_NEAR(fx, 575.8, 0.5);
    EXPECT_NEAR(fy, 575.8, 1.0);
    EXPECT_DOUBLE_EQ(cx, 319.5);
    EXPECT_DOUBLE_EQ(cy, 239.5);

    std::vector<int> frames(streams.size(), 0);
    int64_t last = INT64_MIN;
    bool first_depth = true;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            ASSERT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        const auto& meta = frame->meta();
        ASSERT_LT(meta.stream, streams.size());
        EXPECT_GE(meta.host_stamp_ns, last);
        EXPECT_EQ(meta.host_stamp_ns, meta.device_stamp_ns);
        last = meta.host_stamp_ns;
        ++frames[meta.stream];
        if (static_cast<int>(meta.stream) == depth && first_depth) {
            // OpenNI2's own first frame (MANIFEST.md): 234942 valid pixels, at most 4521 mm.
            first_depth = false;
            const ImageView image = frame->image();
            uint64_t valid = 0;
            uint16_t max = 0;
            for (int y = 0; y < image.desc.height; ++y) {
                for (int x = 0; x < image.desc.width; ++x) {
                    const uint16_t v = image.row<uint16_t>(y)[x];
                    valid += v != 0;
                    max = std::max(max, v);
                }
            }
            EXPECT_EQ(valid, 234942u);
            EXPECT_EQ(max, 4521);
        }
    }
    EXPECT_EQ(frames[0], 12);
    EXPECT_EQ(frames[1], 12);
    EXPECT_GT(last, 300'000'000);  // 0.379 s recorded
}

TEST(OniRecording, ARecordingOpenNI2CannotPlayFailsCleanly) {
    const auto empty =
        test::sharedDataDir() / "01_oni" / "negative" / "bloyot_empty_image_only.oni";
    MIXRAY_REQUIRE_SHARED_DATA(empty);
    auto reader = openOniRecording(empty);
    ASSERT_FALSE(reader);
    EXPECT_NE(reader.status().message().find("bloyot_empty_image_only.oni"), std::string::npos)
        << reader.status().message();
}

}  // namespace
}  // namespace mixray::openni2
