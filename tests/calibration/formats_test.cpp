// Import and export of other tools' calibration formats (calibration/src/calibration_formats.cpp):
// round trips for every model each format holds, errors for those it cannot, the real OpenCV
// and mrcal files of ../shared/data, and OpenCV's own cv::FileStorage reading what mixray writes
// and writing what mixray reads.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/ros_camera_info.h"
#include "test_data.h"

namespace mixray::calibration {
namespace {

namespace fs = std::filesystem;

CameraModel withLens(LensModel lens, std::vector<double> distortion) {
    CameraModel m = CameraModel::pinhole(640, 480, 525.123456789, 526.5, 319.25, 241.75);
    m.lens = lens;
    m.distortion = std::move(distortion);
    return m;
}

struct NamedModel {
    std::string name;
    CameraModel model;
};

std::vector<NamedModel> allModels() {
    return {
        {"opencv0", withLens(LensModel::kPinhole, {})},
        {"opencv4", withLens(LensModel::kPinhole, {0.1, -0.2, 1e-3, -2e-3})},
        {"opencv5", withLens(LensModel::kPinhole, {0.1, -0.2, 1e-3, -2e-3, 0.05})},
        {"opencv8",
         withLens(LensModel::kPinhole, {0.1, -0.2, 1e-3, -2e-3, 0.05, 0.01, -0.02, 0.003})},
        {"fisheye", withLens(LensModel::kFisheye, {0.02, -0.005, 0.001, -2e-4})},
    };
}

CalibrationFile oneCamera(const std::string& name, const CameraModel& model) {
    CalibrationFile f;
    CalibratedCamera c;
    c.name = name;
    c.model = model;
    f.cameras.push_back(c);
    return f;
}

using mixray::test::readText;
using mixray::test::writeText;

// A valid file made invalid: `from` replaced by `to`; `expected` is what the error says after
// the path (line, column, field and cause).
struct BrokenEdit {
    std::string from, to, expected;
};

// Each edit of `original`, written to `path` and imported as `format`, is refused as
// kCorruptData naming the path, line, column and field.
void expectEditsRefused(const std::string& original, const std::vector<BrokenEdit>& edits,
                        const fs::path& path, CalibrationFormat format) {
    for (const BrokenEdit& c : edits) {
        SCOPED_TRACE(c.to);
        std::string text = original;
        const size_t at = text.find(c.from);
        ASSERT_NE(at, std::string::npos);
        text.replace(at, c.from.size(), c.to);
        writeText(path, text);
        auto f = importCalibration(path, format);
        ASSERT_FALSE(f.isOk());
        EXPECT_EQ(f.status().code(), ErrorCode::kCorruptData);
        EXPECT_NE(f.status().message().find(path.string() + c.expected), std::string::npos)
            << f.status().message();
    }
}

void expectSameModel(const CameraModel& a, const CameraModel& b) {
    EXPECT_EQ(a.lens, b.lens);
    EXPECT_EQ(a.width, b.width);
    EXPECT_EQ(a.height, b.height);
    EXPECT_EQ(a.fx, b.fx);
    EXPECT_EQ(a.fy, b.fy);
    EXPECT_EQ(a.cx, b.cx);
    EXPECT_EQ(a.cy, b.cy);
    EXPECT_EQ(a.distortion, b.distortion);
}

// The same pixels for the same points: models that differ only in zero terms agree.
void expectSameProjection(const CameraModel& a, const CameraModel& b) {
    for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.1, 0.2, 1), Eigen::Vector3d(-0.4, 0.3, 1),
                                     Eigen::Vector3d(0.5, -0.35, 0.9)}) {
        auto pa = a.project(p);
        auto pb = b.project(p);
        ASSERT_TRUE(pa && pb);
        EXPECT_LT((*pa - *pb).norm(), 1e-12);
    }
}

// ---- OpenCV FileStorage ----

TEST(OpenCVFormat, ReadsOpenCVsOwnLeftIntrinsics) {
    const fs::path path =
        test::sharedDataDir() / "03_calib_chessboard_stereo_opencv/left_intrinsics.yml";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto f = importCalibration(path);  // recognised from the content
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    ASSERT_EQ(f->cameras.size(), 1u);
    const CalibratedCamera& c = f->cameras[0];
    EXPECT_EQ(c.name, "left_intrinsics");
    EXPECT_EQ(c.model.lens, LensModel::kPinhole);
    EXPECT_EQ(c.model.width, 640);
    EXPECT_EQ(c.model.height, 480);
    // The published numbers (MANIFEST.md, left_intrinsics.yml L11-24), to the file's digits.
    EXPECT_EQ(c.model.fx, 5.3591573396163199e+02);
    EXPECT_EQ(c.model.fy, 5.3591573396163199e+02);
    EXPECT_EQ(c.model.cx, 3.4228315473308373e+02);
    EXPECT_EQ(c.model.cy, 2.3557082909788173e+02);
    ASSERT_EQ(c.model.distortion.size(), 5u);
    EXPECT_EQ(c.model.distortion[0], -2.6637260909660682e-01);
    EXPECT_EQ(c.model.distortion[4], 2.3839153080878486e-01);
    EXPECT_EQ(c.rms_px, 3.9259098975581364e-01);
    EXPECT_EQ(c.views, 13);
    EXPECT_TRUE(c.parent.empty());
}

TEST(OpenCVFormat, ReadsTheArucoTutorialCameraWithoutImageSize) {
    const fs::path dir = test::tempDir();
    const fs::path path =
        test::sharedDataDir() / "03_aruco_charuco_opencv/tutorial_camera_params.yml";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto f = importCalibration(path);
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    const CalibratedCamera& c = f->cameras[0];
    EXPECT_EQ(c.name, "tutorial_camera_params");
    EXPECT_EQ(c.model.fx, 628.158);
    EXPECT_EQ(c.model.fy, 628.156);
    EXPECT_EQ(c.model.cx, 324.099);
    EXPECT_EQ(c.model.cy, 260.908);
    EXPECT_EQ(c.model.distortion,
              (std::vector<double>{0.0995485, -0.206384, 0.00754589, 0.00336531, 0}));
    // The file gives no image size: not known, and writing it elsewhere says so.
    EXPECT_EQ(c.model.width, 0);
    EXPECT_EQ(c.model.height, 0);
    const Status s = exportCalibration(dir / "x.yaml", *f, CalibrationFormat::kRos);
    EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(s.message().find("tutorial_camera_params"), std::string::npos) << s.message();
    CalibrationFile sized = *f;
    sized.cameras[0].model.width = 640;
    sized.cameras[0].model.height = 480;
    EXPECT_TRUE(exportCalibration(dir / "x.yaml", sized, CalibrationFormat::kRos).isOk());
}

TEST(OpenCVFormat, RoundTripsEveryModel) {
    const fs::path dir = test::tempDir();
    for (const NamedModel& m : allModels()) {
        SCOPED_TRACE(m.name);
        CalibrationFile f = oneCamera("kinect/color", m.model);
        f.cameras[0].rms_px = 0.3125;
        f.cameras[0].views = 17;
        f.created = "2026-11-22T14:00:00Z";
        for (const char* ext : {".yml", ".xml", ".json"}) {
            SCOPED_TRACE(ext);
            const fs::path path = dir / (m.name + ext);
            ASSERT_TRUE(exportCalibration(path, f, CalibrationFormat::kOpenCV).isOk());
            auto back = importCalibration(path);
            ASSERT_TRUE(back.isOk()) << back.status().toString() << "\n" << readText(path);
            expectSameModel(m.model, back->cameras[0].model);
            EXPECT_EQ(back->cameras[0].name, "kinect/color");
            EXPECT_EQ(back->cameras[0].rms_px, 0.3125);
            EXPECT_EQ(back->cameras[0].views, 17);
            EXPECT_EQ(back->created, "2026-11-22T14:00:00Z");
        }
    }
}

TEST(OpenCVFormat, OpenCVReadsWhatMixrayWrites) {
    const fs::path dir = test::tempDir();
    for (const NamedModel& m : allModels()) {
        SCOPED_TRACE(m.name);
        const fs::path path = dir / (m.name + ".yml");
        ASSERT_TRUE(
            exportCalibration(path, oneCamera("cam", m.model), CalibrationFormat::kOpenCV).isOk());
        EXPECT_EQ(readText(path).rfind("%YAML:1.0", 0), 0u);
        cv::FileStorage fs(path.string(), cv::FileStorage::READ);
        ASSERT_TRUE(fs.isOpened());
        cv::Mat K, D;
        fs["camera_matrix"] >> K;
        fs["distortion_coefficients"] >> D;
        ASSERT_EQ(K.rows, 3);
        ASSERT_EQ(K.cols, 3);
        EXPECT_EQ(K.at<double>(0, 0), m.model.fx);
        EXPECT_EQ(K.at<double>(1, 1), m.model.fy);
        EXPECT_EQ(K.at<double>(0, 2), m.model.cx);
        EXPECT_EQ(K.at<double>(1, 2), m.model.cy);
        EXPECT_EQ(K.at<double>(0, 1), 0.0);
        EXPECT_EQ(K.at<double>(2, 2), 1.0);
        ASSERT_EQ(D.total(), m.model.distortion.size());
        for (size_t i = 0; i < m.model.distortion.size(); ++i)
            EXPECT_EQ(D.at<double>(static_cast<int>(i)), m.model.distortion[i]);
        EXPECT_EQ(static_cast<int>(fs["image_width"]), 640);
        EXPECT_EQ(static_cast<int>(fs["image_height"]), 480);
        EXPECT_EQ(static_cast<int>(fs["fisheye_model"]), m.model.lens == LensModel::kFisheye);
    }
}

// Files as OpenCV's samples write them: cv::FileStorage writes, mixray reads.
TEST(OpenCVFormat, MixrayReadsWhatOpenCVWrites) {
    const fs::path dir = test::tempDir();
    auto write = [&](const std::string& name, const cv::Mat& D, int fisheye) {
        const fs::path path = dir / name;
        cv::FileStorage fs(path.string(), cv::FileStorage::WRITE);
        fs << "calibration_time"
           << "Sun Nov 22 14:00:00 2026";
        fs << "nr_of_frames" << 25 << "image_width" << 1280 << "image_height" << 720;
        if (fisheye >= 0)
            fs << "fisheye_model" << fisheye;
        fs << "camera_matrix" << cv::Mat(cv::Matx33d(900, 0, 640.5, 0, 901, 359.5, 0, 0, 1));
        fs << "distortion_coefficients" << D;
        fs << "avg_reprojection_error" << 0.25;
        return path;
    };
    // The tutorial's pinhole output (fisheye_model: 0) with OpenCV's 5 coefficients.
    auto pinhole = importCalibration(
        write("pinhole.yml", cv::Mat(cv::Matx<double, 5, 1>(0.1, -0.2, 0.001, 0.002, 0.03)), 0));
    ASSERT_TRUE(pinhole.isOk()) << pinhole.status().toString();
    EXPECT_EQ(pinhole->cameras[0].model.lens, LensModel::kPinhole);
    EXPECT_EQ(pinhole->cameras[0].model.distortion.size(), 5u);
    EXPECT_EQ(pinhole->cameras[0].model.width, 1280);
    EXPECT_EQ(pinhole->cameras[0].views, 25);
    EXPECT_EQ(pinhole->cameras[0].rms_px, 0.25);
    EXPECT_EQ(pinhole->created, "Sun Nov 22 14:00:00 2026");
    // cv::fisheye output: fisheye_model: 1 and four coefficients.
    auto fisheye = importCalibration(
        write("fisheye.xml", cv::Mat(cv::Matx41d(0.01, -0.02, 0.003, -0.0004)), 1));
    ASSERT_TRUE(fisheye.isOk()) << fisheye.status().toString();
    EXPECT_EQ(fisheye->cameras[0].model.lens, LensModel::kFisheye);
    EXPECT_EQ(fisheye->cameras[0].model.distortion,
              (std::vector<double>{0.01, -0.02, 0.003, -0.0004}));
    EXPECT_EQ(fisheye->cameras[0].name, "fisheye");
    // 14 coefficients whose thin-prism and tilt terms are zero: the rational model's 8.
    cv::Mat d14 = cv::Mat::zeros(14, 1, CV_64F);
    for (int i = 0; i < 8; ++i)
        d14.at<double>(i) = 0.01 * (i + 1);
    auto rational = importCalibration(write("d14.yml", d14, -1));
    ASSERT_TRUE(rational.isOk()) << rational.status().toString();
    EXPECT_EQ(rational->cameras[0].model.distortion.size(), 8u);
    // Non-zero thin-prism terms: no mixray model holds them.
    d14.at<double>(9) = 0.001;
    auto prism = importCalibration(write("prism.yml", d14, -1));
    EXPECT_EQ(prism.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(prism.status().message().find("14 coefficients"), std::string::npos)
        << prism.status().message();
    // A fisheye with five coefficients is not cv::fisheye's.
    auto bad_fisheye = importCalibration(
        write("bad_fisheye.yml", cv::Mat(cv::Matx<double, 5, 1>(0, 0, 0, 0, 0)), 1));
    EXPECT_EQ(bad_fisheye.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(bad_fisheye.status().message().find("fisheye_model"), std::string::npos);
}

TEST(OpenCVFormat, Errors) {
    const fs::path dir = test::tempDir();
    const fs::path skew = dir / "skew.yml";
    {
        cv::FileStorage fs(skew.string(), cv::FileStorage::WRITE);
        fs << "camera_matrix" << cv::Mat(cv::Matx33d(900, 2, 640, 0, 900, 360, 0, 0, 1));
    }
    auto s = importCalibration(skew);
    EXPECT_EQ(s.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(s.status().message().find("skew.yml: camera_matrix"), std::string::npos)
        << s.status().message();
    const fs::path no_k = dir / "no_k.yml";
    {
        cv::FileStorage fs(no_k.string(), cv::FileStorage::WRITE);
        fs << "image_width" << 640;
    }
    auto k = importCalibration(no_k, CalibrationFormat::kOpenCV);
    EXPECT_EQ(k.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(k.status().message().find("camera_matrix: missing"), std::string::npos);
    // dictionary_parser_fuzz: text ending after an XML attribute's '=' crashes OpenCV 4.6's
    // FileStorage (a null pointer); it is refused before.
    const fs::path cut = dir / "cut.xml";
    writeText(cut, "<?xml version=\"1.0\"?>\n<opencv_storage><camera_matrix type_id=\n");
    for (std::optional<CalibrationFormat> format :
         {std::optional<CalibrationFormat>(), std::optional(CalibrationFormat::kOpenCV)}) {
        auto c = importCalibration(cut, format);
        EXPECT_EQ(c.status().code(), ErrorCode::kCorruptData);
        EXPECT_NE(c.status().message().find("cut.xml: ends inside an XML tag"), std::string::npos)
            << c.status().message();
    }
    // dictionary_parser_fuzz: a YAML text OpenCV 4.6's reader never returns from (its first
    // document ends early, then a line starts with '-'); refused before.
    const fs::path endless = dir / "endless.yml";
    writeText(endless, "%YAML:1.0\n---L:1.0\n-s: --\ncamera_matrix: 3\n");
    auto e = importCalibration(endless, CalibrationFormat::kOpenCV);
    EXPECT_EQ(e.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(e.status().message().find("endless.yml: text after '---' on its line"),
              std::string::npos)
        << e.status().message();
    const fs::path broken = dir / "broken.yml";
    writeText(broken, "%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: [\n");
    auto b = importCalibration(broken);
    EXPECT_EQ(b.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(b.status().message().find("broken.yml"), std::string::npos);
}

// ---- Kalibr camchain.yaml ----

// The layout of Kalibr's camchain output (its wiki's "YAML formats" page): cam1 an
// equidistant fish-eye, cam1 = T_cn_cnm1 · cam0.
const char* kCamchain = R"(cam0:
  camera_model: pinhole
  intrinsics: [461.629, 460.152, 362.680, 246.049]
  distortion_model: radtan
  distortion_coeffs: [-0.27695497, 0.06712482, 0.00087538, 0.00011556]
  T_cam_imu:
  - [0.01779318, 0.99967549, -0.01822936, 0.07008565]
  - [-0.9998017, 0.01795239, 0.00860714, -0.01771023]
  - [0.00893160, 0.01807260, 0.99979678, 0.00399246]
  - [0.0, 0.0, 0.0, 1.0]
  timeshift_cam_imu: -8.121e-05
  rostopic: /cam0/image_raw
  resolution: [752, 480]
cam1:
  T_cn_cnm1:
  - [0.99997799, 0.00312468, 0.00580935, -0.10999706]
  - [-0.00313474, 0.99999392, 0.00172308, 0.00035524]
  - [-0.00580393, -0.00174126, 0.99998164, -0.00013618]
  - [0.0, 0.0, 0.0, 1.0]
  camera_model: pinhole
  intrinsics: [460.0, 458.5, 370.2, 244.1]
  distortion_model: equidistant
  distortion_coeffs: [0.01, -0.02, 0.003, -0.0004]
  rostopic: /cam1/image_raw
  resolution: [752, 480]
  cam_overlaps: [0]
)";

TEST(KalibrFormat, ReadsACamchain) {
    const fs::path dir = test::tempDir();
    const fs::path path = dir / "camchain.yaml";
    writeText(path, kCamchain);
    auto f = importCalibration(path);
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    ASSERT_EQ(f->cameras.size(), 2u);
    const CalibratedCamera& c0 = f->cameras[0];
    const CalibratedCamera& c1 = f->cameras[1];
    EXPECT_EQ(c0.name, "cam0/image_raw");
    EXPECT_EQ(c0.model.lens, LensModel::kPinhole);
    EXPECT_EQ(c0.model.fx, 461.629);
    EXPECT_EQ(c0.model.cy, 246.049);
    EXPECT_EQ(c0.model.width, 752);
    EXPECT_EQ(c0.model.distortion.size(), 4u);
    EXPECT_TRUE(c0.parent.empty());
    EXPECT_EQ(c1.model.lens, LensModel::kFisheye);
    EXPECT_EQ(c1.parent, "cam0/image_raw");
    // cam1's pose in cam0 is T_cn_cnm1 inverted: cam1 sits 0.11 m along cam0's +x.
    auto T_c0_c1 = f->pose("cam0/image_raw", "cam1/image_raw");
    ASSERT_TRUE(T_c0_c1.isOk());
    EXPECT_NEAR(T_c0_c1->translation().x(), 0.10999706, 1e-5);
    Eigen::Matrix4d T_c1_c0;
    T_c1_c0 << 0.99997799, 0.00312468, 0.00580935, -0.10999706, -0.00313474, 0.99999392, 0.00172308,
        0.00035524, -0.00580393, -0.00174126, 0.99998164, -0.00013618, 0, 0, 0, 1;
    // The file's rotation is orthonormal to its 8 digits only.
    EXPECT_LT((T_c0_c1->inverse().matrix() - T_c1_c0).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(KalibrFormat, RoundTripsARig) {
    const fs::path dir = test::tempDir();
    CalibrationFile f;
    const std::vector<NamedModel> models = allModels();
    // opencv0, opencv4 and fisheye: what radtan, none and equidistant hold.
    for (const NamedModel& m : {models[0], models[1], models[4]}) {
        CalibratedCamera c;
        c.name = "rig/" + m.name;
        c.model = m.model;
        if (!f.cameras.empty()) {
            c.parent = f.cameras.front().name;  // all in the first: the chain is composed
            c.T_parent_camera.translation() = Eigen::Vector3d(0.1 * f.cameras.size(), 0.02, -0.01);
            c.T_parent_camera.linear() =
                Eigen::AngleAxisd(0.2 * f.cameras.size(), Eigen::Vector3d(0.3, 1, 0.1).normalized())
                    .toRotationMatrix();
        }
        f.cameras.push_back(c);
    }
    const fs::path path = dir / "camchain.yaml";
    ASSERT_TRUE(exportCalibration(path, f, CalibrationFormat::kKalibr).isOk());
    auto back = importCalibration(path);
    ASSERT_TRUE(back.isOk()) << back.status().toString() << "\n" << readText(path);
    ASSERT_EQ(back->cameras.size(), 3u);
    for (size_t i = 0; i < 3; ++i) {
        SCOPED_TRACE(i);
        EXPECT_EQ(back->cameras[i].name, f.cameras[i].name);
        expectSameModel(f.cameras[i].model, back->cameras[i].model);
        auto expected = f.pose(f.cameras[0].name, f.cameras[i].name);
        auto got = back->pose(f.cameras[0].name, f.cameras[i].name);
        ASSERT_TRUE(expected.isOk() && got.isOk()) << got.status().toString();
        EXPECT_TRUE(got->isApprox(*expected, 1e-12));
    }
    // A 5- or 8-coefficient model whose higher terms are zero is radtan exactly.
    CalibrationFile zero_k3 = oneCamera("cam", models[2].model);
    zero_k3.cameras[0].model.distortion[4] = 0;
    ASSERT_TRUE(exportCalibration(path, zero_k3, CalibrationFormat::kKalibr).isOk());
    auto radtan = importCalibration(path, CalibrationFormat::kKalibr);
    ASSERT_TRUE(radtan.isOk());
    EXPECT_EQ(radtan->cameras[0].model.distortion.size(), 4u);
    expectSameProjection(zero_k3.cameras[0].model, radtan->cameras[0].model);
}

// calibration_file_fuzz: a camchain whose cam1 has no T_cn_cnm1 was read (two independent
// cameras) but could not be written back. It is written as read: no link, no overlap.
TEST(KalibrFormat, IndependentCamerasRoundTripWithoutALink) {
    const fs::path dir = test::tempDir();
    std::string text = kCamchain;
    const size_t link = text.find("  T_cn_cnm1:");
    ASSERT_NE(link, std::string::npos);
    size_t end = link;
    for (int line = 0; line < 5; ++line)
        end = text.find('\n', end) + 1;
    text.erase(link, end - link);
    const fs::path path = dir / "independent.yaml";
    writeText(path, text);
    auto f = importCalibration(path, CalibrationFormat::kKalibr);
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    ASSERT_EQ(f->cameras.size(), 2u);
    EXPECT_TRUE(f->cameras[1].parent.empty());
    const fs::path out = dir / "written.yaml";
    ASSERT_TRUE(exportCalibration(out, *f, CalibrationFormat::kKalibr).isOk());
    EXPECT_EQ(readText(out).find("T_cn_cnm1"), std::string::npos) << readText(out);
    auto back = importCalibration(out, CalibrationFormat::kKalibr);
    ASSERT_TRUE(back.isOk()) << back.status().toString();
    ASSERT_EQ(back->cameras.size(), 2u);
    EXPECT_TRUE(back->cameras[1].parent.empty());
    EXPECT_EQ(back->cameras[1].name, f->cameras[1].name);
    expectSameModel(f->cameras[1].model, back->cameras[1].model);
}

// calibration_file_fuzz: Kalibr intrinsics mixray's own file cannot hold (a principal point of
// 2462049 px) were read, and the file written from them did not read back. Every reader now
// holds models to the same ranges (CameraModel::validate).
TEST(KalibrFormat, IntrinsicsBeyondMixraysRangesAreRefused) {
    const fs::path dir = test::tempDir();
    std::string text = kCamchain;
    const std::string cy = "246.049]";
    ASSERT_NE(text.find(cy), std::string::npos);
    text.replace(text.find(cy), cy.size(), "2462049]");
    const fs::path path = dir / "far.yaml";
    writeText(path, text);
    auto f = importCalibration(path, CalibrationFormat::kKalibr);
    ASSERT_FALSE(f.isOk());
    EXPECT_EQ(f.status().code(), ErrorCode::kCorruptData) << f.status().toString();
    EXPECT_NE(f.status().message().find("cy must be finite and within"), std::string::npos)
        << f.status().message();
}

TEST(KalibrFormat, RefusesWhatItCannotHold) {
    const fs::path dir = test::tempDir();
    const fs::path path = dir / "camchain.yaml";
    for (const NamedModel& m : {allModels()[2], allModels()[3]}) {
        const Status s =
            exportCalibration(path, oneCamera("wide", m.model), CalibrationFormat::kKalibr);
        EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument) << m.name;
        EXPECT_NE(s.message().find("camera wide's model: pinhole with"), std::string::npos)
            << s.message();
    }
    // A camera posed in another one that the previous camera does not reach: Kalibr's chain
    // has no way to say it (a camera posed in none is written without a link, above).
    CalibrationFile two = oneCamera("a", allModels()[1].model);
    two.cameras.push_back(two.cameras[0]);
    two.cameras.push_back(two.cameras[0]);
    two.cameras[1].name = "b";
    two.cameras[1].parent = "c";
    two.cameras[2].name = "c";
    const Status unlinked = exportCalibration(path, two, CalibrationFormat::kKalibr);
    EXPECT_EQ(unlinked.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(unlinked.message().find("not linked"), std::string::npos) << unlinked.message();
    EXPECT_EQ(exportCalibration(path, two, CalibrationFormat::kKalibr, "a").code(),
              ErrorCode::kInvalidArgument);
}

TEST(KalibrFormat, ErrorsNameLineAndField) {
    const fs::path dir = test::tempDir();
    const std::vector<BrokenEdit> edits = {
        {"camera_model: pinhole\n  intrinsics: [461", "camera_model: omni\n  intrinsics: [461",
         ":2:17: cam0.camera_model: camera_model \"omni\" has no mixray lens model"},
        {"distortion_model: equidistant", "distortion_model: fov",
         ":22:21: cam1.distortion_model: distortion_model \"fov\" has no mixray lens model"},
        {"distortion_coeffs: [0.01, -0.02, 0.003, -0.0004]", "distortion_coeffs: [0.01]",
         ":22:21: cam1.distortion_model: equidistant has 4 coefficients"},
        {"cam1:", "cam2:", ":14:1: cam2: expected cam1"},
        {"  - [0.0, 0.0, 0.0, 1.0]\n  camera_model", "  - [0.0, 0.0, 0.5, 1.0]\n  camera_model",
         ":16:3: cam1.T_cn_cnm1: not a rigid transform"},
        {"resolution: [752, 480]\ncam1", "resolution: [752]\ncam1",
         ":13:15: cam0.resolution: expected [width, height]"},
    };
    expectEditsRefused(kCamchain, edits, dir / "bad_camchain.yaml", CalibrationFormat::kKalibr);
}

// ---- ROS camera_info ----

// As camera_calibration_parsers writes it (the ROS camera calibrator's ost.yaml).
const char* kCameraInfo = R"(image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [580.46715, 0, 315.27153, 0, 576.62721, 247.47257, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.134462, -0.311908, 0.002304, 0.003083, 0.000000]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [587.73773, 0, 316.77307, 0, 0, 585.66626, 248.29638, 0, 0, 0, 1, 0]
)";

TEST(RosFormat, ReadsACameraInfoFile) {
    const fs::path dir = test::tempDir();
    const fs::path path = dir / "ost.yaml";
    writeText(path, kCameraInfo);
    auto f = importCalibration(path);
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    const CalibratedCamera& c = f->cameras[0];
    EXPECT_EQ(c.name, "narrow_stereo");
    EXPECT_EQ(c.model.width, 640);
    EXPECT_EQ(c.model.fx, 580.46715);
    EXPECT_EQ(c.model.fy, 576.62721);
    EXPECT_EQ(c.model.cx, 315.27153);
    EXPECT_EQ(c.model.cy, 247.47257);
    EXPECT_EQ(c.model.distortion,
              (std::vector<double>{0.134462, -0.311908, 0.002304, 0.003083, 0.0}));
}

TEST(RosFormat, RoundTripsEveryModel) {
    const fs::path dir = test::tempDir();
    for (const NamedModel& m : allModels()) {
        SCOPED_TRACE(m.name);
        const fs::path path = dir / (m.name + ".yaml");
        ASSERT_TRUE(
            exportCalibration(path, oneCamera("kinect/color", m.model), CalibrationFormat::kRos)
                .isOk());
        auto back = importCalibration(path);
        ASSERT_TRUE(back.isOk()) << back.status().toString() << "\n" << readText(path);
        const CameraModel& got = back->cameras[0].model;
        EXPECT_EQ(back->cameras[0].name, "kinect/color");
        if (m.model.lens == LensModel::kPinhole && m.model.distortion.size() < 5) {
            // plumb_bob always has k1 k2 t1 t2 k3; the missing terms come back as zeros.
            EXPECT_EQ(got.distortion.size(), 5u);
            expectSameProjection(m.model, got);
            EXPECT_EQ(got.fx, m.model.fx);
        } else {
            expectSameModel(m.model, got);
        }
        const std::string text = readText(path);
        const char* expected_model = m.model.lens == LensModel::kFisheye ? "equidistant"
                                     : m.model.distortion.size() == 8    ? "rational_polynomial"
                                                                         : "plumb_bob";
        EXPECT_NE(text.find(std::string("distortion_model: ") + expected_model), std::string::npos);
    }
}

// The same description feeds the ROS 2 topics (drivers/dds): K, R, P and D as CameraInfo has
// them, and a pose as tf's translation and quaternion.
CalibratedCamera namedCamera(const std::string& name, const CameraModel& model) {
    CalibratedCamera c;
    c.name = name;
    c.model = model;
    return c;
}

TEST(RosCameraInfo, MatricesAndDistortionAsCameraInfoHasThem) {
    const CameraModel m = withLens(LensModel::kPinhole, {0.1, -0.2, 1e-3, -2e-3});
    auto info = toRosCameraInfo(namedCamera("kinect/color", m));
    ASSERT_TRUE(info.isOk()) << info.status().toString();
    EXPECT_EQ(info->width, 640u);
    EXPECT_EQ(info->height, 480u);
    EXPECT_EQ(info->distortion_model, "plumb_bob");
    EXPECT_EQ(info->d, (std::vector<double>{0.1, -0.2, 1e-3, -2e-3, 0.0}));
    EXPECT_EQ(info->k, (std::array<double, 9>{m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1}));
    EXPECT_EQ(info->r, (std::array<double, 9>{1, 0, 0, 0, 1, 0, 0, 0, 1}));
    EXPECT_EQ(info->p, (std::array<double, 12>{m.fx, 0, m.cx, 0, 0, m.fy, m.cy, 0, 0, 0, 1, 0}));

    auto fisheye = toRosCameraInfo(
        namedCamera("env", withLens(LensModel::kFisheye, {0.02, -0.005, 0.001, -2e-4})));
    ASSERT_TRUE(fisheye.isOk());
    EXPECT_EQ(fisheye->distortion_model, "equidistant");
    EXPECT_EQ(fisheye->d.size(), 4u);

    CameraModel stereographic = m;
    stereographic.lens = LensModel::kStereographic;
    stereographic.distortion.clear();
    auto refused = toRosCameraInfo(namedCamera("sky", stereographic));
    ASSERT_FALSE(refused.isOk());
    EXPECT_EQ(refused.status().code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(refused.status().message().find("sky"), std::string::npos);
}

TEST(RosCameraInfo, CalibratedPosesAsTfTransforms) {
    CalibrationFile file = oneCamera("kinect/color", allModels()[0].model);
    CalibratedCamera env = namedCamera("env/color", allModels()[4].model);
    env.parent = "kinect/color";
    env.T_parent_camera = Eigen::Translation3d(0.1, -0.02, 0.3) *
                          Eigen::AngleAxisd(0.5, Eigen::Vector3d(0, 1, 0).normalized());
    file.cameras.push_back(env);
    const std::vector<RosTransform> transforms = toRosTransforms(file);
    ASSERT_EQ(transforms.size(), 1u) << "a camera without a parent has no transform";
    const RosTransform& t = transforms[0];
    EXPECT_EQ(t.parent, "kinect/color");
    EXPECT_EQ(t.child, "env/color");
    EXPECT_DOUBLE_EQ(t.translation[0], 0.1);
    EXPECT_DOUBLE_EQ(t.translation[1], -0.02);
    EXPECT_DOUBLE_EQ(t.translation[2], 0.3);
    EXPECT_NEAR(t.rotation_xyzw[0], 0.0, 1e-15);
    EXPECT_NEAR(t.rotation_xyzw[1], std::sin(0.25), 1e-15);
    EXPECT_NEAR(t.rotation_xyzw[2], 0.0, 1e-15);
    EXPECT_NEAR(t.rotation_xyzw[3], std::cos(0.25), 1e-15);
}

TEST(RosFormat, ErrorsNameLineAndField) {
    const fs::path dir = test::tempDir();
    const std::vector<BrokenEdit> edits = {
        {"distortion_model: plumb_bob", "distortion_model: fisheye",
         ":8:19: distortion_model: distortion model \"fisheye\" has no mixray lens model"},
        {"data: [580.46715, 0,", "data: [580.46715, 1,",
         ":5:3: camera_matrix: expected [fx 0 cx 0 fy cy 0 0 1]"},
        {"  rows: 3\n  cols: 4", "  rows: 4\n  cols: 4",
         ":18:3: projection_matrix: expected 3x4, got 4x4"},
        {"distortion_coefficients:", "distortion_coefficents:",
         ":9:1: distortion_coefficents: unknown field (did you mean distortion_coefficients?)"},
        {"image_width: 640", "image_width: -640", ":1:14: image_width: expected an integer"},
    };
    expectEditsRefused(kCameraInfo, edits, dir / "bad_ost.yaml", CalibrationFormat::kRos);
}

// ---- mixray, sniffing, selection ----

TEST(CalibrationFormats, NamesAndSniffing) {
    const fs::path dir = test::tempDir();
    for (CalibrationFormat format :
         {CalibrationFormat::kMixray, CalibrationFormat::kOpenCV, CalibrationFormat::kMrcal,
          CalibrationFormat::kKalibr, CalibrationFormat::kRos}) {
        EXPECT_EQ(calibrationFormatFromString(toString(format)), format);
    }
    EXPECT_FALSE(calibrationFormatFromString("yaml"));
    const CalibrationFile f = oneCamera("cam", allModels()[1].model);
    for (CalibrationFormat format : {CalibrationFormat::kMixray, CalibrationFormat::kOpenCV,
                                     CalibrationFormat::kKalibr, CalibrationFormat::kRos}) {
        SCOPED_TRACE(toString(format));
        const fs::path path = dir / "sniff.yaml";
        ASSERT_TRUE(exportCalibration(path, f, format).isOk());
        auto back = importCalibration(path);
        ASSERT_TRUE(back.isOk()) << back.status().toString();
        EXPECT_EQ(back->cameras[0].model.fx, f.cameras[0].model.fx);
    }
    const fs::path other = dir / "other.yaml";
    writeText(other, "rig: tabletop\ndevices: []\n");
    auto unknown = importCalibration(other);
    EXPECT_EQ(unknown.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(unknown.status().message().find("cannot tell its calibration format"),
              std::string::npos);
    EXPECT_EQ(importCalibration(dir / "missing.yml").status().code(), ErrorCode::kNotFound);
}

TEST(CalibrationFormats, MixrayFormatThroughImportAndExport) {
    const fs::path dir = test::tempDir();
    CalibrationFile f = oneCamera("a", allModels()[4].model);
    f.cameras.push_back(f.cameras[0]);
    f.cameras[1].name = "b";
    f.cameras[1].parent = "a";
    f.cameras[1].T_parent_camera.translation() = Eigen::Vector3d(0.1, 0, 0);
    const fs::path path = dir / "rig.yaml";
    ASSERT_TRUE(exportCalibration(path, f, CalibrationFormat::kMixray).isOk());
    auto back = importCalibration(path);
    ASSERT_TRUE(back.isOk());
    EXPECT_EQ(back->cameras[1].parent, "a");
    EXPECT_EQ(exportCalibration(path, f, CalibrationFormat::kMixray, "a").code(),
              ErrorCode::kInvalidArgument);
}

TEST(CalibrationFormats, SingleCameraFormatsWriteTheNamedCamera) {
    const fs::path dir = test::tempDir();
    CalibrationFile f = oneCamera("a", allModels()[1].model);
    f.cameras.push_back(oneCamera("b", allModels()[4].model).cameras[0]);
    const fs::path path = dir / "one.yml";
    const Status ambiguous = exportCalibration(path, f, CalibrationFormat::kOpenCV);
    EXPECT_EQ(ambiguous.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(ambiguous.message().find("has 2 (a, b); name the one to write"), std::string::npos)
        << ambiguous.message();
    EXPECT_EQ(exportCalibration(path, f, CalibrationFormat::kRos, "c").code(),
              ErrorCode::kNotFound);
    ASSERT_TRUE(exportCalibration(path, f, CalibrationFormat::kOpenCV, "b").isOk());
    auto back = importCalibration(path);
    ASSERT_TRUE(back.isOk());
    EXPECT_EQ(back->cameras[0].name, "b");
    EXPECT_EQ(back->cameras[0].model.lens, LensModel::kFisheye);
    const Status unwritable =
        exportCalibration(dir / "no/dir/x.yaml", f, CalibrationFormat::kRos, "a");
    EXPECT_EQ(unwritable.code(), ErrorCode::kIoError);
}

// ---- mrcal .cameramodel (through mrcal's C API, calibration/src/mrcal_format.cpp) ----

TEST(MrcalFormat, ReadsMrcalsTestModel) {
    const fs::path path = test::sharedDataDir() / "04_mrcal/cam1.opencv8.cameramodel";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto f = importCalibration(path);  // recognised from the content
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    const CalibratedCamera& c = f->cameras[0];
    EXPECT_EQ(c.name, "cam1.opencv8");
    EXPECT_EQ(c.model.width, 4000);
    EXPECT_EQ(c.model.height, 2200);
    EXPECT_EQ(c.model.fx, 1761);
    EXPECT_EQ(c.model.cx, 1965);
    EXPECT_EQ(c.model.distortion,
              (std::vector<double>{-0.02, 0.03, 0.0002, 0.0005, 0.0196, 0.01, -0.05, 0.04}));
    EXPECT_EQ(c.parent, "reference");
    // The file's projection measured with mrcal 2.2 (MANIFEST.md): cam1 (2140.94643, 1438.82242).
    auto p = c.model.project({0.1, 0.2, 1});
    ASSERT_TRUE(p);
    EXPECT_NEAR(p->x(), 2140.94643, 1e-4);
    EXPECT_NEAR(p->y(), 1438.82242, 1e-4);
}

TEST(MrcalFormat, RoundTripsOpenCVModels) {
    const fs::path dir = test::tempDir();
    for (const NamedModel& m : allModels()) {
        if (m.model.lens != LensModel::kPinhole || m.model.distortion.empty())
            continue;  // mrcal's OPENCV4/5/8; LENSMODEL_PINHOLE has no coefficients to compare
        SCOPED_TRACE(m.name);
        CalibrationFile f = oneCamera("cam", m.model);
        f.cameras[0].parent = "reference";
        f.cameras[0].T_parent_camera.translation() = Eigen::Vector3d(0.5, -0.25, 2);
        const fs::path path = dir / (m.name + ".cameramodel");
        const Status written = exportCalibration(path, f, CalibrationFormat::kMrcal);
        ASSERT_TRUE(written.isOk()) << written.toString();
        auto back = importCalibration(path);
        ASSERT_TRUE(back.isOk()) << back.status().toString();
        expectSameProjection(m.model, back->cameras[0].model);
        EXPECT_EQ(back->cameras[0].model.distortion.size(), m.model.distortion.size());
        EXPECT_TRUE(back->cameras[0].T_parent_camera.isApprox(f.cameras[0].T_parent_camera, 1e-12));
    }
}

// mrcal's splined lens: the mixray and mrcal formats hold it; OpenCV, Kalibr and ROS refuse it
// by name.
TEST(MrcalFormat, SplinedModelsGoWhereTheyFit) {
    const fs::path dir = test::tempDir();
    const fs::path path = test::sharedDataDir() / "04_mrcal/cam0.splined.cameramodel";
    MIXRAY_REQUIRE_SHARED_DATA(path);
    auto f = importCalibration(path);
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    const CameraModel& splined = f->cameras[0].model;
    EXPECT_EQ(toString(splined.lens), "splined_stereographic");
    for (CalibrationFormat format :
         {CalibrationFormat::kOpenCV, CalibrationFormat::kKalibr, CalibrationFormat::kRos}) {
        SCOPED_TRACE(toString(format));
        const Status s = exportCalibration(dir / "x.yaml", *f, format);
        EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument);
        EXPECT_NE(s.message().find("cannot hold camera cam0.splined's model: "
                                   "splined_stereographic"),
                  std::string::npos)
            << s.message();
        EXPECT_FALSE(fs::exists(dir / "x.yaml"));
    }
    for (CalibrationFormat format : {CalibrationFormat::kMixray, CalibrationFormat::kMrcal}) {
        SCOPED_TRACE(toString(format));
        const fs::path out = dir / (std::string("splined.") + std::string(toString(format)));
        ASSERT_TRUE(exportCalibration(out, *f, format).isOk());
        auto back = importCalibration(out);
        ASSERT_TRUE(back.isOk()) << back.status().toString();
        EXPECT_EQ(back->cameras[0].model.lens, splined.lens);
        EXPECT_EQ(back->cameras[0].model.distortion.size(), splined.distortion.size());
        expectSameProjection(splined, back->cameras[0].model);
    }
}

}  // namespace
}  // namespace mixray::calibration
