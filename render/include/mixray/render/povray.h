// The same frame rendered by POV-Ray 3.7, the ray tracer people know: a scene written as a
// POV-Ray scene file for one camera view, Debian's `povray` run on it, and its statistics
// read. `mixray bench render --peer povray` measures the renderer against it on the identical
// scene, and the tests hold the two images alike.
//
// Only what both renderers compute the same way is written, so that the two images differ by
// sampling and floating point alone:
// - shapes: meshes, spheres, boxes, planes and disks (the last three as meshes);
// - materials: diffuse with RT²AR reflectance (POV-Ray's `diffuse` (1 − ρ)/π and
//   `reflection` ρ) and mirrors; Phong, metal and glass are refused (POV-Ray's highlight and
//   Fresnel are other formulas), as are textures and reflectance maps;
// - lights: point lights (the inverse-square fall-off as POV-Ray's `fade_power 2` with a
//   fade distance of 1 µm) and directional ones; spherical and environment lights are refused;
// - paths past max_depth: black, as POV-Ray past max_trace_level, where mixray is told so
//   (RenderOptions::cut_paths_see_environment off).
// Ghosts are written as ordinary objects: POV-Ray renders the whole modelled scene, which
// mixray renders with RenderOptions::only_virtual_footprint off and every object virtual.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/render/scene.h"

namespace mixray::render {

// One frame as POV-Ray renders it: a pinhole camera (no distortion) at a pose, 1 ray per pixel
// through the pixel's centre.
struct PovrayView {
    calibration::CameraModel camera;
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    int max_depth = 3;    // secondary bounces, as RenderOptions::max_depth
    bool shadows = true;  // false: shadowless lights, as RenderOptions::shadows
};

// The scene file. Objects must be anchored to "world". kUnsupported names the first thing
// POV-Ray would render differently (see above); kInvalidArgument for a camera that is not a
// pinhole; mesh files that do not load give their own error.
Result<std::string> povrayScene(const SceneDescription& scene, const PovrayView& view);

// What POV-Ray says about a render on its statistics stream.
struct PovrayStats {
    double parse_s = 0;  // parsing the scene file
    double trace_s = 0;  // tracing the image
    uint64_t pixels = 0;
    uint64_t rays = 0;         // camera and reflected rays ("Rays:")
    uint64_t shadow_rays = 0;  // "Shadow Ray Tests:"
    int threads = 0;           // the trace's
};

// Reads POV-Ray 3.7's statistics text. kCorruptData when the trace time or the ray count is
// missing or malformed (a render that did not finish).
Result<PovrayStats> parsePovrayStats(std::string_view text);

struct PovrayRender {
    Image image;  // rgb8, sRGB-encoded (POV-Ray's PNG with assumed_gamma 1.0)
    PovrayStats stats;
    double wall_s = 0;  // the povray process, start to end
};

// Runs `povray` (found on PATH) on `scene_text` with `threads` render threads, no
// antialiasing, in `work_dir` (which must exist; scene.pov and scene.png are left there).
// kNotFound when POV-Ray is not installed (with how to install it), kIoError naming its
// last lines when it fails.
Result<PovrayRender> renderWithPovray(const std::string& scene_text, int width, int height,
                                      int threads, const std::filesystem::path& work_dir);

}  // namespace mixray::render
