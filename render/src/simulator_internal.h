// Internals shared by the simulator's sources: the scenario setup, its Embree geometry for
// depth, and the sensor models (background views, Kinect depth, IR).
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <memory>
#include <vector>

#include "embree_scene.h"
#include "mixray/render/assets.h"
#include "mixray/render/simulator.h"

namespace mixray::render::detail {

// A scenario's truth plus what rendering it needs beyond the truth.
struct SimSetup {
    SimTruth truth;
    EnvironmentMap environment;
};

// Builds the scenario and writes its textures and environment map into `assets`.
Result<SimSetup> buildScenario(const SimulatorOptions& options,
                               const std::filesystem::path& assets);

// The scene's objects in Embree, for tracing depth rays (the geometry the renderer shades).
class SimGeometry {
public:
    static Result<std::unique_ptr<SimGeometry>> build(const SceneDescription& scene);

    struct SurfaceHit {
        bool valid = false;
        float t = 0;
        Eigen::Vector3f p = Eigen::Vector3f::Zero();
        Eigen::Vector3f n = Eigen::Vector3f::Zero();  // geometric normal, unit
    };
    SurfaceHit intersect(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir) const;
    bool occluded(const Eigen::Vector3f& origin, const Eigen::Vector3f& dir, float t_far) const;

private:
    std::vector<ObjectData> objects_;
    std::unique_ptr<EmbreeScene> scene_;
};

// Unit ray directions (camera frame) through an n x n grid of points in every pixel (n = 1:
// the pixel centre), pixel by pixel; NaN where unproject fails.
std::vector<Eigen::Vector3f> pixelRays(const calibration::CameraModel& model, int n = 1);

// The environment map as the camera sees it along `rays` (pixelRays with n x n samples,
// averaged in linear light), rgb8 sRGB; black where the lens has no ray.
Image environmentView(const EnvironmentMap& map, const calibration::CameraModel& model,
                      const std::vector<Eigen::Vector3f>& rays, int n,
                      const Eigen::Isometry3d& T_world_cam, int threads);

// Kinect depth (docs/simulation.md), registered to the colour camera or aligned with the IR
// camera as truth.depth_registered says; `rays` are that camera's pixel-centre rays.
Result<Image> kinectDepth(const SimTruth& truth, const SimGeometry& geometry,
                          const Eigen::Isometry3d& T_world_color,
                          const std::vector<Eigen::Vector3f>& rays, uint64_t seed, int frame);

// An IR image (ir16, 10-bit like the Kinect's) from a grey render of the IR camera's view.
Image toInfrared(const Image& rgb);

}  // namespace mixray::render::detail
