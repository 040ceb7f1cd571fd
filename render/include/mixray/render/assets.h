// Geometry, textures and environment maps loaded from files (assimp, OpenCV, OpenEXR) into
// plain structs the Renderer builds its Embree scene from.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "mixray/graph/result.h"
#include "mixray/render/scene.h"

namespace mixray::render {

// An indexed triangle mesh in its own frame. normals and uvs are empty or one per position.
// Plain value.
struct TriangleMesh {
    std::vector<Eigen::Vector3f> positions;
    std::vector<Eigen::Vector3f> normals;  // unit, per vertex (smooth shading)
    std::vector<Eigen::Vector2f> uvs;
    std::vector<std::array<uint32_t, 3>> triangles;  // counter-clockwise seen from outside

    bool empty() const { return triangles.empty(); }
};

// What a mesh file says about its own material, for scenes that do not override it.
struct MeshMaterialHint {
    Rgb base_color{0.8f, 0.8f, 0.8f};
    std::filesystem::path base_color_texture;  // resolved against the file's folder; may be empty
    float metallic = 0;
    float roughness = 1;
};

struct LoadedMesh {
    TriangleMesh mesh;
    MeshMaterialHint material;
};

// Where loadMeshFile() keeps big meshes as assimp imported them, in assimp's own binary format
// (assbin), so that the next load skips the import's post-processing: joining a scanned
// model's identical vertices is most of its import (2.4 s of 2.7 s for a 1.1M-triangle PLY;
// the assbin reads in 0.3 s). Only formats that hold a whole mesh in one file (PLY, STL, GLB)
// are kept, each entry for one file at one size and modification time; a cache that cannot be
// written or read is passed by, never an error.
struct MeshCacheSettings {
    std::filesystem::path dir;            // empty: no cache
    uintmax_t min_file_bytes = 8u << 20;  // smaller files import fast enough

    // MIXRAY_MESH_CACHE: a folder, or "off"; unset: $XDG_CACHE_HOME/mixray/meshes, else
    // ~/.cache/mixray/meshes.
    static MeshCacheSettings fromEnvironment();
};

// Loads every mesh of an OBJ, PLY or glTF 2.0 file (assimp), triangulated, with the file's
// node transforms applied and `scale` multiplied in. Vertex normals are computed when the file
// has none. kNotFound for a missing file; kCorruptData naming the file for one assimp cannot
// read or that holds no triangles. Big files go through the mesh cache of
// MeshCacheSettings::fromEnvironment().
Result<std::vector<LoadedMesh>> loadMeshFile(const std::filesystem::path& path, float scale = 1);
Result<std::vector<LoadedMesh>> loadMeshFile(const std::filesystem::path& path, float scale,
                                             const MeshCacheSettings& cache);

// The mesh of an analytic shape (box, plane, disk, and a sphere tessellated with `segments`
// around — the Renderer traces kSphere exactly and uses this only for shadow maps and
// simulators).
TriangleMesh makeShapeMesh(const Shape& shape, int segments = 64);

// An RGB(A) float image in linear light, sampled with bilinear filtering and wrapping in u.
// Plain value; const methods are reentrant.
class Texture {
public:
    Texture() = default;
    Texture(int width, int height, std::vector<Rgb> texels);

    // PNG/JPEG/TIFF (sRGB-encoded, converted to linear) or HDR/EXR (already linear).
    static Result<Texture> load(const std::filesystem::path& path);

    int width() const { return width_; }
    int height() const { return height_; }
    bool empty() const { return texels_.empty(); }
    const Rgb& texel(int x, int y) const { return texels_[static_cast<size_t>(y) * width_ + x]; }
    // uv in [0,1]^2, v = 0 at the top row (glTF/OpenCV convention); u wraps, v clamps.
    Rgb sample(const Eigen::Vector2f& uv) const;

private:
    int width_ = 0;
    int height_ = 0;
    std::vector<Rgb> texels_;
};

// An equirectangular (latitude-longitude) environment map in linear radiance.
//
// Direction convention, in the environment frame (+z up, docs/conventions.md world frame):
// u = 0.5 − atan2(d.y, d.x) / (2π) across the image (+x at the centre column; u grows from +x
// towards −y, so the panorama reads unmirrored from inside, as in Blender and OpenEXR),
// v = acos(d.z) / π down the image (v = 0 straight up). The synthetic OrientationLatLong.exr
// in ../shared/data checks this against OpenEXR's own convention in the tests: OpenEXR's
// (X, Y, Z) with Y up is this frame's (y, z, x) — a rotation, not a mirror.
class EnvironmentMap {
public:
    EnvironmentMap() = default;
    explicit EnvironmentMap(Texture texture) : texture_(std::move(texture)) {}

    // .hdr (Radiance RGBE) or .exr (any compression OpenEXR reads, DWAB included).
    static Result<EnvironmentMap> load(const std::filesystem::path& path);

    bool empty() const { return texture_.empty(); }
    const Texture& texture() const { return texture_; }
    // Radiance arriving from direction `d` (unit, environment frame), bilinear.
    Rgb radiance(const Eigen::Vector3f& d) const;
    // Pixel centre of a direction and back (for tests and the fish-eye map builder).
    Eigen::Vector2f pixelOf(const Eigen::Vector3f& d) const;
    Eigen::Vector3f directionOf(const Eigen::Vector2f& pixel) const;
    // Replaces the lower hemisphere (v > 0.5) by the mirror image of the upper one, for maps
    // from a fish-eye camera that sees only the upper half.
    void mirrorUpperIntoLower();

private:
    Texture texture_;
};

}  // namespace mixray::render
