// NYU Depth V2 raw and SUN RGB-D folders: recognised by layout and content, depth to mm.
#include "mixray/replay/rgbd_datasets.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mixray/replay/convert.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/point_cloud.h"
#include "replay_test_util.h"
#include "test_data.h"

namespace mixray::replay {
namespace {

constexpr int kW = 16;
constexpr int kH = 12;

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// Raw Kinect values of a synthetic NYU frame: a ramp over the valid range, holes (0, 2047).
uint16_t nyuRaw(int u, int v, int frame) {
    if ((u + v) % 7 == 0)
        return 0;
    if ((u * v) % 11 == 3)
        return 2047;
    return static_cast<uint16_t>(400 + 30 * u + 25 * v + frame);
}

// A 16-bit PGM; `big_endian` as the PGM rule says, else little-endian words as NYU's raw
// archives hold them.
void writePgm16(const std::filesystem::path& file, int frame, bool big_endian) {
    std::ofstream out(file, std::ios::binary);
    out << "P5\n" << kW << " " << kH << "\n65535\n";
    for (int v = 0; v < kH; ++v) {
        for (int u = 0; u < kW; ++u) {
            const uint16_t raw = nyuRaw(u, v, frame);
            const char hi = static_cast<char>(raw >> 8), lo = static_cast<char>(raw & 0xFF);
            if (big_endian)
                out << hi << lo;
            else
                out << lo << hi;
        }
    }
}

void writePpm(const std::filesystem::path& file, int frame) {
    std::ofstream out(file, std::ios::binary);
    out << "P6\n" << kW << " " << kH << "\n255\n";
    for (int i = 0; i < kW * kH; ++i)
        out << static_cast<char>(i) << static_cast<char>(frame) << static_cast<char>(200);
}

// Two frames of an NYU raw scene folder (+ an accelerometer dump and INDEX.txt, unread).
void writeSyntheticNyu(const std::filesystem::path& dir, bool big_endian) {
    std::filesystem::create_directories(dir);
    writePgm16(dir / "d-1294886362.665769-3143255701.pgm", 0, big_endian);
    writePpm(dir / "r-1294886362.677140-3143861166.ppm", 0);
    writePgm16(dir / "d-1294886362.699134-3145252781.pgm", 1, big_endian);
    writePpm(dir / "r-1294886362.710467-3145860174.ppm", 1);
    test::writeText(dir / "a-1294886362.680000-3144000000.dump", "accelerometer");
    test::writeText(dir / "INDEX.txt", "d-1294886362.665769-3143255701.pgm\n");
}

TEST(NyuRaw, ConvertsRawDisparityToMillimetresLikeTheToolbox) {
    // depth_m = 351.3 / (1092.5 - raw).
    EXPECT_EQ(nyuRawToMm(0), 0);
    EXPECT_EQ(nyuRawToMm(2047), 0);  // the Kinect's "no reading"
    EXPECT_EQ(nyuRawToMm(1092), 0);  // 702.6 m: far beyond the 10 m the toolbox allows
    EXPECT_EQ(nyuRawToMm(600), static_cast<uint16_t>(std::lround(351300.0 / 492.5)));
    EXPECT_EQ(nyuRawToMm(1000), static_cast<uint16_t>(std::lround(351300.0 / 92.5)));
    EXPECT_EQ(nyuRawToMm(1057), 9896);  // 9.896 m: still inside
    EXPECT_EQ(nyuRawToMm(1058), 0);     // 10.18 m: beyond
}

TEST(NyuRaw, FileNamesGiveExactStamps) {
    EXPECT_EQ(*parseNyuFileName("d-1294886362.665769-3143255701.pgm"), 1294886362665769000);
    EXPECT_EQ(*parseNyuFileName("r-1294886362.677140-3143861166.ppm"), 1294886362677140000);
    for (const char* bad : {"d-1294886362-3143255701.pgm", "d-1294886362.66-x.pgm",
                            "x-1294886362.665769-3143255701.pgm", "d-.5-1.pgm", "rgb.txt"}) {
        EXPECT_FALSE(parseNyuFileName(bad)) << bad;
    }
}

TEST(NyuRaw, BothByteOrdersGiveTheSameMillimetres) {
    for (bool big_endian : {true, false}) {
        const auto dir = test::tempDir() / (big_endian ? "be" : "le");
        writeSyntheticNyu(dir, big_endian);
        ASSERT_TRUE(looksLikeNyuRaw(dir));
        auto reader = openRecording(dir);
        ASSERT_TRUE(reader) << reader.status().toString();
        EXPECT_EQ((*reader)->format(), "nyu-raw");
        ASSERT_EQ((*reader)->streams().size(), 2u);
        EXPECT_EQ((*reader)->streams()[0].name, "nyu/color");
        const StreamInfo& depth = (*reader)->streams()[1];
        EXPECT_EQ(depth.name, "nyu/depth");
        EXPECT_EQ(depth.format.format, PixelFormat::kDepth16);
        EXPECT_EQ(depth.tags.count(kDepthScaleTag), 0u);    // mm, not TUM's 5000/m
        EXPECT_EQ(depth.tags.count(kRegisteredToTag), 0u);  // raw depth is not registered
        auto k = parseIntrinsics(depth.tags.at(kIntrinsicsTag));
        ASSERT_TRUE(k);
        EXPECT_NEAR(k->fx, 582.62448167737955, 1e-9);
        EXPECT_NEAR(k->cx, 312.04475870804731, 1e-9);  // 1-based 313.04... made 0-based
        const auto frames = test::readAll(**reader);
        ASSERT_EQ(frames.size(), 4u);
        int depth_frames = 0;
        for (const auto& f : frames) {
            if (f.meta.stream != 1)
                continue;
            for (int v = 0; v < kH; ++v) {
                for (int u = 0; u < kW; ++u) {
                    ASSERT_EQ(f.image.view().row<uint16_t>(v)[u],
                              nyuRawToMm(nyuRaw(u, v, depth_frames)))
                        << (big_endian ? "big" : "little") << " endian (" << u << "," << v << ")";
                }
            }
            EXPECT_EQ(f.meta.host_stamp_ns,
                      depth_frames == 0 ? 1294886362665769000 : 1294886362699134000);
            ++depth_frames;
        }
        EXPECT_EQ(depth_frames, 2);
    }
}

TEST(NyuRaw, RefusesDepthThatIsNotKinectRaw) {
    const auto dir = test::tempDir();
    // Millimetres up to 60 m do not fit 11 bits in either byte order.
    cv::Mat mm(kH, kW, CV_16UC1);
    for (int v = 0; v < kH; ++v)
        for (int u = 0; u < kW; ++u)
            mm.at<uint16_t>(v, u) = static_cast<uint16_t>(3000 + 3000 * u + 17 * v);
    ASSERT_TRUE(cv::imwrite((dir / "d-1294886362.665769-3143255701.pgm").string(), mm));
    auto reader = openRecording(dir);
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kCorruptData);
    EXPECT_TRUE(contains(reader.status().message(), "not NYU raw Kinect depth"))
        << reader.status().message();
    EXPECT_TRUE(contains(reader.status().message(), "d-1294886362.665769-3143255701.pgm"));
}

// A SUN RGB-D frame folder with depth `mm` (rotated as SUN stores it unless `plain`).
void writeSyntheticSun(const std::filesystem::path& dir, bool plain) {
    std::filesystem::create_directories(dir / "image");
    std::filesystem::create_directories(dir / "depth");
    std::filesystem::create_directories(dir / "depth_bfx");
    cv::Mat color(kH, kW, CV_8UC3, cv::Scalar(30, 60, 90));  // BGR
    ASSERT_TRUE(cv::imwrite((dir / "image" / "NYU0001.png").string(), color));
    cv::Mat depth(kH, kW, CV_16UC1);
    for (int v = 0; v < kH; ++v) {
        for (int u = 0; u < kW; ++u) {
            const uint16_t mm = (u + v) % 5 == 0 ? 0 : static_cast<uint16_t>(500 + 251 * u + 7 * v);
            depth.at<uint16_t>(v, u) = plain ? mm : static_cast<uint16_t>((mm << 3) | (mm >> 13));
        }
    }
    ASSERT_TRUE(cv::imwrite((dir / "depth" / "NYU0001.png").string(), depth));
    test::writeText(dir / "intrinsics.txt",
                    "518.857901 0.000000 284.582449\n0.000000 519.469611 208.736166\n"
                    "0.000000 0.000000 1.000000\n");
}

TEST(SunRgbd, RotatedDepthBecomesMillimetresWithIntrinsicsAndColour) {
    const auto base = test::tempDir();
    const auto dir = base / "NYU0001";
    writeSyntheticSun(dir, false);
    ASSERT_TRUE(looksLikeSunRgbd(dir));
    auto reader = openRecording(dir);
    ASSERT_TRUE(reader) << reader.status().toString();
    EXPECT_EQ((*reader)->format(), "sun-rgbd");
    ASSERT_EQ((*reader)->streams().size(), 2u);
    const StreamInfo& depth = (*reader)->streams()[1];
    EXPECT_EQ(depth.tags.at(kRegisteredToTag), "sun/color");
    auto k = parseIntrinsics(depth.tags.at(kIntrinsicsTag));
    ASSERT_TRUE(k);
    EXPECT_EQ(*k, (PinholeIntrinsics{518.857901, 519.469611, 283.582449, 207.736166}));
    const auto frames = test::readAll(**reader);
    ASSERT_EQ(frames.size(), 2u);
    const auto& d = frames[1];
    ASSERT_EQ(d.meta.stream, 1u);
    for (int v = 0; v < kH; ++v) {
        for (int u = 0; u < kW; ++u) {
            const uint16_t mm = (u + v) % 5 == 0 ? 0 : static_cast<uint16_t>(500 + 251 * u + 7 * v);
            ASSERT_EQ(d.image.view().row<uint16_t>(v)[u], mm) << u << "," << v;
        }
    }
    ASSERT_EQ((*reader)->attachments().size(), 1u);

    // Point clouds straight from the folder: intrinsics from intrinsics.txt, registered colour.
    ASSERT_TRUE((*reader)->seek(INT64_MIN));
    const auto out = base / "clouds";
    auto writer = createPointCloudWriter(out, headerOf(**reader));
    ASSERT_TRUE(writer) << writer.status().toString();
    auto converted = convertRecording(**reader, **writer);
    ASSERT_TRUE(converted) << converted.status().toString();
    auto cloud = readPointCloud(out / "cloud_000000.ply");
    ASSERT_TRUE(cloud) << cloud.status().toString();
    ASSERT_TRUE(cloud->hasColor());
    EXPECT_EQ(cloud->rgb[0], 90);  // R of the BGR (30, 60, 90) image
    EXPECT_EQ(cloud->rgb[2], 30);
    const size_t i = 3 * kW + 4;  // (4,3): 500 + 251 * 4 + 21 = 1525 mm
    EXPECT_FLOAT_EQ(cloud->xyz[i * 3 + 2], 1.525f);
    EXPECT_FLOAT_EQ(cloud->xyz[i * 3 + 0],
                    (4.f - static_cast<float>(k->cx)) * (1.f / static_cast<float>(k->fx)) * 1.525f);
}

TEST(SunRgbd, PlainMillimetresAreNotTakenForSunDepth) {
    const auto dir = test::tempDir() / "NYU0001";
    writeSyntheticSun(dir, true);
    auto reader = openRecording(dir);
    ASSERT_FALSE(reader);
    EXPECT_EQ(reader.status().code(), ErrorCode::kCorruptData);
    EXPECT_TRUE(contains(reader.status().message(), "not SUN RGB-D depth"))
        << reader.status().message();
}

TEST(SunRgbd, IntrinsicsFileErrors) {
    EXPECT_FALSE(parseSunIntrinsics("1 2 3", "intrinsics.txt"));
    EXPECT_FALSE(parseSunIntrinsics("518 1 284 0 519 208 0 0 1", "intrinsics.txt"));
    EXPECT_FALSE(parseSunIntrinsics("518 0 284 0 519 208 0 0 1 5", "intrinsics.txt"));
    EXPECT_FALSE(parseSunIntrinsics("-518 0 284 0 519 208 0 0 1", "intrinsics.txt"));
    auto bad = parseSunIntrinsics("518 0 x 0 519 208 0 0 1", "k/intrinsics.txt");
    ASSERT_FALSE(bad);
    EXPECT_TRUE(contains(bad.status().message(), "k/intrinsics.txt"));
}

TEST(OpenRecording, RegisteredFormatsAreTriedForFiles) {
    const auto dir = test::tempDir();
    test::writeText(dir / "x.magic", "MAGIC...");
    auto before = openRecording(dir / "x.magic");
    ASSERT_FALSE(before);
    EXPECT_EQ(before.status().code(), ErrorCode::kUnsupported);
    registerRecordingFormat(
        {"magic", "a .magic test file",
         [](const std::filesystem::path& p) { return test::readFile(p).rfind("MAGIC", 0) == 0; },
         [](const std::filesystem::path& p,
            const OpenRecordingOptions&) -> Result<std::unique_ptr<RecordingReader>> {
             return Status(ErrorCode::kCorruptData, p.filename().string() + ": magic reader");
         }});
    auto after = openRecording(dir / "x.magic");
    ASSERT_FALSE(after);
    EXPECT_TRUE(contains(after.status().message(), "magic reader")) << after.status().message();
    test::writeText(dir / "y.bin", "nothing");
    auto other = openRecording(dir / "y.bin");
    ASSERT_FALSE(other);
    EXPECT_TRUE(contains(other.status().message(), "a .magic test file"))
        << other.status().message();
}

}  // namespace
}  // namespace mixray::replay
