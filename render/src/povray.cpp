// povray.h: scenes written for POV-Ray 3.7, the renderer run, its statistics read.
#include "mixray/render/povray.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <vector>

#include "mixray/render/assets.h"

extern char** environ;

namespace mixray::render {
namespace {

namespace fs = std::filesystem;

// POV-Ray's point-light fall-off is 2 / (1 + (d / fade)²); with a fade distance far below any
// distance in a scene it is 2·fade² / d² to a relative 1e-6 at 1 mm, so the light's colour is
// its intensity over 2·fade².
constexpr double kFadeDistance = 1e-6;

std::string vec(const Eigen::Vector3d& v) {
    std::ostringstream s;
    s.precision(9);
    s << '<' << v.x() << ',' << v.y() << ',' << v.z() << '>';
    return s.str();
}

std::string rgb(const Eigen::Vector3f& c) {
    return "rgb " + vec(c.cast<double>());
}

std::string resolvePath(const SceneDescription& scene, const fs::path& p) {
    if (p.empty() || p.is_absolute() || scene.source_path.empty())
        return p.string();
    return (scene.source_path.parent_path() / p).string();
}

Status unsupported(const std::string& what) {
    return Status(ErrorCode::kUnsupported,
                  "POV-Ray scene: " + what + " would render differently in POV-Ray");
}

Result<std::string> finishOf(const Material& m) {
    if (!m.albedo_texture.empty() || !m.reflectance_map.empty())
        return unsupported("material '" + m.name + "': textures and reflectance maps");
    std::ostringstream s;
    s.precision(9);
    switch (m.type) {
        case MaterialType::kDiffuse: {
            const float rho = std::clamp(m.reflectance, 0.f, 1.f);
            // mixray: (1 − ρ)·albedo/π·E + ρ·L_reflected; POV-Ray: diffuse·pigment·E +
            // reflection·L_reflected.
            s << "pigment { " << rgb(m.albedo) << " } finish { ambient 0 emission 0 diffuse "
              << (1 - rho) / M_PI << " reflection " << rho << " }";
            return s.str();
        }
        case MaterialType::kMirror: {
            const float rho = std::clamp(m.reflectance > 0 ? m.reflectance : 1.f, 0.f, 1.f);
            s << "pigment { rgb 0 } finish { ambient 0 emission 0 diffuse 0 reflection " << rho
              << " }";
            return s.str();
        }
        case MaterialType::kPhong:
        case MaterialType::kMetal:
        case MaterialType::kGlass:
            break;
    }
    return unsupported("material '" + m.name + "' (Phong, metal and glass)");
}

// Every position and direction goes into the camera's frame with y flipped: x right, y up,
// z forward, POV-Ray's left-handed camera space.
struct ToPovray {
    Eigen::Isometry3d T_pov_world;
    Eigen::Vector3d point(const Eigen::Vector3d& p_world) const { return T_pov_world * p_world; }
    Eigen::Vector3d direction(const Eigen::Vector3d& d_world) const {
        return T_pov_world.linear() * d_world;
    }
};

void writeMesh(std::ostream& out, const TriangleMesh& mesh, const Eigen::Isometry3d& T_pov_object,
               const std::string& material) {
    out << "mesh2 {\n  vertex_vectors { " << mesh.positions.size();
    for (const Eigen::Vector3f& p : mesh.positions)
        out << ",\n    " << vec(T_pov_object * p.cast<double>());
    out << " }\n";
    const bool smooth = mesh.normals.size() == mesh.positions.size();
    if (smooth) {
        out << "  normal_vectors { " << mesh.normals.size();
        for (const Eigen::Vector3f& n : mesh.normals)
            out << ",\n    " << vec(T_pov_object.linear() * n.cast<double>());
        out << " }\n";
    }
    out << "  face_indices { " << mesh.triangles.size();
    for (const auto& t : mesh.triangles)
        out << ",\n    <" << t[0] << ',' << t[1] << ',' << t[2] << '>';
    out << " }\n  " << material << "\n}\n";
}

}  // namespace

Result<std::string> povrayScene(const SceneDescription& scene, const PovrayView& view) {
    const calibration::CameraModel& camera = view.camera;
    if (camera.lens != calibration::LensModel::kPinhole ||
        std::any_of(camera.distortion.begin(), camera.distortion.end(),
                    [](double k) { return k != 0; }) ||
        !(camera.fx > 0) || !(camera.fy > 0) || camera.width < 1 || camera.height < 1)
        return Status(ErrorCode::kInvalidArgument,
                      "POV-Ray scene: the camera must be a pinhole without distortion");
    if (view.max_depth < 0 || view.max_depth > 255)
        return Status(ErrorCode::kInvalidArgument,
                      "POV-Ray scene: max_depth must be in [0, 255] (POV-Ray's trace levels)");
    ToPovray to;
    to.T_pov_world = Eigen::Isometry3d::Identity();
    to.T_pov_world.linear() = Eigen::Vector3d(1, -1, 1).asDiagonal();
    to.T_pov_world = to.T_pov_world * view.T_world_cam.inverse();

    std::ostringstream out;
    out.precision(9);
    out << "// Written by mixray (render/povray.h) for POV-Ray 3.7.\n#version 3.7;\n"
        << "global_settings { assumed_gamma 1.0 max_trace_level " << view.max_depth + 1
        << " adc_bailout 0 ambient_light 0 }\n"
        << "background { rgb 0 }\n";
    // Pixel x's ray, POV-Ray's (u − ½)·right through u = (x + ½)/width, is mixray's
    // (x − cx)/fx when the direction carries the principal point's offset from the centre.
    const double w = camera.width, h = camera.height;
    const Eigen::Vector3d direction(((w - 1) / 2 - camera.cx) / camera.fx,
                                    -((h - 1) / 2 - camera.cy) / camera.fy, 1);
    out << "camera { perspective location <0,0,0> direction " << vec(direction) << " right <"
        << w / camera.fx << ",0,0> up <0," << h / camera.fy << ",0> }\n";

    for (const Light& light : scene.lights) {
        if (light.anchor != "world")
            return unsupported("light '" + light.name + "' anchored to '" + light.anchor + "'");
        const std::string shadowless = view.shadows ? "" : " shadowless";
        if (light.type == LightType::kPoint) {
            const Eigen::Vector3f colour =
                light.intensity / static_cast<float>(2 * kFadeDistance * kFadeDistance);
            out << "light_source { " << vec(to.point(light.position)) << " color " << rgb(colour)
                << " fade_distance " << kFadeDistance << " fade_power 2" << shadowless << " }\n";
        } else if (light.type == LightType::kDirectional) {
            // A parallel light from far up-stream of the scene.
            const Eigen::Vector3d d = to.direction(light.direction.normalized());
            out << "light_source { " << vec(-1e4 * d) << " color " << rgb(light.intensity)
                << " parallel point_at <0,0,0>" << shadowless << " }\n";
        } else {
            return unsupported("light '" + light.name + "' (spherical and environment lights)");
        }
    }

    for (const SceneObject& object : scene.objects) {
        if (object.anchor != "world")
            return unsupported("object '" + object.name + "' anchored to '" + object.anchor + "'");
        const auto material = scene.materials.find(object.material);
        if (material == scene.materials.end())
            return Status(ErrorCode::kInvalidArgument, "POV-Ray scene: object '" + object.name +
                                                           "' has no material '" + object.material +
                                                           "'");
        auto finish = finishOf(material->second);
        if (!finish)
            return finish.status();
        const Eigen::Isometry3d T_pov_object = to.T_pov_world * object.T_anchor_object;
        const Shape& shape = object.shape;
        if (shape.type == ShapeType::kSphere) {
            out << "sphere { " << vec(T_pov_object.translation()) << ", " << shape.radius << ' '
                << *finish << " }\n";
        } else if (shape.type == ShapeType::kMesh) {
            if (shape.mesh_data != nullptr) {
                TriangleMesh mesh = *shape.mesh_data;
                for (Eigen::Vector3f& p : mesh.positions)
                    p *= shape.scale;
                writeMesh(out, mesh, T_pov_object, *finish);
            } else {
                auto loaded = loadMeshFile(resolvePath(scene, shape.mesh), shape.scale);
                if (!loaded)
                    return loaded.status();
                for (const LoadedMesh& part : *loaded)
                    writeMesh(out, part.mesh, T_pov_object, *finish);
            }
        } else {
            // Boxes, planes and disks are the meshes the Renderer traces.
            writeMesh(out, makeShapeMesh(shape), T_pov_object, *finish);
        }
    }
    return out.str();
}

namespace {

// The number after `label` on its line ("Rays:    81972"), or the seconds in parentheses
// ("Trace Time: 0 hours 0 minutes 0 seconds (0.021 seconds)").
std::optional<std::string_view> lineAfter(std::string_view text, std::string_view label) {
    const size_t at = text.find(label);
    if (at == std::string_view::npos)
        return std::nullopt;
    std::string_view rest = text.substr(at + label.size());
    return rest.substr(0, std::min(rest.find('\n'), rest.size()));
}

template <typename T>
std::optional<T> firstNumber(std::string_view line) {
    const size_t start = line.find_first_of("0123456789");
    if (start == std::string_view::npos)
        return std::nullopt;
    T value{};
    const auto [end, error] =
        std::from_chars(line.data() + start, line.data() + line.size(), value);
    if (error != std::errc())
        return std::nullopt;
    return value;
}

std::optional<double> secondsIn(std::string_view line) {
    const size_t open = line.find('(');
    if (open == std::string_view::npos)
        return std::nullopt;
    auto s = firstNumber<double>(line.substr(open));
    if (!s || !std::isfinite(*s) || *s < 0)
        return std::nullopt;
    return s;
}

}  // namespace

Result<PovrayStats> parsePovrayStats(std::string_view text) {
    PovrayStats stats;
    const auto trace = lineAfter(text, "Trace Time:");
    const auto rays = lineAfter(text, "Rays:");
    std::optional<double> trace_s = trace ? secondsIn(*trace) : std::nullopt;
    std::optional<uint64_t> ray_count = rays ? firstNumber<uint64_t>(*rays) : std::nullopt;
    if (!trace_s || !ray_count)
        return Status(ErrorCode::kCorruptData,
                      "POV-Ray's statistics have no trace time or ray count (did it finish?)");
    stats.trace_s = *trace_s;
    stats.rays = *ray_count;
    if (const auto parse = lineAfter(text, "Parse Time:"))
        stats.parse_s = secondsIn(*parse).value_or(0);
    if (const auto pixels = lineAfter(text, "Pixels:"))
        stats.pixels = firstNumber<uint64_t>(*pixels).value_or(0);
    if (const auto shadow = lineAfter(text, "Shadow Ray Tests:"))
        stats.shadow_rays = firstNumber<uint64_t>(*shadow).value_or(0);
    // "using 2 thread(s)" on the line after the trace time.
    const size_t at = text.find("Trace Time:");
    if (const auto using_line = lineAfter(text.substr(at), "using "))
        stats.threads = firstNumber<int>(*using_line).value_or(0);
    return stats;
}

Result<PovrayRender> renderWithPovray(const std::string& scene_text, int width, int height,
                                      int threads, const fs::path& work_dir) {
    const fs::path scene_path = work_dir / "scene.pov";
    const fs::path image_path = work_dir / "scene.png";
    const fs::path log_path = work_dir / "povray.log";
    {
        std::ofstream file(scene_path, std::ios::binary);
        file << scene_text;
        if (!file.flush())
            return Status(ErrorCode::kIoError, scene_path.string() + ": cannot write");
    }
    std::error_code ignored;
    fs::remove(image_path, ignored);
    const std::vector<std::string> args = {"povray",
                                           "-D",  // no display
                                           "-A",  // no antialiasing: 1 ray per pixel
                                           "+FN",
                                           "-GP",  // no progress lines in the log
                                           "+WT" + std::to_string(std::max(1, threads)),
                                           "+W" + std::to_string(width),
                                           "+H" + std::to_string(height),
                                           "+I" + scene_path.string(),
                                           "+O" + image_path.string()};
    std::vector<char*> argv;
    for (const std::string& a : args)
        argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    pid_t pid = -1;
    const auto start = std::chrono::steady_clock::now();
    const int spawned = posix_spawnp(&pid, "povray", &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (spawned != 0)
        return Status(ErrorCode::kNotFound, std::string("cannot run povray (") +
                                                std::strerror(spawned) +
                                                "): install POV-Ray 3.7 (sudo apt-get install "
                                                "povray)");
    int wait_status = 0;
    while (waitpid(pid, &wait_status, 0) < 0 && errno == EINTR) {
    }
    PovrayRender render;
    render.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::ifstream log_file(log_path, std::ios::binary);
    std::string log((std::istreambuf_iterator<char>(log_file)), std::istreambuf_iterator<char>());
    const bool exited_ok = WIFEXITED(wait_status) && WEXITSTATUS(wait_status) == 0;
    if (!exited_ok || !fs::exists(image_path)) {
        const std::string tail = log.size() > 600 ? log.substr(log.size() - 600) : log;
        return Status(ErrorCode::kIoError, "povray failed on " + scene_path.string() + " (see " +
                                               log_path.string() + "):\n" + tail);
    }
    auto stats = parsePovrayStats(log);
    if (!stats)
        return stats.status().withContext(log_path.string());
    render.stats = *stats;
    const cv::Mat bgr = cv::imread(image_path.string(), cv::IMREAD_COLOR);
    if (bgr.empty() || bgr.cols != width || bgr.rows != height)
        return Status(ErrorCode::kCorruptData,
                      image_path.string() + ": POV-Ray's image is missing or not " +
                          std::to_string(width) + "x" + std::to_string(height));
    render.image = Image(ImageDesc::packed(PixelFormat::kRGB8, width, height));
    uint8_t* dst = render.image.bytes().data();
    for (int y = 0; y < height; ++y) {
        const auto* row = bgr.ptr<uint8_t>(y);
        for (int x = 0; x < width; ++x, dst += 3) {
            dst[0] = row[3 * x + 2];
            dst[1] = row[3 * x + 1];
            dst[2] = row[3 * x + 0];
        }
    }
    return render;
}

}  // namespace mixray::render
