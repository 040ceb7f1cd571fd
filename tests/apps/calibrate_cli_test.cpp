// mixray calibrate on the committed simulated calibration session against its ground truth
// (fixtures/sessions/sim_calibration.truth.yaml): the Kinect's colour and IR intrinsics, their
// extrinsics, the depth registration and the fish-eye environment camera's alignment to the world
// marker; the report files and the corners cache round trip.
#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "cli_runner.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/depth_registration.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/mkv.h"
#include "test_data.h"

namespace mixray {
namespace {

namespace fs = std::filesystem;
using calibration::CameraModel;
using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;
using test::CliRun;
using test::mixray;
using test::q;

const fs::path kSession = test::fixturesDir() / "sessions" / "sim_calibration.mkv";
const char* const kTarget = "charuco:7x5:0.05:0.037:DICT_6X6_250";

CameraModel modelOf(const YAML::Node& n) {
    CameraModel m;
    m.lens = calibration::lensModelFromString(n["lens"].as<std::string>()).value();
    m.width = n["width"].as<int>();
    m.height = n["height"].as<int>();
    m.fx = n["fx"].as<double>();
    m.fy = n["fy"].as<double>();
    m.cx = n["cx"].as<double>();
    m.cy = n["cy"].as<double>();
    m.distortion = n["distortion"].as<std::vector<double>>();
    return m;
}

Isometry3d poseOf(const YAML::Node& n) {
    const auto t = n["translation"].as<std::vector<double>>();
    const auto r = n["quaternion"].as<std::vector<double>>();  // w x y z
    Isometry3d T = Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(r[0], r[1], r[2], r[3]).normalized().toRotationMatrix();
    T.translation() = Vector3d(t[0], t[1], t[2]);
    return T;
}

// What the simulator knows about the session.
struct Truth {
    CameraModel color, ir, env;
    Isometry3d T_color_ir, T_world_env;
    std::vector<Isometry3d> T_world_color, T_world_board;
};

Truth readTruth() {
    const YAML::Node y =
        YAML::LoadFile((test::fixturesDir() / "sessions" / "sim_calibration.truth.yaml").string());
    Truth t;
    const YAML::Node cameras = y["cameras"];
    t.color = modelOf(cameras["kinect/color"]["model"]);
    t.ir = modelOf(cameras["kinect/ir"]["model"]);
    t.env = modelOf(cameras["env/color"]["model"]);
    t.T_color_ir = poseOf(cameras["kinect/ir"]["T_color_ir"]);
    t.T_world_env = poseOf(cameras["env/color"]["T_world_env"]);
    for (const YAML::Node& f : y["frames"]) {
        t.T_world_color.push_back(poseOf(f["T_world_color"]));
        t.T_world_board.push_back(poseOf(f["T_world_board"]));
    }
    return t;
}

double angleDeg(const Isometry3d& a, const Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180 / M_PI;
}

// Relative errors of fx fy cx cy, percent, as one line for the log.
std::string intrinsicsErrors(const CameraModel& m, const CameraModel& truth, double* worst) {
    const double e[4] = {m.fx / truth.fx - 1, m.fy / truth.fy - 1, m.cx / truth.cx - 1,
                         m.cy / truth.cy - 1};
    char buf[160];
    std::snprintf(buf, sizeof buf, "fx %+.3f %%, fy %+.3f %%, cx %+.3f %%, cy %+.3f %%", 100 * e[0],
                  100 * e[1], 100 * e[2], 100 * e[3]);
    *worst = 0;
    for (double v : e)
        *worst = std::max(*worst, 100 * std::abs(v));
    return buf;
}

// One calibration of the committed session, shared by the tests below (it takes seconds).
class CalibrateSession : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        // ctest runs each test in its own process, possibly at once: one folder per process.
        out_ = new fs::path(test::binaryDir() / "test-tmp" /
                            ("CalibrateSession-" + std::to_string(getpid())));
        fs::remove_all(*out_);
        run_ = new CliRun(mixray("calibrate " + q(kSession) + " --target " + kTarget +
                                 " --model env/color=fisheye --marker DICT_6X6_250:23:0.1 -o " +
                                 q(*out_)));
        std::printf("%s", run_->output.c_str());
    }
    static void TearDownTestSuite() {
        std::error_code ec;
        fs::remove_all(*out_, ec);
        delete run_;
        delete out_;
        run_ = nullptr;
        out_ = nullptr;
    }
    static calibration::CalibrationFile file() {
        auto read = calibration::readCalibrationFile(*out_ / "calibration.yaml");
        EXPECT_TRUE(read) << read.status().toString();
        return read ? *read : calibration::CalibrationFile{};
    }

    static fs::path* out_;
    static CliRun* run_;
};

fs::path* CalibrateSession::out_ = nullptr;
CliRun* CalibrateSession::run_ = nullptr;

TEST_F(CalibrateSession, IntrinsicsWithinAFifthOfAPercentOfTheTruth) {
    ASSERT_EQ(run_->exit_code, 0) << run_->output;
    const Truth truth = readTruth();
    const calibration::CalibrationFile f = file();
    for (const auto& [name, model] : std::map<std::string, const CameraModel*>{
             {"kinect/color", &truth.color}, {"kinect/ir", &truth.ir}, {"env/color", &truth.env}}) {
        const calibration::CalibratedCamera* c = f.find(name);
        ASSERT_NE(c, nullptr) << name << " not calibrated";
        EXPECT_EQ(c->model.lens, model->lens) << name;
        double worst = 0;
        const std::string line = intrinsicsErrors(c->model, *model, &worst);
        std::printf("%s: %s\n", name.c_str(), line.c_str());
        EXPECT_LT(worst, 0.2) << name << ": " << line;
    }
}

TEST_F(CalibrateSession, ColourToIrWithinAMillimetreAndATenthOfADegree) {
    ASSERT_EQ(run_->exit_code, 0) << run_->output;
    const Truth truth = readTruth();
    const calibration::CalibrationFile f = file();
    auto T_color_ir = f.pose("kinect/color", "kinect/ir");
    ASSERT_TRUE(T_color_ir) << T_color_ir.status().toString();
    const double mm = (T_color_ir->translation() - truth.T_color_ir.translation()).norm() * 1000;
    const double deg = angleDeg(*T_color_ir, truth.T_color_ir);
    std::printf("T_color_ir: %.3f mm, %.4f deg from the truth\n", mm, deg);
    EXPECT_LT(mm, 1.0);
    EXPECT_LT(deg, 0.1);
}

// The file's registration maps a raw depth pixel into the colour image where the truth puts the
// surface point that IR pixel sees (the board, at every corner of every view the IR camera saw
// whole): the registration's geometry (IR model, extrinsics, depth correction) and the depth
// noise together. The registered depth image holds that point's colour-camera depth there.
TEST_F(CalibrateSession, DepthRegistersWithinAPixel) {
    ASSERT_EQ(run_->exit_code, 0) << run_->output;
    const Truth truth = readTruth();
    const calibration::CalibrationFile f = file();
    auto registration = f.depthRegistration("kinect/depth");
    ASSERT_TRUE(registration) << registration.status().toString();
    const auto target = calibration::parseTarget(kTarget);
    ASSERT_TRUE(target);
    auto reader = openMkv(kSession);
    ASSERT_TRUE(reader) << reader.status().toString();
    const auto& streams = (*reader)->streams();
    double worst_px = 0, sum_px = 0;
    std::vector<double> depth_errors_mm;
    int points = 0, frames = 0;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            EXPECT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        if (streams[frame->meta().stream].name != "kinect/depth")
            continue;
        ++frames;
        const auto k = static_cast<size_t>(frame->meta().sequence);
        ASSERT_LT(k, truth.T_world_board.size());
        const Isometry3d T_world_ir = truth.T_world_color[k] * truth.T_color_ir;
        const Isometry3d T_ir_board = T_world_ir.inverse() * truth.T_world_board[k];
        const Vector3d n = T_ir_board.linear().col(2);
        const double plane = n.dot(T_ir_board.translation());
        auto registered = calibration::registerDepth(*registration, frame->image());
        ASSERT_TRUE(registered) << registered.status().toString();
        const ImageView depth = frame->image();
        const ImageView colour_depth = registered->view();
        for (const Vector3d& corner : target->points()) {
            const auto px = truth.ir.project(T_ir_board * corner);
            if (!px)
                continue;
            const int x = static_cast<int>(std::lround(px->x()));
            const int y = static_cast<int>(std::lround(px->y()));
            if (x < 0 || y < 0 || x >= depth.desc.width || y >= depth.desc.height)
                continue;
            const uint16_t raw = depth.row<uint16_t>(y)[x];
            if (raw == 0)
                continue;
            // The truth: where the IR ray through that pixel meets the board.
            const Vector3d ray = truth.ir.unproject(Vector2d(x, y)).value();
            const Vector3d hit = ray * (plane / n.dot(ray));
            const Vector3d in_color = truth.T_color_ir * hit;
            const Vector2d expected = truth.color.project(in_color).value();
            // The file's registration of the raw reading.
            const Vector3d file_ray = registration->depth.unproject(Vector2d(x, y)).value();
            const double z = calibration::correctedDepth(registration->correction, raw * 1e-3, x, y,
                                                         depth.desc.width);
            const auto got = registration->color.project(registration->T_color_depth *
                                                         (file_ray * (z / file_ray.z())));
            ASSERT_TRUE(got);
            const double e = (*got - expected).norm();
            worst_px = std::max(worst_px, e);
            sum_px += e;
            ++points;
            const int u = static_cast<int>(std::lround(expected.x()));
            const int v = static_cast<int>(std::lround(expected.y()));
            if (u >= 0 && v >= 0 && u < colour_depth.desc.width && v < colour_depth.desc.height) {
                const uint16_t mm = colour_depth.row<uint16_t>(v)[u];
                EXPECT_NE(mm, 0) << "frame " << k << " pixel " << u << "," << v;
                if (mm != 0)
                    depth_errors_mm.push_back(std::abs(mm - in_color.z() * 1000));
            }
        }
    }
    EXPECT_EQ(frames, 20);
    ASSERT_GT(points, 200);
    ASSERT_GT(depth_errors_mm.size(), 200u);
    std::sort(depth_errors_mm.begin(), depth_errors_mm.end());
    const double median_mm = depth_errors_mm[depth_errors_mm.size() / 2];
    const double p99_mm = depth_errors_mm[depth_errors_mm.size() * 99 / 100];
    std::printf(
        "depth registration: %d board points, mean %.3f px, worst %.3f px; registered "
        "depth from the truth: median %.2f mm, 99th percentile %.2f mm, worst %.2f mm\n",
        points, sum_px / points, worst_px, median_mm, p99_mm, depth_errors_mm.back());
    EXPECT_LT(worst_px, 1.0);
    // Kinect depth at 0.5-1 m: 1/8-pixel disparity steps of 1-3 mm and noise of ~1 mm (single
    // raw readings lie further off: one of the 469 reads 17 mm near).
    EXPECT_LT(median_mm, 2.0);
    EXPECT_LT(p99_mm, 5.0);
}

TEST_F(CalibrateSession, EnvironmentCameraAlignedToTheMarkerWithinAFifthOfADegree) {
    ASSERT_EQ(run_->exit_code, 0) << run_->output;
    const Truth truth = readTruth();
    const calibration::CalibrationFile f = file();
    const calibration::CalibratedCamera* env = f.find("env/color");
    ASSERT_NE(env, nullptr);
    EXPECT_EQ(env->parent, "world");
    auto T_world_env = f.pose("world", "env/color");
    ASSERT_TRUE(T_world_env) << T_world_env.status().toString();
    const double mm = (T_world_env->translation() - truth.T_world_env.translation()).norm() * 1000;
    const double deg = angleDeg(*T_world_env, truth.T_world_env);
    std::printf("T_world_env: %.3f mm, %.4f deg from the truth\n", mm, deg);
    EXPECT_LT(deg, 0.2);
    EXPECT_LT(mm, 3.0);
}

TEST_F(CalibrateSession, ReportAndCornersCacheRoundTrip) {
    ASSERT_EQ(run_->exit_code, 0) << run_->output;
    for (const char* name :
         {"report.md", "corners.vnl", "kinect_color_residuals.png", "kinect_color_coverage.png",
          "kinect_color_uncertainty.png", "kinect_ir_residuals.png", "kinect_ir_coverage.png",
          "kinect_ir_uncertainty.png", "env_color_residuals.png", "env_color_coverage.png",
          "env_color_uncertainty.png", "rig_kinect_color.png"})
        EXPECT_TRUE(fs::exists(*out_ / name)) << name;

    // The corners cache alone gives the same colour intrinsics (the same corners, the same solve).
    const fs::path again = test::tempDir() / "again";
    CliRun rerun = mixray("calibrate " + q(*out_ / "corners.vnl") + " --target " + kTarget +
                          " --model env/color=fisheye -o " + q(again));
    ASSERT_EQ(rerun.exit_code, 0) << rerun.output;
    auto first = calibration::readCalibrationFile(*out_ / "calibration.yaml");
    auto second = calibration::readCalibrationFile(again / "calibration.yaml");
    ASSERT_TRUE(first && second);
    const calibration::CalibratedCamera* a = first->find("kinect/color");
    const calibration::CalibratedCamera* b = second->find("kinect/color");
    ASSERT_TRUE(a && b);
    EXPECT_NEAR(a->model.fx, b->model.fx, 1e-6 * a->model.fx);
    EXPECT_NEAR(a->model.fy, b->model.fy, 1e-6 * a->model.fy);
    EXPECT_NEAR(a->model.cx, b->model.cx, 1e-6 * a->model.cx);
    EXPECT_NEAR(a->model.cy, b->model.cy, 1e-6 * a->model.cy);
    ASSERT_EQ(a->model.distortion.size(), b->model.distortion.size());
    for (size_t i = 0; i < a->model.distortion.size(); ++i)
        EXPECT_NEAR(a->model.distortion[i], b->model.distortion[i], 1e-6) << i;
}

}  // namespace
}  // namespace mixray
