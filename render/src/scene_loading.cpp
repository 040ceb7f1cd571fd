// Renderer::create(): a scene description loaded (meshes, textures, environment maps) into the
// renderer's materials, objects and lights, and the BVH built.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>

#include "embree_renderer.h"

namespace mixray::render {

using detail::kInf;
using detail::LightData;
using detail::MaterialData;
using detail::ObjectData;
using detail::Vec3;

namespace {

std::filesystem::path resolve(const SceneDescription& scene, const std::filesystem::path& p) {
    if (p.empty() || p.is_absolute() || scene.source_path.empty())
        return p;
    return scene.source_path.parent_path() / p;
}

Result<Texture> loadTexture(const SceneDescription& scene, const std::filesystem::path& path,
                            const std::string& what) {
    auto texture = Texture::load(resolve(scene, path));
    if (!texture)
        return texture.status().withContext(what);
    return texture;
}

void boundMeshes(detail::LoadedGeometry& geometry) {
    Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
    for (const TriangleMesh& mesh : *geometry.meshes)
        for (const Vec3& p : mesh.positions) {
            lo = lo.cwiseMin(p);
            hi = hi.cwiseMax(p);
        }
    geometry.bound_centre = 0.5f * (lo + hi);
    geometry.bound_radius = 0;
    for (const TriangleMesh& mesh : *geometry.meshes)
        for (const Vec3& p : mesh.positions)
            geometry.bound_radius =
                std::max(geometry.bound_radius, (p - geometry.bound_centre).norm());
}

}  // namespace

namespace detail {

Result<std::vector<LightData>> loadLights(const std::filesystem::path& scene_source,
                                          const std::vector<Light>& scene_lights) {
    std::vector<LightData> lights;
    for (const Light& light : scene_lights) {
        LightData data;
        data.light = light;
        if (light.type == LightType::kEnvironment) {
            if (light.environment_image) {
                const FloatImage& image = *light.environment_image;
                std::vector<Rgb> texels(static_cast<size_t>(image.width) * image.height);
                for (int y = 0; y < image.height; ++y)
                    for (int x = 0; x < image.width; ++x) {
                        const float* p = image.at(x, y);
                        texels[static_cast<size_t>(y) * image.width + x] = Rgb(p[0], p[1], p[2]);
                    }
                data.environment = EnvironmentMap(Texture(image.width, image.height, texels));
                data.light.environment_image.reset();  // the texture holds it now
            } else {
                SceneDescription where;
                where.source_path = scene_source;
                auto map = EnvironmentMap::load(resolve(where, light.environment));
                if (!map)
                    return map.status().withContext("light '" + light.name + "' (" +
                                                    light.where.toString() + ")");
                data.environment = std::move(map).value();
            }
            if (light.mirror_lower_hemisphere)
                data.environment.mirrorUpperIntoLower();
        }
        lights.push_back(std::move(data));
    }
    return lights;
}

}  // namespace detail

Result<std::unique_ptr<Renderer>> Renderer::create(const SceneDescription& scene,
                                                   const RenderOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    MIXRAY_RETURN_IF_ERROR(scene.validate());
    const auto start = std::chrono::steady_clock::now();

    std::vector<MaterialData> materials;
    std::map<std::string, int> material_index;
    for (const auto& [name, material] : scene.materials) {
        MaterialData data{material, {}, {}};
        const std::string where = "material '" + name + "' (" + material.where.toString() + ")";
        if (!material.albedo_texture.empty()) {
            auto texture = loadTexture(scene, material.albedo_texture, where);
            if (!texture)
                return texture.status();
            data.albedo_texture = std::move(texture).value();
        }
        if (!material.reflectance_map.empty()) {
            auto texture = loadTexture(scene, material.reflectance_map, where);
            if (!texture)
                return texture.status();
            data.reflectance_map = std::move(texture).value();
        }
        material_index[name] = static_cast<int>(materials.size());
        materials.push_back(std::move(data));
    }

    std::vector<ObjectData> objects;
    detail::MeshCache meshes;
    for (const SceneObject& obj : scene.objects) {
        const std::string where = "object '" + obj.name + "' (" + obj.where.toString() + ")";
        std::optional<MeshMaterialHint> hint;
        auto loaded = detail::loadObjectGeometry(scene, obj, &hint, &meshes);
        if (!loaded)
            return loaded.status();
        ObjectData data = std::move(loaded).value();
        if (const auto it = material_index.find(obj.material); it != material_index.end()) {
            data.material = it->second;
        } else if (obj.material.empty()) {
            // No scene material: what the mesh file says, else the default diffuse grey.
            MaterialData fallback;
            if (hint) {
                fallback.material.albedo = hint->base_color;
                if (!hint->base_color_texture.empty()) {
                    auto texture = loadTexture(scene, hint->base_color_texture, where);
                    if (!texture)
                        return texture.status();
                    fallback.albedo_texture = std::move(texture).value();
                }
            }
            data.material = static_cast<int>(materials.size());
            materials.push_back(std::move(fallback));
        } else {
            return Status(ErrorCode::kCorruptData,
                          where + ": unknown material '" + obj.material + "'");
        }
        objects.push_back(std::move(data));
    }

    auto lights = detail::loadLights(scene.source_path, scene.lights);
    if (!lights)
        return lights.status();

    std::optional<size_t> depth_object;
    if (options.depth_secondary == DepthSecondaryRays::kMesh) {
        MaterialData surface;
        surface.material.name = "depth surface";
        surface.material.reflectance = scene.depth_surface.reflectance;
        surface.albedo_from_camera = true;
        ObjectData data;
        data.name = "depth surface";
        data.role = ObjectRole::kGhost;
        data.shape = ShapeType::kMesh;
        data.depth_surface = true;
        data.meshes->emplace_back();
        data.material = static_cast<int>(materials.size());
        materials.push_back(std::move(surface));
        depth_object = objects.size();
        objects.push_back(std::move(data));
    }

    auto renderer = std::make_unique<detail::EmbreeRenderer>(
        options, std::move(materials), std::move(objects), std::move(lights).value(),
        scene.source_path, depth_object,
        detail::SceneEffects{scene.lens_effects,
                             scene.camera ? scene.camera->aperture : std::nullopt,
                             scene.camera_matching, scene.caustics});
    renderer->setLoadSeconds(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    MIXRAY_RETURN_IF_ERROR(renderer->init());
    return std::unique_ptr<Renderer>(std::move(renderer));
}

namespace detail {

Result<ObjectData> loadObjectGeometry(const SceneDescription& scene, const SceneObject& obj,
                                      std::optional<MeshMaterialHint>* hint, MeshCache* cache) {
    const std::string where = "object '" + obj.name + "' (" + obj.where.toString() + ")";
    ObjectData data;
    data.name = obj.name;
    data.role = obj.role;
    data.shape = obj.shape.type;
    data.anchor = obj.anchor;
    data.T_anchor_object = obj.T_anchor_object.cast<float>();
    if (obj.shape.type == ShapeType::kSphere) {
        data.sphere_radius = obj.shape.radius;
        data.bound_radius = obj.shape.radius;
        return data;
    }
    // What the geometry came from: a mesh in memory, a file, or the shape itself.
    std::optional<std::pair<std::string, float>> key;
    if (obj.shape.type == ShapeType::kMesh && obj.shape.mesh_data != nullptr) {
        char address[32];
        std::snprintf(address, sizeof address, "memory:%p",
                      static_cast<const void*>(obj.shape.mesh_data.get()));
        key.emplace(address, obj.shape.scale);
    } else if (obj.shape.type == ShapeType::kMesh) {
        key.emplace("file:" + resolve(scene, obj.shape.mesh).string(), obj.shape.scale);
    }
    LoadedGeometry* shared = nullptr;
    if (cache != nullptr && key)
        if (const auto it = cache->find(*key); it != cache->end())
            shared = &it->second;
    LoadedGeometry loaded;
    if (shared == nullptr) {
        loaded.meshes = std::make_shared<std::vector<TriangleMesh>>();
        if (obj.shape.type == ShapeType::kMesh && obj.shape.mesh_data != nullptr) {
            loaded.meshes->push_back(*obj.shape.mesh_data);
            for (Vec3& p : loaded.meshes->back().positions)
                p *= obj.shape.scale;
        } else if (obj.shape.type == ShapeType::kMesh) {
            auto from_file = loadMeshFile(resolve(scene, obj.shape.mesh), obj.shape.scale);
            if (!from_file)
                return from_file.status().withContext(where);
            for (LoadedMesh& mesh : from_file.value()) {
                if (!loaded.hint)
                    loaded.hint = mesh.material;
                loaded.meshes->push_back(std::move(mesh.mesh));
            }
        } else {
            loaded.meshes->push_back(makeShapeMesh(obj.shape));
        }
        boundMeshes(loaded);
        if (cache != nullptr && key)
            shared = &(*cache)[*key];
        if (shared != nullptr)
            *shared = loaded;
    }
    const LoadedGeometry& geometry = shared != nullptr ? *shared : loaded;
    if (hint && !*hint)
        *hint = geometry.hint;
    data.meshes = geometry.meshes;
    data.bound_centre = geometry.bound_centre;
    data.bound_radius = geometry.bound_radius;
    if (std::all_of(data.meshes->begin(), data.meshes->end(),
                    [](const TriangleMesh& m) { return m.empty(); }))
        return Status(ErrorCode::kCorruptData, where + ": shape has no triangles");
    return data;
}

}  // namespace detail
}  // namespace mixray::render
