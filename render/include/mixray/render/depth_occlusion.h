// Real surfaces from a Kinect depth map: occlusion of primary rays, RT²AR's screen-space
// traversal for secondary rays (its Algorithm 2), and a triangle mesh of the depth surface.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/graph/image.h"
#include "mixray/render/assets.h"

namespace mixray::render {

// A depth image registered to a camera (same size as camera.width x camera.height): z in
// millimetres along the optical axis, 0 = no measurement. Does not own the pixels.
struct DepthView {
    ImageView depth_mm;  // depth16
    calibration::CameraModel camera;

    // The depth sample at a pixel in metres of z; nullopt for 0 or out of the image.
    std::optional<float> zAt(int x, int y) const;
};

// Distance along the ray through pixel (x, y) to the depth surface: the depth map holds z
// (parallel to the optical axis), a ray travels |p| = z / cos(angle to the axis). nullopt
// where there is no measurement.
std::optional<float> rayDistanceAt(const DepthView& depth, int x, int y);

// RT²AR Algorithm 2, made exact for lens models: walks the image-space projection of the ray
// origin + t·direction (camera frame, metres) from t = 0 to t_max, one pixel step at a time
// along its major axis (a DDA over the projected segment, clipped to the image and to z > 0),
// and returns the first t where the ray passes behind the depth surface by no more than
// `thickness` metres. nullopt when it leaves the image or reaches t_max unblocked.
// "Behind" compares z with the depth surface interpolated between pixel centres (never across
// a silhouette). A hit needs the ray to go from in front of the surface to behind it: a ray
// that starts (or enters the image) already behind it is not blocked there, so offset origins
// on real surfaces off them. `thickness` is at least 1 mm, one depth16 step. Reentrant.
std::optional<float> traceDepthMap(const DepthView& depth, const Eigen::Vector3f& origin_cam,
                                   const Eigen::Vector3f& direction_cam, float t_max,
                                   float thickness);

struct DepthMeshOptions {
    int step = 2;                   // one vertex every `step` pixels
    float max_edge_jump_m = 0.05f;  // no triangle across a depth discontinuity larger than this
                                    // (relative: scaled by z in metres)
};

// A triangle mesh of the depth surface in the camera frame (metres), with per-vertex normals,
// skipping invalid pixels and discontinuities. Rebuilt each frame for Embree's dynamic scene.
// uvs name each vertex's pixel, ((x + 0.5) / width, (y + 0.5) / height), to texture the mesh
// with the registered colour image.
TriangleMesh depthToMesh(const DepthView& depth, const DepthMeshOptions& options = {});

// depthToMesh for a stream of frames: builds into the caller's mesh and keeps its own scratch,
// both sized for the largest mesh of the image size, so frames of one size allocate nothing
// after the first. Thread-bound (one mesher per thread).
class DepthMesher {
public:
    // Replaces `mesh` (same result as depthToMesh); its vectors keep their capacity.
    void build(const DepthView& depth, const DepthMeshOptions& options, TriangleMesh& mesh);

private:
    std::vector<Eigen::Vector3d> points_;  // grid vertices on their pixel rays
    std::vector<double> zs_;               // their z; 0: no point
    std::vector<int64_t> index_;           // grid vertex -> mesh vertex, -1: unused
    std::vector<Eigen::Vector3d> sums_;    // area-weighted face normals per mesh vertex
};

}  // namespace mixray::render
