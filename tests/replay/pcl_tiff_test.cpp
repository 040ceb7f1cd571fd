// PCL OpenNI TIFF folders: timestamps from names, the real PCL frame, writing them back.
#include "mixray/replay/pcl_tiff.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mixray/replay/convert.h"
#include "mixray/replay/depth_units.h"
#include "replay_test_util.h"
#include "test_data.h"

namespace mixray::replay {
namespace {

constexpr const char* kRealStamp = "20121214T142255.814212";
constexpr int64_t kRealStampNs = 1355494975814212000;  // calendar.timegm, UTC

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

TEST(PclStamp, ParsesUtcNamesExactly) {
    EXPECT_EQ(*parsePclStamp(kRealStamp), kRealStampNs);
    EXPECT_EQ(*parsePclStamp("19700101T000000"), 0);
    EXPECT_EQ(*parsePclStamp("19700101T000000.000000001"), 1);
    EXPECT_EQ(*parsePclStamp("20000229T000000.5"), 951782400500000000);
    EXPECT_EQ(*parsePclStamp("19691231T235959"), -1'000'000'000);
    for (const char* bad : {"", "20121214 142255", "20121314T142255", "20130229T000000",
                            "20121214T242255", "20121214T142255.", "20121214T142255.1234567890",
                            "2012121xT142255", "20121214T142255,5"}) {
        auto stamp = parsePclStamp(bad);
        ASSERT_FALSE(stamp) << bad;
        EXPECT_EQ(stamp.status().code(), ErrorCode::kCorruptData) << bad;
    }
}

// tum_list_fuzz found names whose time overflowed 64-bit nanoseconds (signed overflow, UBSan):
// the last nanosecond they hold is read, the first whole second before 1970 they hold too, and
// anything beyond them is refused.
TEST(PclStamp, RefusesTimesBeyondSixtyFourBitNanoseconds) {
    EXPECT_EQ(*parsePclStamp("22620411T234716.854775807"), INT64_MAX);
    EXPECT_EQ(*parsePclStamp("16770921T001244"), -9'223'372'036'000'000'000);
    for (const char* beyond :
         {"22620411T234716.854775847", "22620411T234716.854775808", "16770921T001243.999999999",
          "99991231T235959.999999999", "00000101T000000"}) {
        auto stamp = parsePclStamp(beyond);
        ASSERT_FALSE(stamp) << beyond;
        EXPECT_EQ(stamp.status().code(), ErrorCode::kCorruptData) << beyond;
        EXPECT_NE(stamp.status().message().find("64-bit nanoseconds"), std::string::npos);
    }
}

TEST(PclStamp, FormatsBack) {
    EXPECT_EQ(formatPclStamp(kRealStampNs, 6), kRealStamp);
    EXPECT_EQ(formatPclStamp(0, 0), "19700101T000000");
    EXPECT_EQ(formatPclStamp(-1, 9), "19691231T235959.999999999");
    for (int64_t ns : {kRealStampNs + 123, int64_t{951782400500000000}, int64_t{-1}}) {
        EXPECT_EQ(*parsePclStamp(formatPclStamp(ns, 9)), ns);
    }
}

// Three synthetic captures in PCL's layout, one of them depth-only.
void writeSyntheticPcl(const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir);
    const char* stamps[] = {"20121214T142255.814212", "20121214T142256.074117",
                            "20121214T142256.334285"};
    for (int i = 0; i < 3; ++i) {
        cv::Mat depth(12, 16, CV_16UC1);
        cv::Mat bgr(12, 16, CV_8UC3);
        for (int y = 0; y < 12; ++y) {
            for (int x = 0; x < 16; ++x) {
                depth.at<uint16_t>(y, x) = static_cast<uint16_t>(x * 1000 + y * 7 + i);
                bgr.at<cv::Vec3b>(y, x) =
                    cv::Vec3b(static_cast<uint8_t>(x * 9), static_cast<uint8_t>(y * 20 + i),
                              static_cast<uint8_t>(255 - x));
            }
        }
        const std::string base = (dir / ("frame_" + std::string(stamps[i]))).string();
        cv::imwrite(base + "_depth.tiff", depth);
        if (i != 1)
            cv::imwrite(base + "_rgb.tiff", bgr);
    }
}

TEST(PclTiffFolder, ReadsSyntheticSequenceInOrder) {
    const auto dir = test::tempDir() / "pcl";
    writeSyntheticPcl(dir);
    auto reader = openPclTiff(dir);
    ASSERT_TRUE(reader) << reader.status().toString();
    EXPECT_EQ((*reader)->format(), "pcl-tiff");
    ASSERT_EQ((*reader)->streams().size(), 2u);
    EXPECT_EQ((*reader)->streams()[0].name, "pcl/color");
    EXPECT_EQ((*reader)->streams()[1].name, "pcl/depth");
    EXPECT_EQ((*reader)->streams()[1].format, ImageDesc::packed(PixelFormat::kDepth16, 16, 12));
    EXPECT_EQ(*depthScalePerMetre((*reader)->streams()[1]), 1000);
    const auto frames = test::readAll(**reader);
    ASSERT_EQ(frames.size(), 5u);
    const uint32_t streams[] = {0, 1, 1, 0, 1};  // colour first at equal stamps
    const uint64_t sequences[] = {0, 0, 1, 1, 2};
    for (size_t i = 0; i < frames.size(); ++i) {
        EXPECT_EQ(frames[i].meta.stream, streams[i]) << i;
        EXPECT_EQ(frames[i].meta.sequence, sequences[i]) << i;
    }
    EXPECT_EQ(frames[0].meta.host_stamp_ns, kRealStampNs);
    EXPECT_EQ(frames[2].meta.host_stamp_ns, *parsePclStamp("20121214T142256.074117"));
    const auto* d = reinterpret_cast<const uint16_t*>(frames[4].image.view().data);
    EXPECT_EQ(d[5 * 16 + 3], 3 * 1000 + 5 * 7 + 2);
}

TEST(PclTiffFolder, BadNamesAndBitDepthsAreNamed) {
    const auto tmp = test::tempDir();
    const auto dir = tmp / "pcl";
    writeSyntheticPcl(dir);
    cv::imwrite((dir / "frame_2012-12-14_depth.tiff").string(), cv::Mat(12, 16, CV_16UC1));
    auto reader = openPclTiff(dir);
    ASSERT_FALSE(reader);
    EXPECT_TRUE(contains(reader.status().message(), "frame_2012-12-14_depth.tiff"));
    EXPECT_TRUE(contains(reader.status().message(), "bad timestamp"));

    const auto dir2 = tmp / "pcl8";
    std::filesystem::create_directories(dir2);
    cv::imwrite((dir2 / "frame_20121214T142255.814212_depth.tiff").string(),
                cv::Mat(12, 16, CV_8UC1, cv::Scalar(1)));
    reader = openPclTiff(dir2);
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kCorruptData);
    EXPECT_TRUE(contains(reader.status().message(), "expected 16-bit grey"));

    std::filesystem::create_directories(tmp / "empty");
    reader = openPclTiff(tmp / "empty");
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kNotFound);
}

TEST(PclTiffFolder, TumDepthIsWrittenInMillimetres) {
    RecordingHeader header;
    StreamInfo depth;
    depth.name = "tum/depth";
    depth.kind = StreamKind::kDepth;
    depth.format = ImageDesc::packed(PixelFormat::kDepth16, 3, 1);
    depth.tags[kDepthScaleTag] = "5000";
    header.streams.push_back(depth);
    const auto out = test::tempDir() / "pcl";
    auto writer = createPclTiffWriter(out, header);
    ASSERT_TRUE(writer) << writer.status().toString();
    auto pool = BufferPool::create({depth.format, 0, 1, "p"});
    WritableFrame w = pool->acquire();
    const uint16_t raw[3] = {0, 2, 5005};
    std::memcpy(w.image().data, raw, sizeof(raw));
    w.meta().stream = 0;
    w.meta().host_stamp_ns = kRealStampNs + 1;  // a sub-microsecond stamp needs 9 digits
    ASSERT_TRUE((*writer)->write(std::move(w).publish()));
    ASSERT_TRUE((*writer)->close());
    const auto file = out / "frame_20121214T142255.814212001_depth.tiff";
    cv::Mat tiff = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(tiff.type(), CV_16UC1) << file;
    EXPECT_EQ(tiff.at<uint16_t>(0, 0), 0);
    EXPECT_EQ(tiff.at<uint16_t>(0, 1), 1);
    EXPECT_EQ(tiff.at<uint16_t>(0, 2), 1001);
}

TEST(PclTiffFolder, RealOpenNiFrameReadsAndExportsBitExactly) {
    const auto dir = test::realPclDir();
    const auto depth_file = dir / (std::string("frame_") + kRealStamp + "_depth.tiff");
    const auto rgb_file = dir / (std::string("frame_") + kRealStamp + "_rgb.tiff");
    MIXRAY_REQUIRE_SHARED_DATA(depth_file);
    MIXRAY_REQUIRE_SHARED_DATA(rgb_file);
    auto reader = openPclTiff(dir);
    ASSERT_TRUE(reader) << reader.status().toString();
    ASSERT_EQ((*reader)->streams().size(), 2u);
    EXPECT_EQ((*reader)->streams()[0].format, ImageDesc::packed(PixelFormat::kRGB8, 640, 480));
    EXPECT_EQ((*reader)->streams()[1].format, ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    ASSERT_EQ((*reader)->attachments().size(), 1u);
    const Attachment& xml = (*reader)->attachments()[0];
    EXPECT_EQ(xml.name, std::string("frame_") + kRealStamp + ".xml");
    EXPECT_EQ(xml.mime_type, "application/xml");
    EXPECT_TRUE(contains(std::string(xml.data.begin(), xml.data.end()),
                         "<focal_length_x>525</focal_length_x>"));

    const auto frames = test::readAll(**reader);
    ASSERT_EQ(frames.size(), 2u);
    for (const auto& f : frames) {
        EXPECT_EQ(f.meta.host_stamp_ns, kRealStampNs);
        EXPECT_EQ(f.meta.device_stamp_ns, kRealStampNs);
    }
    cv::Mat depth_tiff = cv::imread(depth_file.string(), cv::IMREAD_UNCHANGED);
    cv::Mat depth(480, 640, CV_16UC1, const_cast<uint8_t*>(frames[1].image.view().data));
    EXPECT_EQ(cv::norm(depth, depth_tiff, cv::NORM_INF), 0.0);
    double max_mm = 0;
    cv::minMaxLoc(depth, nullptr, &max_mm);
    EXPECT_GT(max_mm, 1000);  // MANIFEST.md: 0..~1.7 m
    EXPECT_LT(max_mm, 2000);

    ASSERT_TRUE((*reader)->seek(0));
    const auto out = test::tempDir() / "exported";
    auto summary = exportPclTiff(**reader, out);
    ASSERT_TRUE(summary) << summary.status().toString();
    EXPECT_EQ(summary->frames, 2u);
    test::expectSamePixels(depth_file, out / depth_file.filename());
    test::expectSamePixels(rgb_file, out / rgb_file.filename());
    EXPECT_EQ(test::readFile(out / xml.name), test::readFile(dir / xml.name));
}

}  // namespace
}  // namespace mixray::replay
