// The simulator's scenarios (scene, lights, environment map, cameras, trajectories) and its
// frame renderer: Embree renders of every camera over the environment map seen through it,
// and Kinect-like depth traced through the same geometry.
#include "mixray/render/simulator.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <functional>
#include <numbers>
#include <opencv2/aruco.hpp>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "embree_scene.h"
#include "mixray/render/assets.h"
#include "mixray/render/output.h"
#include "mixray/render/renderer.h"
#include "optics.h"
#include "simulator_internal.h"

namespace mixray::render {
namespace {

namespace fs = std::filesystem;
using Eigen::Isometry3d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180;

Isometry3d pose(const Eigen::Matrix3d& R, const Vector3d& t) {
    Isometry3d T = Isometry3d::Identity();
    T.linear() = R;
    T.translation() = t;
    return T;
}

// The rotation whose z axis is `z` (unit) and whose x axis is along `x_hint` (perpendicular to
// z; world x when it vanishes), turned about z by `roll` (rad).
Eigen::Matrix3d frameAboutZ(const Vector3d& z, Vector3d x_hint, double roll) {
    if (x_hint.norm() < 1e-6)
        x_hint = Vector3d::UnitX();
    const Vector3d x = x_hint.normalized();
    Eigen::Matrix3d R;
    R.col(0) = x;
    R.col(1) = z.cross(x);
    R.col(2) = z;
    return R * Eigen::AngleAxisd(roll, Vector3d::UnitZ()).toRotationMatrix();
}

// A camera at `eye` looking at `target`, image up towards world +z, rolled by `roll` (rad).
Isometry3d lookAt(const Vector3d& eye, const Vector3d& target, double roll = 0) {
    const Vector3d z = (target - eye).normalized();
    return pose(frameAboutZ(z, z.cross(Vector3d::UnitZ()), roll), eye);
}

// Intrinsics defined at 640x480 (Kinect v1), scaled to the chosen size about the pixel-centre
// convention.
calibration::CameraModel scaledModel(calibration::CameraModel m, int width, int height) {
    const double sx = width / static_cast<double>(m.width);
    const double sy = height / static_cast<double>(m.height);
    m.fx *= sx;
    m.fy *= sy;
    m.cx = (m.cx + 0.5) * sx - 0.5;
    m.cy = (m.cy + 0.5) * sy - 0.5;
    m.width = width;
    m.height = height;
    return m;
}

cv::Ptr<cv::aruco::Dictionary> dictionary() {
    return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250);
}

// Printed black is not black, nor paper white: ink and paper reflectances as sRGB levels.
void toPrintedGreys(cv::Mat& image) {
    image.convertTo(image, CV_8U, (235.0 - 18.0) / 255.0, 18.0);
}

// Writes an asset through `write(temporary path)` and renames it into place: two simulators
// sharing an asset folder (parallel tests, a user's scripts) never read a half-written file.
// The temporary name keeps the extension, which picks the format.
Status writeAtomically(const fs::path& path, const std::function<Status(const fs::path&)>& write) {
    static std::atomic<uint64_t> counter{0};
    const fs::path temporary =
        path.parent_path() / (path.stem().string() + ".partial-" + std::to_string(getpid()) + "-" +
                              std::to_string(counter++) + path.extension().string());
    Status written = write(temporary);
    std::error_code ec;
    if (written)
        fs::rename(temporary, path, ec);
    if (!written || ec) {
        fs::remove(temporary, ec);
        return written ? Status(ErrorCode::kIoError, path.string() + ": " + ec.message()) : written;
    }
    return Status::ok();
}

Status writeImage(const fs::path& path, const cv::Mat& image) {
    return writeAtomically(path, [&](const fs::path& file) -> Status {
        try {
            if (!cv::imwrite(file.string(), image))
                return {ErrorCode::kIoError, path.string() + ": cannot write the texture"};
        } catch (const cv::Exception& e) {
            return {ErrorCode::kIoError, path.string() + ": " + e.what()};
        }
        return Status::ok();
    });
}

// The marker with a one-cell white quiet zone, 32 px per cell.
Status writeMarkerTexture(const fs::path& path, int id) {
    cv::Mat marker;
    try {
        cv::aruco::drawMarker(dictionary(), id, 8 * 32, marker, 1);
    } catch (const cv::Exception& e) {
        return {ErrorCode::kInternal, std::string("drawing the marker: ") + e.what()};
    }
    cv::Mat padded(10 * 32, 10 * 32, CV_8U, cv::Scalar(255));
    marker.copyTo(padded(cv::Rect(32, 32, 8 * 32, 8 * 32)));
    toPrintedGreys(padded);
    return writeImage(path, padded);
}

Status writeBoardTexture(const fs::path& path, const SimBoard& board) {
    constexpr int kPxPerSquare = 80;
    cv::Mat image;
    try {
        auto charuco = cv::aruco::CharucoBoard::create(
            board.squares_x, board.squares_y, static_cast<float>(board.square_m),
            static_cast<float>(board.marker_m), dictionary());
        charuco->draw(cv::Size(board.squares_x * kPxPerSquare, board.squares_y * kPxPerSquare),
                      image, 0, 1);
    } catch (const cv::Exception& e) {
        return {ErrorCode::kInternal, std::string("drawing the ChArUco board: ") + e.what()};
    }
    toPrintedGreys(image);
    return writeImage(path, image);
}

// The room around the table as an equirectangular map (environment frame = world, +z up):
// a ceiling, walls with coloured panels, a floor, and one bright disc per light whose
// radiance integrates to the light's irradiance, centred exactly on its direction.
EnvironmentMap makeEnvironment(int width, const std::vector<Light>& lights) {
    const int height = width / 2;
    std::vector<Rgb> texels(static_cast<size_t>(width) * height);
    EnvironmentMap geometry(Texture(width, height, std::vector<Rgb>(texels.size(), Rgb::Zero())));
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const Eigen::Vector3f d =
                geometry.directionOf({static_cast<float>(x), static_cast<float>(y)});
            const float elevation = std::asin(std::clamp(d.z(), -1.f, 1.f));
            const float azimuth = std::atan2(d.y(), d.x());
            Rgb c;
            if (elevation > 0.6f) {  // ceiling, brighter towards the zenith
                c = Rgb(0.32f, 0.34f, 0.38f) * (0.7f + 0.3f * d.z());
            } else if (elevation > -0.15f) {  // walls: 10 panels of varying colour, window frames
                const float panel =
                    (azimuth + static_cast<float>(kPi)) / (2 * static_cast<float>(kPi)) * 10.f;
                const int k = static_cast<int>(panel) % 10;
                const float hue = 0.6f * static_cast<float>(k);
                c = Rgb(0.20f + 0.12f * std::sin(hue), 0.20f + 0.12f * std::sin(hue + 2.1f),
                        0.20f + 0.12f * std::sin(hue + 4.2f));
                const float frac = panel - std::floor(panel);
                if (frac < 0.04f || frac > 0.96f || std::abs(elevation - 0.25f) < 0.015f)
                    c *= 0.35f;
            } else {  // floor
                c = Rgb(0.10f, 0.08f, 0.06f);
            }
            texels[static_cast<size_t>(y) * width + x] = c;
        }
    // Discs of 2° full radiance fading to 0 at 4°: symmetric about the light's direction, so
    // their radiance-weighted mean direction is the light's.
    const double inner = 2 * kDeg, outer = 4 * kDeg;
    for (const Light& light : lights) {
        const Eigen::Vector3f to_light = (-light.direction).normalized().cast<float>();
        std::vector<float> weight(texels.size(), 0.f);
        double integral = 0;
        for (int y = 0; y < height; ++y) {
            const double solid_angle =
                (2 * kPi / width) * (kPi / height) * std::sin(kPi * (y + 0.5) / height);
            for (int x = 0; x < width; ++x) {
                const Eigen::Vector3f d =
                    geometry.directionOf({static_cast<float>(x), static_cast<float>(y)});
                const double angle =
                    std::acos(std::clamp(static_cast<double>(d.dot(to_light)), -1.0, 1.0));
                const double w = angle <= inner  ? 1.0
                                 : angle < outer ? (outer - angle) / (outer - inner)
                                                 : 0.0;
                weight[static_cast<size_t>(y) * width + x] = static_cast<float>(w);
                integral += w * solid_angle;
            }
        }
        if (integral <= 0)
            continue;
        const Rgb radiance = light.intensity / static_cast<float>(integral);
        for (size_t i = 0; i < texels.size(); ++i)
            texels[i] += weight[i] * radiance;
    }
    return EnvironmentMap(Texture(width, height, std::move(texels)));
}

Material diffuse(const std::string& name, const Rgb& albedo) {
    Material m;
    m.name = name;
    m.type = MaterialType::kDiffuse;
    m.albedo = albedo;
    return m;
}

SceneObject object(const std::string& name, ShapeType type, const std::string& material,
                   const Isometry3d& T_world_object) {
    SceneObject o;
    o.name = name;
    o.role = ObjectRole::kGhost;
    o.shape.type = type;
    o.material = material;
    o.T_anchor_object = T_world_object;
    return o;
}

Isometry3d translation(double x, double y, double z) {
    return pose(Eigen::Matrix3d::Identity(), Vector3d(x, y, z));
}

Isometry3d rotZ(double x, double y, double z, double angle) {
    return pose(Eigen::AngleAxisd(angle, Vector3d::UnitZ()).toRotationMatrix(), Vector3d(x, y, z));
}

// Uniform in [lo, hi) from a seeded engine; the standard distributions differ across
// libraries, this does not.
double uniform(std::mt19937_64& rng, double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

// The board plane object's frame (texture top at +y, centre at the origin, printed side +z)
// from OpenCV's board frame (top-left origin, +y down, +z into the board).
Isometry3d T_plane_board(const SimBoard& b) {
    return pose(Eigen::Vector3d(1, -1, -1).asDiagonal(),
                Vector3d(-0.5 * b.squares_x * b.square_m, 0.5 * b.squares_y * b.square_m, 0));
}

// A board whose printed side faces `facing` (unit, world), rotated in its plane by `spin`.
Isometry3d boardFacing(const SimBoard& b, const Vector3d& centre, const Vector3d& facing,
                       double spin) {
    // Plane frame: z = facing; x horizontal-ish.
    return pose(frameAboutZ(facing, Vector3d::UnitZ().cross(facing), spin), centre) *
           T_plane_board(b);
}

Vector3d tilted(const Vector3d& v, double angle, double azimuth) {
    const Vector3d a = v.unitOrthogonal();
    const Vector3d axis = Eigen::AngleAxisd(azimuth, v) * a;
    return (Eigen::AngleAxisd(angle, axis) * v).normalized();
}

// Whether a view held over the environment camera serves its purpose (buildScenario).
struct BoardViewChecks {
    const SimTruth* t;
    Vector3d eye_env;

    // The angle (degrees) between a plane's normal and the ray from `eye` to `point` on it.
    static double incidenceDeg(const Vector3d& normal, const Vector3d& eye, const Vector3d& point) {
        return std::acos(std::min(1.0, std::abs(normal.dot((point - eye).normalized())))) / kDeg;
    }

    // Every point inside the image, `margin` pixels clear of its edges; their pixels in `px`.
    static bool inside(const calibration::CameraModel& m, const Isometry3d& T_world_cam,
                       const std::vector<Vector3d>& world, double margin,
                       std::vector<Eigen::Vector2d>* px = nullptr) {
        for (const Vector3d& p : world) {
            const Vector3d q = T_world_cam.inverse() * p;
            if (m.lens == calibration::LensModel::kPinhole && q.z() <= 0)
                return false;
            const auto pixel = m.project(q);
            if (!pixel || pixel->x() < margin || pixel->y() < margin ||
                pixel->x() > m.width - 1 - margin || pixel->y() > m.height - 1 - margin)
                return false;
            if (px)
                px->push_back(*pixel);
        }
        return true;
    }

    bool overEnvironmentCamera(const SimFrameTruth& f) const {
        const SimBoard& b = *t->board;
        const Isometry3d& T_world_board = *f.T_world_board;
        std::vector<Vector3d> corners;
        for (const Vector3d& c : t->boardCorners())
            corners.push_back(T_world_board * c);
        // The printed side faces -z of OpenCV's board frame.
        const Vector3d front = -T_world_board.linear().col(2);
        const Vector3d centre = T_world_board * Vector3d(0.5 * b.squares_x * b.square_m,
                                                         0.5 * b.squares_y * b.square_m, 0);
        const Vector3d eye = f.T_world_color.translation();
        if (front.dot(eye - centre) <= 0 || front.dot(eye_env - centre) <= 0)
            return false;
        // Pixel sizes are given at 640x480 (the fish-eye's at 480x480) and scale with the image.
        const double scale = t->color.width / 640.0, env_scale = t->env.width / 480.0;
        // The fish-eye: close, the whole board, at most 45° off its normal.
        if ((centre - eye_env).norm() > 0.28 || incidenceDeg(front, eye_env, centre) > 45 ||
            !inside(t->env, t->T_world_env, corners, 4 * env_scale))
            return false;
        // The Kinect: the whole board in colour and IR, at most 55° off its normal.
        if (incidenceDeg(front, eye, centre) > 55 ||
            !inside(t->color, f.T_world_color, corners, 10 * scale) ||
            !inside(t->ir, f.T_world_color * t->T_color_ir, corners, 10 * scale))
            return false;
        // The world marker: whole, 45 px a side or more, at most 60° off its normal, and not
        // behind the board (with its backing's margin) as the Kinect sees it.
        const std::vector<Vector3d> marker = t->markerCornersWorld();
        std::vector<Eigen::Vector2d> px;
        if (!inside(t->color, f.T_world_color, marker, 10 * scale, &px))
            return false;
        for (size_t k = 0; k < 4; ++k)
            if ((px[k] - px[(k + 1) % 4]).norm() < 45 * scale)
                return false;
        const Vector3d marker_normal = t->T_world_marker.linear().col(2);
        if (incidenceDeg(marker_normal, eye, t->T_world_marker.translation()) > 60)
            return false;
        const Isometry3d T_board_world = T_world_board.inverse();
        const Vector3d eye_board = T_board_world * eye;
        for (const Vector3d& m : marker) {
            const Vector3d m_board = T_board_world * m;
            const double s = eye_board.z() / (eye_board.z() - m_board.z());
            if (s <= 0 || s >= 1)
                continue;  // the board's plane is not between them
            const Vector3d hit = eye_board + s * (m_board - eye_board);
            const double margin = 0.03;
            if (hit.x() > -margin && hit.y() > -margin &&
                hit.x() < b.squares_x * b.square_m + margin &&
                hit.y() < b.squares_y * b.square_m + margin)
                return false;
        }
        return true;
    }
};

}  // namespace

std::string_view toString(SimScenario scenario) {
    return scenario == SimScenario::kTabletop ? "tabletop" : "calibration";
}

std::optional<SimScenario> simScenarioFromString(std::string_view name) {
    if (name == "tabletop")
        return SimScenario::kTabletop;
    if (name == "calibration")
        return SimScenario::kCalibration;
    return std::nullopt;
}

Status SimulatorOptions::validate() const {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "simulator options: " + what);
    };
    if (frames < 0 || frames > 100000)
        return bad("frames must be 0 (the scenario's default) to 100000");
    if (width < 16 || height < 16 || width > 4096 || height > 4096)
        return bad("size must be 16x16 to 4096x4096, got " + std::to_string(width) + "x" +
                   std::to_string(height));
    const int n = static_cast<int>(std::lround(std::sqrt(samples_per_pixel)));
    if (samples_per_pixel < 1 || n * n != samples_per_pixel)
        return bad("samples_per_pixel must be a square number >= 1");
    if (env_every < 0)
        return bad("env_every must be >= 0");
    if (threads < 0)
        return bad("threads must be >= 0");
    if (env_map_width < 16 || env_map_width % 2 != 0 || env_map_width > 8192)
        return bad("env_map_width must be even, 16 to 8192");
    if (asset_prefix.empty() || asset_prefix.find('/') != std::string::npos)
        return bad("asset_prefix must be a non-empty file name");
    if (!inserted.lights.empty())
        return bad("inserted objects bring no lights (the scenario's light them)");
    return Status::ok();
}

double KinectDepthModel::depthStep(double z) const {
    return z * z * disparity_step_px / (focal_px * baseline_m);
}

double KinectDepthModel::depthSigma(double z) const {
    return z * z * disparity_noise_px / (focal_px * baseline_m);
}

std::vector<Vector3d> SimTruth::markerCornersWorld() const {
    const double h = 0.5 * marker_size_m;
    // Marker frame: +x right, +y up the marker image, +z out of it.
    const Vector3d corners[4] = {{-h, h, 0}, {h, h, 0}, {h, -h, 0}, {-h, -h, 0}};
    std::vector<Vector3d> out;
    for (const Vector3d& c : corners)
        out.push_back(T_world_marker * c);
    return out;
}

std::vector<Vector3d> SimTruth::boardCorners() const {
    std::vector<Vector3d> out;
    if (!board)
        return out;
    for (int y = 1; y < board->squares_y; ++y)
        for (int x = 1; x < board->squares_x; ++x)
            out.emplace_back(x * board->square_m, y * board->square_m, 0);
    return out;
}

namespace detail {

Result<SimSetup> buildScenario(const SimulatorOptions& options, const fs::path& assets) {
    SimSetup s;
    SimTruth& t = s.truth;
    t.scenario = options.scenario;
    t.seed = options.seed;
    const bool calib = options.scenario == SimScenario::kCalibration;
    t.fps = calib ? 2 : 30;
    const int frames = options.frames > 0 ? options.frames : (calib ? 20 : 45);
    t.env_every = options.env_every > 0 ? options.env_every : (calib ? 1 : 15);
    t.depth_registered = options.register_depth.value_or(!calib);

    // Kinect v1-like intrinsics at 640x480: colour with mild distortion, the IR camera at
    // f ≈ 580 px with its own, 2.5 cm to the colour camera's left, slightly rotated.
    calibration::CameraModel color =
        calibration::CameraModel::pinhole(640, 480, 524.8, 525.4, 318.6, 241.9);
    color.distortion = {0.045, -0.11, 0.0006, -0.0004, 0.04};
    t.color = scaledModel(color, options.width, options.height);
    calibration::CameraModel ir =
        calibration::CameraModel::pinhole(640, 480, 580.0, 580.0, 314.5, 245.5);
    ir.distortion = {-0.06, 0.12, 0.0003, 0.0002, 0.0};
    t.ir = scaledModel(ir, options.width, options.height);
    t.T_color_ir = pose((Eigen::AngleAxisd(0.3 * kDeg, Vector3d::UnitY()) *
                         Eigen::AngleAxisd(-0.15 * kDeg, Vector3d::UnitX()))
                            .toRotationMatrix(),
                        Vector3d(-0.0251, 0.0003, 0.0008));
    // The depth model's disparity focal length follows the IR camera's scaling.
    t.depth_model.focal_px = t.ir.fx;

    // Fish-eye environment camera: square, ~190° field of view, looking up from a post beside
    // the table, tilted 2° and turned 30° about the vertical.
    const int env_side = options.height;
    calibration::CameraModel env;
    env.lens = calibration::LensModel::kFisheye;
    env.width = env.height = 480;
    env.fx = env.fy = 140.0;
    env.cx = 239.2;
    env.cy = 240.3;
    env.distortion = {0.02, -0.005, 0.001, -0.0002};
    t.env = scaledModel(env, env_side, env_side);
    {
        Eigen::Matrix3d R;
        const double a = 30 * kDeg;
        R.col(0) = Vector3d(std::cos(a), std::sin(a), 0);
        R.col(1) = Vector3d(-std::sin(a), std::cos(a), 0);
        R.col(2) = Vector3d::UnitZ();
        R = R * Eigen::AngleAxisd(2 * kDeg, Vector3d::UnitX()).toRotationMatrix();
        t.T_world_env = pose(R, Vector3d(-0.30, 0.28, 0.12));
    }

    // World = the marker's frame: the printed marker lies at z = 0, the table top just under.
    t.T_world_marker = Isometry3d::Identity();
    SceneDescription& scene = t.scene;
    scene.materials["table"] = diffuse("table", Rgb(0.45f, 0.36f, 0.27f));
    scene.materials["marker"] = diffuse("marker", Rgb(1, 1, 1));
    scene.materials["marker"].albedo_texture = assets / (options.asset_prefix + ".marker.png");
    MIXRAY_RETURN_IF_ERROR(
        writeMarkerTexture(scene.materials["marker"].albedo_texture, t.marker_id));
    SceneObject table = object("table", ShapeType::kPlane, "table", translation(0, 0, t.table_z_m));
    table.shape.size = Eigen::Vector3f(1.6f, 1.2f, 0);
    scene.objects.push_back(table);
    SceneObject marker = object("marker", ShapeType::kPlane, "marker", t.T_world_marker);
    const float printed = static_cast<float>(t.marker_size_m * 10 / 8);
    marker.shape.size = Eigen::Vector3f(printed, printed, 0);
    scene.objects.push_back(marker);

    // Two directional lights (exact direction truth): a warm key and a cool fill.
    Light key;
    key.name = "key";
    key.type = LightType::kDirectional;
    key.direction = -Vector3d(0.45, -0.35, 0.82).normalized();
    key.intensity = Rgb(2.6f, 2.45f, 2.2f);
    Light fill = key;
    fill.name = "fill";
    fill.direction = -Vector3d(-0.55, 0.6, 0.58).normalized();
    fill.intensity = Rgb(0.45f, 0.5f, 0.6f);
    t.lights = {key, fill};
    if (calib) {
        // Boards held face-down over the fish-eye see no light from above: a low window
        // behind the Kinect lights them (light from below would pass through the table).
        Light window = key;
        window.name = "window";
        window.direction = -Vector3d(0.7, -0.7, 0.12).normalized();
        window.intensity = Rgb(1.6f, 1.6f, 1.55f);
        t.lights.push_back(window);
    }

    const Vector3d eye_env = t.T_world_env.translation();
    if (!calib) {
        scene.materials["chrome"] = Material{};
        scene.materials["chrome"].name = "chrome";
        scene.materials["chrome"].type = MaterialType::kMirror;
        scene.materials["chrome"].reflectance = 0.9f;
        scene.materials["matte"] = diffuse("matte", Rgb(0.8f, 0.8f, 0.8f));
        scene.materials["red"] = diffuse("red", Rgb(0.62f, 0.09f, 0.07f));
        scene.materials["blue"] = diffuse("blue", Rgb(0.08f, 0.16f, 0.55f));
        scene.materials["blue"].type = MaterialType::kPhong;
        scene.materials["blue"].shininess = 60;
        const double r = 0.04;
        t.probes = {
            {"probe_mirror", MaterialType::kMirror, r, Vector3d(0.15, 0.08, t.table_z_m + r)},
            {"probe_diffuse", MaterialType::kDiffuse, r, Vector3d(0.15, -0.08, t.table_z_m + r)}};
        for (const SimProbe& p : t.probes) {
            SceneObject o =
                object(p.name, ShapeType::kSphere,
                       p.material == MaterialType::kMirror ? "chrome" : "matte",
                       translation(p.centre_world.x(), p.centre_world.y(), p.centre_world.z()));
            o.shape.radius = static_cast<float>(p.radius_m);
            scene.objects.push_back(o);
        }
        SceneObject red = object("box_red", ShapeType::kBox, "red",
                                 rotZ(-0.17, 0.10, t.table_z_m + 0.05, 20 * kDeg));
        red.shape.size = Eigen::Vector3f(0.08f, 0.06f, 0.10f);
        scene.objects.push_back(red);
        SceneObject blue = object("box_blue", ShapeType::kBox, "blue",
                                  rotZ(-0.12, -0.14, t.table_z_m + 0.025, -35 * kDeg));
        blue.shape.size = Eigen::Vector3f(0.05f, 0.05f, 0.05f);
        scene.objects.push_back(blue);

        // A smooth orbit around the marker; time-based, so a shorter clip is a prefix.
        for (int i = 0; i < frames; ++i) {
            const double time = i / t.fps;
            const double phi = -90 * kDeg + 35 * kDeg * std::sin(2 * kPi * time / 6);
            const double rho = 0.62 + 0.04 * std::sin(2 * kPi * time / 4.5);
            const double h = 0.52 + 0.04 * std::cos(2 * kPi * time / 5);
            const Vector3d eye(rho * std::cos(phi), rho * std::sin(phi), h);
            const Vector3d target(0.03 * std::sin(2 * kPi * time / 3.7),
                                  0.02 * std::cos(2 * kPi * time / 4.1), 0.03);
            SimFrameTruth f;
            f.T_world_color = lookAt(eye, target, 3 * kDeg * std::sin(2 * kPi * time / 5.3));
            t.frames.push_back(f);
        }
    } else {
        t.board = SimBoard{};
        const SimBoard& b = *t.board;
        scene.materials["board"] = diffuse("board", Rgb(1, 1, 1));
        scene.materials["board"].albedo_texture = assets / (options.asset_prefix + ".board.png");
        MIXRAY_RETURN_IF_ERROR(writeBoardTexture(scene.materials["board"].albedo_texture, b));
        scene.materials["backing"] = diffuse("backing", Rgb(0.85f, 0.85f, 0.85f));
        std::mt19937_64 rng(options.seed * 0x9e3779b97f4a7c15ULL + 7);
        const BoardViewChecks checks{&t, eye_env};
        const Vector3d towards_marker =
            (t.T_world_marker.translation() - eye_env).cwiseProduct(Vector3d(1, 1, 0)).normalized();
        for (int i = 0; i < frames; ++i) {
            SimFrameTruth f;
            if (i % 3 == 2) {
                // Held over the environment camera by a person standing at the table, tilted
                // towards the Kinect, which stands beyond the marker (on a tripod or in hand)
                // and looks down between the board and the marker, so that it sees both. Drawn
                // until the fish-eye sees the whole board close and not too oblique, and the
                // Kinect sees the whole board and the whole marker, large and not grazing.
                bool found = false;
                for (int attempt = 0; attempt < 2000 && !found; ++attempt) {
                    const Vector3d centre =
                        eye_env + uniform(rng, 0.0, 0.08) * towards_marker +
                        Vector3d(uniform(rng, -0.03, 0.03), uniform(rng, -0.03, 0.03),
                                 uniform(rng, 0.17, 0.23));
                    const Vector3d out =
                        Eigen::AngleAxisd(uniform(rng, -35 * kDeg, 35 * kDeg), Vector3d::UnitZ()) *
                        towards_marker;
                    const Vector3d eye = t.T_world_marker.translation() +
                                         uniform(rng, 0.3, 0.6) * out +
                                         uniform(rng, 0.35, 0.6) * Vector3d::UnitZ();
                    const Vector3d target =
                        centre + uniform(rng, 0.3, 0.6) * (t.T_world_marker.translation() - centre);
                    Vector3d facing =
                        ((eye - centre).normalized() + (eye_env - centre).normalized())
                            .normalized();
                    facing = tilted(facing, uniform(rng, 0, 8 * kDeg), uniform(rng, 0, 2 * kPi));
                    f.T_world_board =
                        boardFacing(b, centre, facing, uniform(rng, -30 * kDeg, 30 * kDeg));
                    f.T_world_color = lookAt(eye, target, uniform(rng, -8 * kDeg, 8 * kDeg));
                    found = checks.overEnvironmentCamera(f);
                }
                if (!found)
                    return Status(ErrorCode::kInternal,
                                  "simulator: no board pose over the environment camera for view " +
                                      std::to_string(i));
            } else {
                // The Kinect's own views: the board anywhere in the image (also partly outside,
                // for the distortion at the edges), near and far, tilted up to 45°.
                const Vector3d centre = Vector3d(uniform(rng, -0.15, 0.15), uniform(rng, -0.1, 0.1),
                                                 uniform(rng, 0.05, 0.2));
                const double distance = uniform(rng, 0.5, 0.85);
                const double azimuth = uniform(rng, 0, 2 * kPi);
                const double elevation = uniform(rng, 25 * kDeg, 70 * kDeg);
                const Vector3d eye =
                    centre + distance * Vector3d(std::cos(elevation) * std::cos(azimuth),
                                                 std::cos(elevation) * std::sin(azimuth),
                                                 std::sin(elevation));
                const Vector3d facing =
                    tilted((eye - centre).normalized(), uniform(rng, 10 * kDeg, 45 * kDeg),
                           uniform(rng, 0, 2 * kPi));
                f.T_world_board =
                    boardFacing(b, centre, facing, uniform(rng, -30 * kDeg, 30 * kDeg));
                // The board's centre at a chosen pixel: the camera turned from looking at it.
                const double reach = 0.38 - 0.25 * (0.85 - distance) / 0.35;
                const Vector3d ray =
                    t.color
                        .unproject(Eigen::Vector2d(
                            t.color.cx + uniform(rng, -reach, reach) * t.color.width,
                            t.color.cy + uniform(rng, -reach, reach) * t.color.height))
                        .value_or(Vector3d::UnitZ());
                const Isometry3d looking = lookAt(eye, centre, uniform(rng, -5 * kDeg, 5 * kDeg));
                f.T_world_color =
                    pose(looking.linear() *
                             Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), ray).inverse(),
                         eye);
            }
            t.frames.push_back(f);
        }
    }
    for (size_t i = 0; i < t.frames.size(); ++i) {
        t.frames[i].stamp_ns =
            1'000'000'000LL +
            static_cast<int64_t>(std::llround(1e9 * static_cast<double>(i) / t.fps));
        t.frames[i].env_frame = i % static_cast<size_t>(t.env_every) == 0;
    }

    // The environment map, written for the renderer (and as ground truth).
    t.environment_map = assets / (options.asset_prefix + ".env.exr");
    const EnvironmentMap map = makeEnvironment(options.env_map_width, t.lights);
    FloatImage exr{map.texture().width(), map.texture().height(), 3, {}};
    exr.pixels.reserve(static_cast<size_t>(exr.width) * exr.height * 3);
    for (int y = 0; y < exr.height; ++y)
        for (int x = 0; x < exr.width; ++x)
            for (int c = 0; c < 3; ++c)
                exr.pixels.push_back(map.texture().texel(x, y)[c]);
    MIXRAY_RETURN_IF_ERROR(writeAtomically(
        t.environment_map, [&](const fs::path& file) { return writeExr(exr, file); }));
    s.environment = map;
    Light environment;
    environment.name = "room";
    environment.type = LightType::kEnvironment;
    environment.environment = t.environment_map;
    scene.lights = t.lights;
    scene.lights.push_back(environment);

    for (SimFrameTruth& f : t.frames) {
        if (!f.T_world_board)
            continue;
        const auto seen = [&](const calibration::CameraModel& m, const Isometry3d& T_world_cam) {
            const Isometry3d T_cam_board = T_world_cam.inverse() * *f.T_world_board;
            const Vector3d front = -(T_cam_board.linear() * Vector3d::UnitZ());
            int inside = 0;
            const auto corners = t.boardCorners();
            for (const Vector3d& c : corners) {
                const Vector3d p = T_cam_board * c;
                if (front.dot(-p) <= 0)
                    continue;
                const auto px = m.project(p);
                if (px && px->x() >= 0 && px->y() >= 0 && px->x() <= m.width - 1 &&
                    px->y() <= m.height - 1)
                    ++inside;
            }
            return corners.empty() ? 0.0 : inside / static_cast<double>(corners.size());
        };
        f.board_in_color = seen(t.color, f.T_world_color);
        int marker_inside = 0;
        for (const Vector3d& c : t.markerCornersWorld()) {
            const auto px = t.color.project(f.T_world_color.inverse() * c);
            if (px && px->x() >= 0 && px->y() >= 0 && px->x() <= t.color.width - 1 &&
                px->y() <= t.color.height - 1)
                ++marker_inside;
        }
        f.marker_in_color = marker_inside / 4.0;
        f.board_in_ir = seen(t.ir, f.T_world_color * t.T_color_ir);
        f.board_in_env = seen(t.env, t.T_world_env);
    }
    MIXRAY_RETURN_IF_ERROR(scene.validate());
    return s;
}

}  // namespace detail

namespace {

// The scene for one frame: the board (calibration) at its pose, all objects virtual so the
// renderer shades every one of them over the background image.
SceneDescription frameScene(const SimTruth& t, const SimFrameTruth& f,
                            const SceneDescription& inserted) {
    SceneDescription scene = t.scene;
    scene.objects.insert(scene.objects.end(), inserted.objects.begin(), inserted.objects.end());
    scene.materials.insert(inserted.materials.begin(), inserted.materials.end());
    if (t.board && f.T_world_board) {
        const SimBoard& b = *t.board;
        const Isometry3d T_world_plane = *f.T_world_board * T_plane_board(b).inverse();
        SceneObject board = object("board", ShapeType::kPlane, "board", T_world_plane);
        board.shape.size = Eigen::Vector3f(static_cast<float>(b.squares_x * b.square_m),
                                           static_cast<float>(b.squares_y * b.square_m), 0);
        scene.objects.push_back(board);
        SceneObject backing = object("board_backing", ShapeType::kPlane, "backing",
                                     T_world_plane * translation(0, 0, -0.001));
        backing.shape.size = board.shape.size + Eigen::Vector3f(0.04f, 0.04f, 0);
        scene.objects.push_back(backing);
    }
    for (SceneObject& o : scene.objects)
        o.role = ObjectRole::kVirtual;
    return scene;
}

class SimulatorImpl : public Simulator {
public:
    SimulatorImpl(const SimulatorOptions& options, detail::SimSetup setup, fs::path temp)
        : options_(options),
          setup_(std::move(setup)),
          temp_(std::move(temp)),
          // The background is antialiased like the renderer's samples (n x n per pixel).
          background_samples_(static_cast<int>(std::lround(std::sqrt(options.samples_per_pixel)))) {
    }
    ~SimulatorImpl() override {
        renderers_.clear();
        if (!temp_.empty()) {
            std::error_code ec;
            fs::remove_all(temp_, ec);
        }
    }

    const SimTruth& truth() const override { return setup_.truth; }
    int frameCount() const override { return static_cast<int>(setup_.truth.frames.size()); }

    Result<SimFrame> render(int index) override {
        const SimTruth& t = setup_.truth;
        MIXRAY_RETURN_IF_ERROR(checkIndex(index));
        const SimFrameTruth& f = t.frames[static_cast<size_t>(index)];
        MIXRAY_RETURN_IF_ERROR(prepare(f));
        SimFrame out;
        out.index = index;
        auto color = renderCamera(0, t.color, f.T_world_color);
        if (!color)
            return color.status();
        out.color = std::move(color).value();
        auto depth =
            detail::kinectDepth(t, *geometry_, f.T_world_color,
                                t.depth_registered ? color_rays_ : ir_rays_, options_.seed, index);
        if (!depth)
            return depth.status();
        out.depth = std::move(depth).value();
        if (t.scenario == SimScenario::kCalibration) {
            auto ir = renderCamera(1, t.ir, f.T_world_color * t.T_color_ir);
            if (!ir)
                return ir.status();
            out.ir = detail::toInfrared(*ir);
        }
        if (f.env_frame) {
            auto env = renderCamera(2, t.env, t.T_world_env);
            if (!env)
                return env.status();
            out.env = std::move(env).value();
        }
        return out;
    }

    Result<Image> renderColor(int index) override {
        const SimTruth& t = setup_.truth;
        MIXRAY_RETURN_IF_ERROR(checkIndex(index));
        const SimFrameTruth& f = t.frames[static_cast<size_t>(index)];
        MIXRAY_RETURN_IF_ERROR(prepare(f));
        return renderCamera(0, t.color, f.T_world_color);
    }

    Status checkIndex(int index) const {
        if (index < 0 || index >= frameCount())
            return Status(ErrorCode::kInvalidArgument, "simulator: frame " + std::to_string(index) +
                                                           " of " + std::to_string(frameCount()));
        return Status::ok();
    }

    Status init() {
        const SimTruth& t = setup_.truth;
        color_rays_ = detail::pixelRays(t.color);
        if (!t.depth_registered)
            ir_rays_ = detail::pixelRays(t.ir);
        background_rays_.push_back(detail::pixelRays(t.color, background_samples_));
        background_rays_.push_back(t.scenario == SimScenario::kCalibration
                                       ? detail::pixelRays(t.ir, background_samples_)
                                       : std::vector<Eigen::Vector3f>{});
        background_rays_.push_back(detail::pixelRays(t.env, background_samples_));
        return Status::ok();
    }

private:
    // Renderers and geometry for this frame's scene: built once when the scene is static,
    // per view when the board moves.
    Status prepare(const SimFrameTruth& f) {
        const bool moving = setup_.truth.board.has_value();
        if (!renderers_.empty() && !moving)
            return Status::ok();
        const SceneDescription scene = frameScene(setup_.truth, f, options_.inserted);
        RenderOptions ro;
        ro.samples_per_pixel = options_.samples_per_pixel;
        ro.max_depth = 3;
        ro.soft_shadows = SoftShadowMethod::kHard;
        ro.depth_secondary = DepthSecondaryRays::kNone;
        ro.threads = options_.threads;
        ro.seed = options_.seed;
        renderers_.clear();
        for (int camera = 0; camera < 3; ++camera) {
            auto r = Renderer::create(scene, ro);
            if (!r)
                return r.status().withContext("simulator");
            renderers_.push_back(std::move(r).value());
        }
        auto geometry = detail::SimGeometry::build(scene);
        if (!geometry)
            return geometry.status();
        geometry_ = std::move(geometry).value();
        return Status::ok();
    }

    Result<Image> renderCamera(int which, const calibration::CameraModel& model,
                               const Isometry3d& T_world_cam) {
        const Image background =
            detail::environmentView(setup_.environment, model, background_rays_[which],
                                    background_samples_, T_world_cam, options_.threads);
        RenderInputs in;
        in.camera_image = background.view();
        in.camera = model;
        in.T_world_cam = T_world_cam;
        in.stop = options_.stop;
        RenderLayers layers;
        MIXRAY_RETURN_IF_ERROR(renderers_[static_cast<size_t>(which)]->render(in, layers));
        return std::move(layers.composite);
    }

    SimulatorOptions options_;
    detail::SimSetup setup_;
    fs::path temp_;
    int background_samples_ = 2;
    std::vector<std::unique_ptr<Renderer>> renderers_;  // colour, IR, environment
    std::unique_ptr<detail::SimGeometry> geometry_;
    std::vector<Eigen::Vector3f> color_rays_;  // pixel centres, for depth
    std::vector<Eigen::Vector3f> ir_rays_;     // IR pixel centres, for IR-aligned depth
    std::vector<std::vector<Eigen::Vector3f>> background_rays_;  // per camera, as renderers_
};

}  // namespace

Result<std::unique_ptr<Simulator>> Simulator::create(const SimulatorOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    fs::path assets = options.asset_dir;
    fs::path temp;
    std::error_code ec;
    if (assets.empty()) {
        const uint64_t tag = std::random_device{}();
        temp = fs::temp_directory_path(ec) / ("mixray-sim-" + std::to_string(tag));
        assets = temp;
    }
    fs::create_directories(assets, ec);
    if (ec)
        return Status(ErrorCode::kIoError,
                      "simulator: cannot create " + assets.string() + ": " + ec.message());
    auto setup = detail::buildScenario(options, assets);
    if (!setup) {
        if (!temp.empty())
            fs::remove_all(temp, ec);
        return setup.status();
    }
    const SceneDescription& real = setup->truth.scene;
    for (const auto& [name, material] : options.inserted.materials) {
        if (real.materials.count(name)) {
            if (!temp.empty())
                fs::remove_all(temp, ec);
            return Status(ErrorCode::kInvalidArgument, "simulator: inserted material \"" + name +
                                                           "\" clashes with the scenario's");
        }
    }
    for (const SceneObject& o : options.inserted.objects) {
        if (std::any_of(real.objects.begin(), real.objects.end(),
                        [&](const SceneObject& r) { return r.name == o.name; })) {
            if (!temp.empty())
                fs::remove_all(temp, ec);
            return Status(ErrorCode::kInvalidArgument, "simulator: inserted object \"" + o.name +
                                                           "\" clashes with the scenario's");
        }
    }
    auto sim = std::make_unique<SimulatorImpl>(options, std::move(setup).value(), temp);
    MIXRAY_RETURN_IF_ERROR(sim->init());
    return std::unique_ptr<Simulator>(std::move(sim));
}

}  // namespace mixray::render
