// Calibration targets (calibration/src/target.cpp) and the corners cache
// (calibration/src/corners_cache.cpp): point layouts against OpenCV and Kalibr, spec strings,
// the .vnl round trip and mrcal-calibrate-cameras reading what we write.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "mixray/calibration/corners_cache.h"
#include "mixray/calibration/detect.h"
#include "mixray/calibration/target.h"
#include "test_data.h"

namespace mixray::calibration {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector2d;
using Eigen::Vector3d;

CalibrationTarget charuco(int cols, int rows, double square, double marker) {
    CalibrationTarget t;
    t.kind = TargetKind::kCharuco;
    t.cols = cols;
    t.rows = rows;
    t.square_m = square;
    t.marker_m = marker;
    t.dictionary = "DICT_6X6_250";
    return t;
}

TEST(Targets, CharucoPointsAreOpenCvsChessboardCorners) {
    for (const auto& [cols, rows] : {std::pair{7, 5}, std::pair{5, 7}, std::pair{3, 4}}) {
        const CalibrationTarget t = charuco(cols, rows, 0.05, 0.037);
        ASSERT_TRUE(t.validate()) << t.validate().toString();
        const auto board = cv::aruco::CharucoBoard::create(
            cols, rows, 0.05f, 0.037f, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250));
        const auto pts = t.points();
        ASSERT_EQ(pts.size(), board->chessboardCorners.size());
        ASSERT_EQ(t.pointCount(), static_cast<int>(pts.size()));
        for (size_t i = 0; i < pts.size(); ++i) {
            const cv::Point3f& p = board->chessboardCorners[i];
            EXPECT_NEAR(pts[i].x(), p.x, 1e-6) << i;
            EXPECT_NEAR(pts[i].y(), p.y, 1e-6) << i;
            EXPECT_EQ(pts[i].z(), 0);
        }
    }
}

TEST(Targets, ChessboardPointsAreRowMajor) {
    const auto t = parseTarget("chessboard:9x6:0.025");
    ASSERT_TRUE(t) << t.status().toString();
    const auto pts = t->points();
    ASSERT_EQ(pts.size(), 54u);
    EXPECT_TRUE(pts[1].isApprox(Vector3d(0.025, 0, 0)));
    EXPECT_TRUE(pts[9].isApprox(Vector3d(0, 0.025, 0)));
    EXPECT_TRUE(pts[53].isApprox(Vector3d(0.2, 0.125, 0)));
}

TEST(Targets, AprilGridIsKalibrsLayout) {
    // Kalibr's createGridPoints for 2x2 tags of 0.1 m at spacing 0.3: ids 0..15 on a 4x4 grid.
    const auto t = parseTarget("aprilgrid:2x2:0.1:0.3");
    ASSERT_TRUE(t) << t.status().toString();
    EXPECT_EQ(t->dictionary, "apriltag:tag36h11");
    const auto pts = t->points();
    ASSERT_EQ(pts.size(), 16u);
    const double a[4] = {0, 0.1, 0.13, 0.23};  // (c / 2)(1 + 0.3) 0.1 + (c % 2) 0.1
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            EXPECT_TRUE(pts[static_cast<size_t>(r * 4 + c)].isApprox(Vector3d(a[c], a[r], 0)))
                << r << " " << c;
    // Tag 3 (upper right) owns ids 10, 11, 15, 14: Kalibr's baseId = 1·2·4 + 1·2 = 10.
    EXPECT_TRUE(pts[10].isApprox(Vector3d(0.13, 0.13, 0)));
    EXPECT_TRUE(pts[15].isApprox(Vector3d(0.23, 0.23, 0)));
}

TEST(Targets, SpecsRoundTripAndBadSpecsNameTheirPart) {
    for (const char* spec : {"chessboard:9x6:0.025", "charuco:7x5:0.05:0.037:DICT_6X6_250",
                             "aprilgrid:6x6:0.088:0.3"}) {
        const auto t = parseTarget(spec);
        ASSERT_TRUE(t) << spec << ": " << t.status().toString();
        EXPECT_EQ(t->spec(), spec);
    }
    const auto bad = [](const char* spec) {
        const auto t = parseTarget(spec);
        EXPECT_FALSE(t) << spec;
        return t ? std::string() : t.status().message();
    };
    EXPECT_NE(bad("circles:9x6:0.02").find("kind"), std::string::npos);
    EXPECT_NE(bad("chessboard:9by6:0.025").find("COLSxROWS"), std::string::npos);
    EXPECT_NE(bad("chessboard:9x6:big").find("metres"), std::string::npos);
    EXPECT_NE(bad("chessboard:1x6:0.025").find("cols and rows"), std::string::npos);
    EXPECT_NE(bad("charuco:7x5:0.05:0.06:DICT_6X6_250").find("marker_m"), std::string::npos);
    EXPECT_NE(bad("charuco:7x5:0.05:0.03:DICT_NOPE").find("dictionary"), std::string::npos);
    EXPECT_NE(bad("charuco:40x40:0.05:0.03:DICT_4X4_50").find("do not fit"), std::string::npos);
    EXPECT_NE(bad("aprilgrid:6x6:0.088").find("aprilgrid:COLSxROWS"), std::string::npos);
    EXPECT_NE(bad("aprilgrid:6x6:0.088:0").find("tag_spacing"), std::string::npos);
}

TEST(Targets, UsableViewsAreTheUnrejected) {
    CameraViews cam;
    cam.views.resize(3);
    cam.views[1].rejection = ViewRejection::kBlurred;
    const auto used = cam.usable();
    ASSERT_EQ(used.size(), 2u);
    EXPECT_EQ(used[0], &cam.views[0]);
    EXPECT_EQ(used[1], &cam.views[2]);
    EXPECT_EQ(toString(ViewRejection::kTooOblique), "too oblique");
}

// ---- corners cache ----

TEST(CornersCache, RoundTripsCamerasKeysIdsWeightsAndRejections) {
    const fs::path dir = test::tempDir();
    CameraViews a, b;
    a.camera = "kinect/color";
    a.width = 640;
    a.height = 480;
    a.target = charuco(7, 5, 0.05, 0.037);
    b = a;
    b.camera = "env camera";  // names may hold spaces
    b.width = 480;
    TargetView v;
    v.source = "sim.mkv#kinect/color@3";
    v.key = 3;
    v.corners = {{0, Vector2d(10.25, 20.5), 1.0},
                 {7, Vector2d(101.125, 3.0625), 0.5},
                 {23, Vector2d(600.1, 470.9), 0.25}};
    a.views.push_back(v);
    TargetView r;
    r.source = "sim.mkv#kinect/color@4";
    r.key = 4;
    r.rejection = ViewRejection::kBlurred;
    r.why = "edge blur 5.1 px > 4.0 px";
    a.views.push_back(r);
    v.source = "sim.mkv#env/color@3";
    b.views.push_back(v);
    const fs::path file = dir / "corners.vnl";
    ASSERT_TRUE(writeCornersCache(file, {a, b}));
    const auto back = readCornersCache(file);
    ASSERT_TRUE(back) << back.status().toString();
    ASSERT_EQ(back->size(), 2u);
    EXPECT_EQ((*back)[1].camera, "env camera");
    EXPECT_EQ((*back)[1].width, 480);
    EXPECT_EQ((*back)[0].target.spec(), a.target.spec());
    const CameraViews& got = (*back)[0];
    ASSERT_EQ(got.views.size(), 2u);
    EXPECT_EQ(got.views[0].source, v.source.substr(0, 0) + "sim.mkv#kinect/color@3");
    EXPECT_EQ(got.views[0].key, 3);
    ASSERT_EQ(got.views[0].corners.size(), 3u);
    for (size_t i = 0; i < 3; ++i) {
        EXPECT_EQ(got.views[0].corners[i].id, v.corners[i].id);
        EXPECT_EQ(got.views[0].corners[i].pixel, v.corners[i].pixel);  // exact: shortest repr
        EXPECT_EQ(got.views[0].corners[i].weight, v.corners[i].weight);
    }
    EXPECT_EQ(got.views[1].rejection, ViewRejection::kBlurred);
    EXPECT_EQ(got.views[1].why, r.why);
    EXPECT_TRUE(got.views[1].corners.empty());
    // One row per ChArUco corner: 24 for the used view, mrcal's "- -" for the rejected one.
    std::ifstream in(file);
    int rows = 0, missing = 0;
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("sim.mkv#kinect/color@3 ", 0) == 0)
            ++rows;
        if (line == "sim.mkv#kinect/color@3 - - -")
            ++missing;
    }
    EXPECT_EQ(rows, 24);
    EXPECT_EQ(missing, 21);
}

TEST(CornersCache, ReadsMrcalsOwnFilesAndRejectsShortViews) {
    const fs::path dir = test::tempDir();
    const auto target = parseTarget("chessboard:3x2:0.02");
    ASSERT_TRUE(target);
    {
        std::ofstream f(dir / "mrgingham.vnl");
        f << "# filename x y level\n"
             "a.jpg 1 2 0\na.jpg 3 4 1\na.jpg - - -\na.jpg 7 8 -\na.jpg 9 10 0\na.jpg 11 12 2\n"
             "b.jpg - -\n";
    }
    EXPECT_FALSE(readCornersCache(dir / "mrgingham.vnl"));  // no target known
    const auto got = readCornersCache(dir / "mrgingham.vnl", *target, ImageSize{640, 480});
    ASSERT_TRUE(got) << got.status().toString();
    ASSERT_EQ(got->size(), 1u);
    EXPECT_EQ((*got)[0].width, 640);
    EXPECT_EQ((*got)[0].height, 480);
    const auto& views = (*got)[0].views;
    ASSERT_EQ(views.size(), 2u);
    EXPECT_EQ(views[1].key, 1);
    ASSERT_EQ(views[0].corners.size(), 4u);
    EXPECT_EQ(views[0].corners[1].weight, 0.5);
    EXPECT_EQ(views[0].corners[2].id, 4);
    EXPECT_EQ(views[0].corners[3].weight, 0.25);
    EXPECT_EQ(views[1].rejection, ViewRejection::kNoTarget);
    {
        std::ofstream f(dir / "short.vnl");
        f << "# filename x y level\na.jpg 1 2 0\na.jpg 3 4 0\n";
    }
    const auto bad = readCornersCache(dir / "short.vnl", *target);
    ASSERT_FALSE(bad);
    EXPECT_EQ(bad.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(bad.status().message().find("short.vnl:2"), std::string::npos)
        << bad.status().message();
    EXPECT_EQ(readCornersCache(dir / "absent.vnl", *target).status().code(), ErrorCode::kNotFound);
}

// mrcal's caches carry no image size: it comes from the size given, else from the image the
// first view with corners names (as mrcal-calibrate-cameras: from the working directory or
// next to the cache), else the error says which file was looked for and how to give the size.
TEST(CornersCache, MrcalCachesTakeTheImageSizeFromTheImagesOrSayWhich) {
    const fs::path dir = test::tempDir();
    const auto target = parseTarget("chessboard:3x2:0.02");
    ASSERT_TRUE(target);
    {
        std::ofstream f(dir / "mrcal.vnl");
        f << "# filename x y level\nnone.png - -\n";
        for (int i = 0; i < 6; ++i)
            f << "view0.png " << 10 + i << " " << 20 + i << " 0\n";
    }
    const auto absent = readCornersCache(dir / "mrcal.vnl", *target);
    ASSERT_FALSE(absent);
    EXPECT_EQ(absent.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(absent.status().message().find((dir / "view0.png").string()), std::string::npos)
        << absent.status().message();
    EXPECT_NE(absent.status().message().find("--image-size"), std::string::npos)
        << absent.status().message();

    std::ofstream(dir / "view0.png") << "not a PNG";
    const auto unreadable = readCornersCache(dir / "mrcal.vnl", *target);
    ASSERT_FALSE(unreadable);
    EXPECT_NE(unreadable.status().message().find("cannot be read"), std::string::npos)
        << unreadable.status().message();

    ASSERT_TRUE(cv::imwrite((dir / "view0.png").string(), cv::Mat(123, 321, CV_8UC1, 7)));
    const auto from_image = readCornersCache(dir / "mrcal.vnl", *target);
    ASSERT_TRUE(from_image) << from_image.status().toString();
    EXPECT_EQ((*from_image)[0].width, 321);
    EXPECT_EQ((*from_image)[0].height, 123);

    // The size given wins over the images, as mrcal's --imagersize does.
    const auto given = readCornersCache(dir / "mrcal.vnl", *target, ImageSize{4000, 2200});
    ASSERT_TRUE(given) << given.status().toString();
    EXPECT_EQ((*given)[0].width, 4000);
    EXPECT_EQ((*given)[0].height, 2200);
    EXPECT_FALSE(readCornersCache(dir / "mrcal.vnl", *target, ImageSize{0, 2200}));

    // A mixray cache names its sizes: a different one given is refused, not silently used.
    CameraViews camera = (*given)[0];
    camera.camera = "cam";
    ASSERT_TRUE(writeCornersCache(dir / "mixray.vnl", {camera}));
    EXPECT_EQ(readCornersCache(dir / "mixray.vnl", {}, ImageSize{4000, 2200})->front().width, 4000);
    const auto differs = readCornersCache(dir / "mixray.vnl", {}, ImageSize{640, 480});
    ASSERT_FALSE(differs);
    EXPECT_NE(differs.status().message().find("4000x2200, not 640x480"), std::string::npos)
        << differs.status().message();
}

TEST(CornersCache, MrcalCalibrateCamerasReadsWhatWeWrite) {
    const fs::path data = test::sharedDataDir() / "03_calib_chessboard_stereo_opencv";
    MIXRAY_REQUIRE_SHARED_DATA(data / "left01.jpg");
    if (!fs::exists("/usr/bin/mrcal-calibrate-cameras") || !fs::exists("/usr/bin/python3"))
        GTEST_SKIP() << "mrcal-calibrate-cameras not installed";
    const auto target = parseTarget("chessboard:9x6:0.025");
    ASSERT_TRUE(target);
    const auto views = detectInFolder(data, *target, "left*.jpg");
    ASSERT_TRUE(views) << views.status().toString();
    const fs::path dir = test::tempDir();
    ASSERT_TRUE(writeCornersCache(dir / "corners.vnl", {*views}));
    const std::string cmd = "cd " + dir.string() +
                            " && /usr/bin/python3 /usr/bin/mrcal-calibrate-cameras --corners-cache "
                            "corners.vnl --lensmodel LENSMODEL_OPENCV8 --focal 500 "
                            "--object-spacing 0.025 --object-width-n 9 --object-height-n 6 "
                            "--imagersize 640 480 --outdir " +
                            dir.string() + " 'left*.jpg' > mrcal.log 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << "see " << (dir / "mrcal.log");
    std::ifstream model(dir / "camera-0.cameramodel");
    ASSERT_TRUE(model) << "mrcal wrote no model; see " << (dir / "mrcal.log");
    std::string text((std::istreambuf_iterator<char>(model)), std::istreambuf_iterator<char>());
    // Its focal length near OpenCV's published 535.9 px for these images.
    const auto k = text.find("'intrinsics'");
    ASSERT_NE(k, std::string::npos);
    const double fx = std::atof(text.c_str() + text.find('[', k) + 1);
    std::printf("mrcal-calibrate-cameras on our corners cache: fx %.2f px\n", fx);
    EXPECT_NEAR(fx, 535.9, 10);
}

}  // namespace
}  // namespace mixray::calibration
