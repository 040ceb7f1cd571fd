// Depth to organized point clouds: PCL's own deprojection of the real PCL frame, PCD/PLY files
// that PCL's tools read, the per-frame cloud writer and its errors.
#include "mixray/replay/point_cloud.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "mixray/replay/convert.h"
#include "mixray/replay/pcl_tiff.h"
#include "mixray/replay/tum.h"
#include "replay_test_util.h"
#include "test_data.h"

namespace mixray::replay {
namespace {

constexpr const char* kRealFrame = "frame_20121214T142255.814212";

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

// Same grid, NaN in the same points, coordinates within 4 ulp (EXPECT_FLOAT_EQ, as PCL's own
// grabber test compares), the same colours when both have them. Stops after a few failures.
void expectSameCloud(const PointCloud& a, const PointCloud& b, const std::string& what) {
    ASSERT_EQ(a.width, b.width) << what;
    ASSERT_EQ(a.height, b.height) << what;
    ASSERT_EQ(a.xyz.size(), b.xyz.size()) << what;
    int failures = 0;
    size_t valid = 0;
    for (size_t i = 0; i < a.size() && failures < 5; ++i) {
        for (int c = 0; c < 3; ++c) {
            const float x = a.xyz[i * 3 + c];
            const float y = b.xyz[i * 3 + c];
            if (std::isnan(x) || std::isnan(y)) {
                if (std::isnan(x) != std::isnan(y)) {
                    ADD_FAILURE() << what << ": point " << i << " coordinate " << c << ": " << x
                                  << " vs " << y;
                    ++failures;
                }
                continue;
            }
            if (!::testing::internal::FloatingPoint<float>(x).AlmostEquals(
                    ::testing::internal::FloatingPoint<float>(y))) {
                ADD_FAILURE() << what << ": point " << i << " (" << i % a.width << ","
                              << i / a.width << ") coordinate " << c << ": " << x << " vs " << y;
                ++failures;
            }
        }
        valid += std::isnan(a.xyz[i * 3 + 2]) ? 0 : 1;
        if (a.hasColor() && b.hasColor()) {
            for (int c = 0; c < 3; ++c) {
                if (a.rgb[i * 3 + c] != b.rgb[i * 3 + c]) {
                    ADD_FAILURE() << what << ": colour of point " << i;
                    ++failures;
                    break;
                }
            }
        }
    }
    EXPECT_GT(valid, 0u) << what << ": no valid point at all";
}

PointCloud syntheticCloud(bool color) {
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 5, 3));
    Image rgb(ImageDesc::packed(PixelFormat::kRGB8, 5, 3));
    for (int v = 0; v < 3; ++v) {
        for (int u = 0; u < 5; ++u) {
            depth.mutableView().row<uint16_t>(v)[u] = (u + v) % 4 == 0 ? 0 : 700 + 37 * u + 5 * v;
            uint8_t* c = rgb.mutableView().row<uint8_t>(v) + u * 3;
            c[0] = static_cast<uint8_t>(10 * u);
            c[1] = static_cast<uint8_t>(50 + v);
            c[2] = static_cast<uint8_t>(255 - u);
        }
    }
    const ImageView color_view = rgb.view();
    auto cloud =
        deprojectDepth(depth.view(), 1000, {525, 520, 2.5, 1}, color ? &color_view : nullptr);
    EXPECT_TRUE(cloud) << cloud.status().toString();
    return cloud ? *cloud : PointCloud{};
}

TEST(PointCloud, DeprojectsLikePclWithNanForNoDepth) {
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 4, 2));
    depth.mutableView().row<uint16_t>(0)[0] = 0;
    depth.mutableView().row<uint16_t>(0)[3] = 1500;
    depth.mutableView().row<uint16_t>(1)[1] = 5000;
    auto cloud = deprojectDepth(depth.view(), 1000, {500, 400, 1.5, 0.5});
    ASSERT_TRUE(cloud) << cloud.status().toString();
    EXPECT_EQ(cloud->width, 4);
    EXPECT_EQ(cloud->height, 2);
    EXPECT_FALSE(cloud->hasColor());
    EXPECT_TRUE(std::isnan(cloud->xyz[0]) && std::isnan(cloud->xyz[1]) &&
                std::isnan(cloud->xyz[2]));
    // (3,0) at 1.5 m: x = (3 - 1.5) / 500 * 1.5, y = (0 - 0.5) / 400 * 1.5.
    EXPECT_FLOAT_EQ(cloud->xyz[3 * 3 + 0], 1.5f * 1.5f / 500.f);
    EXPECT_FLOAT_EQ(cloud->xyz[3 * 3 + 1], -0.5f * 1.5f / 400.f);
    EXPECT_FLOAT_EQ(cloud->xyz[3 * 3 + 2], 1.5f);
    // TUM units: 5000 per metre.
    auto tum = deprojectDepth(depth.view(), 5000, {500, 400, 1.5, 0.5});
    ASSERT_TRUE(tum);
    EXPECT_FLOAT_EQ(tum->xyz[5 * 3 + 2], 1.0f);

    Image mono(ImageDesc::packed(PixelFormat::kMono8, 4, 2));
    EXPECT_EQ(deprojectDepth(mono.view(), 1000, {500, 400, 1, 1}).status().code(),
              ErrorCode::kInvalidArgument);
    EXPECT_EQ(deprojectDepth(depth.view(), 1000, {0, 400, 1, 1}).status().code(),
              ErrorCode::kInvalidArgument);
    Image small(ImageDesc::packed(PixelFormat::kRGB8, 2, 2));
    const ImageView small_view = small.view();
    auto mismatch = deprojectDepth(depth.view(), 1000, {500, 400, 1, 1}, &small_view);
    ASSERT_FALSE(mismatch);
    EXPECT_TRUE(contains(mismatch.status().message(), "size")) << mismatch.status().message();
}

TEST(PointCloud, IntrinsicsParseAndFormat) {
    auto k = parseIntrinsics("525,525.5, 319.5,239.5");
    ASSERT_TRUE(k) << k.status().toString();
    EXPECT_EQ(*k, (PinholeIntrinsics{525, 525.5, 319.5, 239.5}));
    EXPECT_EQ(*parseIntrinsics(formatIntrinsics({517.306408, 516.469215, 318.643040, 255.313989})),
              (PinholeIntrinsics{517.306408, 516.469215, 318.643040, 255.313989}));
    for (const char* bad : {"", "525", "525,525,320", "525,525,320,240,1", "525,x,320,240",
                            "-1,525,320,240", "525,525,nan,240"}) {
        auto r = parseIntrinsics(bad);
        ASSERT_FALSE(r) << bad;
        EXPECT_EQ(r.status().code(), ErrorCode::kInvalidArgument) << bad;
    }
    EXPECT_TRUE(contains(parseIntrinsics("525,x,320,240").status().message(), "fy"));
}

TEST(PointCloud, PcdAndPlyRoundTripExactly) {
    for (bool color : {false, true}) {
        const PointCloud cloud = syntheticCloud(color);
        const std::string what = color ? "with colour" : "without colour";
        auto ascii = parsePcd(encodePcd(cloud, PcdEncoding::kAscii), "ascii.pcd");
        ASSERT_TRUE(ascii) << ascii.status().toString();
        expectSameCloud(*ascii, cloud, "pcd ascii " + what);
        EXPECT_EQ(ascii->hasColor(), color);
        auto binary = parsePcd(encodePcd(cloud, PcdEncoding::kBinary), "binary.pcd");
        ASSERT_TRUE(binary) << binary.status().toString();
        expectSameCloud(*binary, cloud, "pcd binary " + what);
        EXPECT_EQ(binary->xyz.size(), cloud.xyz.size());
        auto ply = parsePly(encodePly(cloud), "cloud.ply");
        ASSERT_TRUE(ply) << ply.status().toString();
        expectSameCloud(*ply, cloud, "ply " + what);
        EXPECT_EQ(ply->rgb, cloud.rgb);
    }
    // The PCD header says what PCL and Open3D need for an organized cloud with colour.
    const std::string pcd = encodePcd(syntheticCloud(true), PcdEncoding::kAscii);
    EXPECT_TRUE(contains(pcd, "FIELDS x y z rgb\n")) << pcd;
    EXPECT_TRUE(contains(pcd, "WIDTH 5\nHEIGHT 3\n")) << pcd;
    EXPECT_TRUE(contains(pcd, "nan nan nan")) << pcd;
    const std::string ply = encodePly(syntheticCloud(false));
    EXPECT_TRUE(contains(ply, "format binary_little_endian 1.0\n"));
    EXPECT_TRUE(contains(ply, "obj_info num_cols 5\nobj_info num_rows 3\n"));
}

TEST(PointCloud, ParsersRejectDamagedFilesWithReasons) {
    const PointCloud cloud = syntheticCloud(true);
    const std::string pcd = encodePcd(cloud, PcdEncoding::kBinary);
    const std::string ply = encodePly(cloud);
    for (size_t cut : {size_t{0}, size_t{20}, pcd.size() / 2, pcd.size() - 1}) {
        auto r = parsePcd(pcd.substr(0, cut), "cut.pcd");
        ASSERT_FALSE(r) << cut;
        EXPECT_EQ(r.status().code(), ErrorCode::kCorruptData);
        EXPECT_TRUE(contains(r.status().message(), "cut.pcd")) << r.status().message();
    }
    for (size_t cut : {size_t{0}, size_t{10}, ply.size() / 2, ply.size() - 1}) {
        auto r = parsePly(ply.substr(0, cut), "cut.ply");
        ASSERT_FALSE(r) << cut;
        EXPECT_EQ(r.status().code(), ErrorCode::kCorruptData);
    }
    std::string huge = pcd;
    huge.replace(huge.find("POINTS 15"), 9, "POINTS 99999999999");
    EXPECT_FALSE(parsePcd(huge, "huge.pcd"));
    EXPECT_FALSE(
        parsePcd("VERSION 0.7\nFIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                 "WIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n",
                 "noxyz.pcd"));
    EXPECT_FALSE(
        parsePly("ply\nformat binary_big_endian 1.0\nelement vertex 0\nend_header\n", "be.ply"));
}

// PCL's grabber test: the real TIFF frame, deprojected with fx = fy = 525, cx 320, cy 240 and
// 1 mm units, equals PCL's reference cloud point for point (NaN where depth is 0). Here through
// the whole path a user runs: the PCL folder reader (intrinsics from its XML sidecar, colour
// registered), the cloud writer, and the PCD file read back.
TEST(PointCloud, RealPclFrameMatchesPclsReferenceCloud) {
    const auto dir = test::realPclDir();
    const auto reference_file = dir / (std::string(kRealFrame) + ".reference.pcd");
    MIXRAY_REQUIRE_SHARED_DATA(reference_file);
    auto reference = readPointCloud(reference_file);
    ASSERT_TRUE(reference) << reference.status().toString();
    ASSERT_EQ(reference->width, 640);
    ASSERT_EQ(reference->height, 480);

    auto reader = openPclTiff(dir);
    ASSERT_TRUE(reader) << reader.status().toString();
    const RecordingHeader header = headerOf(**reader);
    auto k = depthIntrinsics(header, 1, {});
    ASSERT_TRUE(k) << k.status().toString();
    EXPECT_EQ(*k, (PinholeIntrinsics{525, 525, 320, 240}));

    for (PointCloudFormat format : {PointCloudFormat::kPcd, PointCloudFormat::kPly}) {
        ASSERT_TRUE((*reader)->seek(INT64_MIN));
        const auto out = test::tempDir() / (format == PointCloudFormat::kPcd ? "pcd" : "ply");
        PointCloudWriterOptions options;
        options.format = format;
        auto writer = createPointCloudWriter(out, header, options);
        ASSERT_TRUE(writer) << writer.status().toString();
        auto summary = convertRecording(**reader, **writer);
        ASSERT_TRUE(summary) << summary.status().toString();
        const std::string name =
            std::string("cloud_000000.") + (format == PointCloudFormat::kPcd ? "pcd" : "ply");
        auto cloud = readPointCloud(out / name);
        ASSERT_TRUE(cloud) << cloud.status().toString();
        EXPECT_TRUE(cloud->hasColor());
        expectSameCloud(*cloud, *reference, name + " vs PCL's reference");
        const std::string list = test::readFile(out / "clouds.txt");
        EXPECT_TRUE(contains(list, "1355494975.814212000 " + name)) << list;
    }
}

// PCL's own tools read what mixray writes: pcl_convert_pcd_ascii_binary rewrites our binary PCD
// as ASCII, pcl_ply2pcd turns our PLY into a PCD; both come back as the same organized cloud.
TEST(PointCloud, PclToolsReadOurFiles) {
    for (const char* tool : {"/usr/bin/pcl_convert_pcd_ascii_binary", "/usr/bin/pcl_ply2pcd"}) {
        if (!std::filesystem::exists(tool)) {
            GTEST_SKIP() << tool << " is absent (Debian package pcl-tools, scripts/setup-deps)";
        }
    }
    const auto dir = test::tempDir();
    const PointCloud cloud = syntheticCloud(true);
    ASSERT_TRUE(writePointCloud(dir / "ours.pcd", cloud, PointCloudFormat::kPcd));
    ASSERT_TRUE(writePointCloud(dir / "ours.ply", cloud, PointCloudFormat::kPly));
    const auto run = [&](const std::string& command) {
        const int rc =
            std::system((command + " > " + (dir / "tool.log").string() + " 2>&1").c_str());
        EXPECT_EQ(rc, 0) << command << "\n" << test::readFile(dir / "tool.log");
    };
    run("/usr/bin/pcl_convert_pcd_ascii_binary '" + (dir / "ours.pcd").string() + "' '" +
        (dir / "pcl_ascii.pcd").string() + "' 0");
    auto ascii = readPointCloud(dir / "pcl_ascii.pcd");
    ASSERT_TRUE(ascii) << ascii.status().toString();
    expectSameCloud(*ascii, cloud, "PCL's ASCII rewrite of our PCD");
    EXPECT_EQ(ascii->rgb, cloud.rgb);

    run("/usr/bin/pcl_ply2pcd -format 0 '" + (dir / "ours.ply").string() + "' '" +
        (dir / "pcl_from_ply.pcd").string() + "'");
    auto from_ply = readPointCloud(dir / "pcl_from_ply.pcd");
    ASSERT_TRUE(from_ply) << from_ply.status().toString();
    expectSameCloud(*from_ply, cloud, "PCL's PCD of our PLY");
    EXPECT_EQ(from_ply->rgb, cloud.rgb);
}

// Open3D (Debian python3-open3d) reads the same files: every point, NaN kept, colours equal.
TEST(PointCloud, Open3dReadsOurFiles) {
    if (std::system("/usr/bin/python3 -c 'import open3d' > /dev/null 2>&1") != 0) {
        GTEST_SKIP() << "Open3D is absent (Debian package python3-open3d, scripts/setup-deps)";
    }
    const auto dir = test::tempDir();
    const PointCloud cloud = syntheticCloud(true);
    ASSERT_TRUE(writePointCloud(dir / "b.pcd", cloud, PointCloudFormat::kPcd));
    ASSERT_TRUE(writePointCloud(dir / "a.pcd", cloud, PointCloudFormat::kPcd, PcdEncoding::kAscii));
    ASSERT_TRUE(writePointCloud(dir / "c.ply", cloud, PointCloudFormat::kPly));
    test::writeText(dir / "dump.py",
                    "import sys, open3d\n"
                    "p = open3d.io.read_point_cloud(sys.argv[1], remove_nan_points=False,\n"
                    "                               remove_infinite_points=False)\n"
                    "for x, c in zip(p.points, p.colors):\n"
                    "    print(repr(float(x[0])), repr(float(x[1])), repr(float(x[2])),\n"
                    "          round(c[0] * 255), round(c[1] * 255), round(c[2] * 255))\n");
    for (const char* name : {"b.pcd", "a.pcd", "c.ply"}) {
        const auto out = dir / (std::string(name) + ".txt");
        const std::string command = "/usr/bin/python3 '" + (dir / "dump.py").string() + "' '" +
                                    (dir / name).string() + "' > '" + out.string() + "' 2>&1";
        ASSERT_EQ(std::system(command.c_str()), 0) << name << ": " << test::readFile(out);
        std::istringstream lines(test::readFile(out));
        PointCloud read;
        read.width = cloud.width;
        read.height = cloud.height;
        std::string x, y, z;
        int r = 0, g = 0, b = 0;
        while (lines >> x >> y >> z >> r >> g >> b) {
            for (const std::string& v : {x, y, z}) {
                read.xyz.push_back(v == "nan" ? std::numeric_limits<float>::quiet_NaN()
                                              : static_cast<float>(std::stod(v)));
            }
            for (int c : {r, g, b})
                read.rgb.push_back(static_cast<uint8_t>(c));
        }
        ASSERT_EQ(read.xyz.size(), cloud.xyz.size()) << name << ": " << test::readFile(out);
        expectSameCloud(read, cloud, std::string("Open3D reading our ") + name);
        EXPECT_EQ(read.rgb, cloud.rgb) << name;
    }
}

TEST(PointCloud, WriterNeedsIntrinsicsAndSaysHow) {
    const auto dir = test::tempDir();
    test::writeSyntheticTum(dir / "tum", 2);
    auto reader = openTum(dir / "tum");
    ASSERT_TRUE(reader) << reader.status().toString();
    const RecordingHeader header = headerOf(**reader);
    auto writer = createPointCloudWriter(dir / "clouds", header);
    ASSERT_FALSE(writer);
    EXPECT_EQ(writer.status().code(), ErrorCode::kNotFound);
    EXPECT_TRUE(contains(writer.status().message(), "--intrinsics")) << writer.status().message();
    EXPECT_FALSE(std::filesystem::exists(dir / "clouds"));

    // With intrinsics: one cloud per depth frame, TUM's 5000/m units, registered colour.
    PointCloudWriterOptions options;
    options.intrinsics = PinholeIntrinsics{517.3, 516.5, 15.5, 11.5};
    writer = createPointCloudWriter(dir / "clouds", header, options);
    ASSERT_TRUE(writer) << writer.status().toString();
    auto summary = convertRecording(**reader, **writer);
    ASSERT_TRUE(summary) << summary.status().toString();
    auto first = readPointCloud(dir / "clouds" / "cloud_000000.ply");
    ASSERT_TRUE(first) << first.status().toString();
    EXPECT_TRUE(first->hasColor());
    EXPECT_TRUE(std::filesystem::exists(dir / "clouds" / "cloud_000001.ply"));
    EXPECT_FALSE(std::filesystem::exists(dir / "clouds" / "cloud_000002.ply"));
    // The synthetic depth's first pixel in 5000/m units becomes metres exactly as PCL would.
    ASSERT_TRUE((*reader)->seek(INT64_MIN));
    const auto frames = test::readAll(**reader);
    for (const auto& f : frames) {
        if (f.meta.stream != 1)
            continue;
        const uint16_t raw = f.image.view().row<uint16_t>(0)[0];
        if (raw != 0) {
            EXPECT_FLOAT_EQ(first->xyz[2],
                            static_cast<float>(raw) * static_cast<float>(1.0 / 5000));
        }
        break;
    }
}

}  // namespace
}  // namespace mixray::replay
