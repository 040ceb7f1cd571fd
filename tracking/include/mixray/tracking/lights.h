// Real light estimation: from a light-probe sphere in the camera image (de Castro, de
// Figueiredo, Velho 2012, "Realistic Shadows for Mobile AR", §3), from the fish-eye environment
// camera (Kán & Kaufmann 2012, §5), and an equirectangular environment map from the fish-eye
// image. Directions are in the world (marker) frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"
#include "mixray/tracking/estimate.h"

namespace mixray::tracking {

enum class ProbeMaterial : uint8_t { kMirror, kDiffuse };

// A light-probe sphere of known radius at a known place in the world (marker) frame. Plain
// value.
struct LightProbe {
    std::string name;
    ProbeMaterial material = ProbeMaterial::kMirror;
    double radius_m = 0.04;
    Eigen::Vector3d centre_world{0, 0, 0.04};
    double albedo = 0.8;  // kDiffuse: grey diffuse reflectance (gives lights' strengths)

    Status validate() const;
};

// Where the probe's image is sampled (the paper's two variants).
enum class ProbeDomain : uint8_t {
    kImage,   // every image pixel inside the probe's projected outline
    kSphere,  // a fixed (u,v) grid over the visible half of the sphere: cost independent of
              // how big the probe appears
};

// Every field has a working default.
struct ProbeOptions {
    ProbeDomain domain = ProbeDomain::kImage;
    int sphere_samples = 128;  // kSphere: samples along u and along v
    int max_lights = 2;        // the n most representative lights returned
    // Luminance counted as the maximum: 8-bit images clip, and a highlight's plateau is a few
    // codes wide after demosaicing and compression.
    double max_luminance_tolerance = 0.02;  // fraction of the full scale
    double min_visible_fraction = 0.6;      // of the outline inside the image, else "out of view"

    Status validate() const;
};

// The probe's outline in the image, for overlays. Plain value.
struct ProbeOutline {
    Eigen::Vector2d centre_px{0, 0};
    double radius_px = 0;
};

struct ProbeResult {
    // Most representative first: strongest fitted light (diffuse), largest highlight (mirror,
    // whose clipped highlights leave size as the only measure of strength). Intensities are
    // relative, the first light's luminance 1.
    std::vector<EstimatedLight> lights;
    ProbeOutline outline;
};

// Lights from one colour image of the probe, given the camera's pose. kNotFound with the reason
// when the probe is out of view, too small or shows no highlight (a black or flat image);
// kInvalidArgument for a bad probe, options or pixel format (kRGB8, kBGR8, kMono8). Reentrant.
Result<ProbeResult> estimateProbeLights(const ImageView& color,
                                        const calibration::CameraModel& camera,
                                        const Eigen::Isometry3d& T_world_camera,
                                        const LightProbe& probe, const ProbeOptions& options = {});

// The fish-eye environment camera and where it sits. Plain value.
struct EnvironmentCamera {
    calibration::CameraModel model;  // usually LensModel::kFisheye
    Eigen::Isometry3d T_world_env = Eigen::Isometry3d::Identity();
    // Lights are placed this far from the environment camera (Kán & Kaufmann: the room's
    // size); 0: directional lights only.
    double room_radius_m = 0;
    // The image's response: linear radiance = (sRGB-decoded value) * exposure_scale.
    double exposure_scale = 1;

    Status validate() const;
};

// Every field has a working default.
struct EnvironmentLightOptions {
    double threshold = 0.9;  // blob threshold, fraction of the full scale (after decoding)
    int max_lights = 4;      // biggest blobs kept
    double min_area_px = 4;  // smaller blobs are noise
    double max_saturated_fraction = 0.25;  // more of the image clipped: over-exposed
    double min_mean = 0.01;                // mean below this (fraction of full scale): black

    Status validate() const;
};

// Lights from one environment image. kNotFound with the reason for an over-exposed, black or
// featureless image; kInvalidArgument for bad inputs. Reentrant.
Result<std::vector<EstimatedLight>> estimateEnvironmentLights(
    const ImageView& env, const EnvironmentCamera& camera,
    const EnvironmentLightOptions& options = {});

// An equirectangular environment map (linear RGB, `width` x width/2, the renderer's
// convention: render::EnvironmentMap, u = 0.5 − atan2(d.y, d.x)/2π, v = acos(d.z)/π) in the
// world frame from one fish-eye image. The lower hemisphere is the mirror image of the upper
// (row y equals row height−1−y, as EnvironmentMap::mirrorUpperIntoLower() makes it); upper
// directions outside the lens's view take the nearest seen value in their column.
// kInvalidArgument for bad inputs (width: even, 16 to 8192). Reentrant.
Result<FloatImage> environmentMapFromFisheye(const ImageView& env, const EnvironmentCamera& camera,
                                             int width = 512);

// Everything estimated from one environment frame.
// The map is shared and immutable: estimates are copied to every frame that reads them.
struct EnvironmentEstimate {
    std::vector<EstimatedLight> lights;
    std::shared_ptr<const FloatImage> environment_map;
};

// Environment lights and map from one fish-eye image after another, each estimate keeping the
// last good value when an image gives none. EnvironmentLightNode (environment_light_node.h)
// runs it in the device graph, on a thread of its own. Thread-bound.
class EnvironmentEstimator {
public:
    EnvironmentEstimator(EnvironmentCamera camera, EnvironmentLightOptions options = {},
                         int map_width = 512);
    ~EnvironmentEstimator();
    EnvironmentEstimator(const EnvironmentEstimator&) = delete;
    EnvironmentEstimator& operator=(const EnvironmentEstimator&) = delete;

    // Estimates from the image at `stamp_ns` (fresh, or stale with the reason when the image
    // gives none: over-exposed, black, a wrong pixel format, a camera the lens cannot map).
    const Estimate<EnvironmentEstimate>& estimate(const ImageView& env, int64_t stamp_ns);
    const Estimate<EnvironmentEstimate>& latest() const { return latest_; }

private:
    struct Geometry;
    EnvironmentCamera camera_;
    EnvironmentLightOptions options_;
    int map_width_ = 512;
    // Built on the first image: the lens unprojection of every pixel is the costly part.
    std::unique_ptr<Geometry> geometry_;
    Estimate<EnvironmentEstimate> latest_;
};

}  // namespace mixray::tracking
