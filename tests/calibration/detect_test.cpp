// Target detection and view rejection (calibration/src/detect.cpp): synthetic renders with
// exact corners, the real OpenCV chessboard and ChArUco photos of ../shared/data, image
// folders with bad files, and the simulated calibration session.
#include "mixray/calibration/detect.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <string>

#include "target_render.h"
#include "test_data.h"

namespace mixray::calibration {
namespace {

namespace fs = std::filesystem;
using Eigen::Isometry3d;
using Eigen::Vector2d;

struct Errors {
    double sum = 0, sumsq = 0, max = 0;
    int n = 0;
    Vector2d bias{0, 0};
    void add(const Vector2d& e) {
        sum += e.norm();
        sumsq += e.squaredNorm();
        max = std::max(max, e.norm());
        bias += e;
        ++n;
    }
    double mean() const { return n ? sum / n : 0; }
    double rms() const { return n ? std::sqrt(sumsq / n) : 0; }
    void merge(const Errors& o) {
        sum += o.sum;
        sumsq += o.sumsq;
        max = std::max(max, o.max);
        n += o.n;
        bias += o.bias;
    }
};

cv::Mat matOf(const Image& img) {
    const ImageView v = img.view();
    return cv::Mat(v.desc.height, v.desc.width, CV_8U, const_cast<uint8_t*>(v.data),
                   static_cast<size_t>(v.desc.stride_bytes));
}

ImageView viewOf(const cv::Mat& m) {
    ImageView v;
    v.desc = ImageDesc{m.type() == CV_16U ? PixelFormat::kIR16 : PixelFormat::kMono8, m.cols,
                       m.rows, static_cast<int>(m.step[0])};
    v.data = m.data;
    v.size_bytes = m.step[0] * static_cast<size_t>(m.rows);
    return v;
}

// Detected corners against the projected truth, by id; for a chessboard, whose ends look
// alike (detectors may start at any of them), each against the nearest truth point.
Errors compare(const TargetView& view, const std::vector<Vector2d>& truth, bool chessboard) {
    Errors e;
    for (const Corner& c : view.corners) {
        Vector2d best = c.pixel - truth[static_cast<size_t>(c.id)];
        if (chessboard)
            for (const Vector2d& t : truth)
                if ((c.pixel - t).norm() < best.norm())
                    best = c.pixel - t;
        e.add(best);
    }
    return e;
}

TargetView viewOfPoints(const std::vector<cv::Point2f>& pts) {
    TargetView v;
    for (size_t i = 0; i < pts.size(); ++i)
        v.corners.push_back({static_cast<int>(i), Vector2d(pts[i].x, pts[i].y), 1});
    return v;
}

TEST(Detect, SyntheticChessboardCornersWithinATenthOfAPixel) {
    const auto target = parseTarget("chessboard:9x6:0.03");
    ASSERT_TRUE(target);
    const CameraModel camera = synth::testCamera();
    Errors ours, sb, classic;
    for (const auto& [tilt, yaw] :
         {std::pair{20.0, -15.0}, std::pair{-35.0, 10.0}, std::pair{50.0, 30.0}}) {
        const Isometry3d T = synth::boardPose(*target, 0.55, tilt, yaw);
        const Image img = synth::renderTarget(camera, *target, T);
        const auto truth = synth::projectPoints(camera, *target, T);
        const auto view = detectTarget(img.view(), *target);
        ASSERT_TRUE(view) << view.status().toString();
        ASSERT_EQ(view->rejection, ViewRejection::kNone) << view->why;
        ASSERT_EQ(view->corners.size(), 54u);
        ours.merge(compare(*view, truth, true));
        // OpenCV's detectors alone, for comparison: the sector-based one, and the classic one
        // with cornerSubPix as its tutorial has it.
        std::vector<cv::Point2f> pts;
        ASSERT_TRUE(cv::findChessboardCornersSB(matOf(img), cv::Size(9, 6), pts,
                                                cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY));
        sb.merge(compare(viewOfPoints(pts), truth, true));
        ASSERT_TRUE(cv::findChessboardCorners(matOf(img), cv::Size(9, 6), pts));
        cv::cornerSubPix(
            matOf(img), pts, cv::Size(5, 5), cv::Size(-1, -1),
            cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-4));
        classic.merge(compare(viewOfPoints(pts), truth, true));
    }
    std::printf(
        "synthetic chessboard, 3 poses: ours rms %.3f max %.3f px; findChessboardCornersSB rms "
        "%.3f max %.3f px; findChessboardCorners + cornerSubPix(5x5) rms %.3f max %.3f px\n",
        ours.rms(), ours.max, sb.rms(), sb.max, classic.rms(), classic.max);
    EXPECT_LT(ours.rms(), 0.1);
    EXPECT_LT(ours.max, 0.2);
    EXPECT_LT(ours.rms(), sb.rms());
    EXPECT_LT(ours.rms(), classic.rms());
}

TEST(Detect, SyntheticCharucoCornersWithinATenthOfAPixel) {
    const auto target = parseTarget("charuco:7x5:0.05:0.037:DICT_6X6_250");
    ASSERT_TRUE(target);
    const CameraModel camera = synth::testCamera();
    Errors all, interpolated;
    for (const auto& [tilt, yaw] : {std::pair{25.0, 10.0}, std::pair{-30.0, -20.0}}) {
        const Isometry3d T = synth::boardPose(*target, 0.6, tilt, yaw);
        const Image img = synth::renderTarget(camera, *target, T);
        const auto truth = synth::projectPoints(camera, *target, T);
        const auto view = detectTarget(img.view(), *target);
        ASSERT_TRUE(view) << view.status().toString();
        ASSERT_EQ(view->rejection, ViewRejection::kNone) << view->why;
        EXPECT_EQ(view->corners.size(), 24u);
        all.merge(compare(*view, truth, false));
        // interpolateCornersCharuco's own corners with kCharucoOffsetPx taken off (issue 4's
        // +0.5 px), before our saddle fit: centred on the truth again.
        const auto markers = detectMarkers(img.view(), "DICT_6X6_250");
        ASSERT_TRUE(markers);
        const auto raw =
            charucoCorners(img.view(), {7, 5, 0.05, 0.037, "DICT_6X6_250", 0}, *markers);
        ASSERT_TRUE(raw) << raw.status().toString();
        TargetView rv;
        rv.corners = *raw;
        interpolated.merge(compare(rv, truth, false));
    }
    const Vector2d bias = all.bias / all.n, raw_bias = interpolated.bias / interpolated.n;
    std::printf(
        "synthetic ChArUco: interpolateCornersCharuco − 0.5 px rms %.3f max %.3f px, bias (%.3f, "
        "%.3f) px; with the saddle fit rms %.3f max %.3f px, bias (%.3f, %.3f) px\n",
        interpolated.rms(), interpolated.max, raw_bias.x(), raw_bias.y(), all.rms(), all.max,
        bias.x(), bias.y());
    EXPECT_LT(raw_bias.norm(), 0.1);  // without the shift it would be (0.5, 0.5)
    EXPECT_LT(all.rms(), 0.1);
    EXPECT_LT(all.max, 0.2);
    EXPECT_LT(bias.norm(), 0.05);
}

TEST(Detect, SyntheticAprilGridCornersInKalibrsOrder) {
    const auto target = parseTarget("aprilgrid:4x3:0.04:0.3");
    ASSERT_TRUE(target);
    const CameraModel camera = synth::testCamera();
    const Isometry3d T = synth::boardPose(*target, 0.45, 20, -15);
    const Image img = synth::renderTarget(camera, *target, T);
    const auto truth = synth::projectPoints(camera, *target, T);
    const auto view = detectTarget(img.view(), *target);
    ASSERT_TRUE(view) << view.status().toString();
    ASSERT_EQ(view->rejection, ViewRejection::kNone) << view->why;
    EXPECT_EQ(view->corners.size(), 48u);
    const Errors e = compare(*view, truth, false);
    std::printf("synthetic AprilGrid: %d corners, rms %.3f max %.3f px\n", e.n, e.rms(), e.max);
    EXPECT_LT(e.rms(), 0.1);
    EXPECT_LT(e.max, 0.25);  // a wrong id order would be off by whole tags
}

// The renders draw AprilGrid tags as libapriltag's tag images, upright along +y. Kalibr's
// kalibr_create_target_pdf draws cell (row i from the top, column j) of an upright tag white
// where bit 35 − 6i − j of its code is set (its codes, from Kaess's AprilTags library, are
// listed MSB first, turned twice by np.rot90): for ids 0–2 that is libapriltag's image, cell
// for cell, in the same orientation.
TEST(Detect, AprilGridTagsAreDrawnAsKalibrPrintsThem) {
    const uint64_t kalibr_codes[3] = {0xd5d628584, 0xd97f18b49, 0xdd280910e};
    std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)> tf(tag36h11_create(),
                                                                        tag36h11_destroy);
    for (int id = 0; id < 3; ++id) {
        image_u8_t* im = apriltag_to_image(tf.get(), id);
        for (int i = 0; i < 6; ++i)
            for (int j = 0; j < 6; ++j) {
                const bool white = im->buf[(i + 2) * im->stride + (j + 2)] > 127;
                EXPECT_EQ(white, ((kalibr_codes[id] >> (35 - 6 * i - j)) & 1) != 0)
                    << id << " " << i << " " << j;
            }
        std::free(im->buf);  // libapriltag does not export image_u8_destroy
        std::free(im);
    }
}

TEST(Detect, IrImagesAreStretched) {
    const auto target = parseTarget("charuco:7x5:0.05:0.037:DICT_6X6_250");
    ASSERT_TRUE(target);
    const CameraModel camera = synth::testCamera();
    const Isometry3d T = synth::boardPose(*target, 0.6, 15, 5);
    const Image img = synth::renderTarget(camera, *target, T);
    cv::Mat ir;
    matOf(img).convertTo(ir, CV_16U, 3.0, 200);  // a dim 16-bit signal: 200..965 of 65535
    const auto view = detectTarget(viewOf(ir), *target);
    ASSERT_TRUE(view) << view.status().toString();
    EXPECT_EQ(view->rejection, ViewRejection::kNone) << view->why;
    EXPECT_EQ(view->corners.size(), 24u);
}

TEST(Detect, EachRejectionSaysWhyWithNumbers) {
    const auto target = parseTarget("charuco:7x5:0.05:0.037:DICT_6X6_250");
    ASSERT_TRUE(target);
    const CameraModel camera = synth::testCamera();
    const Isometry3d T = synth::boardPose(*target, 0.6, 40, 0);
    const Image img = synth::renderTarget(camera, *target, T);

    Image blank(ImageDesc::packed(PixelFormat::kMono8, 640, 480));
    std::fill(blank.bytes().begin(), blank.bytes().end(), uint8_t{128});
    auto v = detectTarget(blank.view(), *target);
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rejection, ViewRejection::kNoTarget);
    EXPECT_NE(v->why.find("0 markers"), std::string::npos) << v->why;

    DetectionOptions strict;
    strict.min_point_fraction = 1.0;
    Isometry3d off = T;
    off.translation().x() += 0.2;  // part of the board out of the image
    v = detectTarget(synth::renderTarget(camera, *target, off).view(), *target, strict);
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rejection, ViewRejection::kPartialTarget);
    EXPECT_NE(v->why.find(" of 24 points"), std::string::npos) << v->why;

    // Blur: a chessboard, which OpenCV still finds through it.
    const auto chess = parseTarget("chessboard:9x6:0.03");
    ASSERT_TRUE(chess);
    const Image sharp = synth::renderTarget(camera, *chess, synth::boardPose(*chess, 0.55, 20, 0));
    v = detectTarget(sharp.view(), *chess);
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rejection, ViewRejection::kNone) << v->why;
    cv::Mat blurred;
    cv::GaussianBlur(matOf(sharp), blurred, cv::Size(0, 0), 2.5);
    v = detectTarget(viewOf(blurred), *chess);
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rejection, ViewRejection::kBlurred) << v->why;
    EXPECT_NE(v->why.find("edge blur"), std::string::npos) << v->why;
    std::printf("blur σ 2.5 px: %s; ", v->why.c_str());

    DetectionOptions upright;
    upright.max_tilt_deg = 30;
    upright.camera = camera;
    v = detectTarget(img.view(), *target, upright);
    ASSERT_TRUE(v);
    EXPECT_EQ(v->rejection, ViewRejection::kTooOblique);
    std::printf("tilt: %s\n", v->why.c_str());
    EXPECT_NE(v->why.find("tilted 40"), std::string::npos) << v->why;

    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 64, 48));
    EXPECT_EQ(detectTarget(depth.view(), *target).status().code(), ErrorCode::kInvalidArgument);
}

TEST(Detect, FolderWithBadFilesGivesRejectedViewsNotErrors) {
    const auto target = parseTarget("chessboard:9x6:0.03");
    ASSERT_TRUE(target);
    const CameraModel camera = synth::testCamera();
    const fs::path dir = test::tempDir() / "cam0";
    fs::create_directories(dir);
    const Image img = synth::renderTarget(camera, *target, synth::boardPose(*target, 0.55, 20, 0));
    ASSERT_TRUE(cv::imwrite((dir / "a.png").string(), matOf(img)));
    { std::ofstream(dir / "b.png") << "not a png"; }
    cv::Mat small;
    cv::resize(matOf(img), small, cv::Size(320, 240));
    ASSERT_TRUE(cv::imwrite((dir / "c.png").string(), small));
    ASSERT_TRUE(cv::imwrite((dir / "d.png").string(), cv::Mat(480, 640, CV_8U, cv::Scalar(90))));
    { std::ofstream(dir / "notes.txt") << "skipped by the pattern"; }
    std::vector<double> fractions;
    const auto views = detectInFolder(dir, *target, "*.png", {},
                                      [&](double f, std::string_view) { fractions.push_back(f); });
    ASSERT_TRUE(views) << views.status().toString();
    EXPECT_EQ(views->camera, "cam0");
    EXPECT_EQ(views->width, 640);
    ASSERT_EQ(views->views.size(), 4u);
    EXPECT_EQ(views->views[0].rejection, ViewRejection::kNone) << views->views[0].why;
    EXPECT_EQ(views->views[1].rejection, ViewRejection::kUnreadable);
    EXPECT_EQ(views->views[2].rejection, ViewRejection::kWrongSize);
    EXPECT_NE(views->views[2].why.find("320x240"), std::string::npos);
    EXPECT_EQ(views->views[3].rejection, ViewRejection::kNoTarget);
    EXPECT_EQ(views->views[3].key, 3);
    EXPECT_EQ(fractions, (std::vector<double>{0.25, 0.5, 0.75, 1.0}));
    EXPECT_EQ(detectInFolder(dir / "nope", *target).status().code(), ErrorCode::kNotFound);
    EXPECT_EQ(detectInFolder(dir, *target, "*.jpg").status().code(), ErrorCode::kNotFound);
}

// ---- real photos ----

Vector2d nearest(const Vector2d& p, const std::vector<cv::Point2f>& pts) {
    Vector2d best(1e9, 1e9);
    for (const cv::Point2f& q : pts)
        if ((Vector2d(q.x, q.y) - p).norm() < (best - p).norm())
            best = Vector2d(q.x, q.y);
    return best;
}

TEST(Detect, OpenCvLeftChessboardsAllFoundAndAgreeWithCornerSubPix) {
    const fs::path dir = test::sharedDataDir() / "03_calib_chessboard_stereo_opencv";
    MIXRAY_REQUIRE_SHARED_DATA(dir / "left01.jpg");
    const auto target = parseTarget("chessboard:9x6:0.025");
    ASSERT_TRUE(target);
    const auto views = detectInFolder(dir, *target, "left*.jpg");
    ASSERT_TRUE(views) << views.status().toString();
    ASSERT_EQ(views->views.size(), 13u);
    // The reference: OpenCV's tutorial, findChessboardCorners + cornerSubPix with an 11x11
    // half-window. On the small far squares that 23 px window takes in neighbouring corners
    // and drifts (up to 6.4 px from the same with a 5x5 half-window on left02.jpg): corners
    // where the two windows disagree by more than half a pixel are the reference's failures
    // and are counted, not compared.
    Errors all;
    int unstable = 0;
    double worst_blur = 0;
    for (const TargetView& v : views->views) {
        ASSERT_EQ(v.rejection, ViewRejection::kNone) << v.source << ": " << v.why;
        ASSERT_EQ(v.corners.size(), 54u) << v.source;
        const cv::Mat grey = cv::imread(v.source, cv::IMREAD_GRAYSCALE);
        std::vector<cv::Point2f> wide, narrow;
        ASSERT_TRUE(cv::findChessboardCorners(grey, cv::Size(9, 6), wide)) << v.source;
        narrow = wide;
        const cv::TermCriteria stop(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.001);
        cv::cornerSubPix(grey, wide, cv::Size(11, 11), cv::Size(-1, -1), stop);
        cv::cornerSubPix(grey, narrow, cv::Size(5, 5), cv::Size(-1, -1), stop);
        for (const Corner& c : v.corners) {
            const Vector2d ref = nearest(c.pixel, wide);
            if ((nearest(ref, narrow) - ref).norm() > 0.5) {
                ++unstable;
                EXPECT_LT((nearest(c.pixel, narrow) - c.pixel).norm(), 0.5) << v.source;
                continue;
            }
            all.add(c.pixel - ref);
        }
        DetectionOptions probe;
        probe.max_edge_blur_px = 1e-3;  // every view "blurred": its why has the number
        const auto b = detectTarget(viewOf(grey), *target, probe);
        ASSERT_TRUE(b);
        worst_blur = std::max(worst_blur, std::atof(b->why.c_str() + b->why.find("blur ") + 5));
    }
    std::printf(
        "left*.jpg: 13/13 boards, 54 corners each; vs findChessboardCorners + "
        "cornerSubPix(11x11) over %d corners: mean %.3f rms %.3f max %.3f px (%d corners "
        "where the reference drifts left out); worst edge blur %.2f px\n",
        all.n, all.mean(), all.rms(), all.max, unstable, worst_blur);
    EXPECT_LT(all.mean(), 0.1);
    EXPECT_LT(unstable, 13 * 54 / 20);
    EXPECT_LT(worst_blur, DetectionOptions{}.max_edge_blur_px);
}

TEST(Detect, OpenCvCharucoPhoto) {
    const fs::path dir = test::sharedDataDir() / "03_aruco_charuco_opencv";
    MIXRAY_REQUIRE_SHARED_DATA(dir / "choriginal.jpg");
    const auto target = parseTarget("charuco:5x7:0.04:0.02:DICT_6X6_250");
    ASSERT_TRUE(target);
    const cv::Mat img = cv::imread((dir / "choriginal.jpg").string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty());
    ImageView v;
    v.desc = ImageDesc{PixelFormat::kBGR8, img.cols, img.rows, static_cast<int>(img.step[0])};
    v.data = img.data;
    v.size_bytes = img.step[0] * static_cast<size_t>(img.rows);
    const auto view = detectTarget(v, *target);
    ASSERT_TRUE(view) << view.status().toString();
    EXPECT_EQ(view->rejection, ViewRejection::kNone) << view->why;
    std::printf("choriginal.jpg: %zu of 24 ChArUco corners\n", view->corners.size());
    EXPECT_GE(view->corners.size(), 20u);
}

// ---- the simulated session ----

// Per frame, the fraction of the board's corners inside each camera's image (the truth file's
// board_seen: {color: C, ir: I, env: E}).
std::vector<std::array<double, 3>> boardSeen(const fs::path& truth) {
    std::ifstream in(truth);
    std::vector<std::array<double, 3>> out;
    for (std::string line; std::getline(in, line);) {
        const auto k = line.find("board_seen: {color: ");
        if (k == std::string::npos)
            continue;
        std::array<double, 3> f{};
        const char* p = line.c_str() + k + 20;
        f[0] = std::atof(p);
        f[1] = std::atof(line.c_str() + line.find("ir: ", k) + 4);
        f[2] = std::atof(line.c_str() + line.find("env: ", k) + 5);
        out.push_back(f);
    }
    return out;
}

TEST(Detect, SimulatedCalibrationSessionViewsShareKeysAcrossCameras) {
    const fs::path dir = test::fixturesDir() / "sessions";
    ASSERT_TRUE(fs::exists(dir / "sim_calibration.mkv"));
    const auto seen = boardSeen(dir / "sim_calibration.truth.yaml");
    ASSERT_EQ(seen.size(), 20u);
    const auto target = parseTarget("charuco:7x5:0.05:0.037:DICT_6X6_250");
    ASSERT_TRUE(target);
    int calls = 0;
    double last = 0;
    DetectionOptions options;
    options.marker_dictionary = "DICT_6X6_250";  // the world marker, id 23
    const auto detection = detectInRecording(dir / "sim_calibration.mkv", *target, options,
                                             [&](double f, std::string_view) {
                                                 ++calls;
                                                 EXPECT_GE(f, last);
                                                 last = f;
                                             });
    ASSERT_TRUE(detection) << detection.status().toString();
    EXPECT_EQ(last, 1.0);
    EXPECT_EQ(calls, 3 * 20);
    std::map<std::string, const CameraViews*> by;
    for (const CameraViews& c : detection->cameras)
        by[c.camera] = &c;
    ASSERT_EQ(by.size(), 3u);  // kinect/depth and truth/pose are no images of the board
    const std::array<const char*, 3> names = {"kinect/color", "kinect/ir", "env/color"};
    for (size_t k = 0; k < names.size(); ++k) {
        ASSERT_TRUE(by.count(names[k])) << names[k];
        const CameraViews& c = *by[names[k]];
        ASSERT_EQ(c.views.size(), 20u) << names[k];
        std::string counts;
        size_t found_total = 0, in_view_total = 0;
        for (size_t i = 0; i < c.views.size(); ++i) {
            // One key per capture instant, the same in every stream.
            EXPECT_EQ(c.views[i].key, static_cast<int64_t>(i)) << names[k];
            const double truth = seen[i][k];
            const size_t found = c.views[i].corners.size();
            const auto in_view = static_cast<size_t>(std::lround(24 * truth));
            counts += " " + std::to_string(found) + "/" + std::to_string(in_view);
            // Never more corners than the truth has in the image; none where it has none.
            EXPECT_LE(found, in_view) << names[k] << " " << i;
            found_total += found;
            in_view_total += in_view;
            // Every third view holds the board over the fish-eye, close: most of it found there.
            if (k == 2 && i % 3 == 2) {
                EXPECT_GE(found, 16u) << names[k] << " " << i;
            }
        }
        std::printf("%s corners found/in view per frame:%s\n", names[k], counts.c_str());
        if (k < 2) {
            // The Kinect's cameras: the board is placed across the whole image, partly beyond
            // its edges, where markers cut by the edge take their corners with them (found
            // 414 of 478 colour corners, 420 of 469 IR).
            EXPECT_GE(static_cast<double>(found_total), 0.85 * static_cast<double>(in_view_total))
                << names[k];
        }
    }

    // The raw depth stream, aligned with the IR camera, at every key some camera saw the board.
    ASSERT_EQ(detection->depth.size(), 1u);
    const RecordedDepth& depth = detection->depth.front();
    EXPECT_EQ(depth.stream, "kinect/depth");
    EXPECT_EQ(depth.aligned_with, "kinect/ir");
    std::set<int64_t> usable;
    for (const CameraViews& c : detection->cameras)
        for (const TargetView* v : c.usable())
            usable.insert(v->key);
    ASSERT_EQ(depth.frames.size(), usable.size());
    for (const KeyedDepthImage& d : depth.frames) {
        EXPECT_TRUE(usable.count(d.key)) << d.key;
        EXPECT_EQ(d.depth_mm.desc().format, PixelFormat::kDepth16);
        EXPECT_EQ(d.depth_mm.desc().width, 640);
    }

    // The world marker on the table, where the colour camera sees it whole.
    const CameraViews& color = *by["kinect/color"];
    int with_marker = 0;
    for (const TargetView& v : color.views)
        for (const SeenMarker& m : v.markers)
            with_marker += m.id == 23;
    // The six views over the fish-eye are drawn so that the colour camera sees the marker.
    EXPECT_GE(with_marker, 6);
    std::printf("world marker in %d of %zu colour views\n", with_marker, color.views.size());
}

}  // namespace
}  // namespace mixray::calibration
