// The simulator (render/src/simulator*.cpp) against ground truth computed here independently:
// an analytic ray caster for its planes, boxes and spheres, OpenCV's own marker and ChArUco
// detectors, and the closed-form shading of a Lambertian probe.
#include "mixray/render/simulator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stop_token>

#include "mixray/graph/mkv.h"
#include "mixray/graph/pose.h"
#include "mixray/render/renderer.h"
#include "mixray/render/scene_file.h"
#include "mixray/tracking/setup.h"
#include "test_data.h"

namespace mixray::render {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;
namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- an analytic ray caster over the simulator's shapes ----
struct AnalyticHit {
    double t = kInf;
    Vector3d n = Vector3d::Zero();
    int object = -1;
};

AnalyticHit castRay(const SceneDescription& scene, const Vector3d& o, const Vector3d& d) {
    AnalyticHit best;
    for (int i = 0; i < static_cast<int>(scene.objects.size()); ++i) {
        const SceneObject& obj = scene.objects[static_cast<size_t>(i)];
        const Isometry3d T_obj_world = obj.T_anchor_object.inverse();
        const Vector3d oo = T_obj_world * o;
        const Vector3d dd = T_obj_world.linear() * d;
        double t = kInf;
        Vector3d n_obj;
        if (obj.shape.type == ShapeType::kSphere) {
            const double r = obj.shape.radius;
            const double b = oo.dot(dd), c = oo.squaredNorm() - r * r;
            const double disc = b * b - c;
            if (disc >= 0) {
                const double s = std::sqrt(disc);
                t = -b - s > 1e-9 ? -b - s : (-b + s > 1e-9 ? -b + s : kInf);
                n_obj = (oo + t * dd) / r;
            }
        } else if (obj.shape.type == ShapeType::kPlane) {
            if (std::abs(dd.z()) > 1e-12) {
                const double s = -oo.z() / dd.z();
                const Vector3d p = oo + s * dd;
                if (s > 1e-9 && std::abs(p.x()) <= 0.5 * obj.shape.size.x() &&
                    std::abs(p.y()) <= 0.5 * obj.shape.size.y()) {
                    t = s;
                    n_obj = Vector3d::UnitZ();
                }
            }
        } else if (obj.shape.type == ShapeType::kBox) {
            const Vector3d h = 0.5 * obj.shape.size.cast<double>();
            double lo = -kInf, hi = kInf;
            int axis = -1;
            for (int k = 0; k < 3; ++k) {
                if (std::abs(dd[k]) < 1e-15) {
                    if (std::abs(oo[k]) > h[k])
                        lo = kInf;
                    continue;
                }
                double a = (-h[k] - oo[k]) / dd[k], b = (h[k] - oo[k]) / dd[k];
                if (a > b)
                    std::swap(a, b);
                if (a > lo) {
                    lo = a;
                    axis = k;
                }
                hi = std::min(hi, b);
            }
            if (lo <= hi && lo > 1e-9 && axis >= 0) {
                t = lo;
                n_obj = Vector3d::Zero();
                n_obj[axis] = dd[axis] > 0 ? -1 : 1;
            }
        }
        if (t < best.t) {
            best.t = t;
            best.n = (obj.T_anchor_object.linear() * n_obj).normalized();
            best.object = i;
        }
    }
    return best;
}

int objectIndex(const SceneDescription& scene, const std::string& name) {
    for (size_t i = 0; i < scene.objects.size(); ++i)
        if (scene.objects[i].name == name)
            return static_cast<int>(i);
    return -1;
}

double luminance(const Image& rgb, int x, int y) {
    const uint8_t* p = rgb.view().row<uint8_t>(y) + 3 * x;
    return 0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2];
}

float srgbEncode(float linear) {
    const float c = std::clamp(linear, 0.f, 1.f);
    return 255.f * (c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1 / 2.4f) - 0.055f);
}

cv::Mat grey(const Image& rgb) {
    const ImageDesc& d = rgb.desc();
    cv::Mat m(d.height, d.width, CV_8UC3, const_cast<uint8_t*>(rgb.view().data),
              static_cast<size_t>(d.stride_bytes));
    cv::Mat g;
    cv::cvtColor(m, g, cv::COLOR_RGB2GRAY);
    return g;
}

std::optional<Vector2d> projectWorld(const calibration::CameraModel& m,
                                     const Isometry3d& T_world_cam, const Vector3d& p_world) {
    return m.project(T_world_cam.inverse() * p_world);
}

// One tabletop frame at full size, shared by the tests that look at it.
struct TabletopFrame {
    std::unique_ptr<Simulator> sim;
    SimFrame frame;
};
const TabletopFrame& tabletop() {
    static TabletopFrame* shared = [] {
        auto* f = new TabletopFrame;
        // 320x240 keeps the sanitizer build's run short; the checks do not need more pixels.
        SimulatorOptions o;
        o.frames = 1;
        o.width = 320;
        o.height = 240;
        // Kept for the whole run (never destroyed): its assets go to the build tree, not /tmp.
        o.asset_dir = test::binaryDir() / "test-tmp" / "simulator_shared_tabletop";
        auto sim = Simulator::create(o);
        EXPECT_TRUE(sim) << sim.status().toString();
        if (sim) {
            auto frame = (*sim)->render(0);
            EXPECT_TRUE(frame) << frame.status().toString();
            if (frame)
                f->frame = std::move(frame).value();
            f->sim = std::move(sim).value();
        }
        return f;
    }();
    return *shared;
}

TEST(Simulator, OptionsAreValidated) {
    SimulatorOptions o;
    EXPECT_TRUE(o.validate());
    o.samples_per_pixel = 3;
    EXPECT_EQ(o.validate().code(), ErrorCode::kInvalidArgument);
    o = SimulatorOptions{};
    o.width = 8;
    EXPECT_FALSE(o.validate());
    o = SimulatorOptions{};
    o.frames = -1;
    EXPECT_FALSE(o.validate());
    EXPECT_FALSE(Simulator::create(o));
    EXPECT_EQ(simScenarioFromString("calibration"), SimScenario::kCalibration);
    EXPECT_FALSE(simScenarioFromString("kitchen"));
}

TEST(Simulator, IsDeterministicForASeedAndTheNoiseFollowsTheSeed) {
    SimulatorOptions o;
    o.width = 96;
    o.height = 72;
    o.frames = 2;
    o.env_map_width = 128;
    auto a = Simulator::create(o);
    o.threads = 1;  // a different split of the work must not change a pixel
    auto b = Simulator::create(o);
    o.seed = 2;
    auto c = Simulator::create(o);
    ASSERT_TRUE(a && b && c);
    for (int i = 0; i < 2; ++i) {
        auto fa = (*a)->render(i), fb = (*b)->render(i), fc = (*c)->render(i);
        ASSERT_TRUE(fa && fb && fc);
        EXPECT_TRUE(sameImage(fa->color.view(), fb->color.view())) << i;
        EXPECT_TRUE(sameImage(fa->depth.view(), fb->depth.view())) << i;
        EXPECT_EQ(fa->env.bytes().empty(), i != 0);
        if (i == 0) {
            EXPECT_TRUE(sameImage(fa->env.view(), fb->env.view()));
        }
        EXPECT_FALSE(sameImage(fa->depth.view(), fc->depth.view())) << "seed changes the noise";
    }
    // Frames are a function of their index: rendering out of order changes nothing.
    auto again = (*a)->render(0);
    auto first = (*b)->render(0);
    ASSERT_TRUE(again && first);
    EXPECT_TRUE(sameImage(again->color.view(), first->color.view()));
    EXPECT_FALSE((*a)->render(2));
}

TEST(Simulator, CamerasMovesAndTruthIsConsistent) {
    const SimTruth& t = tabletop().sim->truth();
    EXPECT_EQ(t.color.width, 320);
    EXPECT_EQ(t.env.lens, calibration::LensModel::kFisheye);
    EXPECT_TRUE(t.color.validate());
    EXPECT_TRUE(t.ir.validate());
    EXPECT_TRUE(t.env.validate());
    // The fish-eye sees at least a hemisphere: straight up and 90° off axis project inside.
    for (const Vector3d& d : {Vector3d(0, 0, 1), Vector3d(1, 0, 0.001), Vector3d(0, -1, 0.001)}) {
        auto px = t.env.project(d);
        ASSERT_TRUE(px);
        EXPECT_TRUE(px->x() >= 0 && px->x() <= t.env.width - 1 && px->y() >= 0 &&
                    px->y() <= t.env.height - 1);
    }
    // It looks up: its optical axis is within a few degrees of world +z.
    EXPECT_GT((t.T_world_env.linear() * Vector3d::UnitZ()).z(), std::cos(3 * M_PI / 180));
    // The key and fill lights are directional with unit-free directions in the world.
    ASSERT_EQ(t.lights.size(), 2u);
    for (const Light& l : t.lights)
        EXPECT_EQ(l.type, LightType::kDirectional);
    // The camera moves: every frame's pose differs from the previous one, smoothly.
    SimulatorOptions o;
    o.width = 64;
    o.height = 48;
    auto sim = Simulator::create(o);
    ASSERT_TRUE(sim);
    const auto& frames = (*sim)->truth().frames;
    ASSERT_EQ(frames.size(), 45u);
    for (size_t i = 1; i < frames.size(); ++i) {
        const double step =
            (frames[i].T_world_color.translation() - frames[i - 1].T_world_color.translation())
                .norm();
        EXPECT_GT(step, 1e-4) << i;
        EXPECT_LT(step, 0.02) << i;
        // The marker stays in view.
        auto px = projectWorld((*sim)->truth().color, frames[i].T_world_color, Vector3d::Zero());
        ASSERT_TRUE(px);
        EXPECT_TRUE(px->x() > 5 && px->x() < 59 && px->y() > 5 && px->y() < 43) << i;
    }
}

TEST(Simulator, MarkerCellsAndCornersLandWhereTheTrueCameraProjectsThem) {
    const TabletopFrame& f = tabletop();
    const SimTruth& t = f.sim->truth();
    const Isometry3d& T = t.frames[0].T_world_color;
    // Dark and light cells at the projected cell centres, as the dictionary says.
    cv::Mat bits =
        cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250)
            ->getBitsFromByteList(cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250)
                                      ->bytesList.rowRange(t.marker_id, t.marker_id + 1),
                                  6);
    const double cell = t.marker_size_m / 8;
    int checked = 0;
    for (int row = 0; row < 8; ++row)
        for (int col = 0; col < 8; ++col) {
            const bool border = row == 0 || col == 0 || row == 7 || col == 7;
            const bool white = !border && bits.at<uint8_t>(row - 1, col - 1) != 0;
            // Marker frame: +x right, +y up the image, so row r sits at y = h - (r + 0.5)·cell.
            const Vector3d p_marker(-0.5 * t.marker_size_m + (col + 0.5) * cell,
                                    0.5 * t.marker_size_m - (row + 0.5) * cell, 0);
            auto px = projectWorld(t.color, T, t.T_world_marker * p_marker);
            ASSERT_TRUE(px);
            const double v = luminance(f.frame.color, static_cast<int>(std::lround(px->x())),
                                       static_cast<int>(std::lround(px->y())));
            if (white)
                EXPECT_GT(v, 150) << "cell " << row << "," << col;
            else
                EXPECT_LT(v, 60) << "cell " << row << "," << col;
            ++checked;
        }
    EXPECT_EQ(checked, 64);

    // The black square's edges lie where the truth projects them: along the edge, the linear
    // luminance crosses halfway from the black border to the white quiet zone at the projected
    // edge, to a fraction of a pixel.
    const auto linear = [&](double x, double y) {
        const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
        const double ax = x - x0, ay = y - y0;
        const auto at = [&](int xx, int yy) {
            const double v = luminance(f.frame.color, xx, yy) / 255.0;
            return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
        };
        return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x0 + 1, y0)) +
               ay * ((1 - ax) * at(x0, y0 + 1) + ax * at(x0 + 1, y0 + 1));
    };
    const double half = 0.5 * t.marker_size_m;
    int edges = 0;
    for (int side = 0; side < 4; ++side)
        for (double along : {-0.25, 0.0, 0.25}) {
            const Vector3d normal = side == 0   ? Vector3d(1, 0, 0)
                                    : side == 1 ? Vector3d(-1, 0, 0)
                                    : side == 2 ? Vector3d(0, 1, 0)
                                                : Vector3d(0, -1, 0);
            const Vector3d tangent(-normal.y(), normal.x(), 0);
            const Vector3d edge = half * normal + along * t.marker_size_m * tangent;
            auto p = projectWorld(t.color, T, t.T_world_marker * edge);
            auto q = projectWorld(t.color, T, t.T_world_marker * (edge + 0.5 * cell * normal));
            ASSERT_TRUE(p && q);
            const Vector2d u = (*q - *p).normalized();
            const double inside = linear(p->x() - 2 * u.x(), p->y() - 2 * u.y());
            const double outside = linear(p->x() + 2 * u.x(), p->y() + 2 * u.y());
            ASSERT_GT(outside, inside + 0.3) << "side " << side;
            const double level = 0.5 * (inside + outside);
            double crossing = NAN;
            for (double s = -2; s < 2; s += 0.01) {
                const double a = linear(p->x() + s * u.x(), p->y() + s * u.y());
                const double b = linear(p->x() + (s + 0.01) * u.x(), p->y() + (s + 0.01) * u.y());
                if (a <= level && b > level) {
                    crossing = s + 0.01 * (level - a) / (b - a);
                    break;
                }
            }
            EXPECT_NEAR(crossing, 0, 0.25) << "side " << side << " at " << along;
            ++edges;
        }
    EXPECT_EQ(edges, 12);

    // OpenCV's detector finds and decodes the marker (its corner refinement is coarse on a
    // marker this small, so only roughly where the truth projects the corners).
    auto parameters = cv::aruco::DetectorParameters::create();
    parameters->cornerRefinementMethod = cv::aruco::CORNER_REFINE_SUBPIX;
    std::vector<int> ids;
    std::vector<std::vector<cv::Point2f>> corners;
    cv::aruco::detectMarkers(grey(f.frame.color),
                             cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250), corners,
                             ids, parameters);
    const auto it = std::find(ids.begin(), ids.end(), t.marker_id);
    ASSERT_NE(it, ids.end()) << "marker " << t.marker_id << " not detected";
    const auto& found = corners[static_cast<size_t>(it - ids.begin())];
    const auto truth = t.markerCornersWorld();
    for (int k = 0; k < 4; ++k) {
        auto px = projectWorld(t.color, T, truth[static_cast<size_t>(k)]);
        ASSERT_TRUE(px);
        EXPECT_NEAR(found[static_cast<size_t>(k)].x, px->x(), 2.0) << "corner " << k;
        EXPECT_NEAR(found[static_cast<size_t>(k)].y, px->y(), 2.0) << "corner " << k;
    }
}

// Checks a simulated depth image against the analytic scene seen by the camera it is aligned
// with: the colour camera (registered) or the IR camera (raw).
void expectDepthMatchesGeometry(const SimTruth& t, const Image& depth_image, bool registered) {
    const Isometry3d& T_world_color = t.frames[0].T_world_color;
    const Isometry3d T_world_ir = T_world_color * t.T_color_ir;
    const calibration::CameraModel& cam = registered ? t.color : t.ir;
    const Isometry3d& T_world_cam = registered ? T_world_color : T_world_ir;
    const Vector3d eye = T_world_cam.translation();
    const Vector3d projector = T_world_ir * Vector3d(t.depth_model.baseline_m, 0, 0);
    const int w = cam.width, h = cam.height;
    std::vector<double> z_true(static_cast<size_t>(w) * h, NAN);
    std::vector<Vector3d> points(z_true.size());
    std::vector<Vector3d> normals(z_true.size());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            auto d_cam = cam.unproject(Vector2d(x, y));
            if (!d_cam)
                continue;
            const Vector3d d = T_world_cam.linear() * *d_cam;
            const AnalyticHit hit = castRay(t.scene, eye, d);
            if (hit.object < 0)
                continue;
            const size_t i = static_cast<size_t>(y) * w + x;
            z_true[i] = hit.t * d_cam->z();
            points[i] = eye + hit.t * d;
            normals[i] = hit.n;
        }
    int valid = 0, within = 0, shadow_violations = 0, edge_violations = 0, shadowed = 0,
        grazing_violations = 0;
    double sum_error = 0;
    const ImageView depth = depth_image.view();
    ASSERT_EQ(depth.desc.width, w);
    ASSERT_EQ(depth.desc.format, PixelFormat::kDepth16);
    for (int y = 1; y < h - 1; ++y)
        for (int x = 1; x < w - 1; ++x) {
            const size_t i = static_cast<size_t>(y) * w + x;
            const uint16_t mm = depth.row<uint16_t>(y)[x];
            const double z = z_true[i];
            // Where the analytic depth jumps, the sensor must return no depth.
            bool jump = std::isnan(z);
            for (int dy = -1; dy <= 1 && !jump; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const double zn = z_true[static_cast<size_t>(y + dy) * w + x + dx];
                    if (!(std::abs(zn - z) <= 0.05 * z))
                        jump = true;
                }
            if (jump && mm != 0)
                ++edge_violations;
            if (std::isnan(z))
                continue;
            // A point the projector cannot light is a hole.
            const Vector3d p = points[i];
            const Vector3d to_projector = projector - p;
            const Vector3d n = normals[i].dot(to_projector) > 0 ? normals[i] : -normals[i];
            const AnalyticHit blocker = castRay(t.scene, p + 1e-4 * n, to_projector.normalized());
            if (blocker.t < to_projector.norm() - 1e-3) {
                ++shadowed;
                if (mm != 0)
                    ++shadow_violations;
            }
            // Surfaces seen at a grazing angle from the IR camera return no pattern.
            const Vector3d to_ir = (T_world_ir.translation() - p).normalized();
            if (std::abs(normals[i].dot(to_ir)) < std::cos(79 * M_PI / 180) && mm != 0)
                ++grazing_violations;
            if (mm == 0)
                continue;
            ++valid;
            const double error = mm / 1000.0 - z;
            sum_error += error;
            const double bound =
                t.depth_model.depthStep(z) + 5 * t.depth_model.depthSigma(z) + 0.0015;
            if (std::abs(error) <= bound)
                ++within;
        }
    EXPECT_EQ(edge_violations, 0);
    EXPECT_EQ(shadow_violations, 0);
    EXPECT_EQ(grazing_violations, 0);
    EXPECT_GT(shadowed, 50) << "the boxes and probes cast projector shadows";
    EXPECT_GT(valid, w * h / 2);
    EXPECT_GE(within, valid - valid / 1000) << "of " << valid;
    EXPECT_LT(std::abs(sum_error / valid), 0.001) << "depth is unbiased";
    if (!registered)
        return;
    // The IR camera's narrower view leaves the registered image's left and right edges empty.
    for (int y = 0; y < h; ++y)
        for (int x : {0, 1, 2, w - 3, w - 2, w - 1})
            EXPECT_EQ(depth.row<uint16_t>(y)[x], 0) << x << "," << y;
}

TEST(Simulator, DepthMatchesTheTrueGeometryWithinTheNoiseModel) {
    const TabletopFrame& f = tabletop();
    expectDepthMatchesGeometry(f.sim->truth(), f.frame.depth, true);
}

TEST(Simulator, RawDepthIsAlignedWithTheIrCamera) {
    SimulatorOptions o;
    o.frames = 1;
    o.width = 320;
    o.height = 240;
    o.samples_per_pixel = 1;
    o.register_depth = false;
    o.asset_dir = test::binaryDir() / "test-tmp" / "simulator_raw_depth";
    auto sim = Simulator::create(o);
    ASSERT_TRUE(sim) << sim.status().toString();
    ASSERT_FALSE((*sim)->truth().depth_registered);
    auto frame = (*sim)->render(0);
    ASSERT_TRUE(frame) << frame.status().toString();
    expectDepthMatchesGeometry((*sim)->truth(), frame->depth, false);
}

TEST(Simulator, ProbesShowTheLightsWhereTheGeometrySays) {
    const TabletopFrame& f = tabletop();
    const SimTruth& t = f.sim->truth();
    const Isometry3d& T = t.frames[0].T_world_color;
    const Vector3d eye = T.translation();
    int mirrored = 0, shaded = 0;
    for (const SimProbe& probe : t.probes) {
        if (probe.material == MaterialType::kMirror) {
            // The highlight of each light: the sphere point whose normal bisects the view
            // direction and the light.
            for (const Light& light : t.lights) {
                const Vector3d l = -light.direction.normalized();
                Vector3d n = ((eye - probe.centre_world).normalized() + l).normalized();
                for (int k = 0; k < 50; ++k) {
                    const Vector3d p = probe.centre_world + probe.radius_m * n;
                    n = ((eye - p).normalized() + l).normalized();
                }
                const Vector3d p = probe.centre_world + probe.radius_m * n;
                if (n.dot((eye - p).normalized()) < 0.3)
                    continue;  // too close to the limb to check at this size
                auto px = projectWorld(t.color, T, p);
                ASSERT_TRUE(px);
                const int x = static_cast<int>(std::lround(px->x()));
                const int y = static_cast<int>(std::lround(px->y()));
                EXPECT_GT(luminance(f.frame.color, x, y), 245) << light.name;
                // The point facing the camera mirrors the dimmer room behind it.
                const Vector3d facing = (eye - probe.centre_world).normalized();
                if (facing.dot(n) < std::cos(15 * M_PI / 180)) {
                    auto off =
                        projectWorld(t.color, T, probe.centre_world + probe.radius_m * facing);
                    ASSERT_TRUE(off);
                    EXPECT_LT(luminance(f.frame.color, static_cast<int>(std::lround(off->x())),
                                        static_cast<int>(std::lround(off->y()))),
                              200)
                        << light.name;
                }
                ++mirrored;
            }
        } else {
            // Lambert under the two directional lights, shadows from the analytic scene.
            const Material& m = t.scene.materials.at("matte");
            const Vector3d view = (eye - probe.centre_world).normalized();
            for (int k = 0; k < 40; ++k) {
                const double a = 2 * M_PI * k / 40.0, r = 0.6 * std::sqrt((k % 10 + 0.5) / 10.0);
                const Vector3d u = view.unitOrthogonal(), v = view.cross(u);
                const Vector3d aim =
                    (std::sqrt(1 - r * r) * view + r * std::cos(a) * u + r * std::sin(a) * v)
                        .normalized();
                // The pixel that point falls in, and the surface point its centre sees.
                auto px = projectWorld(t.color, T, probe.centre_world + probe.radius_m * aim);
                ASSERT_TRUE(px);
                const int x = static_cast<int>(std::lround(px->x()));
                const int y = static_cast<int>(std::lround(px->y()));
                auto ray = t.color.unproject(Vector2d(x, y));
                ASSERT_TRUE(ray);
                const Vector3d d = T.linear() * *ray;
                const AnalyticHit hit = castRay(t.scene, eye, d);
                if (hit.object != objectIndex(t.scene, probe.name))
                    continue;  // hidden from the camera
                const Vector3d p = eye + hit.t * d;
                const Vector3d n = hit.n;
                Eigen::Vector3f radiance = Eigen::Vector3f::Zero();
                for (const Light& light : t.lights) {
                    const Vector3d l = -light.direction.normalized();
                    const double c = n.dot(l);
                    if (c <= 0 || castRay(t.scene, p + 1e-5 * n, l).object >= 0)
                        continue;
                    radiance +=
                        (m.albedo / static_cast<float>(M_PI)).cwiseProduct(light.intensity) *
                        static_cast<float>(c);
                }
                const uint8_t* pixel = f.frame.color.view().row<uint8_t>(y) + 3 * x;
                for (int ch = 0; ch < 3; ++ch)
                    EXPECT_NEAR(pixel[ch], srgbEncode(radiance[ch]), 4)
                        << "normal " << n.transpose() << " channel " << ch;
                ++shaded;
            }
        }
    }
    EXPECT_GE(mirrored, 1);
    EXPECT_GE(shaded, 30);
}

// ChArUco corners as OpenCV finds them in `image` (grey), by id.
std::map<int, cv::Point2f> charucoCorners(const cv::Mat& image, const SimBoard& b) {
    auto dict = cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250);
    auto board =
        cv::aruco::CharucoBoard::create(b.squares_x, b.squares_y, static_cast<float>(b.square_m),
                                        static_cast<float>(b.marker_m), dict);
    std::vector<int> ids;
    std::vector<std::vector<cv::Point2f>> corners;
    cv::aruco::detectMarkers(image, dict, corners, ids);
    std::map<int, cv::Point2f> out;
    if (ids.empty())
        return out;
    std::vector<cv::Point2f> charuco;
    std::vector<int> charuco_ids;
    cv::aruco::interpolateCornersCharuco(corners, ids, image, board, charuco, charuco_ids);
    for (size_t i = 0; i < charuco_ids.size(); ++i)
        out[charuco_ids[i]] = charuco[i];
    return out;
}

// Median distance between detected corners and the truth's projections; counts the corners.
double medianCornerError(const std::map<int, cv::Point2f>& found, const SimTruth& t,
                         const calibration::CameraModel& model, const Isometry3d& T_world_cam,
                         const Isometry3d& T_world_board, int* count) {
    const auto corners = t.boardCorners();
    std::vector<double> errors;
    for (const auto& [id, p] : found) {
        auto px =
            projectWorld(model, T_world_cam, T_world_board * corners[static_cast<size_t>(id)]);
        // OpenCV 4.6's ChArUco refinement reports corners with the pixel's top-left corner
        // at 0 (it adds 0.5 after cornerSubPix); mixray's pixel (0,0) is a pixel centre.
        if (px)
            errors.push_back(std::hypot(p.x - 0.5 - px->x(), p.y - 0.5 - px->y()));
    }
    *count = static_cast<int>(errors.size());
    if (errors.empty())
        return kInf;
    std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
    return errors[errors.size() / 2];
}

cv::Mat irToGrey(const Image& ir) {
    const ImageDesc& d = ir.desc();
    cv::Mat m(d.height, d.width, CV_16U, const_cast<uint8_t*>(ir.view().data),
              static_cast<size_t>(d.stride_bytes));
    cv::Mat g;
    m.convertTo(g, CV_8U, 255.0 / 1023.0);
    return g;
}

TEST(Simulator, CalibrationBoardCornersLandWhereTheTruthProjectsThem) {
    SimulatorOptions o;
    o.scenario = SimScenario::kCalibration;
    o.frames = 3;  // view 2 is held over the fish-eye
    // One sample per pixel keeps the sanitizer build's run short; corners stay sub-pixel.
    o.samples_per_pixel = 1;
    auto sim = Simulator::create(o);
    ASSERT_TRUE(sim) << sim.status().toString();
    const SimTruth& t = (*sim)->truth();
    ASSERT_TRUE(t.board);
    EXPECT_EQ(t.boardCorners().size(), 24u);
    {
        const int view = 2;  // held over the fish-eye: seen by all three cameras
        const SimFrameTruth& f = t.frames[static_cast<size_t>(view)];
        ASSERT_TRUE(f.T_world_board);
        auto frame = (*sim)->render(view);
        ASSERT_TRUE(frame) << frame.status().toString();
        ASSERT_EQ(frame->ir.desc().format, PixelFormat::kIR16);
        ASSERT_FALSE(frame->env.bytes().empty());
        int count = 0;
        EXPECT_EQ(f.board_in_color, 1.0) << view;
        const double color = medianCornerError(charucoCorners(grey(frame->color), *t.board), t,
                                               t.color, f.T_world_color, *f.T_world_board, &count);
        EXPECT_GE(count, 16) << "view " << view;
        // Seen at about 50° from its normal (the Kinect also sees the marker): OpenCV's corner
        // refinement reads 0.28 px there at one sample per pixel.
        EXPECT_LT(color, 0.35) << "view " << view;
        const double ir =
            medianCornerError(charucoCorners(irToGrey(frame->ir), *t.board), t, t.ir,
                              f.T_world_color * t.T_color_ir, *f.T_world_board, &count);
        EXPECT_GE(count, 16) << "view " << view;
        EXPECT_LT(ir, 0.25) << "view " << view;
        if (view == 2) {
            EXPECT_EQ(f.board_in_env, 1.0);
            const double env = medianCornerError(charucoCorners(grey(frame->env), *t.board), t,
                                                 t.env, t.T_world_env, *f.T_world_board, &count);
            EXPECT_GE(count, 6) << "fish-eye";
            EXPECT_LT(env, 0.35) << "fish-eye";
        }
    }
}

// A stop requested while the session renders (here from the progress callback after two
// frames; a signal does it through mixray simulate) ends it with a closed recording of the
// frames done, and a summary that says so.
TEST(Simulator, AStoppedSessionKeepsAClosedRecordingOfTheFramesDone) {
    const fs::path dir = test::tempDir();
    std::stop_source stop;
    SimulatorOptions o;
    o.width = 160;
    o.height = 120;
    o.frames = 5;
    o.stop = stop.get_token();
    auto summary = simulateSession(o, dir / "clip.mkv", [&](int done, int) {
        if (done == 2)
            stop.request_stop();
    });
    ASSERT_TRUE(summary) << summary.status().toString();
    EXPECT_TRUE(summary->stopped);
    EXPECT_EQ(summary->frames, 2);
    EXPECT_EQ(summary->frames_planned, 5);
    auto reader = openMkv(dir / "clip.mkv");
    ASSERT_TRUE(reader) << reader.status().toString();
    int colour = 0;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            // Not kCorruptData: the file was finished, not cut.
            EXPECT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        colour += (*reader)->streams()[frame->meta().stream].name == "kinect/color";
    }
    EXPECT_EQ(colour, 2);

    // Stopped before it starts: no frame rendered.
    std::stop_source early;
    early.request_stop();
    o.stop = early.get_token();
    auto none = simulateSession(o, dir / "none.mkv");
    ASSERT_TRUE(none) << none.status().toString();
    EXPECT_TRUE(none->stopped);
    EXPECT_EQ(none->frames, 0);
}

TEST(Simulator, SessionIsAnOrdinaryRecordingWithTruthBesideIt) {
    const fs::path dir = test::tempDir();
    SimulatorOptions o;
    o.width = 160;
    o.height = 120;
    o.frames = 3;
    o.env_every = 2;
    int progress_calls = 0;
    auto summary = simulateSession(o, dir / "clip.mkv", [&](int done, int total) {
        ++progress_calls;
        EXPECT_EQ(total, 3);
        EXPECT_EQ(done, progress_calls);
    });
    ASSERT_TRUE(summary) << summary.status().toString();
    EXPECT_EQ(summary->frames, 3);
    EXPECT_EQ(summary->env_frames, 2);
    EXPECT_EQ(progress_calls, 3);
    for (const char* name : {"clip.mkv", "clip.truth.yaml", "clip.tum", "clip.scene.yaml",
                             "clip.tracking.yaml", "clip.env.exr", "clip.marker.png"})
        EXPECT_TRUE(fs::exists(dir / name)) << name;

    // The same simulation in memory: what the file must hold.
    auto sim = Simulator::create(o);
    ASSERT_TRUE(sim);
    const SimTruth& t = (*sim)->truth();

    auto reader = openMkv(dir / "clip.mkv");
    ASSERT_TRUE(reader) << reader.status().toString();
    const auto& streams = (*reader)->streams();
    ASSERT_EQ(streams.size(), 4u);
    EXPECT_EQ(streams[0].name, "kinect/color");
    EXPECT_EQ(streams[0].format, ImageDesc::packed(PixelFormat::kRGB8, 160, 120));
    EXPECT_EQ(streams[1].name, "kinect/depth");
    EXPECT_EQ(streams[1].format.format, PixelFormat::kDepth16);
    EXPECT_EQ(streams[1].tags.at("registered_to"), "kinect/color");
    EXPECT_EQ(streams[2].name, "env/color");
    EXPECT_EQ(streams[2].format, ImageDesc::packed(PixelFormat::kRGB8, 120, 120));
    EXPECT_EQ(streams[3].name, "truth/pose");
    EXPECT_EQ(streams[3].kind, StreamKind::kPose);
    EXPECT_EQ(streams[3].tags.at("ground_truth"), "true");
    EXPECT_EQ(streams[3].tags.at("pose_of"), "kinect/color");
    ASSERT_FALSE((*reader)->attachments().empty());
    EXPECT_EQ((*reader)->attachments()[0].name, "truth.yaml");

    std::map<std::string, int> counts;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame) {
            EXPECT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        const StreamInfo& info = streams[frame->meta().stream];
        ++counts[info.name];
        const auto i = static_cast<size_t>(frame->meta().sequence);
        if (info.name == "truth/pose") {
            auto record = decodePoseRecord(frame->image());
            ASSERT_TRUE(record) << record.status().toString();
            EXPECT_EQ(record->frame_sequence, i);
            EXPECT_EQ(record->frame_device_stamp_ns, t.frames[i].stamp_ns);
            EXPECT_TRUE(record->transform().isApprox(t.frames[i].T_world_color, 1e-12));
            EXPECT_EQ(frame->meta().device_stamp_ns, t.frames[i].stamp_ns);
        } else if (info.name == "kinect/color" || info.name == "kinect/depth") {
            auto expected = (*sim)->render(static_cast<int>(i));
            ASSERT_TRUE(expected);
            const Image& image = info.name == "kinect/color" ? expected->color : expected->depth;
            EXPECT_TRUE(sameImage(frame->image(), image.view())) << info.name << " " << i;
            EXPECT_EQ(frame->meta().device_stamp_ns, t.frames[i].stamp_ns);
        }
    }
    EXPECT_EQ(counts["kinect/color"], 3);
    EXPECT_EQ(counts["kinect/depth"], 3);
    EXPECT_EQ(counts["env/color"], 2);
    EXPECT_EQ(counts["truth/pose"], 3);

    // The TUM trajectory reads back to the truth (9 decimals).
    std::ifstream tum(dir / "clip.tum");
    std::string line;
    size_t row = 0;
    while (std::getline(tum, line)) {
        if (line.empty() || line[0] == '#')
            continue;
        std::istringstream in(line);
        double stamp, x, y, z, qx, qy, qz, qw;
        ASSERT_TRUE(in >> stamp >> x >> y >> z >> qx >> qy >> qz >> qw) << line;
        ASSERT_LT(row, t.frames.size());
        const Isometry3d& T = t.frames[row].T_world_color;
        EXPECT_NEAR(stamp, t.frames[row].stamp_ns * 1e-9, 1e-9);
        EXPECT_NEAR((T.translation() - Vector3d(x, y, z)).norm(), 0, 2e-9);
        const Eigen::Quaterniond q(qw, qx, qy, qz);
        EXPECT_NEAR(Eigen::Quaterniond(T.linear()).angularDistance(q), 0, 1e-8);
        ++row;
    }
    EXPECT_EQ(row, 3u);

    // The real scene file parses and renders (its environment map and texture load).
    auto scene = loadScene(dir / "clip.scene.yaml");
    ASSERT_TRUE(scene) << scene.status().toString();
    EXPECT_EQ(scene->objects.size(), t.scene.objects.size());
    for (const SceneObject& obj : scene->objects)
        EXPECT_EQ(obj.role, ObjectRole::kGhost) << obj.name;
    EXPECT_TRUE(Renderer::create(*scene, RenderOptions{})) << "scene assets load";

    // The truth file names every camera, the marker, the probes and the lights.
    std::ifstream truth_file(dir / "clip.truth.yaml");
    const std::string truth((std::istreambuf_iterator<char>(truth_file)),
                            std::istreambuf_iterator<char>());
    for (const char* key :
         {"kinect/color:", "kinect/ir:", "env/color:", "T_color_ir:", "T_world_env:",
          "depth_model:", "Khoshelham", "marker:", "id: 23", "probe_mirror", "probe_diffuse",
          "to_light_world", "environment:", "trajectory:", "frames:"})
        EXPECT_NE(truth.find(key), std::string::npos) << key;

    // The truth file records the options that render the session again.
    auto again = readSimulationOptions(truth, "clip.truth.yaml");
    ASSERT_TRUE(again) << again.status().toString();
    EXPECT_EQ(again->scenario, o.scenario);
    EXPECT_EQ(again->frames, 3);
    EXPECT_EQ(again->seed, o.seed);
    EXPECT_EQ(again->width, 160);
    EXPECT_EQ(again->height, 120);
    EXPECT_EQ(again->samples_per_pixel, o.samples_per_pixel);
    EXPECT_EQ(again->env_every, 2);
    EXPECT_EQ(again->env_map_width, o.env_map_width);
    EXPECT_FALSE(readSimulationOptions("version: 1\n", "x.yaml"));
    EXPECT_FALSE(readSimulationOptions("simulation: {scenario: moon}\n", "x.yaml"));

    // The tracking setup a user of this rig would write: the true camera, marker, probes and
    // environment camera.
    auto setup = tracking::loadTrackingSetup(dir / "clip.tracking.yaml");
    ASSERT_TRUE(setup) << setup.status().toString();
    EXPECT_EQ(setup->camera.stream, "kinect/color");
    EXPECT_EQ(setup->camera.model.fx, t.color.fx);
    ASSERT_EQ(setup->targets.size(), 1u);
    EXPECT_EQ(setup->targets[0].id, t.marker_id);
    EXPECT_EQ(setup->targets[0].size_m, t.marker_size_m);
    ASSERT_EQ(setup->probes.size(), t.probes.size());
    EXPECT_EQ(setup->probes[0].centre_world, t.probes[0].centre_world);
    ASSERT_TRUE(setup->environment);
    EXPECT_TRUE(setup->environment->camera.T_world_env.isApprox(t.T_world_env, 1e-15));
    const auto& attachments = (*reader)->attachments();
    EXPECT_TRUE(std::any_of(attachments.begin(), attachments.end(),
                            [](const Attachment& a) { return a.name == "tracking.yaml"; }));

    // A file that is not .mkv is refused before anything is written.
    EXPECT_EQ(simulateSession(o, dir / "clip.avi").status().code(), ErrorCode::kInvalidArgument);
}

// Objects inserted into the scenario render as real ones (the ground truth of a composite):
// they change the image where they stand, and nowhere far from them.
TEST(Simulator, InsertedObjectsAreRenderedAsReal) {
    SimulatorOptions o;
    o.frames = 1;
    o.width = 160;
    o.height = 120;
    o.samples_per_pixel = 1;
    auto plain = Simulator::create(o);
    ASSERT_TRUE(plain);
    SceneObject ball;
    ball.name = "inserted_ball";
    ball.shape.type = ShapeType::kSphere;
    ball.shape.radius = 0.03f;
    ball.material = "inserted_red";
    ball.T_anchor_object.translation() = Vector3d(0, 0.12, 0.03);
    Material red;
    red.name = "inserted_red";
    red.albedo = Rgb(0.9f, 0.05f, 0.05f);
    o.inserted.objects.push_back(ball);
    o.inserted.materials["inserted_red"] = red;
    auto with = Simulator::create(o);
    ASSERT_TRUE(with) << with.status().toString();
    auto a = (*plain)->renderColor(0);
    auto b = (*with)->renderColor(0);
    ASSERT_TRUE(a && b);
    const SimTruth& t = (*with)->truth();
    const auto centre = projectWorld(t.color, t.frames[0].T_world_color, Vector3d(0, 0.12, 0.03));
    ASSERT_TRUE(centre);
    int changed_near = 0, changed_far = 0;
    for (int y = 0; y < o.height; ++y) {
        for (int x = 0; x < o.width; ++x) {
            const uint8_t* pa = a->view().row<uint8_t>(y) + 3 * x;
            const uint8_t* pb = b->view().row<uint8_t>(y) + 3 * x;
            if (std::abs(pa[0] - pb[0]) + std::abs(pa[1] - pb[1]) + std::abs(pa[2] - pb[2]) < 6)
                continue;
            // Within the ball's disc and its shadow, cast away from the key light.
            ((Vector2d(x, y) - *centre).norm() < 40 ? changed_near : changed_far)++;
        }
    }
    EXPECT_GT(changed_near, 50);
    EXPECT_EQ(changed_far, 0);
    // renderColor is render()'s colour image.
    auto full = (*with)->render(0);
    ASSERT_TRUE(full);
    EXPECT_TRUE(sameImage(full->color.view(), b->view()));

    // Names that clash with the scenario's, and lights, are refused.
    SimulatorOptions clash = o;
    clash.inserted.objects[0].name = "table";
    EXPECT_EQ(Simulator::create(clash).status().code(), ErrorCode::kInvalidArgument);
    clash = o;
    clash.inserted.materials["table"] = red;
    EXPECT_EQ(Simulator::create(clash).status().code(), ErrorCode::kInvalidArgument);
    clash = o;
    clash.inserted.lights.push_back(Light{});
    EXPECT_EQ(Simulator::create(clash).status().code(), ErrorCode::kInvalidArgument);
}

TEST(Simulator, CommittedTabletopSessionIsWhatTheSimulatorMakes) {
    // The committed session's ground-truth poses are exactly those of a fresh simulator with
    // its options, and the truth file beside it is the one attached inside it.
    const fs::path dir = test::fixturesDir() / "sessions";
    SimulatorOptions o;
    o.frames = 36;
    o.width = 64;  // poses do not depend on the image size
    o.height = 48;
    auto sim = Simulator::create(o);
    ASSERT_TRUE(sim);
    const SimTruth& t = (*sim)->truth();
    auto reader = openMkv(dir / "sim_tabletop.mkv");
    ASSERT_TRUE(reader) << reader.status().toString();
    ASSERT_FALSE((*reader)->attachments().empty());
    std::ifstream file(dir / "sim_tabletop.truth.yaml", std::ios::binary);
    const std::string truth((std::istreambuf_iterator<char>(file)),
                            std::istreambuf_iterator<char>());
    const auto& attached = (*reader)->attachments()[0].data;
    EXPECT_EQ(std::string(attached.begin(), attached.end()), truth);
    auto recorded = readSimulationOptions(truth, "sim_tabletop.truth.yaml");
    ASSERT_TRUE(recorded) << recorded.status().toString();
    EXPECT_EQ(recorded->frames, 36);
    EXPECT_EQ(recorded->seed, 1u);
    EXPECT_EQ(recorded->width, 640);
    EXPECT_EQ(recorded->height, 480);
    int poses = 0;
    while (true) {
        auto frame = (*reader)->next();
        if (!frame)
            break;
        if ((*reader)->streams()[frame->meta().stream].name != "truth/pose")
            continue;
        auto record = decodePoseRecord(frame->image());
        ASSERT_TRUE(record);
        ASSERT_LT(record->frame_sequence, t.frames.size());
        const Isometry3d& T = t.frames[record->frame_sequence].T_world_color;
        EXPECT_EQ(record->translation, T.translation()) << record->frame_sequence;
        ++poses;
    }
    EXPECT_EQ(poses, 36);
}

}  // namespace
}  // namespace mixray::render
