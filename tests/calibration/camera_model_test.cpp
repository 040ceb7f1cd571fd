// CameraModel: projection against OpenCV and mrcal, project/unproject round trips, validate(),
// scaled() and the YAML form.
#include "mixray/calibration/camera_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "mixray/calibration/camera_model_yaml.h"
#include "mrcal_format.h"
#include "published_lenses.h"
#include "test_data.h"

namespace mixray::calibration {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

using test::fisheyeModels;
using test::NamedModel;
using test::pinholeModels;

cv::Mat cameraMatrix(const CameraModel& m) {
    return (cv::Mat_<double>(3, 3) << m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1);
}

std::vector<cv::Point3d> randomPoints(int count, double max_slope, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> slope(-max_slope, max_slope);
    std::uniform_real_distribution<double> depth(0.2, 8.0);
    std::vector<cv::Point3d> points;
    for (int i = 0; i < count; ++i) {
        const double z = depth(rng);
        points.emplace_back(slope(rng) * z, slope(rng) * z, z);
    }
    points.emplace_back(0, 0, 1);  // the optical axis
    return points;
}

// Pixels on a grid spanning the whole image, edges and corners included (pixel areas reach
// from -0.5 to size-0.5).
std::vector<Eigen::Vector2d> imageGrid(const CameraModel& m, int steps) {
    std::vector<Eigen::Vector2d> pixels;
    for (int j = 0; j <= steps; ++j) {
        for (int i = 0; i <= steps; ++i) {
            pixels.emplace_back(-0.5 + m.width * static_cast<double>(i) / steps,
                                -0.5 + m.height * static_cast<double>(j) / steps);
        }
    }
    return pixels;
}

TEST(CameraModelTest, PinholeFactoryAndNames) {
    const CameraModel m = CameraModel::pinhole(640, 480, 500, 501, 319.5, 239.5);
    EXPECT_EQ(m.lens, LensModel::kPinhole);
    EXPECT_EQ(m.width, 640);
    EXPECT_EQ(m.height, 480);
    EXPECT_EQ(m.fx, 500);
    EXPECT_EQ(m.fy, 501);
    EXPECT_EQ(m.cx, 319.5);
    EXPECT_EQ(m.cy, 239.5);
    EXPECT_TRUE(m.distortion.empty());
    EXPECT_TRUE(m.validate().isOk());
    EXPECT_EQ(lensModelFromString(toString(LensModel::kFisheye)), LensModel::kFisheye);
    EXPECT_EQ(lensModelFromString(toString(LensModel::kPinhole)), LensModel::kPinhole);
    EXPECT_FALSE(lensModelFromString("orthographic").has_value());
}

TEST(CameraModelTest, PinholeProjectMatchesOpenCV) {
    for (const auto& [name, model] : pinholeModels()) {
        SCOPED_TRACE(name);
        ASSERT_TRUE(model.validate().isOk()) << model.validate().toString();
        const std::vector<cv::Point3d> points = randomPoints(500, 0.7, 42);
        std::vector<cv::Point2d> expected;
        cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cameraMatrix(model),
                          model.distortion, expected);
        for (size_t i = 0; i < points.size(); ++i) {
            const auto pixel = model.project({points[i].x, points[i].y, points[i].z});
            ASSERT_TRUE(pixel.has_value());
            EXPECT_NEAR(pixel->x(), expected[i].x, 1e-9) << "point " << i;
            EXPECT_NEAR(pixel->y(), expected[i].y, 1e-9) << "point " << i;
        }
    }
}

TEST(CameraModelTest, FisheyeProjectMatchesOpenCV) {
    for (const auto& [name, model] : fisheyeModels()) {
        SCOPED_TRACE(name);
        ASSERT_TRUE(model.validate().isOk()) << model.validate().toString();
        // Up to ~60° off axis, inside the field of view of both lenses.
        const std::vector<cv::Point3d> points = randomPoints(500, 1.2, 7);
        std::vector<cv::Point2d> expected;
        cv::fisheye::projectPoints(points, expected, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0),
                                   cameraMatrix(model), model.distortion);
        for (size_t i = 0; i < points.size(); ++i) {
            const auto pixel = model.project({points[i].x, points[i].y, points[i].z});
            ASSERT_TRUE(pixel.has_value());
            EXPECT_NEAR(pixel->x(), expected[i].x, 1e-9) << "point " << i;
            EXPECT_NEAR(pixel->y(), expected[i].y, 1e-9) << "point " << i;
        }
    }
}

TEST(CameraModelTest, PinholeBehindCameraIsNullopt) {
    const CameraModel m = pinholeModels()[1].model;
    EXPECT_FALSE(m.project({0.1, 0.2, 0.0}).has_value());
    EXPECT_FALSE(m.project({0.1, 0.2, -1.0}).has_value());
    EXPECT_FALSE(m.project({0, 0, 0}).has_value());
}

void expectRoundTrip(const CameraModel& model, bool require_all) {
    int converged = 0;
    const std::vector<Eigen::Vector2d> grid = imageGrid(model, 40);
    for (const Eigen::Vector2d& pixel : grid) {
        const auto ray = model.unproject(pixel);
        if (!ray) {
            EXPECT_FALSE(require_all) << "no ray for pixel " << pixel.transpose();
            continue;
        }
        ++converged;
        EXPECT_NEAR(ray->norm(), 1.0, 1e-12);
        const auto back = model.project(*ray);
        ASSERT_TRUE(back.has_value()) << "pixel " << pixel.transpose();
        EXPECT_NEAR((*back - pixel).norm(), 0.0, 1e-6) << "pixel " << pixel.transpose();
    }
    EXPECT_GT(converged, 0);
}

TEST(CameraModelTest, PinholeRoundTripWholeImage) {
    for (const auto& [name, model] : pinholeModels()) {
        SCOPED_TRACE(name);
        expectRoundTrip(model, /*require_all=*/true);
    }
}

TEST(CameraModelTest, FisheyeRoundTripWholeImage) {
    for (const auto& [name, model] : fisheyeModels()) {
        SCOPED_TRACE(name);
        expectRoundTrip(model, /*require_all=*/true);
    }
}

TEST(CameraModelTest, UnprojectIsTheRayOfTheProjectedPoint) {
    for (const auto& named : pinholeModels()) {
        const CameraModel& model = named.model;
        SCOPED_TRACE(named.name);
        for (const cv::Point3d& p : randomPoints(100, 0.5, 3)) {
            const Eigen::Vector3d point(p.x, p.y, p.z);
            const auto ray = model.unproject(*model.project(point));
            ASSERT_TRUE(ray.has_value());
            EXPECT_NEAR((*ray - point.normalized()).norm(), 0.0, 1e-9);
        }
    }
    // The principal point looks straight down the optical axis.
    const CameraModel m = pinholeModels()[2].model;
    const auto axis = m.unproject({m.cx, m.cy});
    ASSERT_TRUE(axis.has_value());
    EXPECT_NEAR((*axis - Eigen::Vector3d(0, 0, 1)).norm(), 0.0, 1e-15);
}

TEST(CameraModelTest, FisheyeSeesBehindTheImagePlaneUpToItsLimit) {
    const CameraModel m = fisheyeModels()[1].model;
    for (double theta_deg : {0.0, 30.0, 89.0, 90.0, 95.0, 99.5}) {
        SCOPED_TRACE(theta_deg);
        for (double phi_deg : {0.0, 45.0, 160.0, 270.0}) {
            const double theta = theta_deg * kDeg, phi = phi_deg * kDeg;
            const Eigen::Vector3d dir(std::sin(theta) * std::cos(phi),
                                      std::sin(theta) * std::sin(phi), std::cos(theta));
            const auto pixel = m.project(2.5 * dir);
            ASSERT_TRUE(pixel.has_value());
            const auto ray = m.unproject(*pixel);
            ASSERT_TRUE(ray.has_value());
            EXPECT_NEAR((*ray - dir).norm(), 0.0, 1e-9);
        }
    }
    // Beyond 100° off axis, and straight behind, is outside the model's field of view.
    EXPECT_FALSE(m.project({std::sin(101 * kDeg), 0, std::cos(101 * kDeg)}).has_value());
    EXPECT_FALSE(m.project({0, 0, -1}).has_value());
    // The image corners look behind the image plane.
    const auto corner = m.unproject({-0.5, -0.5});
    ASSERT_TRUE(corner.has_value());
    EXPECT_LT(corner->z(), 0.0);
    // Pixels beyond the image circle of 100° do not unproject.
    const double r100 = m.fx * 100 * kDeg * 1.2;
    EXPECT_FALSE(m.unproject({m.cx + r100, m.cy}).has_value());
}

TEST(CameraModelTest, FisheyeFoldOverLimitsTheFieldOfView) {
    // OpenCV's test lens: its polynomial stops increasing before 100°, so the model ends there.
    const CameraModel m = fisheyeModels()[0].model;
    EXPECT_TRUE(m.project({std::sin(60 * kDeg), 0, std::cos(60 * kDeg)}).has_value());
    EXPECT_FALSE(m.project({std::sin(99 * kDeg), 0, std::cos(99 * kDeg)}).has_value());

    // Find the fold by a fine scan of dθ_d/dθ; the model ends there, in both directions.
    const std::vector<double>& k = m.distortion;
    auto thetaD = [&](double t) {
        const double t2 = t * t;
        return t *
               (1 + k[0] * t2 + k[1] * t2 * t2 + k[2] * t2 * t2 * t2 + k[3] * t2 * t2 * t2 * t2);
    };
    double fold = 0;
    while (fold < 100 * kDeg && thetaD(fold + 1e-5) > thetaD(fold))
        fold += 1e-5;
    ASSERT_LT(fold, 100 * kDeg);
    auto dir = [](double t) { return Eigen::Vector3d(std::sin(t), 0, std::cos(t)); };
    const auto inside = m.project(dir(fold - 0.01));
    ASSERT_TRUE(inside.has_value());
    const auto ray = m.unproject(*inside);
    ASSERT_TRUE(ray.has_value());
    EXPECT_NEAR((*ray - dir(fold - 0.01)).norm(), 0.0, 1e-9);
    EXPECT_FALSE(m.project(dir(fold + 0.01)).has_value());
    EXPECT_FALSE(m.unproject({m.cx + m.fx * (thetaD(fold) + 0.01), m.cy}).has_value());
}

TEST(CameraModelTest, ValidateNamesTheField) {
    const CameraModel good = pinholeModels()[1].model;
    ASSERT_TRUE(good.validate().isOk());

    auto expectInvalid = [](const CameraModel& m, const std::string& field) {
        const Status status = m.validate();
        EXPECT_EQ(status.code(), ErrorCode::kInvalidArgument) << field;
        EXPECT_NE(status.message().find(field), std::string::npos) << status.message();
    };
    CameraModel m = good;
    m.width = 0;
    expectInvalid(m, "width");
    m = good;
    m.height = -3;
    expectInvalid(m, "height");
    m = good;
    m.fx = -1;
    expectInvalid(m, "fx");
    m = good;
    m.fy = std::numeric_limits<double>::infinity();
    expectInvalid(m, "fy");
    m = good;
    m.cx = std::nan("");
    expectInvalid(m, "cx");
    m = good;
    m.cy = std::nan("");
    expectInvalid(m, "cy");
    m = good;
    m.distortion = {0.1, 0.2, 0.3};
    expectInvalid(m, "distortion");
    m = good;
    m.distortion = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
    expectInvalid(m, "distortion");
    m = good;
    m.distortion[2] = std::nan("");
    expectInvalid(m, "distortion");

    for (size_t n : {0u, 4u, 5u, 8u}) {
        m = good;
        m.distortion.assign(n, 0.01);
        EXPECT_TRUE(m.validate().isOk()) << n << " coefficients";
    }
    m = fisheyeModels()[0].model;
    EXPECT_TRUE(m.validate().isOk());
    m.distortion.push_back(0);
    expectInvalid(m, "distortion");
    m.distortion.clear();
    expectInvalid(m, "distortion");
}

TEST(CameraModelTest, ScaledKeepsRaysThroughScaledPixels) {
    const CameraModel full = pinholeModels()[2].model;
    for (double scale : {0.5, 0.25, 2.0}) {
        SCOPED_TRACE(scale);
        const CameraModel small = full.scaled(scale);
        EXPECT_EQ(small.width, static_cast<int>(std::lround(full.width * scale)));
        EXPECT_EQ(small.height, static_cast<int>(std::lround(full.height * scale)));
        EXPECT_DOUBLE_EQ(small.fx, full.fx * scale);
        EXPECT_DOUBLE_EQ(small.fy, full.fy * scale);
        EXPECT_EQ(small.distortion, full.distortion);
        EXPECT_EQ(small.lens, full.lens);
        // The image edges (-0.5 and size-0.5) map onto the scaled image's edges.
        for (const cv::Point3d& p : randomPoints(20, 0.5, 11)) {
            const Eigen::Vector3d point(p.x, p.y, p.z);
            const Eigen::Vector2d a = *full.project(point);
            const Eigen::Vector2d b = *small.project(point);
            EXPECT_NEAR(b.x(), (a.x() + 0.5) * scale - 0.5, 1e-9);
            EXPECT_NEAR(b.y(), (a.y() + 0.5) * scale - 0.5, 1e-9);
        }
    }
    // Halving a 640-wide image with the centre at 319.5 puts it at 159.5.
    const CameraModel half = CameraModel::pinhole(640, 480, 500, 500, 319.5, 239.5).scaled(0.5);
    EXPECT_DOUBLE_EQ(half.cx, 159.5);
    EXPECT_DOUBLE_EQ(half.cy, 119.5);
    EXPECT_EQ(half.width, 320);
    EXPECT_EQ(half.height, 240);
}

// ---- mrcal's stereographic and splined stereographic lenses ----

CameraModel stereographic() {
    CameraModel m = CameraModel::pinhole(1024, 768, 400, 402, 511.5, 383.5);
    m.lens = LensModel::kStereographic;
    return m;
}

// A wide splined lens with a smooth, non-trivial correction field.
CameraModel splined() {
    CameraModel m = stereographic();
    m.lens = LensModel::kSplinedStereographic;
    m.spline = {3, 12, 10, 170};
    for (int y = 0; y < m.spline.ny; ++y) {
        for (int x = 0; x < m.spline.nx; ++x) {
            m.distortion.push_back(0.01 * std::sin(0.7 * x + 0.3 * y));
            m.distortion.push_back(-0.008 * std::cos(0.4 * x - 0.5 * y));
        }
    }
    return m;
}

std::filesystem::path mrcalData(const char* name) {
    return mixray::test::sharedDataDir() / "04_mrcal" / name;
}

TEST(CameraModelTest, MrcalLensNamesRoundTrip) {
    EXPECT_EQ(toString(LensModel::kStereographic), "stereographic");
    EXPECT_EQ(toString(LensModel::kSplinedStereographic), "splined_stereographic");
    EXPECT_EQ(lensModelFromString("stereographic"), LensModel::kStereographic);
    EXPECT_EQ(lensModelFromString("LENSMODEL_STEREOGRAPHIC"), LensModel::kStereographic);
    const CameraModel m = splined();
    EXPECT_EQ(m.lensName(), "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=12_Ny=10_fov_x_deg=170");
    EXPECT_EQ(lensModelFromString(m.lensName()), LensModel::kSplinedStereographic);
    EXPECT_EQ(splineConfigFromString(m.lensName()), m.spline);
    EXPECT_EQ(stereographic().lensName(), "stereographic");
    EXPECT_FALSE(
        splineConfigFromString("LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=12").has_value());
    EXPECT_FALSE(splineConfigFromString(m.lensName() + "_extra").has_value());
    EXPECT_FALSE(splineConfigFromString("LENSMODEL_OPENCV8").has_value());
}

TEST(CameraModelTest, MrcalLensesValidate) {
    EXPECT_TRUE(stereographic().validate().isOk());
    EXPECT_TRUE(splined().validate().isOk()) << splined().validate().toString();
    CameraModel m = stereographic();
    m.distortion = {0.1};
    EXPECT_NE(m.validate().message().find("distortion"), std::string::npos);
    m = splined();
    m.distortion.pop_back();
    EXPECT_NE(m.validate().message().find("240"), std::string::npos) << m.validate().message();
    m = splined();
    m.spline.order = 4;
    EXPECT_NE(m.validate().message().find("order"), std::string::npos);
    m = splined();
    m.spline.fov_x_deg = 0;
    EXPECT_NE(m.validate().message().find("fov_x_deg"), std::string::npos);
    m = splined();
    m.spline.nx = 2;
    EXPECT_NE(m.validate().message().find("Nx"), std::string::npos);
}

TEST(CameraModelTest, StereographicRoundTripWholeImage) {
    expectRoundTrip(stereographic(), /*require_all=*/true);
    expectRoundTrip(splined(), /*require_all=*/true);
}

TEST(CameraModelTest, MrcalCam0RoundTripWholeImage) {
    MIXRAY_REQUIRE_SHARED_DATA(mrcalData("cam0.splined.cameramodel"));
    for (const char* name : {"cam0.splined.cameramodel", "cam0.opencv8.cameramodel"}) {
        SCOPED_TRACE(name);
        auto camera = detail::readMrcalCameramodel(mrcalData(name));
        ASSERT_TRUE(camera.isOk()) << camera.status().toString();
        expectRoundTrip(camera->model, /*require_all=*/true);
    }
}

TEST(CameraModelTest, MrcalLensesAgreeWithMrcalsMeasuredProjections) {
    MIXRAY_REQUIRE_SHARED_DATA(mrcalData("cam0.splined.cameramodel"));
    // MANIFEST.md: mrcal 2.2's project([0.1, 0.2, 1]), printed to 5 decimals.
    const struct {
        const char* file;
        Eigen::Vector2d expected;
    } cases[] = {{"cam0.opencv8.cameramodel", {2141.67015, 1439.34362}},
                 {"cam1.opencv8.cameramodel", {2140.94643, 1438.82242}},
                 {"cam0.splined.cameramodel", {2148.73465, 1413.23704}}};
    for (const auto& c : cases) {
        SCOPED_TRACE(c.file);
        auto camera = detail::readMrcalCameramodel(mrcalData(c.file));
        ASSERT_TRUE(camera.isOk()) << camera.status().toString();
        const auto q = camera->model.project({0.1, 0.2, 1.0});
        ASSERT_TRUE(q.has_value());
        EXPECT_NEAR(q->x(), c.expected.x(), 6e-6);
        EXPECT_NEAR(q->y(), c.expected.y(), 6e-6);
    }
}

TEST(CameraModelTest, StereographicSeesBehindTheCamera) {
    const CameraModel m = stereographic();
    // 120° off axis: u = 2 tan(60°) along x.
    const auto behind = m.project({std::sin(120 * kDeg), 0, std::cos(120 * kDeg)});
    ASSERT_TRUE(behind.has_value());
    EXPECT_NEAR(behind->x(), 511.5 + 400 * 2 * std::tan(60 * kDeg), 1e-9);
    EXPECT_FALSE(m.project({0, 0, -1}).has_value());
    EXPECT_FALSE(m.project({0, 0, 0}).has_value());
    // The splined lens ends where its control points do: 170° wide, so not 100° off axis.
    const CameraModel s = splined();
    EXPECT_TRUE(s.project({std::sin(80 * kDeg), 0, std::cos(80 * kDeg)}).has_value());
    EXPECT_FALSE(s.project({std::sin(100 * kDeg), 0, std::cos(100 * kDeg)}).has_value());
}

TEST(CameraModelTest, ScaledIsExactForMrcalLenses) {
    for (const CameraModel& full : {stereographic(), splined()}) {
        SCOPED_TRACE(full.lensName());
        for (double scale : {0.5, 2.0}) {
            const CameraModel other = full.scaled(scale);
            EXPECT_EQ(other.spline, full.spline);
            for (const cv::Point3d& p : randomPoints(50, 1.5, 13)) {
                const Eigen::Vector3d point(p.x, p.y, p.z);
                const auto a = full.project(point);
                const auto b = other.project(point);
                ASSERT_TRUE(a && b);
                EXPECT_NEAR(b->x(), (a->x() + 0.5) * scale - 0.5, 1e-9);
                EXPECT_NEAR(b->y(), (a->y() + 0.5) * scale - 0.5, 1e-9);
            }
        }
    }
}

TEST(CameraModelTest, YamlRoundTripKeepsEveryLens) {
    std::vector<CameraModel> models = {pinholeModels()[4].model, fisheyeModels()[0].model,
                                       stereographic(), splined()};
    for (const CameraModel& m : models) {
        SCOPED_TRACE(m.lensName());
        const std::string text = cameraModelYaml(m);
        yaml::Reader reader("model.yaml");
        auto root = reader.load(text, 1 << 20, 16, "a camera model");
        ASSERT_TRUE(root.isOk()) << root.status().toString();
        auto back = readCameraModel(reader, *root);
        ASSERT_TRUE(back.isOk()) << back.status().toString() << "\n" << text;
        EXPECT_EQ(back->lens, m.lens);
        EXPECT_EQ(back->spline, m.spline);
        EXPECT_EQ(back->width, m.width);
        EXPECT_EQ(back->height, m.height);
        EXPECT_EQ(back->fx, m.fx);
        EXPECT_EQ(back->fy, m.fy);
        EXPECT_EQ(back->cx, m.cx);
        EXPECT_EQ(back->cy, m.cy);
        EXPECT_EQ(back->distortion, m.distortion);
    }
    // A splined lens without its configuration, or with the wrong number of values, is refused
    // naming what was expected.
    yaml::Reader reader("bad.yaml");
    auto bare = reader.load(
        "{lens: splined_stereographic, width: 10, height: 10, fx: 1, fy: 1, cx: 0, cy: 0}", 1 << 20,
        16, "a camera model");
    ASSERT_TRUE(bare.isOk());
    auto refused = readCameraModel(reader, *bare);
    ASSERT_FALSE(refused.isOk());
    EXPECT_NE(refused.status().message().find("LENSMODEL_SPLINED_STEREOGRAPHIC_order"),
              std::string::npos)
        << refused.status().message();
    auto short_list = reader.load(
        "{lens: LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=4_Ny=4_fov_x_deg=90, width: 10, "
        "height: 10, fx: 1, fy: 1, cx: 0, cy: 0, distortion: [0, 0]}",
        1 << 20, 16, "a camera model");
    ASSERT_TRUE(short_list.isOk());
    auto refused_count = readCameraModel(reader, *short_list);
    ASSERT_FALSE(refused_count.isOk());
    EXPECT_NE(refused_count.status().message().find("32"), std::string::npos)
        << refused_count.status().message();
}

}  // namespace
}  // namespace mixray::calibration
