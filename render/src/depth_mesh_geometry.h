// The depth camera's surface in Embree: a dynamic prototype scene rebuilt every frame from the
// depth mesh, over buffers that persist between frames.
#pragma once

#include <embree3/rtcore.h>

#include <cstdint>
#include <vector>

#include "mixray/render/assets.h"

namespace mixray::render::detail {

// One triangle geometry (camera frame) in its own scene, built with RTC_BUILD_QUALITY_LOW and
// RTC_SCENE_FLAG_DYNAMIC (a Kinect mesh changes completely every frame, so a fast build beats a
// good BVH) and RTC_SCENE_FLAG_ROBUST (watertight). The vertex and index buffers are shared with
// Embree and owned here; they grow only when a frame needs more room than any before. Thread-bound:
// update() must not run while rays are traced through scene().
class DepthMeshGeometry {
public:
    explicit DepthMeshGeometry(RTCDevice device);
    ~DepthMeshGeometry();
    DepthMeshGeometry(const DepthMeshGeometry&) = delete;
    DepthMeshGeometry& operator=(const DepthMeshGeometry&) = delete;

    // The prototype to instance; owned here.
    RTCScene scene() const { return scene_; }

    // Copies the mesh's positions and triangles into the shared buffers and rebuilds the BVH.
    // An empty mesh disables the geometry. Returns false when the buffers had to grow (the
    // first frames), true when the frame reused them.
    bool update(const TriangleMesh& mesh);

private:
    RTCScene scene_ = nullptr;
    RTCGeometry geometry_ = nullptr;
    std::vector<float> vertices_;    // x, y, z per vertex and one float more: Embree loads 16 B
    std::vector<uint32_t> indices_;  // three per triangle
    bool attached_ = false;
    bool enabled_ = true;
};

}  // namespace mixray::render::detail
