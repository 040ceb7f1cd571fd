// Depth-map occlusion: ray distances, RT²AR's depth-map traversal and the depth mesh, against
// analytic planes and boxes seen through pinhole, distorted and fish-eye lenses, and on real
// Kinect frames.
#include "mixray/render/depth_occlusion.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "mixray/graph/recording.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/open_recording.h"
#include "test_data.h"

namespace mixray::render {
namespace {

using calibration::CameraModel;
using calibration::LensModel;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- analytic scenes ----

// The plane through `point` with unit `normal` (facing the camera).
struct Plane {
    Vector3d point;
    Vector3d normal;

    double signedDistance(const Vector3d& p) const { return normal.dot(p - point); }
    // Distance along the ray o + t·u (u unit) to the plane; +inf when it does not hit ahead.
    double hit(const Vector3d& o, const Vector3d& u) const {
        const double denom = normal.dot(u);
        if (denom == 0)
            return kInf;
        const double t = normal.dot(point - o) / denom;
        return t > 0 ? t : kInf;
    }
};

// An axis-aligned box (camera frame).
struct Box {
    Vector3d lo;
    Vector3d hi;

    double hit(const Vector3d& o, const Vector3d& u) const {
        double t0 = 0, t1 = kInf;
        for (int k = 0; k < 3; ++k) {
            if (u[k] == 0) {
                if (o[k] < lo[k] || o[k] > hi[k])
                    return kInf;
                continue;
            }
            double a = (lo[k] - o[k]) / u[k];
            double b = (hi[k] - o[k]) / u[k];
            if (a > b)
                std::swap(a, b);
            t0 = std::max(t0, a);
            t1 = std::min(t1, b);
        }
        return t0 <= t1 && t0 > 0 ? t0 : kInf;
    }
    bool contains(const Vector3d& p, double margin) const {
        return (p.array() >= lo.array() - margin).all() && (p.array() <= hi.array() + margin).all();
    }
};

struct Scene {
    std::optional<Plane> plane;
    std::optional<Box> box;

    double hit(const Vector3d& o, const Vector3d& u) const {
        double t = kInf;
        if (plane)
            t = std::min(t, plane->hit(o, u));
        if (box)
            t = std::min(t, box->hit(o, u));
        return t;
    }
};

// A depth16 image of `scene` as `camera` sees it: z rounded to millimetres, 0 where nothing is
// hit within the depth16 range.
Image renderDepth(const CameraModel& camera, const Scene& scene) {
    Image image(ImageDesc::packed(PixelFormat::kDepth16, camera.width, camera.height));
    const MutableImageView view = image.mutableView();
    for (int y = 0; y < camera.height; ++y) {
        for (int x = 0; x < camera.width; ++x) {
            uint16_t value = 0;
            if (const auto u = camera.unproject(Vector2d(x, y))) {
                const double t = scene.hit(Vector3d::Zero(), *u);
                const double z_mm = t * u->z() * 1000;
                if (std::isfinite(z_mm) && z_mm >= 0.5 && z_mm < 65535) {
                    value = static_cast<uint16_t>(std::lround(z_mm));
                }
            }
            view.row<uint16_t>(y)[x] = value;
        }
    }
    return image;
}

struct NamedCamera {
    const char* name;
    CameraModel camera;
};

void PrintTo(const NamedCamera& camera, std::ostream* os) {
    *os << camera.name;
}

std::vector<NamedCamera> testCameras() {
    CameraModel pinhole = CameraModel::pinhole(640, 480, 525, 525, 319.5, 239.5);
    CameraModel barrel = CameraModel::pinhole(640, 480, 520, 522, 322.3, 236.9);
    barrel.distortion = {-0.28, 0.09, 0.0012, -0.0008, -0.012};
    CameraModel fisheye = CameraModel::pinhole(640, 480, 250, 250, 318.2, 241.7);
    fisheye.lens = LensModel::kFisheye;
    fisheye.distortion = {0.021, -0.006, 0.0012, -0.0002};
    return {{"pinhole", pinhole}, {"distorted", barrel}, {"fisheye", fisheye}};
}

// A tilted wall 1.5–6 m away, facing the camera.
Plane testPlane() {
    return {Vector3d(0.1, -0.05, 2.4), Vector3d(0.25, -0.35, -1).normalized()};
}

// A wall at 3 m and a box 1.3–1.7 m away in front of it.
Plane testWall() {
    return {Vector3d(0, 0, 3), Vector3d(0, 0, -1)};
}
Box testBox() {
    return {Vector3d(-0.2, -0.2, 1.3), Vector3d(0.2, 0.2, 1.7)};
}

// The test scenes as a lens sees them, rendered once per lens: unprojecting every pixel is
// most of this suite's time, above all under the sanitizers.
const Image& cachedDepth(const NamedCamera& lens, bool with_box) {
    static std::map<std::pair<std::string, bool>, Image> cache;
    const auto key = std::pair{std::string(lens.name), with_box};
    auto it = cache.find(key);
    if (it == cache.end()) {
        const Scene scene = with_box ? Scene{testWall(), testBox()} : Scene{testPlane(), {}};
        it = cache.emplace(key, renderDepth(lens.camera, scene)).first;
    }
    return it->second;
}

class DepthOcclusion : public ::testing::TestWithParam<NamedCamera> {
protected:
    void SetUp() override {
        camera_ = GetParam().camera;
        ASSERT_TRUE(camera_.validate()) << camera_.validate().toString();
    }
    DepthView view(const Image& image) const { return {image.view(), camera_}; }
    const Image& planeDepth() const { return cachedDepth(GetParam(), false); }
    const Image& boxDepth() const { return cachedDepth(GetParam(), true); }

    CameraModel camera_;
};

// ---- DepthView / rayDistanceAt ----

TEST_P(DepthOcclusion, ZAtReadsMetresAndRejectsHolesAndBorders) {
    Image image(ImageDesc::packed(PixelFormat::kDepth16, camera_.width, camera_.height));
    const MutableImageView m = image.mutableView();
    std::fill(image.bytes().begin(), image.bytes().end(), 0);
    m.row<uint16_t>(3)[5] = 1234;
    m.row<uint16_t>(camera_.height - 1)[camera_.width - 1] = 65535;
    const DepthView depth = view(image);
    EXPECT_FLOAT_EQ(*depth.zAt(5, 3), 1.234f);
    EXPECT_FLOAT_EQ(*depth.zAt(camera_.width - 1, camera_.height - 1), 65.535f);
    EXPECT_FALSE(depth.zAt(6, 3));  // 0 = no measurement
    EXPECT_FALSE(depth.zAt(-1, 3));
    EXPECT_FALSE(depth.zAt(5, -1));
    EXPECT_FALSE(depth.zAt(camera_.width, 3));
    EXPECT_FALSE(depth.zAt(5, camera_.height));
    EXPECT_FALSE(rayDistanceAt(depth, 6, 3));
    EXPECT_FALSE(rayDistanceAt(depth, -1, -1));
}

TEST_P(DepthOcclusion, RayDistanceIsTheTrueDistanceAlongThePixelRay) {
    const Plane plane = testPlane();
    const Image& image = planeDepth();
    const DepthView depth = view(image);
    int checked = 0;
    for (int y = 0; y < camera_.height; y += 3) {
        for (int x = 0; x < camera_.width; x += 3) {
            const auto distance = rayDistanceAt(depth, x, y);
            const auto u = camera_.unproject(Vector2d(x, y));
            if (!depth.zAt(x, y)) {
                EXPECT_FALSE(distance);
                continue;
            }
            ASSERT_TRUE(distance && u);
            // Exact for the stored z, and the true distance within z's rounding to 1 mm.
            const double truth = plane.hit(Vector3d::Zero(), *u);
            EXPECT_NEAR(*distance, *depth.zAt(x, y) / u->z(), 2e-6 * truth);
            EXPECT_NEAR(*distance, truth, 0.5e-3 / u->z() + 2e-6 * truth) << x << "," << y;
            ++checked;
        }
    }
    EXPECT_GT(checked, 10000);
}

// ---- traceDepthMap ----

// Random secondary rays from points in front of the wall to points on it: the walk finds the
// analytic crossing to within the depth map's 1 mm quantisation (scaled by the incidence).
TEST_P(DepthOcclusion, TraceHitsThePlaneAtTheAnalyticDistance) {
    const Plane plane = testPlane();
    const Image& image = planeDepth();
    const DepthView depth = view(image);
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> px(2, camera_.width - 3);
    std::uniform_int_distribution<int> py(2, camera_.height - 3);
    std::uniform_real_distribution<double> fraction(0.15, 0.85);
    int traced = 0;
    double worst = 0;
    while (traced < 1500) {
        const int ax = px(rng), ay = py(rng), bx = px(rng), by = py(rng);
        const auto ua = camera_.unproject(Vector2d(ax, ay));
        const auto ub = camera_.unproject(Vector2d(bx, by));
        ASSERT_TRUE(ua && ub);
        const double ta = plane.hit(Vector3d::Zero(), *ua);
        const double tb = plane.hit(Vector3d::Zero(), *ub);
        if (!std::isfinite(ta) || !std::isfinite(tb) || !depth.zAt(ax, ay) || !depth.zAt(bx, by))
            continue;
        const Vector3d origin = *ua * (ta * fraction(rng));
        const Vector3d target = *ub * tb;
        const Vector3d dir = (target - origin).normalized();
        const double incidence = std::abs(plane.normal.dot(dir));
        if (incidence < 0.2)
            continue;
        const double truth = (target - origin).norm();
        const auto t = traceDepthMap(depth, origin.cast<float>(), dir.cast<float>(),
                                     static_cast<float>(3 * truth), 0.05f);
        ASSERT_TRUE(t) << "ray " << ax << "," << ay << " -> " << bx << "," << by;
        // 1 mm of z moves the plane by at most ~1.3 mm along its normal here; float t adds 1e-6.
        // z rounded to 1 mm: 0.5 mm of z is 0.5 mm / cos(angle to the axis) along the pixel
        // ray, and that over the incidence along the traced ray.
        const double tolerance = 1e-3 / (ub->z() * incidence) + 2e-6 * truth;
        EXPECT_NEAR(*t, truth, tolerance) << "ray " << ax << "," << ay << " -> " << bx << "," << by;
        worst = std::max(worst, std::abs(*t - truth) * incidence);
        ++traced;
    }
    RecordProperty("worst_normal_error_mm", std::to_string(worst * 1e3));
}

// Primary rays (from the camera centre along pixel rays, whose image does not move) and rays
// along the optical axis find the same distance as rayDistanceAt.
TEST_P(DepthOcclusion, TraceAlongPixelRaysMatchesRayDistance) {
    const Image& image = planeDepth();
    const DepthView depth = view(image);
    for (int y = 1; y < camera_.height; y += 37) {
        for (int x = 1; x < camera_.width; x += 41) {
            const auto distance = rayDistanceAt(depth, x, y);
            if (!distance)
                continue;
            const Vector3f u = camera_.unproject(Vector2d(x, y))->cast<float>();
            const auto t = traceDepthMap(depth, Vector3f::Zero(), u, 1e30f, 0.02f);
            ASSERT_TRUE(t) << x << "," << y;
            EXPECT_NEAR(*t, *distance, 1e-4 * *distance) << x << "," << y;
            // Starting part of the way along, and with a direction that is not unit length.
            const auto t2 = traceDepthMap(depth, 0.25f * *distance * u, 3 * u, 1e30f, 0.02f);
            ASSERT_TRUE(t2);
            EXPECT_NEAR(*t2 * 3, 0.75f * *distance, 1e-4 * *distance);
            for (const float scale : {1e-3f, 1e3f}) {
                const auto ts = traceDepthMap(depth, Vector3f::Zero(), scale * u, 1e30f, 0.02f);
                ASSERT_TRUE(ts);
                EXPECT_NEAR(*ts * scale, *distance, 1e-4 * *distance);
            }
        }
    }
    const Vector3d axis(0, 0, 1);
    const double truth = testPlane().hit(Vector3d(0, 0, 0.3), axis);
    const auto t = traceDepthMap(depth, Vector3f(0, 0, 0.3f), Vector3f(0, 0, 1), 100, 0.02f);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, truth, 3e-3);
}

TEST_P(DepthOcclusion, TraceMissesRaysThatNeverCrossInFrontToBehind) {
    const Plane plane = testPlane();
    const Image& image = planeDepth();
    const DepthView depth = view(image);
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> px(0, camera_.width - 1);
    std::uniform_int_distribution<int> py(0, camera_.height - 1);
    std::uniform_real_distribution<double> angle(0, 2 * M_PI);
    const Vector3d e1 = plane.normal.unitOrthogonal();
    const Vector3d e2 = plane.normal.cross(e1);
    int traced = 0;
    while (traced < 300) {
        const int x = px(rng), y = py(rng);
        if (!depth.zAt(x, y))
            continue;
        const Vector3d u = *camera_.unproject(Vector2d(x, y));
        const Vector3d on_plane = u * plane.hit(Vector3d::Zero(), u);
        // Where 1 px of the depth map resolves 5 cm of the wall: within 60° of the axis, 6 m.
        if (u.z() < 0.5 || on_plane.norm() > 6)
            continue;
        const double a = angle(rng);
        const Vector3f along = (std::cos(a) * e1 + std::sin(a) * e2).cast<float>();
        // Parallel to the wall for 2 m, 5 cm in front of it or 10 cm behind it (beyond the
        // 5 cm shell).
        const Vector3f in_front = (on_plane + 0.05 * plane.normal).cast<float>();
        const Vector3f behind = (on_plane - 0.10 * plane.normal).cast<float>();
        EXPECT_FALSE(traceDepthMap(depth, in_front, along, 2, 0.05f)) << x << "," << y;
        EXPECT_FALSE(traceDepthMap(depth, behind, along, 2, 0.05f)) << x << "," << y;
        // Towards the camera from in front of the wall, and away from it from behind.
        EXPECT_FALSE(traceDepthMap(depth, in_front, -in_front, 10, 0.05f));
        EXPECT_FALSE(traceDepthMap(depth, behind, behind, 1e30f, 0.05f));
        ++traced;
    }
}

TEST_P(DepthOcclusion, TraceStopsAtTheImageBorderAndAtTMax) {
    const Plane plane = testPlane();
    const Image& image = planeDepth();
    const DepthView depth = view(image);
    // Towards a point of the wall that lies outside the image, from in front of the wall
    // inside it: the crossing is not in the depth map, so there is none to report.
    const Vector3d e1 = (Vector3d::UnitX() - plane.normal.x() * plane.normal).normalized();
    int checked = 0;
    for (int y = 40; y < camera_.height - 40; y += 40) {
        const Vector3d u = *camera_.unproject(Vector2d(camera_.width - 30, y));
        const Vector3d on_plane = u * plane.hit(Vector3d::Zero(), u);
        const Vector3d target = on_plane + 3.0 * e1;
        const auto target_px = camera_.project(target);
        if (!target_px || target_px->x() < camera_.width + 20)
            continue;
        const Vector3d origin = 0.6 * on_plane;
        const Vector3d dir = (target - origin).normalized();
        EXPECT_FALSE(traceDepthMap(depth, origin.cast<float>(), dir.cast<float>(), 1e30f, 0.5f))
            << y;
        ++checked;
    }
    EXPECT_GE(checked, 3);

    // t_max before the wall, just after it, infinite and huge.
    const Vector3d u = *camera_.unproject(Vector2d(200, 300));
    const double truth = plane.hit(Vector3d::Zero(), u);
    const Vector3f origin = (0.3 * u).cast<float>();
    const Vector3f dir = Vector3d(0.3, 0.1, 0.6).normalized().cast<float>();
    const double t_wall = plane.hit(0.3 * u, dir.cast<double>());
    ASSERT_TRUE(std::isfinite(t_wall) && truth > 0);
    EXPECT_FALSE(traceDepthMap(depth, origin, dir, static_cast<float>(0.95 * t_wall), 0.05f));
    for (const float t_max :
         {static_cast<float>(1.05 * t_wall), 1e30f, std::numeric_limits<float>::infinity(),
          std::numeric_limits<float>::max()}) {
        const auto t = traceDepthMap(depth, origin, dir, t_max, 0.05f);
        ASSERT_TRUE(t) << t_max;
        EXPECT_NEAR(*t, t_wall, 5e-3) << t_max;
    }
}

TEST_P(DepthOcclusion, TraceEntersTheImageFromOutside) {
    const Plane plane = testPlane();
    const Image& image = planeDepth();
    const DepthView depth = view(image);
    // From beside and behind the camera (outside its view) towards points on the wall.
    for (const Vector3d& origin :
         {Vector3d(-2.5, 0.2, 0.3), Vector3d(0.5, 2.0, -0.5), Vector3d(1.5, -1.5, 0.02)}) {
        for (int y = 100; y < camera_.height - 50; y += 90) {
            for (int x = 100; x < camera_.width - 50; x += 110) {
                const Vector3d u = *camera_.unproject(Vector2d(x, y));
                const Vector3d target = u * plane.hit(Vector3d::Zero(), u);
                const Vector3d dir = (target - origin).normalized();
                if (std::abs(plane.normal.dot(dir)) < 0.2)
                    continue;
                const auto t =
                    traceDepthMap(depth, origin.cast<float>(), dir.cast<float>(), 1e30f, 0.05f);
                ASSERT_TRUE(t) << origin.transpose() << " -> " << x << "," << y;
                EXPECT_NEAR(*t, (target - origin).norm(),
                            2e-3 / std::abs(plane.normal.dot(dir)) + 1e-5)
                    << origin.transpose() << " -> " << x << "," << y;
            }
        }
    }
}

// A box 1.3–1.7 m away in front of a wall at 3 m. A ray passing behind the box's front face is
// blocked only if it is no deeper behind it than the thickness; then it hits the silhouette.
TEST_P(DepthOcclusion, TraceHonoursThicknessBehindSilhouettes) {
    const Image& image = boxDepth();
    const DepthView depth = view(image);
    // The silhouette's pixel ray on the left: the front face's edge x/z, through the lens.
    const Vector3d edge = Vector3d(-0.2, 0.0, 1.3).normalized();
    for (const double z : {1.32, 1.42, 1.85}) {
        const Vector3f origin(-0.8f, 0.0f, static_cast<float>(z));
        const Vector3f dir(1, 0, 0);
        const double silhouette = edge.x() / edge.z() * z - origin.x();
        const double depth_behind = z - 1.3;
        for (const float thickness : {0.05f, 0.15f, 1.0f}) {
            const auto t = traceDepthMap(depth, origin, dir, 5, thickness);
            if (depth_behind <= thickness) {
                ASSERT_TRUE(t) << z << " " << thickness;
                // One pixel at this depth is ~3 mm wide (wider at the fish-eye's rim).
                EXPECT_NEAR(*t, silhouette, 1e-2) << z << " " << thickness;
            } else {
                EXPECT_FALSE(t) << z << " " << thickness << " hit at " << *t;
            }
        }
    }
    // In front of the box: hits its front face head-on.
    const auto t = traceDepthMap(depth, Vector3f(0.05f, 0.02f, 0.5f), Vector3f(0, 0, 1), 10, 0.05f);
    ASSERT_TRUE(t);
    EXPECT_NEAR(*t, 0.8, 2e-3);
}

TEST_P(DepthOcclusion, TraceSeesNothingThroughHolesAndRejectsBadInput) {
    Image image = planeDepth();
    const MutableImageView m = image.mutableView();
    const int cx = camera_.width / 2, cy = camera_.height / 2;
    for (int y = cy - 40; y < cy + 40; ++y) {
        for (int x = cx - 40; x < cx + 40; ++x)
            m.row<uint16_t>(y)[x] = 0;
    }
    const DepthView depth = view(image);
    const Vector3f u = camera_.unproject(Vector2d(cx, cy))->cast<float>();
    EXPECT_FALSE(traceDepthMap(depth, Vector3f::Zero(), u, 1e30f, 0.05f));
    const Vector3f u_valid = camera_.unproject(Vector2d(cx - 60, cy))->cast<float>();
    EXPECT_TRUE(traceDepthMap(depth, Vector3f::Zero(), u_valid, 1e30f, 0.05f));

    const float nan = std::numeric_limits<float>::quiet_NaN();
    EXPECT_FALSE(traceDepthMap(depth, Vector3f::Zero(), Vector3f::Zero(), 10, 0.05f));
    EXPECT_FALSE(traceDepthMap(depth, Vector3f(nan, 0, 0), u_valid, 10, 0.05f));
    EXPECT_FALSE(traceDepthMap(depth, Vector3f::Zero(), Vector3f(0, nan, 1), 10, 0.05f));
    EXPECT_FALSE(traceDepthMap(depth, Vector3f::Zero(), u_valid, 0, 0.05f));
    EXPECT_FALSE(traceDepthMap(depth, Vector3f::Zero(), u_valid, -1, 0.05f));
    EXPECT_FALSE(traceDepthMap(depth, Vector3f::Zero(), u_valid, nan, 0.05f));
    EXPECT_TRUE(traceDepthMap(depth, Vector3f::Zero(), u_valid, 10, nan));  // thickness -> 1 mm
    EXPECT_TRUE(traceDepthMap(depth, Vector3f::Zero(), u_valid, 10, -1));
    // Entirely behind the camera, and a depth view whose size disagrees with its camera.
    EXPECT_FALSE(traceDepthMap(depth, Vector3f(0, 0, -1), Vector3f(0.1f, 0, -1), 1e30f, 0.05f));
    DepthView wrong = depth;
    wrong.camera = camera_.scaled(0.5);
    EXPECT_FALSE(traceDepthMap(wrong, Vector3f::Zero(), u_valid, 10, 0.05f));
    EXPECT_TRUE(depthToMesh(wrong).empty());
    wrong.camera = camera_;
    wrong.camera.fx = 0;  // an invalid model
    EXPECT_FALSE(traceDepthMap(wrong, Vector3f::Zero(), u_valid, 10, 0.05f));
    EXPECT_TRUE(depthToMesh(wrong).empty());
    EXPECT_TRUE(depthToMesh(DepthView{}).empty());
}

// ---- depthToMesh ----

TEST_P(DepthOcclusion, MeshReproducesThePlane) {
    const Plane plane = testPlane();
    const Image& image = planeDepth();
    const DepthView depth = view(image);
    const TriangleMesh mesh = depthToMesh(depth);
    ASSERT_FALSE(mesh.empty());
    ASSERT_EQ(mesh.normals.size(), mesh.positions.size());
    ASSERT_EQ(mesh.uvs.size(), mesh.positions.size());
    double angle_sum = 0;
    std::vector<double> angles;
    Vector3d normal_sum = Vector3d::Zero();
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
        const Vector3d p = mesh.positions[v].cast<double>();
        // z rounded to 1 mm moves the point along its ray by up to 0.5 mm of z.
        EXPECT_LE(std::abs(plane.signedDistance(p)),
                  0.5e-3 * std::abs(plane.normal.dot(p)) / p.z() + 1e-5);
        EXPECT_NEAR(mesh.normals[v].norm(), 1, 1e-5);
        const double angle =
            std::acos(std::clamp(mesh.normals[v].cast<double>().dot(plane.normal), -1.0, 1.0));
        angle_sum += angle;
        angles.push_back(angle);
        normal_sum += mesh.normals[v].cast<double>();
        // Each vertex sits on its pixel's ray: uv names the pixel.
        const Vector2d pixel(mesh.uvs[v].x() * camera_.width - 0.5,
                             mesh.uvs[v].y() * camera_.height - 0.5);
        EXPECT_LT((*camera_.project(p) - pixel).norm(), 2e-3);
    }
    // Normals are the plane's up to the 1 mm quantisation of z, which tilts a face 2 px wide
    // (8–25 mm here) by up to a few degrees; on average they are unbiased.
    std::sort(angles.begin(), angles.end());
    const double deg = 180 / M_PI;
    EXPECT_LT(std::acos(normal_sum.normalized().dot(plane.normal)) * deg, 0.2);
    EXPECT_LT(angle_sum / angles.size() * deg, 2.0);
    EXPECT_LT(angles[angles.size() * 99 / 100] * deg, 8.0);
    RecordProperty("mean_normal_error_deg", std::to_string(angle_sum / angles.size() * deg));
    for (const auto& t : mesh.triangles) {
        const Vector3d n = (mesh.positions[t[1]] - mesh.positions[t[0]])
                               .cross(mesh.positions[t[2]] - mesh.positions[t[0]])
                               .cast<double>();
        EXPECT_GT(n.dot(plane.normal), 0) << "triangles face the camera";
    }
    // Every 2x2 block of grid vertices within the 5 % depth step becomes two triangles (far
    // out at a fish-eye's rim the wall is seen so obliquely that neighbours differ by more).
    size_t cells = 0, any = 0;
    for (int y = 0; y + 2 < camera_.height; y += 2) {
        for (int x = 0; x + 2 < camera_.width; x += 2) {
            std::vector<float> z;
            for (const auto& [dx, dy] : {std::pair{0, 0}, {2, 0}, {0, 2}, {2, 2}}) {
                if (const auto zi = depth.zAt(x + dx, y + dy))
                    z.push_back(*zi);
            }
            any += z.size() >= 3;
            const auto [lo, hi] = std::minmax_element(z.begin(), z.end());
            cells += z.size() == 4 && *hi - *lo <= 0.05f * *lo;
        }
    }
    EXPECT_GE(mesh.triangles.size(), 2 * cells);
    EXPECT_LE(mesh.triangles.size(), 2 * any);
    EXPECT_GT(cells, any * 8 / 10);
}

TEST_P(DepthOcclusion, MeshDoesNotBridgeDepthDiscontinuities) {
    const Plane wall = testWall();
    const Box box = testBox();
    const Image& image = boxDepth();
    const TriangleMesh mesh = depthToMesh(view(image), {.step = 1});
    ASSERT_FALSE(mesh.empty());
    std::vector<int> on_box(mesh.positions.size());
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
        const Vector3d p = mesh.positions[v].cast<double>();
        const bool b = box.contains(p, 2e-3);
        const bool w = std::abs(wall.signedDistance(p)) < 2e-3;
        ASSERT_NE(b, w) << p.transpose();
        on_box[v] = b;
    }
    size_t box_triangles = 0;
    for (const auto& t : mesh.triangles) {
        EXPECT_EQ(on_box[t[0]], on_box[t[1]]);
        EXPECT_EQ(on_box[t[0]], on_box[t[2]]);
        box_triangles += on_box[t[0]];
    }
    EXPECT_GT(box_triangles, 1000u);
    EXPECT_GT(mesh.triangles.size() - box_triangles, 1000u);
}

INSTANTIATE_TEST_SUITE_P(Lenses, DepthOcclusion, ::testing::ValuesIn(testCameras()),
                         [](const auto& param_info) { return std::string(param_info.param.name); });

// ---- real Kinect frames ----

struct RealFrame {
    Image depth_mm;
    CameraModel camera;
};

// The first depth frame of a recording, in millimetres.
std::optional<RealFrame> readDepth(const std::filesystem::path& dir, const CameraModel& camera) {
    auto reader = replay::openRecording(dir);
    EXPECT_TRUE(reader) << reader.status().toString();
    if (!reader)
        return std::nullopt;
    const auto& streams = (*reader)->streams();
    for (;;) {
        auto frame = (*reader)->next();
        if (!frame) {
            ADD_FAILURE() << "no depth frame in " << dir << ": " << frame.status().toString();
            return std::nullopt;
        }
        const StreamInfo& info = streams.at(frame->meta().stream);
        if (info.format.format != PixelFormat::kDepth16)
            continue;
        const auto scale = replay::depthScalePerMetre(info);
        EXPECT_TRUE(scale);
        if (!scale)
            return std::nullopt;
        RealFrame out{
            Image(ImageDesc::packed(PixelFormat::kDepth16, info.format.width, info.format.height)),
            camera};
        const Status converted =
            replay::rescaleDepth(frame->image(), *scale, out.depth_mm.mutableView(), 1000);
        EXPECT_TRUE(converted) << converted.toString();
        if (!converted)
            return std::nullopt;
        return out;
    }
}

// A TUM folder around the single TUM frame (links to the shared files, not copies).
std::filesystem::path tumFolder(const std::filesystem::path& data) {
    const auto dir = test::tempDir() / "tum";
    std::filesystem::create_directories(dir / "rgb");
    std::filesystem::create_directories(dir / "depth");
    std::filesystem::create_symlink(data / "TUM_color.png", dir / "rgb" / "1.000000.png");
    std::filesystem::create_symlink(data / "TUM_depth.png", dir / "depth" / "1.000000.png");
    std::ofstream(dir / "rgb.txt") << "# color images\n1.000000 rgb/1.000000.png\n";
    std::ofstream(dir / "depth.txt") << "# depth maps\n1.000000 depth/1.000000.png\n";
    return dir;
}

CameraModel tumFr1() {
    CameraModel camera =
        CameraModel::pinhole(640, 480, 517.306408, 516.469215, 318.643040, 255.313989);
    camera.distortion = {0.262383, -0.953104, -0.005358, 0.002628, 1.163314};
    return camera;
}

void checkRealFrame(const RealFrame& frame) {
    const DepthView depth{frame.depth_mm.view(), frame.camera};
    const int w = frame.camera.width, h = frame.camera.height;
    size_t valid = 0, hidden = 0, visible = 0;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const auto z = depth.zAt(x, y);
            const auto distance = rayDistanceAt(depth, x, y);
            ASSERT_EQ(z.has_value(), distance.has_value()) << x << "," << y;
            if (!z)
                continue;
            ++valid;
            const Vector3d u = *frame.camera.unproject(Vector2d(x, y));
            ASSERT_NEAR(*distance, *z * u.norm() / u.z(), 2e-6 * *distance) << x << "," << y;
            // Virtual points 10 cm behind and in front of the real surface on this pixel's ray,
            // looked up the way a renderer does: project, take the pixel, compare distances.
            const Vector3d surface = u * (*z / u.z());
            for (const double offset : {0.1, -0.1}) {
                const Vector3d p = surface + offset * u;
                const Vector2d px = *frame.camera.project(p);
                const int qx = static_cast<int>(std::lround(px.x()));
                const int qy = static_cast<int>(std::lround(px.y()));
                ASSERT_EQ(qx, x);
                ASSERT_EQ(qy, y);
                // The renderer looks up rayDistanceAt(depth, qx, qy): `distance`, same pixel.
                const bool is_hidden = p.norm() > *distance;
                if (offset > 0) {
                    hidden += is_hidden;
                } else {
                    visible += !is_hidden;
                }
            }
        }
    }
    EXPECT_GT(valid, static_cast<size_t>(w * h / 2));
    EXPECT_EQ(hidden, valid);
    EXPECT_EQ(visible, valid);

    // Primary rays through the depth-map walk agree with the per-pixel distance.
    for (int y = 3; y < h; y += 13) {
        for (int x = 5; x < w; x += 11) {
            const auto distance = rayDistanceAt(depth, x, y);
            if (!distance)
                continue;
            const Vector3f u = frame.camera.unproject(Vector2d(x, y))->cast<float>();
            const auto t = traceDepthMap(depth, Vector3f::Zero(), u, 1e30f, 0.05f);
            ASSERT_TRUE(t) << x << "," << y;
            EXPECT_NEAR(*t, *distance, 1e-4 * *distance + 1e-5) << x << "," << y;
        }
    }

    // Secondary rays from a point 10 cm in front of the real surface at one pixel to a point
    // 10 cm behind it at another: the walk starts in front and ends behind, so with an
    // unlimited shell it must report a crossing on the way, at or before the far point.
    std::mt19937 rng(3);
    std::uniform_int_distribution<int> px(0, w - 1);
    std::uniform_int_distribution<int> py(0, h - 1);
    int pairs = 0;
    while (pairs < 2000) {
        const int ax = px(rng), ay = py(rng), bx = px(rng), by = py(rng);
        const auto za = depth.zAt(ax, ay);
        const auto zb = depth.zAt(bx, by);
        if (!za || !zb)
            continue;
        const Vector3d ua = *frame.camera.unproject(Vector2d(ax, ay));
        const Vector3d ub = *frame.camera.unproject(Vector2d(bx, by));
        const Vector3d from = ua * (*za / ua.z()) - 0.1 * ua;
        const Vector3d to = ub * (*zb / ub.z()) + 0.1 * ub;
        const auto t = traceDepthMap(depth, from.cast<float>(), (to - from).cast<float>(), 1, 1e9f);
        ASSERT_TRUE(t) << ax << "," << ay << " -> " << bx << "," << by;
        EXPECT_GT(*t, 0);
        EXPECT_LE(*t, 1.0f + 1e-6f);
        ++pairs;
    }

    const TriangleMesh mesh = depthToMesh(depth);
    ASSERT_EQ(mesh.uvs.size(), mesh.positions.size());
    for (size_t v = 0; v < mesh.positions.size(); ++v) {
        const Vector2d pixel(mesh.uvs[v].x() * w - 0.5, mesh.uvs[v].y() * h - 0.5);
        const Vector3d p = mesh.positions[v].cast<double>();
        ASSERT_LT((*frame.camera.project(p) - pixel).norm(), 2e-3) << v;
        ASSERT_NEAR(p.z(),
                    *depth.zAt(static_cast<int>(std::lround(pixel.x())),
                               static_cast<int>(std::lround(pixel.y()))),
                    1e-6 * p.z());
        ASSERT_NEAR(mesh.normals[v].norm(), 1, 1e-5);
    }
    // A smooth indoor scene: most valid 2x2 grid cells become two triangles, never more.
    size_t cells = 0, any = 0;
    for (int y = 0; y + 2 < h; y += 2) {
        for (int x = 0; x + 2 < w; x += 2) {
            const int n = depth.zAt(x, y).has_value() + depth.zAt(x + 2, y).has_value() +
                          depth.zAt(x, y + 2).has_value() + depth.zAt(x + 2, y + 2).has_value();
            cells += n == 4;
            any += n >= 3;
        }
    }
    EXPECT_GT(mesh.triangles.size(), 2 * cells * 8 / 10);
    EXPECT_LE(mesh.triangles.size(), 2 * any);
    ::testing::Test::RecordProperty("triangles", std::to_string(mesh.triangles.size()));
    ::testing::Test::RecordProperty("full_cells", std::to_string(cells));
}

TEST(DepthOcclusionReal, TumFrame) {
    const auto data = test::sharedDataDir() / "02_rgbd_single_frames_open3d";
    MIXRAY_REQUIRE_SHARED_DATA(data / "TUM_depth.png");
    const auto frame = readDepth(tumFolder(data), tumFr1());
    ASSERT_TRUE(frame);
    checkRealFrame(*frame);
}

TEST(DepthOcclusionReal, PclTiffFrame) {
    const auto dir = test::sharedDataDir() / "02_rgbd_pcl_openni_tiff";
    MIXRAY_REQUIRE_SHARED_DATA(dir);
    const auto frame = readDepth(dir, CameraModel::pinhole(640, 480, 525, 525, 320, 240));
    ASSERT_TRUE(frame);
    checkRealFrame(*frame);
}

}  // namespace
}  // namespace mixray::render
