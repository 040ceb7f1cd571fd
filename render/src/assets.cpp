// Meshes from files (assimp) and analytic shapes tessellated into triangle meshes (assets.h).
#include "mixray/render/assets.h"

#include <assimp/material.h>
#include <assimp/mesh.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/version.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>

namespace mixray::render {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Fills in unit normals where a vertex has none usable (zero, NaN) from the area-weighted
// normals of its triangles; a file's own normals are kept where they are fine.
void repairNormals(TriangleMesh& mesh) {
    const size_t n = mesh.positions.size();
    if (mesh.normals.size() != n)
        mesh.normals.assign(n, Eigen::Vector3f::Zero());
    std::vector<char> bad(n, 0);
    bool any_bad = false;
    for (size_t i = 0; i < n; ++i) {
        const float length = mesh.normals[i].norm();
        if (!std::isfinite(length) || length < 1e-12f) {
            bad[i] = 1;
            any_bad = true;
        } else {
            mesh.normals[i] /= length;
        }
    }
    if (!any_bad)
        return;
    std::vector<Eigen::Vector3f> accumulated(n, Eigen::Vector3f::Zero());
    for (const auto& t : mesh.triangles) {
        // The cross product's length is twice the area: larger faces weigh more.
        const Eigen::Vector3f face = (mesh.positions[t[1]] - mesh.positions[t[0]])
                                         .cross(mesh.positions[t[2]] - mesh.positions[t[0]]);
        for (uint32_t v : t)
            accumulated[v] += face;
    }
    for (size_t i = 0; i < n; ++i) {
        if (!bad[i])
            continue;
        const float length = accumulated[i].norm();
        mesh.normals[i] = length > 0 && std::isfinite(length)
                              ? Eigen::Vector3f(accumulated[i] / length)
                              : Eigen::Vector3f::UnitZ();
    }
}

// A texture path from a material, resolved against the model's folder. Embedded textures
// ("*0") have no file of their own and give an empty path.
std::filesystem::path resolveTexturePath(const aiString& texture,
                                         const std::filesystem::path& model_dir) {
    std::string name = texture.C_Str();
    if (name.empty() || name[0] == '*')
        return {};
    // Models written on Windows use backslashes.
    std::replace(name.begin(), name.end(), '\\', '/');
    const std::filesystem::path path(name);
    if (path.is_absolute())
        return path.lexically_normal();
    return (model_dir / path).lexically_normal();
}

MeshMaterialHint materialHint(const aiMaterial& material, const std::filesystem::path& dir) {
    MeshMaterialHint hint;
    // assimp adds this material to files that have none: keep our defaults then.
    if (material.GetName() == aiString(AI_DEFAULT_MATERIAL_NAME))
        return hint;
    aiColor4D colour;
    if (material.Get(AI_MATKEY_BASE_COLOR, colour) == AI_SUCCESS ||
        material.Get(AI_MATKEY_COLOR_DIFFUSE, colour) == AI_SUCCESS) {
        const Rgb rgb(colour.r, colour.g, colour.b);
        if (rgb.allFinite())
            hint.base_color = rgb.cwiseMax(0.0f);
    }
    for (aiTextureType type : {aiTextureType_BASE_COLOR, aiTextureType_DIFFUSE}) {
        aiString texture;
        if (material.GetTextureCount(type) > 0 &&
            material.GetTexture(type, 0, &texture) == AI_SUCCESS) {
            hint.base_color_texture = resolveTexturePath(texture, dir);
            if (!hint.base_color_texture.empty())
                break;
        }
    }
    float value = 0;
    if (material.Get(AI_MATKEY_METALLIC_FACTOR, value) == AI_SUCCESS && std::isfinite(value)) {
        hint.metallic = std::clamp(value, 0.0f, 1.0f);
    }
    if (material.Get(AI_MATKEY_ROUGHNESS_FACTOR, value) == AI_SUCCESS && std::isfinite(value)) {
        hint.roughness = std::clamp(value, 0.0f, 1.0f);
    }
    return hint;
}

// Copies the triangles of one assimp mesh; points and lines are dropped.
TriangleMesh convertMesh(const aiMesh& in, float scale) {
    TriangleMesh mesh;
    mesh.positions.reserve(in.mNumVertices);
    for (unsigned i = 0; i < in.mNumVertices; ++i) {
        const aiVector3D& p = in.mVertices[i];
        mesh.positions.emplace_back(p.x * scale, p.y * scale, p.z * scale);
    }
    if (in.HasNormals()) {
        mesh.normals.reserve(in.mNumVertices);
        for (unsigned i = 0; i < in.mNumVertices; ++i) {
            const aiVector3D& n = in.mNormals[i];
            mesh.normals.emplace_back(n.x, n.y, n.z);
        }
    }
    if (in.HasTextureCoords(0)) {
        mesh.uvs.reserve(in.mNumVertices);
        for (unsigned i = 0; i < in.mNumVertices; ++i) {
            const aiVector3D& t = in.mTextureCoords[0][i];
            mesh.uvs.emplace_back(t.x, t.y);
        }
    }
    mesh.triangles.reserve(in.mNumFaces);
    for (unsigned f = 0; f < in.mNumFaces; ++f) {
        const aiFace& face = in.mFaces[f];
        if (face.mNumIndices != 3)
            continue;
        const uint32_t a = face.mIndices[0], b = face.mIndices[1], c = face.mIndices[2];
        if (a >= in.mNumVertices || b >= in.mNumVertices || c >= in.mNumVertices)
            continue;
        mesh.triangles.push_back({a, b, c});
    }
    repairNormals(mesh);
    return mesh;
}

// ---- analytic shapes ----

void addQuad(TriangleMesh& mesh, const Eigen::Vector3f& centre, const Eigen::Vector3f& right,
             const Eigen::Vector3f& up) {
    // Corners counter-clockwise seen from the side `right × up` points to.
    const auto base = static_cast<uint32_t>(mesh.positions.size());
    const Eigen::Vector3f normal = right.cross(up).normalized();
    const Eigen::Vector3f corners[4] = {centre - right - up, centre + right - up,
                                        centre + right + up, centre - right + up};
    // v = 0 at the top edge (the +up side), as textures expect.
    const Eigen::Vector2f uvs[4] = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
    for (int i = 0; i < 4; ++i) {
        mesh.positions.push_back(corners[i]);
        mesh.normals.push_back(normal);
        mesh.uvs.push_back(uvs[i]);
    }
    mesh.triangles.push_back({base, base + 1, base + 2});
    mesh.triangles.push_back({base, base + 2, base + 3});
}

TriangleMesh makeBox(const Eigen::Vector3f& size) {
    TriangleMesh mesh;
    const Eigen::Vector3f h = 0.5f * size;
    const Eigen::Vector3f x(h.x(), 0, 0), y(0, h.y(), 0), z(0, 0, h.z());
    addQuad(mesh, x, y, z);    // +x face: y × z = +x
    addQuad(mesh, -x, -y, z);  // -x face: (-y) × z = -x
    addQuad(mesh, y, z, x);    // +y face: z × x = +y
    addQuad(mesh, -y, -z, x);  // -y face
    addQuad(mesh, z, x, y);    // +z face: x × y = +z
    addQuad(mesh, -z, -x, y);  // -z face
    return mesh;
}

TriangleMesh makePlane(const Eigen::Vector3f& size) {
    TriangleMesh mesh;
    addQuad(mesh, Eigen::Vector3f::Zero(), Eigen::Vector3f(0.5f * size.x(), 0, 0),
            Eigen::Vector3f(0, 0.5f * size.y(), 0));
    return mesh;
}

TriangleMesh makeDisk(float radius, int segments) {
    TriangleMesh mesh;
    // Planar uv over the disk's bounding square, v = 0 at +y like the plane.
    mesh.positions.emplace_back(0, 0, 0);
    mesh.normals.emplace_back(0, 0, 1);
    mesh.uvs.emplace_back(0.5f, 0.5f);
    for (int i = 0; i < segments; ++i) {
        const float phi = 2 * kPi * static_cast<float>(i) / static_cast<float>(segments);
        const float c = std::cos(phi), s = std::sin(phi);
        mesh.positions.emplace_back(radius * c, radius * s, 0);
        mesh.normals.emplace_back(0, 0, 1);
        mesh.uvs.emplace_back(0.5f + 0.5f * c, 0.5f - 0.5f * s);
    }
    for (int i = 0; i < segments; ++i) {
        const auto a = static_cast<uint32_t>(1 + i);
        const auto b = static_cast<uint32_t>(1 + (i + 1) % segments);
        mesh.triangles.push_back({0, a, b});
    }
    return mesh;
}

TriangleMesh makeSphere(float radius, int segments) {
    TriangleMesh mesh;
    const int rings = std::max(2, segments / 2);
    // A seam column is duplicated (u = 0 and u = 1) so uvs do not jump across it; the poles
    // are rows of coincident vertices, one per column, each with its own u.
    for (int r = 0; r <= rings; ++r) {
        const float v = static_cast<float>(r) / static_cast<float>(rings);
        const float theta = v * kPi;
        for (int s = 0; s <= segments; ++s) {
            const float u = static_cast<float>(s) / static_cast<float>(segments);
            const float phi = u * 2 * kPi;
            const Eigen::Vector3f n(std::sin(theta) * std::cos(phi),
                                    std::sin(theta) * std::sin(phi), std::cos(theta));
            mesh.positions.push_back(radius * n);
            mesh.normals.push_back(n);
            mesh.uvs.emplace_back(u, v);
        }
    }
    const auto stride = static_cast<uint32_t>(segments + 1);
    for (int r = 0; r < rings; ++r) {
        for (int s = 0; s < segments; ++s) {
            const uint32_t a = static_cast<uint32_t>(r) * stride + static_cast<uint32_t>(s);
            const uint32_t b = a + 1;
            const uint32_t c = a + stride;
            const uint32_t d = c + 1;
            // Rows run from +z down; columns grow with φ (counter-clockwise about +z): (a, c, d)
            // winds counter-clockwise seen from outside. Pole triangles would be degenerate.
            if (r > 0)
                mesh.triangles.push_back({a, c, b});
            if (r < rings - 1)
                mesh.triangles.push_back({b, c, d});
        }
    }
    return mesh;
}

}  // namespace

MeshCacheSettings MeshCacheSettings::fromEnvironment() {
    MeshCacheSettings settings;
    const char* chosen = std::getenv("MIXRAY_MESH_CACHE");
    if (chosen != nullptr && *chosen != '\0') {
        if (std::string_view(chosen) != "off")
            settings.dir = chosen;
        return settings;
    }
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && *xdg == '/')
        settings.dir = std::filesystem::path(xdg) / "mixray" / "meshes";
    else if (const char* home = std::getenv("HOME"); home != nullptr && *home == '/')
        settings.dir = std::filesystem::path(home) / ".cache" / "mixray" / "meshes";
    return settings;
}

namespace {

// The import's flags: the cache holds a scene imported with them, and its entries change name
// when they do.
constexpr unsigned kImportFlags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                                  aiProcess_GenSmoothNormals | aiProcess_PreTransformVertices |
                                  aiProcess_SortByPType | aiProcess_FlipUVs |
                                  aiProcess_ValidateDataStructure;

// The cache entry of `path` as it is now (its size and modification time, the import's flags
// and assimp's version in the name), or none when the file is small or there is no cache.
std::optional<std::filesystem::path> meshCacheEntry(const std::filesystem::path& path,
                                                    const MeshCacheSettings& cache) {
    std::error_code ec;
    if (cache.dir.empty())
        return std::nullopt;
    // Only formats that hold the whole mesh in one file: an OBJ's .mtl or a glTF's buffers
    // could change without the key seeing it.
    std::string extension = path.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (extension != ".ply" && extension != ".stl" && extension != ".glb")
        return std::nullopt;
    const uintmax_t bytes = std::filesystem::file_size(path, ec);
    if (ec || bytes < cache.min_file_bytes)
        return std::nullopt;
    const auto modified = std::filesystem::last_write_time(path, ec);
    if (ec)
        return std::nullopt;
    const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
    const std::string key =
        absolute.string() + '|' + std::to_string(bytes) + '|' +
        std::to_string(modified.time_since_epoch().count()) + '|' + std::to_string(kImportFlags) +
        '|' + std::to_string(aiGetVersionMajor()) + '.' + std::to_string(aiGetVersionMinor()) +
        '.' + std::to_string(aiGetVersionRevision());
    uint64_t hash = 1469598103934665603ull;  // FNV-1a: stable across runs and builds
    for (unsigned char c : key)
        hash = (hash ^ c) * 1099511628211ull;
    char name[32];
    std::snprintf(name, sizeof name, "-%016llx.assbin", static_cast<unsigned long long>(hash));
    return cache.dir / (path.stem().string() + name);
}

// Whether `entry` starts as assimp's binary dumps do. Assimp 5.2 leaks the file it opened when
// it rejects a file with another header, so such an entry is not given to it.
bool hasAssbinHeader(const std::filesystem::path& entry) {
    static constexpr std::string_view kMagic = "ASSIMP.binary-dump.";
    std::ifstream file(entry, std::ios::binary);
    std::string head(kMagic.size(), '\0');
    return file.read(head.data(), static_cast<std::streamsize>(head.size())) && head == kMagic;
}

// Writes the imported scene as the cache entry: to a temporary name, then renamed, so that a
// reader never sees half an entry.
void writeMeshCacheEntry(const aiScene& scene, const std::filesystem::path& entry) {
    std::error_code ec;
    std::filesystem::create_directories(entry.parent_path(), ec);
    const std::filesystem::path partial =
        entry.string() + ".partial-" + std::to_string(static_cast<long>(getpid()));
    Assimp::Exporter exporter;
    if (exporter.Export(&scene, "assbin", partial.string()) == aiReturn_SUCCESS)
        std::filesystem::rename(partial, entry, ec);
    std::filesystem::remove(partial, ec);
}

}  // namespace

Result<std::vector<LoadedMesh>> loadMeshFile(const std::filesystem::path& path, float scale) {
    return loadMeshFile(path, scale, MeshCacheSettings::fromEnvironment());
}

Result<std::vector<LoadedMesh>> loadMeshFile(const std::filesystem::path& path, float scale,
                                             const MeshCacheSettings& cache) {
    if (!std::isfinite(scale) || scale <= 0) {
        return Result<std::vector<LoadedMesh>>(
            ErrorCode::kInvalidArgument,
            path.string() + ": mesh scale must be finite and > 0, got " + std::to_string(scale));
    }
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
        return Result<std::vector<LoadedMesh>>(ErrorCode::kNotFound,
                                               "mesh file not found: " + path.string());
    }
    if (std::filesystem::is_directory(path, ec)) {
        return Result<std::vector<LoadedMesh>>(ErrorCode::kInvalidArgument,
                                               "mesh path is a directory: " + path.string());
    }
    try {
        Assimp::Importer importer;
        const auto complete = [](const aiScene* scene) {
            return scene != nullptr && !(scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) &&
                   scene->mRootNode != nullptr;
        };
        const std::optional<std::filesystem::path> entry = meshCacheEntry(path, cache);
        const aiScene* scene = nullptr;
        if (entry && hasAssbinHeader(*entry)) {
            // Imported and post-processed already: only checked. An entry that does not read
            // is imported again from the file.
            try {
                scene = importer.ReadFile(entry->string(), aiProcess_ValidateDataStructure);
            } catch (const std::exception&) {
                scene = nullptr;
            }
            if (!complete(scene))
                scene = nullptr;
        }
        if (scene == nullptr) {
            // Points and lines have no surface to trace.
            importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE,
                                        aiPrimitiveType_POINT | aiPrimitiveType_LINE);
            // FlipUVs turns assimp's bottom-left uv origin into the top-left one textures use.
            scene = importer.ReadFile(path.string(), kImportFlags);
            if (!complete(scene)) {
                return Result<std::vector<LoadedMesh>>(
                    ErrorCode::kCorruptData,
                    path.string() + ": cannot read mesh: " + importer.GetErrorString());
            }
            if (entry)
                writeMeshCacheEntry(*scene, *entry);
        }
        const std::filesystem::path dir = path.parent_path();
        std::vector<LoadedMesh> meshes;
        for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
            const aiMesh* in = scene->mMeshes[m];
            if (!in || !(in->mPrimitiveTypes & aiPrimitiveType_TRIANGLE))
                continue;
            LoadedMesh loaded;
            loaded.mesh = convertMesh(*in, scale);
            if (loaded.mesh.empty())
                continue;
            if (in->mMaterialIndex < scene->mNumMaterials) {
                loaded.material = materialHint(*scene->mMaterials[in->mMaterialIndex], dir);
            }
            meshes.push_back(std::move(loaded));
        }
        if (meshes.empty()) {
            return Result<std::vector<LoadedMesh>>(
                ErrorCode::kCorruptData, path.string() + ": mesh file holds no triangles");
        }
        return meshes;
    } catch (const std::exception& e) {
        return Result<std::vector<LoadedMesh>>(ErrorCode::kCorruptData,
                                               path.string() + ": cannot read mesh: " + e.what());
    } catch (...) {
        return Result<std::vector<LoadedMesh>>(ErrorCode::kCorruptData,
                                               path.string() + ": cannot read mesh: unknown error");
    }
}

TriangleMesh makeShapeMesh(const Shape& shape, int segments) {
    segments = std::max(segments, 3);
    switch (shape.type) {
        case ShapeType::kBox:
            return makeBox(shape.size);
        case ShapeType::kPlane:
            return makePlane(shape.size);
        case ShapeType::kDisk:
            return makeDisk(shape.radius, segments);
        case ShapeType::kSphere:
            return makeSphere(shape.radius, std::max(segments, 4));
        case ShapeType::kMesh:
            // A mesh shape's triangles come from its file: loadMeshFile().
            return {};
    }
    return {};
}

}  // namespace mixray::render
