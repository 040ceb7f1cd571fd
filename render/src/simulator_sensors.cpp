// The simulator's sensor models: what each camera sees of the environment map, Kinect-like
// structured-light depth, and IR images.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>

#include "optics.h"
#include "simulator_internal.h"

namespace mixray::render::detail {
namespace {

using Eigen::Vector3d;
using Eigen::Vector3f;

void parallelRows(int height, int threads, const std::function<void(int)>& row) {
    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, height),
                          [&](const tbb::blocked_range<int>& r) {
                              for (int y = r.begin(); y < r.end(); ++y)
                                  row(y);
                          });
    });
}

// Standard normal from a per-pixel stream (Box-Muller), identical on every platform.
double gaussian(optics::Rng& rng) {
    const double u1 = (static_cast<double>(rng.next() >> 11) + 1.0) * 0x1.0p-53;  // (0, 1]
    const double u2 = static_cast<double>(rng.next() >> 11) * 0x1.0p-53;
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

}  // namespace

Result<std::unique_ptr<SimGeometry>> SimGeometry::build(const SceneDescription& scene) {
    auto g = std::make_unique<SimGeometry>();
    for (const SceneObject& o : scene.objects) {
        if (o.anchor != "world")
            return Status(ErrorCode::kInternal,
                          "simulator: object '" + o.name + "' is not anchored to the world");
        auto loaded = loadObjectGeometry(scene, o);
        if (!loaded)
            return loaded.status().withContext("simulator");
        ObjectData d = std::move(loaded).value();
        d.active = true;
        d.R_world_object = d.T_anchor_object.linear();
        d.t_world_object = d.T_anchor_object.translation();
        g->objects_.push_back(std::move(d));
    }
    auto built = EmbreeScene::build(g->objects_);
    if (!built)
        return built.status().withContext("simulator");
    g->scene_ = std::move(built).value();
    MIXRAY_RETURN_IF_ERROR(g->scene_->setPoses(g->objects_));
    return g;
}

SimGeometry::SurfaceHit SimGeometry::intersect(const Vector3f& origin, const Vector3f& dir) const {
    const Hit hit =
        EmbreeScene::intersect(scene_->all(), origin, dir, std::numeric_limits<float>::infinity());
    SurfaceHit s;
    if (!hit.valid)
        return s;
    s.valid = true;
    s.t = hit.t;
    s.p = origin + hit.t * dir;
    const ObjectData& o = objects_[hit.object];
    if (o.shape == ShapeType::kSphere) {
        s.n = (s.p - o.t_world_object).normalized();
    } else {
        const TriangleMesh& mesh = (*o.meshes)[hit.mesh];
        const auto& tri = mesh.triangles[hit.prim];
        const Vector3f a = mesh.positions[tri[0]], b = mesh.positions[tri[1]],
                       c = mesh.positions[tri[2]];
        s.n = (o.R_world_object * (b - a).cross(c - a)).normalized();
    }
    return s;
}

bool SimGeometry::occluded(const Vector3f& origin, const Vector3f& dir, float t_far) const {
    return EmbreeScene::occluded(scene_->all(), origin, dir, t_far);
}

std::vector<Vector3f> pixelRays(const calibration::CameraModel& model, int n) {
    std::vector<Vector3f> rays(static_cast<size_t>(model.width) * model.height * n * n);
    parallelRows(model.height, 0, [&](int y) {
        for (int x = 0; x < model.width; ++x)
            for (int k = 0; k < n * n; ++k) {
                const double dx = n == 1 ? 0 : ((k % n) + 0.5) / n - 0.5;
                const double dy = n == 1 ? 0 : ((k / n) + 0.5) / n - 0.5;
                const auto d = model.unproject({x + dx, y + dy});
                rays[(static_cast<size_t>(y) * model.width + x) * n * n + k] =
                    d ? Vector3f(d->cast<float>().normalized()) : Vector3f::Constant(NAN);
            }
    });
    return rays;
}

Image environmentView(const EnvironmentMap& map, const calibration::CameraModel& model,
                      const std::vector<Vector3f>& rays, int n,
                      const Eigen::Isometry3d& T_world_cam, int threads) {
    Image out(ImageDesc::packed(PixelFormat::kRGB8, model.width, model.height));
    const Eigen::Matrix3f R = T_world_cam.linear().cast<float>();
    const MutableImageView view = out.mutableView();
    parallelRows(model.height, threads, [&](int y) {
        uint8_t* row = view.row<uint8_t>(y);
        for (int x = 0; x < model.width; ++x) {
            Rgb sum = Rgb::Zero();
            const size_t base = (static_cast<size_t>(y) * model.width + x) * n * n;
            for (int k = 0; k < n * n; ++k) {
                const Vector3f& d = rays[base + static_cast<size_t>(k)];
                if (d.allFinite())
                    sum += map.radiance(R * d);
            }
            sum /= static_cast<float>(n * n);
            for (int c = 0; c < 3; ++c)
                row[3 * x + c] = optics::encodeSrgb8(sum[c]);
        }
    });
    return out;
}

Result<Image> kinectDepth(const SimTruth& t, const SimGeometry& geometry,
                          const Eigen::Isometry3d& T_world_color, const std::vector<Vector3f>& rays,
                          uint64_t seed, int frame) {
    // The image is the colour camera's (registered) or the IR camera's own (raw).
    const calibration::CameraModel& cam = t.depth_registered ? t.color : t.ir;
    const KinectDepthModel& model = t.depth_model;
    const int w = cam.width, h = cam.height;
    const size_t count = static_cast<size_t>(w) * h;
    if (rays.size() != count)
        return Status(ErrorCode::kInternal, "simulator: depth rays do not match the camera");
    const Eigen::Isometry3d T_world_ir = T_world_color * t.T_color_ir;
    const Eigen::Isometry3d T_ir_world = T_world_ir.inverse();
    const Eigen::Isometry3d T_cam_ir =
        t.depth_registered ? t.T_color_ir : Eigen::Isometry3d::Identity();
    const Eigen::Isometry3d& T_world_cam = t.depth_registered ? T_world_color : T_world_ir;
    const Vector3f eye = T_world_cam.translation().cast<float>();
    const Eigen::Matrix3f R = T_world_cam.linear().cast<float>();
    const Vector3f ir_centre = T_world_ir.translation().cast<float>();
    const Vector3f projector = (T_world_ir * Vector3d(model.baseline_m, 0, 0)).cast<float>();
    const double fb = model.focal_px * model.baseline_m;
    const float cos_grazing =
        static_cast<float>(std::cos(model.max_incidence_deg * std::numbers::pi / 180));

    std::vector<float> z_true(count, NAN);
    std::vector<float> z_measured(count, 0.f);
    parallelRows(h, 0, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const size_t i = static_cast<size_t>(y) * w + x;
            const Vector3f& d_cam = rays[i];
            if (!d_cam.allFinite())
                continue;
            const SimGeometry::SurfaceHit hit = geometry.intersect(eye, R * d_cam);
            if (!hit.valid)
                continue;
            z_true[i] = hit.t * d_cam.z();
            const Vector3d p_ir = T_ir_world * hit.p.cast<double>();
            if (p_ir.z() < model.min_range_m || p_ir.z() > model.max_range_m)
                continue;
            // The IR camera must see the point inside its image: its narrower view leaves
            // the registered image's borders without depth.
            const auto px = t.ir.project(p_ir);
            if (!px || px->x() < 0 || px->y() < 0 || px->x() > t.ir.width - 1 ||
                px->y() > t.ir.height - 1)
                continue;
            // Both the IR camera and the projector must see the point, at a usable angle.
            bool seen = true;
            for (const Vector3f& target : {ir_centre, projector}) {
                const Vector3f delta = target - hit.p;
                const float dist = delta.norm();
                const Vector3f dir = delta / dist;
                const Vector3f n = hit.n.dot(dir) >= 0 ? hit.n : Vector3f(-hit.n);
                if (n.dot(dir) < cos_grazing ||
                    geometry.occluded(hit.p + 1e-4f * n, dir, dist - 2e-4f)) {
                    seen = false;
                    break;
                }
            }
            if (!seen)
                continue;
            optics::Rng rng(seed ^ (static_cast<uint64_t>(frame) * 0x9e3779b97f4a7c15ULL) ^
                            (static_cast<uint64_t>(i) * 0xc2b2ae3d27d4eb4fULL) ^ 0xde97ULL);
            const double disparity = fb / p_ir.z() + model.disparity_noise_px * gaussian(rng);
            const double quantised =
                std::round(disparity / model.disparity_step_px) * model.disparity_step_px;
            if (quantised <= 0)
                continue;
            const Vector3d measured_ir = p_ir * ((fb / quantised) / p_ir.z());
            z_measured[i] = static_cast<float>((T_cam_ir * measured_ir).z());
        }
    });

    // Block matching fails across depth discontinuities: holes along object edges.
    Image out(ImageDesc::packed(PixelFormat::kDepth16, w, h));
    std::fill(out.bytes().begin(), out.bytes().end(), uint8_t{0});
    const MutableImageView view = out.mutableView();
    const float jump = static_cast<float>(model.edge_jump);
    parallelRows(h, 0, [&](int y) {
        auto* row = view.row<uint16_t>(y);
        for (int x = 0; x < w; ++x) {
            const size_t i = static_cast<size_t>(y) * w + x;
            if (z_measured[i] <= 0)
                continue;
            const float z = z_true[i];
            bool edge = false;
            for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1) && !edge; ++yy)
                for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 1); ++xx) {
                    const float zn = z_true[static_cast<size_t>(yy) * w + xx];
                    if (!(std::abs(zn - z) <= jump * z)) {  // NaN neighbours count too
                        edge = true;
                        break;
                    }
                }
            if (edge)
                continue;
            row[x] = static_cast<uint16_t>(
                std::clamp<long>(std::lround(1000.0 * z_measured[i]), 1, 65535));
        }
    });
    return out;
}

Image toInfrared(const Image& rgb) {
    const ImageDesc& d = rgb.desc();
    Image out(ImageDesc::packed(PixelFormat::kIR16, d.width, d.height));
    const ImageView in = rgb.view();
    const MutableImageView view = out.mutableView();
    for (int y = 0; y < d.height; ++y) {
        const uint8_t* src = in.row<uint8_t>(y);
        auto* dst = view.row<uint16_t>(y);
        for (int x = 0; x < d.width; ++x) {
            const float lum = 0.2126f * optics::srgbToLinear(src[3 * x] / 255.f) +
                              0.7152f * optics::srgbToLinear(src[3 * x + 1] / 255.f) +
                              0.0722f * optics::srgbToLinear(src[3 * x + 2] / 255.f);
            dst[x] = static_cast<uint16_t>(std::min(1023.f, std::round(1000.f * lum)));
        }
    }
    return out;
}

}  // namespace mixray::render::detail
