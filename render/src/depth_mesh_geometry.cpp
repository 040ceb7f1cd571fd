// A dynamic Embree scene over shared, persistent buffers for the per-frame depth mesh.
#include "depth_mesh_geometry.h"

#include <algorithm>
#include <cstring>

namespace mixray::render::detail {

DepthMeshGeometry::DepthMeshGeometry(RTCDevice device) {
    scene_ = rtcNewScene(device);
    // Robust: watertight edges. Camera rays through the centre of a grid cell run exactly along
    // a shared diagonal, and the fast test lets such rays slip between the two triangles.
    rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_LOW);
    geometry_ = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(geometry_, RTC_BUILD_QUALITY_LOW);
    // No triangles yet: an empty, committed scene that instances can refer to. The geometry
    // joins it with its first buffers.
    rtcCommitScene(scene_);
}

DepthMeshGeometry::~DepthMeshGeometry() {
    if (geometry_ != nullptr)
        rtcReleaseGeometry(geometry_);
    if (scene_ != nullptr)
        rtcReleaseScene(scene_);
}

bool DepthMeshGeometry::update(const TriangleMesh& mesh) {
    if (mesh.empty()) {
        if (attached_ && enabled_) {
            rtcDisableGeometry(geometry_);
            enabled_ = false;
        }
        rtcCommitScene(scene_);
        return true;
    }
    const size_t vertex_floats = 3 * mesh.positions.size() + 1;
    const size_t index_count = 3 * mesh.triangles.size();
    const bool reused = vertices_.size() >= vertex_floats && indices_.size() >= index_count;
    // Grown to the mesh's capacity: a DepthMesher reserves the largest mesh of its image size,
    // so the first frame sizes the buffers for all that follow.
    if (vertices_.size() < vertex_floats)
        vertices_.resize(std::max(vertex_floats, 3 * mesh.positions.capacity() + 1));
    if (indices_.size() < index_count)
        indices_.resize(std::max(index_count, 3 * mesh.triangles.capacity()));
    for (size_t i = 0; i < mesh.positions.size(); ++i)
        std::memcpy(vertices_.data() + 3 * i, mesh.positions[i].data(), 3 * sizeof(float));
    for (size_t i = 0; i < mesh.triangles.size(); ++i)
        std::memcpy(indices_.data() + 3 * i, mesh.triangles[i].data(), 3 * sizeof(uint32_t));
    // The item counts change every frame; the memory behind them only when it grew.
    rtcSetSharedGeometryBuffer(geometry_, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                               vertices_.data(), 0, 3 * sizeof(float), mesh.positions.size());
    rtcSetSharedGeometryBuffer(geometry_, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                               indices_.data(), 0, 3 * sizeof(uint32_t), mesh.triangles.size());
    if (!enabled_) {
        rtcEnableGeometry(geometry_);
        enabled_ = true;
    }
    rtcCommitGeometry(geometry_);
    if (!attached_) {
        rtcAttachGeometryByID(scene_, geometry_, 0);
        attached_ = true;
    }
    rtcCommitScene(scene_);
    return reused;
}

}  // namespace mixray::render::detail
