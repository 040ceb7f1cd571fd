// The Renderer's options and ray log (mixray/render/renderer.h). The renderer itself:
// embree_renderer.h (the frame loop), frame_setup.cpp, camera_rays.h, integrator.h,
// shadow_rays.h, film.h and scene_loading.cpp (Renderer::create).
#include "mixray/render/renderer.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "embree_scene.h"

namespace mixray::render {

Status RenderOptions::validate() const {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "render options: " + what);
    };
    if (max_depth < 0 || max_depth > 64)
        return bad("max_depth must be in [0, 64]");
    const int root = static_cast<int>(std::lround(std::sqrt(std::max(samples_per_pixel, 0))));
    if (samples_per_pixel < 1 || samples_per_pixel > 256 || root * root != samples_per_pixel)
        return bad("samples_per_pixel must be a square number in [1, 256]");
    if (shadow_samples < 1 || shadow_samples > 1024)
        return bad("shadow_samples must be in [1, 1024]");
    if (!(depth_ghost_agreement >= 0 && depth_ghost_agreement < 0.5f))
        return bad("depth_ghost_agreement must be in [0, 0.5)");
    if (!std::isfinite(depth_thickness_m) || depth_thickness_m <= 0)
        return bad("depth_thickness_m must be positive and finite");
    if (threads < 0)
        return bad("threads must be >= 0");
    if (tile_size < 1 || tile_size > 1024)
        return bad("tile_size must be in [1, 1024]");
    if (!embree_isa.empty() &&
        std::none_of(std::begin(detail::kEmbreeIsaNames), std::end(detail::kEmbreeIsaNames),
                     [&](const char* name) { return embree_isa == name; }))
        return bad("embree_isa '" + embree_isa +
                   "' is none of sse2, sse4.2, avx, avx2, avx512 (or empty: the best)");
    return Status::ok();
}

RenderInputs::ShutterPoses shutterFromMotion(const Eigen::Isometry3d& T_world_cam_before,
                                             const Eigen::Isometry3d& T_world_cam,
                                             double frame_interval_s, double exposure_s) {
    // The motion between the frames in the camera's frame, as a turn and a travel, taken as
    // uniform: a fraction s of it is the turn's angle times s and the travel times s (exact for
    // a pure turn or a pure travel, first order for both).
    const Eigen::Isometry3d step = T_world_cam_before.inverse() * T_world_cam;
    const Eigen::AngleAxisd turn(step.linear());
    const double s = exposure_s / (2 * frame_interval_s);
    const auto part = [&](double fraction) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = Eigen::AngleAxisd(fraction * turn.angle(), turn.axis()).toRotationMatrix();
        T.translation() = fraction * step.translation();
        return T;
    };
    return {T_world_cam * part(-s), T_world_cam * part(s)};
}

}  // namespace mixray::render
