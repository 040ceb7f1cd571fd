// The rig calibration file (calibration/src/calibration_file.cpp): exact round trips, poses
// composed through parents, depth registrations, and errors naming file:line:field.
#include "mixray/calibration/calibration_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "test_data.h"

namespace mixray::calibration {
namespace {

namespace fs = std::filesystem;

Eigen::Isometry3d pose(const Eigen::Vector3d& t, double angle, const Eigen::Vector3d& axis) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
    T.translation() = t;
    return T;
}

CameraModel model(LensModel lens, int width, int height, std::vector<double> distortion) {
    CameraModel m = CameraModel::pinhole(width, height, 0.81 * width, 0.8 * width,
                                         width / 2.0 - 0.37, height / 2.0 + 0.21);
    m.lens = lens;
    m.distortion = std::move(distortion);
    return m;
}

// A rig with every field set: a camera chain color -> world, ir -> color, env -> world, and a
// depth registration with a per-pixel map.
CalibrationFile fullFile() {
    CalibrationFile f;
    f.created = "2026-11-22T14:00:00Z mixray test \"quoted\" \\ back";
    f.target = "charuco:7x5:0.05:0.037:DICT_6X6_250";
    CalibratedCamera color;
    color.name = "kinect/color";
    color.model = model(LensModel::kPinhole, 640, 480,
                        {0.1234567890123, -0.2, 1e-4, -3.3e-5, 0.05, 0.001, -0.002, 0.0003});
    color.parent = "world";
    color.T_parent_camera = pose({0.1, -0.2, 0.7}, 0.3, {1, 2, 3});
    Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Random();
    color.pose_covariance = a * a.transpose() * 1e-6;
    color.intrinsics_stddev = {0.3,  0.31, 0.2,  0.21, 1e-3, 2e-3,
                               1e-5, 2e-5, 3e-3, 1e-4, 2e-4, 3e-4};
    color.rms_px = 0.2125;
    color.views = 20;
    CalibratedCamera ir;
    ir.name = "kinect/ir";
    ir.model = model(LensModel::kPinhole, 64, 48, {-0.1, 0.2, 0, 0, 0});
    ir.parent = "kinect/color";
    ir.T_parent_camera = pose({-0.025, 0.001, 0.002}, 0.01, {0, 1, 0});
    CalibratedCamera env;
    env.name = "env/color";
    env.model = model(LensModel::kFisheye, 480, 480, {0.02, -0.005, 0.001, -2e-4});
    env.parent = "world";
    env.T_parent_camera = pose({-0.3, 0.28, 0.12}, 2.5, {0.2, -0.1, 1});
    CalibratedCamera loose;  // no pose: not calibrated
    loose.name = "spare";
    loose.model = CameraModel::pinhole(320, 240, 300, 300, 159.5, 119.5);
    loose.lens = LensSettings{2.8, 4.5, 0.8};
    f.cameras = {color, ir, env, loose};
    CalibratedDepth d;
    d.stream = "kinect/depth";
    d.depth_camera = "kinect/ir";
    d.color_camera = "kinect/color";
    d.correction.scale = 1.002;
    d.correction.offset_m = -0.003;
    d.correction.alpha0 = 1.25;
    d.correction.alpha1 = 0.875;
    d.correction.distortion.resize(64 * 48);
    for (size_t i = 0; i < d.correction.distortion.size(); ++i)
        d.correction.distortion[i] = static_cast<float>(std::sin(0.37 * i) * 1e-3);
    f.depth = {d};
    return f;
}

using mixray::test::readText;
using mixray::test::writeText;

void expectSameCamera(const CalibratedCamera& a, const CalibratedCamera& b) {
    SCOPED_TRACE(a.name);
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.model.lens, b.model.lens);
    EXPECT_EQ(a.model.width, b.model.width);
    EXPECT_EQ(a.model.height, b.model.height);
    EXPECT_EQ(a.model.fx, b.model.fx);
    EXPECT_EQ(a.model.fy, b.model.fy);
    EXPECT_EQ(a.model.cx, b.model.cx);
    EXPECT_EQ(a.model.cy, b.model.cy);
    EXPECT_EQ(a.model.distortion, b.model.distortion);
    EXPECT_EQ(a.parent, b.parent);
    EXPECT_TRUE(a.T_parent_camera.isApprox(b.T_parent_camera, 1e-15))
        << a.T_parent_camera.matrix() << "\n"
        << b.T_parent_camera.matrix();
    ASSERT_EQ(a.pose_covariance.has_value(), b.pose_covariance.has_value());
    if (a.pose_covariance) {
        EXPECT_EQ(*a.pose_covariance, *b.pose_covariance);
    }
    EXPECT_EQ(a.intrinsics_stddev, b.intrinsics_stddev);
    EXPECT_EQ(a.rms_px, b.rms_px);
    EXPECT_EQ(a.views, b.views);
    ASSERT_EQ(a.lens.has_value(), b.lens.has_value());
    if (a.lens) {
        EXPECT_EQ(a.lens->f_number, b.lens->f_number);
        EXPECT_EQ(a.lens->focal_length_mm, b.lens->focal_length_mm);
        EXPECT_EQ(a.lens->focus_distance_m, b.lens->focus_distance_m);
    }
}

TEST(CalibrationFile, WritesAndReadsBackEveryFieldExactly) {
    const fs::path dir = test::tempDir();
    const CalibrationFile f = fullFile();
    const fs::path path = dir / "rig.calib.yaml";
    ASSERT_TRUE(writeCalibrationFile(path, f).isOk());
    auto back = readCalibrationFile(path);
    ASSERT_TRUE(back.isOk()) << back.status().toString();
    EXPECT_EQ(back->created, f.created);
    EXPECT_EQ(back->target, f.target);
    ASSERT_EQ(back->cameras.size(), f.cameras.size());
    for (size_t i = 0; i < f.cameras.size(); ++i)
        expectSameCamera(f.cameras[i], back->cameras[i]);
    ASSERT_EQ(back->depth.size(), 1u);
    const CalibratedDepth& d = back->depth[0];
    EXPECT_EQ(d.stream, "kinect/depth");
    EXPECT_EQ(d.depth_camera, "kinect/ir");
    EXPECT_EQ(d.color_camera, "kinect/color");
    EXPECT_EQ(d.correction.scale, 1.002);
    EXPECT_EQ(d.correction.offset_m, -0.003);
    EXPECT_EQ(d.correction.alpha0, 1.25);
    EXPECT_EQ(d.correction.alpha1, 0.875);
    EXPECT_EQ(d.correction.distortion, f.depth[0].correction.distortion);  // bit for bit

    // No temporary file is left beside it.
    size_t entries = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(path.parent_path()))
        ++entries;
    EXPECT_EQ(entries, 1u);
}

// calibration_file_fuzz: a line break in weak: was written raw inside quotes and read back as a
// space; control characters are written escaped now.
TEST(CalibrationFile, TextWithControlCharactersReadsBackTheSame) {
    const fs::path dir = test::tempDir();
    CalibrationFile f = fullFile();
    f.cameras[0].weak =
        std::string("fx and fy:\n\tweak; \"quoted\" \\ \x01\x1f\x7f") + '\0' + "end";
    const fs::path path = dir / "rig.calib.yaml";
    ASSERT_TRUE(writeCalibrationFile(path, f).isOk());
    auto back = readCalibrationFile(path);
    ASSERT_TRUE(back.isOk()) << back.status().toString();
    EXPECT_EQ(back->cameras[0].weak, f.cameras[0].weak);
}

TEST(CalibrationFile, MapIsBase64OfLittleEndianFloat32) {
    const fs::path dir = test::tempDir();
    CalibrationFile f = fullFile();
    auto& map = f.depth[0].correction.distortion;
    std::fill(map.begin(), map.end(), 0.0f);
    map[0] = 1.0f;  // 00 00 80 3F
    map[1] = 2.0f;  // 00 00 00 40
    const fs::path path = dir / "map.calib.yaml";
    ASSERT_TRUE(writeCalibrationFile(path, f).isOk());
    const std::string text = readText(path);
    EXPECT_NE(text.find("encoding: base64-float32le"), std::string::npos);
    // 00 00 80 3F 00 00 00 40 encodes as "AACAPwAAAEA".
    EXPECT_NE(text.find("AACAPwAAAEA"), std::string::npos);
}

TEST(CalibrationFile, PosesComposeThroughParents) {
    const CalibrationFile f = fullFile();
    const Eigen::Isometry3d T_world_color = f.cameras[0].T_parent_camera;
    const Eigen::Isometry3d T_color_ir = f.cameras[1].T_parent_camera;
    const Eigen::Isometry3d T_world_env = f.cameras[2].T_parent_camera;

    auto T_world_ir = f.pose("world", "kinect/ir");
    ASSERT_TRUE(T_world_ir.isOk()) << T_world_ir.status().toString();
    EXPECT_TRUE(T_world_ir->isApprox(T_world_color * T_color_ir, 1e-14));

    auto T_env_ir = f.pose("env/color", "kinect/ir");
    ASSERT_TRUE(T_env_ir.isOk()) << T_env_ir.status().toString();
    EXPECT_TRUE(T_env_ir->isApprox(T_world_env.inverse() * T_world_color * T_color_ir, 1e-12));

    auto T_ir_color = f.pose("kinect/ir", "kinect/color");
    ASSERT_TRUE(T_ir_color.isOk());
    EXPECT_TRUE(T_ir_color->isApprox(T_color_ir.inverse(), 1e-14));

    auto same = f.pose("kinect/ir", "kinect/ir");
    ASSERT_TRUE(same.isOk());
    EXPECT_TRUE(same->isApprox(Eigen::Isometry3d::Identity(), 1e-15));

    // A camera without a parent is the root of its own frame only.
    auto T_spare_spare = f.pose("spare", "spare");
    EXPECT_TRUE(T_spare_spare.isOk());
    auto unlinked = f.pose("world", "spare");
    EXPECT_EQ(unlinked.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(unlinked.status().message().find("not linked"), std::string::npos)
        << unlinked.status().message();

    auto unknown_camera = f.pose("world", "kinect/rgb");
    EXPECT_EQ(unknown_camera.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(unknown_camera.status().message().find("kinect/rgb"), std::string::npos);
    auto unknown_frame = f.pose("marker", "kinect/ir");
    EXPECT_EQ(unknown_frame.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(unknown_frame.status().message().find("no frame named \"marker\""), std::string::npos)
        << unknown_frame.status().message();

    const CalibratedCamera* ir = f.find("kinect/ir");
    ASSERT_NE(ir, nullptr);
    EXPECT_EQ(ir->model.width, 64);
    EXPECT_EQ(f.find("nothing"), nullptr);
}

TEST(CalibrationFile, CyclesAreErrors) {
    const fs::path dir = test::tempDir();
    CalibrationFile f = fullFile();
    f.cameras[0].parent = "kinect/ir";  // color -> ir -> color
    auto p = f.pose("world", "env/color");
    EXPECT_TRUE(p.isOk());  // the cycle is elsewhere
    auto cyclic = f.pose("kinect/color", "kinect/ir");
    EXPECT_EQ(cyclic.status().code(), ErrorCode::kCorruptData);
    EXPECT_NE(cyclic.status().message().find("cycle"), std::string::npos);
    const Status written = writeCalibrationFile(dir / "cycle.yaml", f);
    EXPECT_EQ(written.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(written.message().find("cycle: kinect/color -> kinect/ir -> kinect/color"),
              std::string::npos)
        << written.message();
}

TEST(CalibrationFile, DepthRegistrationComposesTheCameras) {
    const CalibrationFile f = fullFile();
    auto r = f.depthRegistration("kinect/depth");
    ASSERT_TRUE(r.isOk()) << r.status().toString();
    EXPECT_EQ(r->depth.width, 64);
    EXPECT_EQ(r->color.width, 640);
    EXPECT_TRUE(r->T_color_depth.isApprox(f.cameras[1].T_parent_camera, 1e-15));
    EXPECT_EQ(r->correction.scale, 1.002);
    EXPECT_EQ(r->correction.distortion.size(), 64u * 48u);
    auto missing = f.depthRegistration("kinect/ir");
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(missing.status().message().find("registered: kinect/depth"), std::string::npos);

    CalibrationFile unlinked = f;
    unlinked.cameras[1].parent.clear();
    unlinked.cameras[1].T_parent_camera = Eigen::Isometry3d::Identity();
    auto no_pose = unlinked.depthRegistration("kinect/depth");
    EXPECT_EQ(no_pose.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(no_pose.status().message().find("depth registration of kinect/depth"),
              std::string::npos);
}

TEST(CalibrationFile, WriterRefusesWhatTheReaderWouldRefuse) {
    const fs::path dir = test::tempDir();
    struct Case {
        std::string name;
        void (*change)(CalibrationFile&);
        std::string expected;
    };
    const std::vector<Case> cases = {
        {"duplicate", [](CalibrationFile& f) { f.cameras[1].name = "kinect/color"; },
         "a second camera with this name"},
        {"bad name", [](CalibrationFile& f) { f.cameras[0].name = "kinect color"; }, "name:"},
        {"bad model", [](CalibrationFile& f) { f.cameras[0].model.fx = -1; }, "model:"},
        {"pose without parent",
         [](CalibrationFile& f) { f.cameras[3].T_parent_camera.translation().x() = 1; },
         "parent is empty"},
        {"stddev count", [](CalibrationFile& f) { f.cameras[0].intrinsics_stddev.pop_back(); },
         "intrinsics_stddev: expected 12"},
        {"map size", [](CalibrationFile& f) { f.depth[0].correction.distortion.pop_back(); },
         "3071 values; the depth camera kinect/ir is 64x48"},
        {"unknown depth camera", [](CalibrationFile& f) { f.depth[0].depth_camera = "kinect/irr"; },
         "depth_camera: no camera \"kinect/irr\""},
        {"covariance", [](CalibrationFile& f) { (*f.cameras[0].pose_covariance)(0, 1) += 1; },
         "pose_covariance"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        CalibrationFile f = fullFile();
        c.change(f);
        const fs::path path = dir / "refused.yaml";
        const Status s = writeCalibrationFile(path, f);
        EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument);
        EXPECT_NE(s.message().find(c.expected), std::string::npos) << s.message();
        EXPECT_FALSE(fs::exists(path));
    }
}

TEST(CalibrationFile, FileErrors) {
    const fs::path dir = test::tempDir();
    auto missing = readCalibrationFile(dir / "missing.yaml");
    EXPECT_EQ(missing.status().code(), ErrorCode::kNotFound);
    const Status unwritable = writeCalibrationFile(dir / "no/such/dir/x.yaml", fullFile());
    EXPECT_EQ(unwritable.code(), ErrorCode::kIoError);
    EXPECT_NE(unwritable.message().find("no/such/dir/x.yaml"), std::string::npos);
}

// Valid text for the error cases to break one line at a time.
const char* kValid =
    "version: 1\n"                                                                     // 1
    "cameras:\n"                                                                       // 2
    "  - name: a\n"                                                                    // 3
    "    model: {width: 64, height: 48, fx: 50, fy: 50, cx: 31.5, cy: 23.5}\n"         // 4
    "    parent: b\n"                                                                  // 5
    "    T_parent_camera: {translation: [0.1, 0, 0], quaternion: [1, 0, 0, 0]}\n"      // 6
    "  - name: b\n"                                                                    // 7
    "    model: {width: 64, height: 48, fx: 50, fy: 50, cx: 31.5, cy: 23.5}\n"         // 8
    "    parent: world\n"                                                              // 9
    "    T_parent_camera: {translation: [0, 0, 1], rotation_deg: [0, 0, 90]}\n"        // 10
    "depth:\n"                                                                         // 11
    "  - {stream: d, depth_camera: a, color_camera: b, correction: {scale: 1.01}}\n";  // 12

// Line 6 or 10 of kValid, for cases that add a line after it.
const char* kPose = "    T_parent_camera: {translation: [0.1, 0, 0], quaternion: [1, 0, 0, 0]}";

std::string replaceLine(std::string text, int line, const std::string& replacement) {
    size_t start = 0;
    for (int i = 1; i < line; ++i)
        start = text.find('\n', start) + 1;
    const size_t end = text.find('\n', start);
    return text.replace(start, end - start, replacement);
}

TEST(CalibrationFile, ReadsTheValidText) {
    const fs::path dir = test::tempDir();
    const fs::path path = dir / "valid.yaml";
    writeText(path, kValid);
    auto f = readCalibrationFile(path);
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    auto T_world_a = f->pose("world", "a");
    ASSERT_TRUE(T_world_a.isOk());
    // b is turned 90° about z and 1 m up; a is 0.1 m along b's x, which is world's y.
    EXPECT_TRUE(T_world_a->translation().isApprox(Eigen::Vector3d(0, 0.1, 1), 1e-12))
        << T_world_a->translation().transpose();
    auto r = f->depthRegistration("d");
    ASSERT_TRUE(r.isOk());
    EXPECT_EQ(r->correction.scale, 1.01);
    EXPECT_TRUE(r->correction.distortion.empty());
}

TEST(CalibrationFile, ErrorsNameFileLineAndField) {
    const fs::path dir = test::tempDir();
    struct Case {
        int line;
        std::string replacement;
        std::string expected;  // after "FILE:"
    };
    const std::vector<Case> cases = {
        {1, "version: 2", "1:10: version: expected an integer from 1 to 1"},
        {1, "versio: 1", "1:1: versio: unknown field (did you mean version?)"},
        {3, "  - nam: a", "3:5: cameras[0].nam: unknown field (did you mean name?)"},
        {4, "    model: {width: 64, height: 48, fx: 50, fy: 50, cx: 31.5}",
         "4:12: cameras[0].model.cy: missing required field"},
        {5, "    parent: a", "5:13: cameras[0].parent: a camera cannot be its own parent"},
        {5, "    parent: b c", "5:13: cameras[0].parent: expected a name"},
        {6, "    T_parent_camera: {translation: [0.1, 0, 0], quaternion: [1, 1, 0, 0]}",
         "6:61: cameras[0].T_parent_camera.quaternion: not a unit quaternion"},
        {6, std::string(kPose) + "\n    rms_px: -1",
         "7:13: cameras[0].rms_px: expected a number from 0"},
        {7, "  - name: a", "7:5: cameras[1]: a second camera named \"a\""},
        {9, "    parent: a", "3:5: cameras[0]: the cameras' parents form a cycle: a -> b -> a"},
        {9, "    views: 3", "10:22: cameras[1].T_parent_camera: a pose needs parent:"},
        {10, std::string(kPose) + "\n    pose_covariance: [[1, 0, 0, 0, 0, 0]]",
         "11:22: cameras[1].pose_covariance: expected 6 rows of 6 numbers"},
        {10, std::string(kPose) + "\n    intrinsics_stddev: [1, 2, 3]",
         "11:24: cameras[1].intrinsics_stddev: expected a list of 4 standard deviations"},
        {6, std::string(kPose) + "\n    lens: {f_number: 2, focal_length_mm: 50}",
         "7:11: cameras[0].lens.focus_distance_m: missing required field"},
        {6,
         std::string(kPose) + "\n    lens: {f_number: 0, focal_length_mm: 50, focus_distance_m: 1}",
         "7:22: cameras[0].lens.f_number: expected a number above 0"},
        {12, "  - {stream: d, depth_camera: c, color_camera: b}",
         "12:31: depth[0].depth_camera: no camera \"c\" in the file (cameras: a, b)"},
        {12,
         "  - {stream: d, depth_camera: a, color_camera: b, correction: {distortion: {width: 2, "
         "height: 1, encoding: base64-float32le, data: AAAAAAAAAAA=}}}",
         "12:76: depth[0].correction.distortion: the map is 2x1; the depth camera is 64x48"},
        {12, "  - {stream: d, depth_camera: a, color_camera: b, correction: {scale: 0}}",
         "12:71: depth[0].correction.scale: expected a number above 0"},
        // calibration_file_fuzz: the reader took what writeCalibrationFile() refuses.
        {1, "version: 1\ncreated: \"a\\tb\"",
         "2:10: created: expected one line without control characters"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.replacement);
        const fs::path path = dir / "bad.calib.yaml";
        writeText(path, replaceLine(kValid, c.line, c.replacement));
        auto f = readCalibrationFile(path);
        ASSERT_FALSE(f.isOk());
        EXPECT_EQ(f.status().code(), ErrorCode::kCorruptData);
        EXPECT_NE(f.status().message().find(path.string() + ":" + c.expected), std::string::npos)
            << f.status().message();
    }
}

TEST(CalibrationFile, MapErrorsNameTheField) {
    const fs::path dir = test::tempDir();
    CalibrationFile f = fullFile();
    const fs::path path = dir / "map.yaml";
    ASSERT_TRUE(writeCalibrationFile(path, f).isOk());
    std::string text = readText(path);
    // Damage the base64: a character outside the alphabet, then a map a value short.
    const size_t data = text.find("data: |\n");
    ASSERT_NE(data, std::string::npos);
    const size_t first = text.find_first_not_of(' ', data + 8);
    std::string bad = text;
    bad[first] = '*';
    writeText(path, bad);
    auto damaged = readCalibrationFile(path);
    ASSERT_FALSE(damaged.isOk());
    EXPECT_NE(damaged.status().message().find("depth[0].correction.distortion.data: not valid "
                                              "base64 text"),
              std::string::npos)
        << damaged.status().message();

    f.depth[0].correction.distortion[5] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(writeCalibrationFile(path, f).code(), ErrorCode::kInvalidArgument);
}

// The example in docs/calibration.md reads, and poses and registrations come out of it.
TEST(CalibrationFile, DocumentedExampleReads) {
    const fs::path dir = test::tempDir();
    const std::string doc = readText(test::sourceDir() / "docs/calibration.md");
    const size_t section = doc.find("## Calibration files");
    ASSERT_NE(section, std::string::npos);
    const size_t start = doc.find("```yaml\n", section);
    ASSERT_NE(start, std::string::npos);
    const size_t end = doc.find("```\n", start + 8);
    const fs::path path = dir / "doc.calib.yaml";
    writeText(path, doc.substr(start + 8, end - start - 8));
    auto f = readCalibrationFile(path);
    ASSERT_TRUE(f.isOk()) << f.status().toString();
    EXPECT_EQ(f->cameras.size(), 3u);
    EXPECT_EQ(f->cameras[0].views, 20);
    auto r = f->depthRegistration("kinect/depth");
    ASSERT_TRUE(r.isOk()) << r.status().toString();
    EXPECT_NEAR(r->T_color_depth.translation().x(), -0.025, 1e-15);
    auto T_env_ir = f->pose("env/color", "kinect/ir");
    EXPECT_TRUE(T_env_ir.isOk());
}

}  // namespace
}  // namespace mixray::calibration
