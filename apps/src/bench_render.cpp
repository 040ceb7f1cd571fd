// mixray bench render: RT²AR's scenes (a metal teapot on a real chessboard table; two Stanford
// dragons of ~1.1M triangles each beside it) rendered with a slowly orbiting camera, and the
// rays of one frame traced again by bare Embree on the same BVH: the renderer's efficiency; and
// the compositor's quality ladder, each rung against full quality.
#include "bench_render.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <sstream>
#include <thread>

#include "console.h"
#include "mixray/render/assets.h"
#include "mixray/render/bench_seam.h"
#include "mixray/render/compositor_node.h"
#include "mixray/render/output.h"
#include "mixray/render/povray.h"
#include "mixray/render/renderer.h"
#include "test_data_paths.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using namespace mixray::render;

struct BenchRenderOptions {
    std::string sizes = "640x480,1280x720";
    int frames = 20;
    int threads = 0;
    std::string scenes = "teapot,soft,dragons,dof,shadow-maps,caustics,ladder";
    bool json = false;
    int repeats = 3;
    std::string shared_data;
    std::string embree_isas = "best";         // "best", "all" or a comma list of embreeIsas()
    std::string map_sizes = "512,1024,2048";  // shadow-maps: texels on a side
    std::string peer;                         // "povray": the same scene in POV-Ray instead
};

struct Size {
    int width = 0, height = 0;
};

// Comma-separated items, empty ones included ("a," is "a" and "").
std::vector<std::string> splitList(const std::string& text) {
    std::vector<std::string> items(1);
    for (char c : text)
        if (c == ',')
            items.emplace_back();
        else
            items.back() += c;
    return items;
}

Result<std::vector<Size>> parseSizes(const std::string& text) {
    std::vector<Size> sizes;
    for (const std::string& item : splitList(text)) {
        Size s;
        char x = 0;
        std::stringstream one(item);
        if (!(one >> s.width >> x >> s.height) || x != 'x' || !one.eof() || s.width < 16 ||
            s.height < 16 || s.width > 8192 || s.height > 8192)
            return Status(ErrorCode::kInvalidArgument,
                          "--size: '" + item + "' is not WIDTHxHEIGHT with sides in [16, 8192]");
        sizes.push_back(s);
    }
    return sizes;
}

Result<std::vector<std::string>> parseScenes(const std::string& text) {
    static const std::vector<std::string> known = {"teapot",      "soft",     "dragons", "dof",
                                                   "shadow-maps", "caustics", "ladder"};
    std::vector<std::string> scenes = splitList(text);
    for (const std::string& item : scenes)
        if (std::find(known.begin(), known.end(), item) == known.end())
            return Status(ErrorCode::kInvalidArgument,
                          "--scenes: unknown scene '" + item +
                              "' (teapot, soft, dragons, dof, shadow-maps, caustics, ladder)");
    return scenes;
}

// One midpoint split: every triangle into four (shared edge midpoints are computed from the
// same two endpoints, so neighbours agree), or one triangle into two across its longest edge.
// The second leaves T-junctions whose cracks are below float precision: fine for throughput.
struct Subdivider {
    TriangleMesh& mesh;

    uint32_t midpoint(uint32_t a, uint32_t b) {
        mesh.positions.push_back(0.5f * (mesh.positions[a] + mesh.positions[b]));
        if (!mesh.normals.empty()) {
            const Eigen::Vector3f n = mesh.normals[a] + mesh.normals[b];
            mesh.normals.push_back(n.squaredNorm() > 0 ? n.normalized() : mesh.normals[a]);
        }
        if (!mesh.uvs.empty())
            mesh.uvs.push_back(0.5f * (mesh.uvs[a] + mesh.uvs[b]));
        return static_cast<uint32_t>(mesh.positions.size() - 1);
    }
    void splitAllInFour() {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> mids;
        const auto mid = [&](uint32_t a, uint32_t b) {
            const auto key = std::minmax(a, b);
            const auto it = mids.find(key);
            if (it != mids.end())
                return it->second;
            return mids[key] = midpoint(key.first, key.second);
        };
        std::vector<std::array<uint32_t, 3>> out;
        out.reserve(mesh.triangles.size() * 4);
        for (const auto t : mesh.triangles) {
            const uint32_t ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
            out.push_back({t[0], ab, ca});
            out.push_back({ab, t[1], bc});
            out.push_back({ca, bc, t[2]});
            out.push_back({ab, bc, ca});
        }
        mesh.triangles = std::move(out);
    }
    void splitInTwo(size_t i) {
        auto t = mesh.triangles[i];
        const auto len = [&](int e) {
            return (mesh.positions[t[e]] - mesh.positions[t[(e + 1) % 3]]).squaredNorm();
        };
        const int e = len(0) >= len(1) && len(0) >= len(2) ? 0 : (len(1) >= len(2) ? 1 : 2);
        const uint32_t a = t[e], b = t[(e + 1) % 3], c = t[(e + 2) % 3];
        const uint32_t m = midpoint(a, b);
        mesh.triangles[i] = {a, m, c};
        mesh.triangles.push_back({m, b, c});
    }
    float area(size_t i) const {
        const auto& t = mesh.triangles[i];
        return (mesh.positions[t[1]] - mesh.positions[t[0]])
            .cross(mesh.positions[t[2]] - mesh.positions[t[0]])
            .squaredNorm();
    }
    void subdivideTo(size_t target) {
        while (mesh.triangles.size() * 4 <= target)
            splitAllInFour();
        while (mesh.triangles.size() * 2 <= target) {
            const size_t n = mesh.triangles.size();
            for (size_t i = 0; i < n; ++i)
                splitInTwo(i);
        }
        const size_t extra = target - mesh.triangles.size();
        std::vector<size_t> order(mesh.triangles.size());
        std::iota(order.begin(), order.end(), 0);
        std::nth_element(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(extra),
                         order.end(), [&](size_t a, size_t b) { return area(a) > area(b); });
        for (size_t k = 0; k < extra; ++k)
            splitInTwo(order[k]);
    }
};

Eigen::Isometry3d pose(const Eigen::Vector3d& translation, double rot_x_deg, double rot_z_deg) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translate(translation);
    T.rotate(Eigen::AngleAxisd(rot_z_deg * M_PI / 180, Eigen::Vector3d::UnitZ()));
    T.rotate(Eigen::AngleAxisd(rot_x_deg * M_PI / 180, Eigen::Vector3d::UnitX()));
    return T;
}

// fixtures/scenes/teapot_chessboard.yaml, built in code so the bench needs no source tree.
const Eigen::Vector3d kBoardCentre(0.125, 0.0875, 0);

SceneDescription teapotScene(const fs::path& shared, bool sphere_light) {
    SceneDescription scene;
    Material metal;
    metal.name = "teapot_metal";
    metal.type = MaterialType::kMetal;
    metal.f0 = {0.95f, 0.93f, 0.88f};
    scene.materials[metal.name] = metal;
    Material table;
    table.name = "table";
    table.albedo = Rgb::Constant(0.55f);
    table.reflectance = 0.15f;
    scene.materials[table.name] = table;
    SceneObject teapot;
    teapot.name = "teapot";
    teapot.shape.type = ShapeType::kMesh;
    teapot.shape.mesh = shared / "06_models" / "newell_teapot.obj";
    teapot.shape.scale = 0.02f;
    teapot.material = metal.name;
    teapot.T_anchor_object = pose(kBoardCentre, 90, 0);
    scene.objects.push_back(teapot);
    SceneObject plane;
    plane.name = "table";
    plane.role = ObjectRole::kGhost;
    plane.shape.type = ShapeType::kPlane;
    plane.shape.size = {1.2f, 0.8f, 0};
    plane.material = table.name;
    plane.T_anchor_object = pose(kBoardCentre, 0, 0);
    scene.objects.push_back(plane);
    Light lamp;
    lamp.name = "lamp";
    lamp.type = sphere_light ? LightType::kSphere : LightType::kPoint;
    lamp.position = {0.4, -0.3, 0.8};
    lamp.radius = 0.08f;
    lamp.intensity = Rgb::Constant(2.0f);
    scene.lights.push_back(lamp);
    return scene;
}

// ladder: the teapot scene under its spherical lamp with a glass ball beside the teapot and a
// room around them (a light upper half, a darker floor: an estimated environment's shape), so
// that what each rung of the quality ladder gives up shows on metal, glass and shadows.
SceneDescription ladderScene(const fs::path& shared) {
    SceneDescription scene = teapotScene(shared, true);
    Material glass;
    glass.name = "glass";
    glass.type = MaterialType::kGlass;
    glass.ior = Rgb::Constant(1.5f);
    scene.materials[glass.name] = glass;
    SceneObject ball;
    ball.name = "glass_ball";
    ball.shape.type = ShapeType::kSphere;
    ball.shape.radius = 0.03f;
    ball.material = glass.name;
    ball.T_anchor_object = pose(kBoardCentre + Eigen::Vector3d(0.1, -0.05, 0.03), 0, 0);
    scene.objects.push_back(ball);
    auto room = std::make_shared<FloatImage>();
    room->width = 64;
    room->height = 32;
    room->pixels.resize(static_cast<size_t>(room->width) * room->height * 3);
    for (int y = 0; y < room->height; ++y)
        for (int x = 0; x < room->width; ++x) {
            const bool upper = y < room->height / 2;  // row 0 looks up (+z)
            float* texel = room->at(x, y);
            texel[0] = upper ? 0.55f : 0.25f;
            texel[1] = upper ? 0.6f : 0.22f;
            texel[2] = upper ? 0.7f : 0.2f;
        }
    Light environment;
    environment.name = "room";
    environment.type = LightType::kEnvironment;
    environment.environment_image = std::move(room);
    scene.lights.push_back(environment);
    return scene;
}

constexpr size_t kDragonTriangles = 1'100'000;

// Writes `mesh` as a binary PLY (positions and triangles), as a scanned model comes.
Status writePly(const TriangleMesh& mesh, const fs::path& path) {
    std::ofstream out(path, std::ios::binary);
    out << "ply\nformat binary_little_endian 1.0\ncomment mixray bench render\nelement vertex "
        << mesh.positions.size()
        << "\nproperty float x\nproperty float y\nproperty float z\nelement face "
        << mesh.triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
    for (const Eigen::Vector3f& p : mesh.positions)
        out.write(reinterpret_cast<const char*>(p.data()), 3 * sizeof(float));
    for (const auto& t : mesh.triangles) {
        const uint8_t three = 3;
        const std::array<int32_t, 3> index = {
            static_cast<int32_t>(t[0]), static_cast<int32_t>(t[1]), static_cast<int32_t>(t[2])};
        out.write(reinterpret_cast<const char*>(&three), 1);
        out.write(reinterpret_cast<const char*>(index.data()), sizeof index);
    }
    if (!out.flush())
        return Status(ErrorCode::kIoError, path.string() + ": cannot write");
    return Status::ok();
}

// The dragons' mesh file and how long it takes to load: assimp's import, and a load from the
// mesh cache (MeshCacheSettings), which the renderer then gets.
struct DragonMesh {
    fs::path ply;
    double import_ms = 0;  // without the mesh cache
    double cached_ms = 0;  // from it; 0 when there is no cache
};

// Two Stanford dragons of 1.1M triangles (photon_dragon_100k.obj split to that count) beside
// the teapot, both from one binary PLY file, as a scanned model arrives: the renderer loads it
// once and builds its BVH once for both. The file is written into `dir` unless it is there.
Result<SceneDescription> dragonScene(const fs::path& shared, const fs::path& dir,
                                     DragonMesh& dragon_mesh) {
    SceneDescription scene = teapotScene(shared, false);
    const fs::path ply = dir / "dragon_1.1M.ply";
    if (!fs::exists(ply)) {
        auto loaded = loadMeshFile(shared / "06_models" / "photon_dragon_100k.obj");
        if (!loaded)
            return loaded.status();
        TriangleMesh mesh;
        for (const LoadedMesh& part : *loaded) {
            const auto base = static_cast<uint32_t>(mesh.positions.size());
            mesh.positions.insert(mesh.positions.end(), part.mesh.positions.begin(),
                                  part.mesh.positions.end());
            for (auto t : part.mesh.triangles)
                mesh.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
        }
        Subdivider{mesh}.subdivideTo(kDragonTriangles);
        fs::create_directories(dir);
        const fs::path partial = ply.string() + ".partial";
        MIXRAY_RETURN_IF_ERROR(writePly(mesh, partial));
        fs::rename(partial, ply);
    }
    dragon_mesh.ply = ply;
    const auto timeLoad = [&](const MeshCacheSettings& cache) -> Result<double> {
        const auto start = std::chrono::steady_clock::now();
        auto loaded = loadMeshFile(ply, 0.01f, cache);
        if (!loaded)
            return loaded.status();
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count();
    };
    auto imported = timeLoad(MeshCacheSettings{});
    if (!imported)
        return imported.status();
    dragon_mesh.import_ms = *imported;
    const MeshCacheSettings cache = MeshCacheSettings::fromEnvironment();
    if (!cache.dir.empty()) {
        MIXRAY_RETURN_IF_ERROR(timeLoad(cache).status());  // makes the entry if there is none
        auto cached = timeLoad(cache);
        if (!cached)
            return cached.status();
        dragon_mesh.cached_ms = *cached;
    }
    Material jade;
    jade.name = "dragon";
    jade.type = MaterialType::kPhong;
    jade.albedo = {0.25f, 0.55f, 0.3f};
    scene.materials[jade.name] = jade;
    for (int i = 0; i < 2; ++i) {
        SceneObject dragon;
        dragon.name = "dragon" + std::to_string(i);
        dragon.shape.type = ShapeType::kMesh;
        dragon.shape.mesh = ply;
        dragon.shape.scale = 0.01f;
        dragon.material = jade.name;
        dragon.T_anchor_object = pose(
            kBoardCentre + Eigen::Vector3d(i == 0 ? -0.16 : 0.16, 0.06, 0), 90, i == 0 ? 30 : -30);
        scene.objects.push_back(dragon);
    }
    return scene;
}

// A torus of tube radius `tube` around a circle of radius `ring` in z = 0, `around` x `across`
// quads: Kán & Kaufmann's metal ring (9K triangles).
std::shared_ptr<TriangleMesh> torusMesh(float ring, float tube, int around, int across) {
    auto mesh = std::make_shared<TriangleMesh>();
    for (int i = 0; i < around; ++i) {
        const float u =
            2 * static_cast<float>(M_PI) * static_cast<float>(i) / static_cast<float>(around);
        for (int j = 0; j < across; ++j) {
            const float v =
                2 * static_cast<float>(M_PI) * static_cast<float>(j) / static_cast<float>(across);
            const Eigen::Vector3f centre(ring * std::cos(u), ring * std::sin(u), 0);
            const Eigen::Vector3f n(std::cos(v) * std::cos(u), std::cos(v) * std::sin(u),
                                    std::sin(v));
            mesh->positions.push_back(centre + tube * n);
            mesh->normals.push_back(n);
        }
    }
    const auto index = [&](int i, int j) {
        return static_cast<uint32_t>((i % around) * across + (j % across));
    };
    for (int i = 0; i < around; ++i)
        for (int j = 0; j < across; ++j) {
            mesh->triangles.push_back({index(i, j), index(i + 1, j), index(i + 1, j + 1)});
            mesh->triangles.push_back({index(i, j), index(i + 1, j + 1), index(i, j + 1)});
        }
    return mesh;
}

// Kán & Kaufmann's Table 1 scenes as far as their models exist here, on the chessboard table
// under the point lamp: a metal ring (a torus of 9 216 triangles built in code), a glass sphere
// (their Figures 6 and 8) and a glass dragon (photon_dragon_100k.obj; theirs had 201K
// triangles). Their glass Buddha is not in ../shared/data.
Result<SceneDescription> causticScene(const fs::path& shared, const std::string& generator) {
    SceneDescription scene = teapotScene(shared, false);
    std::erase_if(scene.objects, [](const SceneObject& o) { return o.name == "teapot"; });
    SceneObject object;
    object.name = generator;
    Material material;
    material.name = generator;
    if (generator == "ring") {
        material.type = MaterialType::kMetal;
        material.f0 = {0.95f, 0.64f, 0.54f};  // copper-gold, as their ring
        object.shape.type = ShapeType::kMesh;
        object.shape.mesh_data = torusMesh(0.05f, 0.006f, 96, 48);
        object.shape.mesh = "torus (built in code)";
        object.T_anchor_object = pose(kBoardCentre + Eigen::Vector3d(0, 0, 0.006), 0, 0);
    } else if (generator == "sphere") {
        material.type = MaterialType::kGlass;
        object.shape.type = ShapeType::kSphere;
        object.shape.radius = 0.04f;
        object.T_anchor_object = pose(kBoardCentre + Eigen::Vector3d(0, 0, 0.04), 0, 0);
    } else {
        material.type = MaterialType::kGlass;
        object.shape.type = ShapeType::kMesh;
        object.shape.mesh = shared / "06_models" / "photon_dragon_100k.obj";
        object.shape.scale = 0.012f;
        object.T_anchor_object = pose(kBoardCentre, 90, 20);
    }
    object.material = material.name;
    scene.materials[material.name] = material;
    scene.objects.push_back(object);
    return scene;
}

double processCpuSeconds() {
    return static_cast<double>(processCpuNs()) / 1e9;
}

struct Config {
    std::string scene;  // teapot, soft, dragons, dof, shadow-maps, caustics, ladder
    std::string name;
    RenderOptions options;
    LensEffects lens_effects = {};              // added to the scene
    std::optional<LensAperture> aperture = {};  // the camera's, added to the scene
    CameraMatching camera_matching = {};        // added to the scene
    // Motion blur: the shutter open over this fraction of the time between frames at 30 fps,
    // the orbit's motion between frames scaled to it; 0: none.
    double exposure_fraction = 0;
    std::optional<ShadowMapSettings> shadow_map = {};  // given to every light
    // caustics: the generator's scene (ring, sphere, dragon), the photons (none: no caustics),
    // and whether the light moves a little every frame, so that photons are shot every frame
    // (the paper's fps_r) rather than reused (fps_n).
    std::string generator = {};
    std::optional<CausticSettings> caustics = {};
    bool move_light = false;
    std::optional<int> rung = {};  // ladder: the quality ladder's rung, from 1 (rungText())
};

// RT²AR's teapot rows: primary rays only, + hard shadows, + shadows and 3 bounces.
std::vector<std::pair<std::string, RenderOptions>> teapotVariants(const RenderOptions& base) {
    RenderOptions primary = base;
    primary.max_depth = 0;
    primary.shadows = false;
    RenderOptions shadows = base;
    shadows.max_depth = 0;
    RenderOptions bounces = base;
    bounces.max_depth = 3;
    return {
        {"primary only", primary}, {"+ hard shadows", shadows}, {"+ shadows + 3 bounces", bounces}};
}

std::vector<Config> configsFor(const std::string& scene, int threads,
                               const std::vector<int>& map_sizes) {
    RenderOptions base;
    base.threads = threads;
    base.soft_shadows = SoftShadowMethod::kHard;
    std::vector<Config> out;
    if (scene == "teapot") {
        for (const auto& [name, options] : teapotVariants(base))
            out.push_back({scene, name, options});
        const RenderOptions bounces = out.back().options;  // a copy: out grows below
        // RT²AR §IV-F's lens effects on the frame above. Thresholds low enough that most of the
        // teapot blooms: the effects' worst case, against the row above as the baseline.
        LensEffects lens;
        lens.bloom = Bloom{};
        lens.bloom->threshold = 0.25f;
        lens.glare = Glare{};
        lens.glare->threshold = 0.35f;
        out.push_back({scene, "+ shadows + 3 bounces + bloom and glare", bounces, lens});
        // Camera matching: the camera image's noise measured every frame and added to the
        // virtual pixels, against the same row without it.
        CameraMatching matching;
        matching.noise = 1;
        out.push_back(
            {scene, "+ shadows + 3 bounces + camera noise matched", bounces, {}, {}, matching});
    } else if (scene == "dof") {
        // Kán & Kaufmann §3.1's depth of field (their Figure 8: 25 rays per pixel, then the
        // lens), on the teapot frame with 25 samples per pixel as the baseline.
        RenderOptions supersampled = base;
        supersampled.max_depth = 3;
        supersampled.samples_per_pixel = 25;
        LensAperture lens;
        lens.f_number = 1.4f;
        lens.focal_length_mm = 50;
        lens.focus_distance_m = 0.4f;  // in front of the teapot, 0.5 m away
        out.push_back({scene, "25 samples/pixel, shadows + 3 bounces", supersampled});
        out.push_back({scene,
                       "25 samples/pixel, shadows + 3 bounces + depth of field (50 mm f/1.4)",
                       supersampled,
                       {},
                       lens});
        // Motion blur (camera matching) on the same frame: a 1/60 s exposure at 30 fps.
        out.push_back({scene,
                       "25 samples/pixel, shadows + 3 bounces + motion blur (1/60 s)",
                       supersampled,
                       {},
                       {},
                       {},
                       0.5});
    } else if (scene == "shadow-maps") {
        // Castro et al.'s Tabela I on the teapot under the spherical lamp: shadow maps of 512²,
        // 1024² and 2048² (hard, PCF 3x3, VSM; VSM also in their 8-bit path and bit-packed in
        // RGBA8) against ray-traced soft shadows of the same light, the first row, which the
        // others' image difference is measured against.
        RenderOptions soft = base;
        soft.soft_shadows = SoftShadowMethod::kAdaptive;
        soft.shadow_samples = 20;
        out.push_back({scene, "ray-traced soft shadows, 20 samples adaptive (reference)", soft});
        out.push_back({scene, "ray-traced hard shadows", base});
        for (int resolution : map_sizes) {
            const std::string side = std::to_string(resolution) + "²";
            const auto add = [&](const std::string& what, ShadowMapFilter filter,
                                 ShadowMapStorage storage) {
                ShadowMapSettings map;
                map.resolution = resolution;
                map.filter = filter;
                map.storage = storage;
                Config c{scene, "shadow map " + side + " " + what, base};
                c.shadow_map = map;
                out.push_back(c);
            };
            add("hard", ShadowMapFilter::kHard, ShadowMapStorage::kFloat);
            add("PCF 3x3", ShadowMapFilter::kPcf, ShadowMapStorage::kFloat);
            add("VSM", ShadowMapFilter::kVsm, ShadowMapStorage::kFloat);
            // Tabela I's two columns: z and z² in 8 bits each, and bit-packed into RGBA.
            add("VSM, 8-bit z and z² (no bit packing)", ShadowMapFilter::kVsm,
                ShadowMapStorage::kEightBit);
            add("VSM, z and z² bit-packed in RGBA8", ShadowMapFilter::kVsm,
                ShadowMapStorage::kPackedRgba8);
        }
    } else if (scene == "caustics") {
        // Kán & Kaufmann's Table 1: photons per frame and samples per pixel as theirs.
        const auto add = [&](const std::string& generator, int photons, int spp, bool reshoot) {
            RenderOptions o = base;
            o.samples_per_pixel = spp;
            Config c{scene, "", o};
            c.generator = generator;
            if (photons > 0) {
                CausticSettings caustics;
                caustics.photons = photons;
                caustics.radius_m = 0.004f;
                c.caustics = caustics;
            }
            c.move_light = reshoot;
            c.name = (generator == "ring" ? "metal ring" : "glass " + generator) + ", " +
                     (photons > 0 ? std::to_string(photons / 1000) + "K photons " +
                                        (reshoot ? "shot every frame" : "reused")
                                  : std::string("no caustics")) +
                     ", " + std::to_string(spp) + " sample" + (spp > 1 ? "s" : "") + "/pixel";
            out.push_back(c);
        };
        add("ring", 0, 1, false);
        add("ring", 280000, 1, true);
        add("ring", 280000, 1, false);
        add("ring", 280000, 4, false);
        add("sphere", 150000, 1, true);
        add("sphere", 150000, 1, false);
        add("dragon", 240000, 1, true);
        add("dragon", 240000, 1, false);
    } else if (scene == "ladder") {
        // The compositor's quality ladder (render::qualityLadder) from what `mixray run` would
        // be asked for at its best, each rung against the first, full quality.
        RenderOptions best = base;
        best.samples_per_pixel = 4;
        best.soft_shadows = SoftShadowMethod::kAdaptive;
        best.shadow_samples = 20;
        best.max_depth = 3;
        const std::vector<QualityStep> ladder = qualityLadder(best);
        for (size_t k = 0; k < ladder.size(); ++k) {
            const int step = static_cast<int>(k);
            Config c{scene,
                     rungText(step, static_cast<int>(ladder.size()), ladder[k].label()) +
                         (k == 0 ? " (reference)" : ""),
                     ladder[k].applied(best)};
            c.rung = step + 1;
            out.push_back(c);
        }
    } else if (scene == "soft") {
        RenderOptions uniform = base;
        uniform.soft_shadows = SoftShadowMethod::kUniform;
        uniform.shadow_samples = 20;
        RenderOptions adaptive = uniform;
        adaptive.soft_shadows = SoftShadowMethod::kAdaptive;
        // The uniform row is the reference the others' composites are measured against; the
        // hard-shadow row (one ray to the lamp's centre) is the floor of any method that traces
        // at least one shadow ray per shaded point; the row without rays to the lights is the
        // ceiling of every shadow method.
        RenderOptions unshadowed = base;
        unshadowed.shadows = false;
        out.push_back({scene, "soft shadows, 20 samples uniform, 3 bounces (reference)", uniform});
        out.push_back({scene, "soft shadows, 20 samples adaptive, 3 bounces", adaptive});
        out.push_back({scene, "hard shadows (one ray to the lamp's centre), 3 bounces", base});
        out.push_back({scene, "no shadow rays to the lights (every light unoccluded), 3 bounces",
                       unshadowed});
    } else {
        RenderOptions shadows = base;
        shadows.max_depth = 0;
        out.push_back(
            {scene, "2 dragons (1.1M triangles each) + teapot, primary + shadows", shadows});
        out.push_back(
            {scene, "2 dragons (1.1M triangles each) + teapot, shadows + 3 bounces", base});
    }
    return out;
}

// A camera 0.5 m from the board centre, 45° above the table, orbiting a little each frame.
Eigen::Isometry3d cameraPose(int frame) {
    const double azimuth = (-100 + 0.7 * frame) * M_PI / 180;
    const double elevation = (45 + 2 * std::sin(frame * 0.3)) * M_PI / 180;
    const Eigen::Vector3d target = kBoardCentre + Eigen::Vector3d(0, 0, 0.04);
    const Eigen::Vector3d eye =
        target + 0.5 * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                       std::cos(elevation) * std::sin(azimuth),
                                       std::sin(elevation));
    const Eigen::Vector3d forward = (target - eye).normalized();
    const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
    const Eigen::Vector3d down = forward.cross(right);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear().col(0) = right;
    T.linear().col(1) = down;
    T.linear().col(2) = forward;
    T.translation() = eye;
    return T;
}

// What the real camera would see: the 10x7 chessboard of 25 mm squares on a grey table.
void paintCameraImage(const calibration::CameraModel& camera, const Eigen::Isometry3d& T_world_cam,
                      Image& image) {
    for (int y = 0; y < camera.height; ++y) {
        uint8_t* row = image.bytes().data() + static_cast<size_t>(y) * camera.width * 3;
        for (int x = 0; x < camera.width; ++x) {
            const Eigen::Vector3d d =
                T_world_cam.linear() *
                Eigen::Vector3d((x - camera.cx) / camera.fx, (y - camera.cy) / camera.fy, 1);
            uint8_t v = 70;  // the room behind the table
            const double t = -T_world_cam.translation().z() / d.z();
            if (t > 0) {
                const Eigen::Vector3d p = T_world_cam.translation() + t * d;
                const Eigen::Vector3d q = p - kBoardCentre;
                if (std::abs(q.x()) < 0.6 && std::abs(q.y()) < 0.4)
                    v = 150;
                if (p.x() >= 0 && p.x() < 0.25 && p.y() >= 0 && p.y() < 0.175)
                    v = ((static_cast<int>(p.x() / 0.025) + static_cast<int>(p.y() / 0.025)) & 1)
                            ? 30
                            : 225;
            }
            // A sensor's noise, σ about 2 codes (camera matching measures it).
            uint64_t h = (static_cast<uint64_t>(y) * 0x9e3779b97f4a7c15ULL) ^
                         (static_cast<uint64_t>(x) * 0xc2b2ae3d27d4eb4fULL);
            h ^= h >> 29;
            h *= 0xbf58476d1ce4e5b9ULL;
            h ^= h >> 32;
            const int grain = static_cast<int>(h % 7) - 3;  // uniform on −3..3: σ = 2
            row[3 * x] = row[3 * x + 1] = row[3 * x + 2] =
                static_cast<uint8_t>(std::clamp(static_cast<int>(v) + grain, 0, 255));
        }
    }
}

struct Figures {
    std::string scene, config;
    std::optional<int> rung;  // ladder rows
    Size size;
    int frames = 0;
    double fps = 0;
    double frame_ms = 0;
    double pixels_traced = 0;                           // per frame
    double shadow_map_ms = 0;                           // per frame: rendering the shadow maps
    double caustic_shoot_ms = 0, caustic_build_ms = 0;  // per frame: t_p and t_b
    double caustic_photons = 0;                         // per frame, stored
    Image composite;  // the logged frame's, for image differences between rows
    Image camera;     // the logged frame's camera image
    // shadow-maps, soft, ladder: against the first row of the same size.
    std::optional<double> rmse_vs_reference;        // of the composite, 0..255
    std::optional<double> speedup_vs_reference;     // its frame time over this row's
    double primary = 0, secondary = 0, shadow = 0;  // rays per frame
    double mrays_per_s = 0;
    // The logged frame: its rays on the renderer and on bare Embree.
    uint64_t logged_rays = 0;
    double renderer_ms = 0;
    double renderer_cpu_ms = 0;  // the process's CPU time
    bench::BareTraceTimes bare;
    bool log_matches_stats = false;
    bench::CreationTimes created;  // the renderer's: its meshes loaded and its BVH built
};

Result<Figures> benchOne(Renderer& renderer, const Config& config, const std::vector<Light>& lights,
                         Size size, int frames, int repeats) {
    const double f = 0.9 * size.width;
    RenderInputs inputs;
    inputs.camera = calibration::CameraModel::pinhole(
        size.width, size.height, f, f, (size.width - 1) / 2.0, (size.height - 1) / 2.0);
    Image image(ImageDesc::packed(PixelFormat::kRGB8, size.width, size.height));
    inputs.camera_image = image.view();
    RenderLayers out;
    // Wall-clock and process CPU seconds of one render() call.
    int light_moves = 0;  // move_light: every render() call, repeats of a pose too
    const auto frame = [&](int i, RenderStats& stats) -> Result<std::pair<double, double>> {
        inputs.T_world_cam = cameraPose(i);
        if (config.exposure_fraction > 0)
            inputs.shutter = shutterFromMotion(cameraPose(i - 1), inputs.T_world_cam, 1 / 30.0,
                                               config.exposure_fraction / 30.0);
        paintCameraImage(inputs.camera, inputs.T_world_cam, image);
        const double cpu_start = processCpuSeconds();
        const auto start = std::chrono::steady_clock::now();
        if (config.move_light) {
            // A light that moves re-shoots the photons: 10 µm a frame, as if tracked.
            std::vector<Light> moved = lights;
            for (Light& light : moved)
                light.position.x() += 1e-5 * ++light_moves;
            MIXRAY_RETURN_IF_ERROR(renderer.setLights(moved));
        }
        MIXRAY_RETURN_IF_ERROR(renderer.render(inputs, out, &stats));
        return std::pair{
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
            processCpuSeconds() - cpu_start};
    };
    RenderStats stats;
    MIXRAY_RETURN_IF_ERROR(frame(-1, stats).status());  // warm-up: ray cache, page faults
    Figures fig;
    fig.scene = config.scene;
    fig.config = config.name;
    fig.rung = config.rung;
    fig.size = size;
    fig.frames = frames;
    double total = 0;
    for (int i = 0; i < frames; ++i) {
        auto seconds = frame(i, stats);
        if (!seconds)
            return seconds.status();
        total += seconds->first;
        fig.pixels_traced += static_cast<double>(stats.pixels_traced);
        fig.shadow_map_ms += 1e3 * stats.shadow_map_seconds;
        fig.caustic_shoot_ms += 1e3 * stats.caustic_shoot_seconds;
        fig.caustic_build_ms += 1e3 * stats.caustic_build_seconds;
        fig.caustic_photons += static_cast<double>(stats.caustic_photons);
        fig.primary += static_cast<double>(stats.primary_rays);
        fig.secondary += static_cast<double>(stats.secondary_rays);
        fig.shadow += static_cast<double>(stats.shadow_rays);
    }
    fig.fps = frames / total;
    fig.frame_ms = 1e3 * total / frames;
    fig.mrays_per_s = (fig.primary + fig.secondary + fig.shadow) / total / 1e6;
    for (double* v :
         {&fig.pixels_traced, &fig.shadow_map_ms, &fig.caustic_shoot_ms, &fig.caustic_build_ms,
          &fig.caustic_photons, &fig.primary, &fig.secondary, &fig.shadow})
        *v /= frames;

    // One frame logged, then the same frame (same pose, same seed: the same rays) timed
    // without the log, best of `repeats` as for bare Embree.
    bench::RayLog log;
    inputs.T_world_cam = cameraPose(frames / 2);
    paintCameraImage(inputs.camera, inputs.T_world_cam, image);
    MIXRAY_RETURN_IF_ERROR(bench::renderLoggingRays(renderer, inputs, out, &stats, log));
    fig.composite = out.composite;
    fig.camera = image;
    fig.logged_rays = log.rays.size();
    fig.log_matches_stats = log.count(bench::RayLog::Kind::kPrimary) == stats.primary_rays &&
                            log.count(bench::RayLog::Kind::kSecondary) == stats.secondary_rays &&
                            log.count(bench::RayLog::Kind::kShadow) == stats.shadow_rays;
    double best = 1e30, best_cpu = 1e30;
    for (int r = 0; r < repeats; ++r) {
        auto seconds = frame(frames / 2, stats);
        if (!seconds)
            return seconds.status();
        best = std::min(best, seconds->first);
        best_cpu = std::min(best_cpu, seconds->second);
    }
    fig.renderer_ms = 1e3 * best;
    fig.renderer_cpu_ms = 1e3 * best_cpu;
    fig.bare = bench::traceBare(renderer, log, repeats);
    return fig;
}

const char* rayKindName(bench::RayLog::Kind kind) {
    switch (kind) {
        case bench::RayLog::Kind::kPrimary:
            return "primary";
        case bench::RayLog::Kind::kSecondary:
            return "secondary";
        case bench::RayLog::Kind::kShadow:
            return "shadow";
    }
    return "?";
}

std::string formatMs(double seconds) {
    char text[32];
    std::snprintf(text, sizeof text, "%.2f ms", 1e3 * seconds);
    return text;
}

void printFigures(const Figures& f) {
    std::printf("%s: %s, %dx%d, %d frames\n", f.scene.c_str(), f.config.c_str(), f.size.width,
                f.size.height, f.frames);
    const double pixels = static_cast<double>(f.size.width) * f.size.height;
    std::printf("  scene created in %.0f ms: loaded %.0f ms, BVH of %llu triangles %.0f ms\n",
                1e3 * (f.created.load_s + f.created.bvh_s), 1e3 * f.created.load_s,
                static_cast<unsigned long long>(f.created.triangles_built), 1e3 * f.created.bvh_s);
    std::printf("  fps %8.1f   frame %7.2f ms   pixels traced %9.0f (%4.1f %%)\n", f.fps,
                f.frame_ms, f.pixels_traced, 100 * f.pixels_traced / pixels);
    std::printf("  rays/frame  primary %9.0f  secondary %9.0f  shadow %9.0f   %7.2f Mrays/s\n",
                f.primary, f.secondary, f.shadow, f.mrays_per_s);
    if (f.caustic_photons > 0)
        std::printf("  caustics: t_p %7.2f ms  t_b %6.2f ms  t_r %7.2f ms  (%.0f photons stored)\n",
                    f.caustic_shoot_ms, f.caustic_build_ms,
                    f.frame_ms - f.caustic_shoot_ms - f.caustic_build_ms, f.caustic_photons);
    if (f.shadow_map_ms > 0)
        std::printf("  shadow maps %7.2f ms of the frame\n", f.shadow_map_ms);
    if (f.rmse_vs_reference && f.speedup_vs_reference)
        std::printf(
            "  vs the reference: %.2fx its fps; composite RMSE %.2f codes (%.2f %% of full "
            "scale)\n",
            *f.speedup_vs_reference, *f.rmse_vs_reference, 100 * *f.rmse_vs_reference / 255);
    const double bare_ms = 1e3 * f.bare.total();
    std::printf(
        "  same %llu rays, bare Embree %7.2f ms (primary %s %.2f, secondary %s %.2f, shadow %s "
        "%.2f) vs renderer %7.2f ms: efficiency %5.1f %%%s\n",
        static_cast<unsigned long long>(f.logged_rays), bare_ms, f.bare.primary_method.c_str(),
        1e3 * f.bare.primary_s, f.bare.secondary_method.c_str(), 1e3 * f.bare.secondary_s,
        f.bare.shadow_method.c_str(), 1e3 * f.bare.shadow_s, f.renderer_ms,
        f.renderer_ms > 0 ? 100 * bare_ms / f.renderer_ms : 0.0,
        f.log_matches_stats ? "" : "  (ray log does not match the stats!)");
    // Every way bare Embree traced each kind: what batching the renderer's rays could gain.
    std::string ways;
    for (const auto kind : {bench::RayLog::Kind::kPrimary, bench::RayLog::Kind::kSecondary,
                            bench::RayLog::Kind::kShadow}) {
        std::string line;
        for (const bench::BareTraceTimes::Method& m : f.bare.tried)
            if (m.kind == kind && m.wall_s > 0)
                line += (line.empty() ? "" : ", ") + m.name + " " + formatMs(m.wall_s);
        if (!line.empty())
            ways += std::string(ways.empty() ? "" : "; ") + rayKindName(kind) + " " + line;
    }
    if (!ways.empty())
        std::printf("  bare Embree, each way: %s\n", ways.c_str());
    const double bare_cpu_ms = 1e3 * f.bare.totalCpu();
    std::printf(
        "  same rays, CPU time: bare Embree %7.2f ms vs renderer %7.2f ms: efficiency "
        "%5.1f %%\n",
        bare_cpu_ms, f.renderer_cpu_ms,
        f.renderer_cpu_ms > 0 ? 100 * bare_cpu_ms / f.renderer_cpu_ms : 0.0);
}

nlohmann::json triedJson(const bench::BareTraceTimes& bare) {
    nlohmann::json out = nlohmann::json::array();
    for (const bench::BareTraceTimes::Method& m : bare.tried)
        out.push_back({{"kind", rayKindName(m.kind)},
                       {"method", m.name},
                       {"wall_ms", 1e3 * m.wall_s},
                       {"cpu_ms", 1e3 * m.cpu_s}});
    return out;
}

nlohmann::json toJson(const Figures& f) {
    return {{"scene", f.scene},
            {"config", f.config},
            {"rung", f.rung ? nlohmann::json(*f.rung) : nlohmann::json()},
            {"width", f.size.width},
            {"height", f.size.height},
            {"frames", f.frames},
            {"fps", f.fps},
            {"frame_ms", f.frame_ms},
            {"pixels_traced", f.pixels_traced},
            {"shadow_map_ms", f.shadow_map_ms},
            {"caustics",
             {{"t_p_ms", f.caustic_shoot_ms},
              {"t_b_ms", f.caustic_build_ms},
              {"photons_stored", f.caustic_photons}}},
            {"rmse_vs_reference",
             f.rmse_vs_reference ? nlohmann::json(*f.rmse_vs_reference) : nlohmann::json()},
            {"speedup_vs_reference",
             f.speedup_vs_reference ? nlohmann::json(*f.speedup_vs_reference) : nlohmann::json()},
            {"rays_per_frame",
             {{"primary", f.primary}, {"secondary", f.secondary}, {"shadow", f.shadow}}},
            {"mrays_per_s", f.mrays_per_s},
            {"logged_rays", f.logged_rays},
            {"log_matches_stats", f.log_matches_stats},
            {"renderer_ms", f.renderer_ms},
            {"bare_ms",
             {{"primary", 1e3 * f.bare.primary_s},
              {"secondary", 1e3 * f.bare.secondary_s},
              {"shadow", 1e3 * f.bare.shadow_s},
              {"total", 1e3 * f.bare.total()}}},
            {"bare_tried", triedJson(f.bare)},
            {"bare_methods",
             {{"primary", f.bare.primary_method},
              {"secondary", f.bare.secondary_method},
              {"shadow", f.bare.shadow_method}}},
            {"efficiency", f.renderer_ms > 0 ? 1e3 * f.bare.total() / f.renderer_ms : 0.0},
            {"renderer_cpu_ms", f.renderer_cpu_ms},
            {"bare_cpu_ms", 1e3 * f.bare.totalCpu()},
            {"created",
             {{"load_ms", 1e3 * f.created.load_s},
              {"bvh_ms", 1e3 * f.created.bvh_s},
              {"triangles_built", f.created.triangles_built}}},
            {"efficiency_cpu",
             f.renderer_cpu_ms > 0 ? 1e3 * f.bare.totalCpu() / f.renderer_cpu_ms : 0.0}};
}

// "best" is Embree's own choice (""), "all" every ISA this machine offers, else a comma list.
Result<std::vector<std::string>> parseIsas(const std::string& text) {
    if (text == "best")
        return std::vector<std::string>{""};
    const std::vector<std::string> available = embreeIsas();
    if (text == "all")
        return available;
    std::vector<std::string> isas = splitList(text);
    for (const std::string& isa : isas) {
        if (std::find(available.begin(), available.end(), isa) == available.end()) {
            std::string names;
            for (const std::string& a : available)
                names += " " + a;
            return Status(ErrorCode::kInvalidArgument, "--embree-isa: '" + isa +
                                                           "' is not available here (best, all "
                                                           "or some of:" +
                                                           names + ")");
        }
    }
    return isas;
}

// Root mean square difference of two rgb8 composites of one frame, in codes, over the pixels
// where either differs from the camera image: what the virtual content changed.
double rmse(const Image& a, const Image& b, const Image& camera) {
    const auto x = a.bytes(), y = b.bytes(), c = camera.bytes();
    if (x.size() != y.size() || x.size() != c.size() || x.empty())
        return std::numeric_limits<double>::quiet_NaN();
    double sum = 0;
    size_t n = 0;
    for (size_t i = 0; i + 2 < x.size(); i += 3) {
        if (std::equal(&x[i], &x[i] + 3, &c[i]) && std::equal(&y[i], &y[i] + 3, &c[i]))
            continue;
        for (size_t k = i; k < i + 3; ++k) {
            const double d = static_cast<double>(x[k]) - static_cast<double>(y[k]);
            sum += d * d;
        }
        n += 3;
    }
    return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
}

// --peer povray: RT²AR's teapot scene as both renderers can draw it identically (povray.h):
// a mirror-and-diffuse Newell teapot on a table with a chessboard of 25 mm squares (two meshes,
// dark and light, 0.5 mm above the table), one point light, every object virtual: the full
// frame. `ar`: the AR frame instead, where the table is a ghost and the camera image shows the
// board, as in the teapot scene.
std::shared_ptr<TriangleMesh> boardSquares(bool dark) {
    auto mesh = std::make_shared<TriangleMesh>();
    for (int i = 0; i < 10; ++i)
        for (int j = 0; j < 7; ++j) {
            if (((i + j) % 2 == 1) != dark)
                continue;
            const auto base = static_cast<uint32_t>(mesh->positions.size());
            for (const auto& [x, y] : {std::pair{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}})
                mesh->positions.emplace_back(0.025f * static_cast<float>(x),
                                             0.025f * static_cast<float>(y), 0.0005f);
            mesh->triangles.push_back({base, base + 1, base + 2});
            mesh->triangles.push_back({base, base + 2, base + 3});
        }
    return mesh;
}

SceneDescription peerTeapotScene(const fs::path& shared, bool ar) {
    SceneDescription scene = teapotScene(shared, false);
    Material teapot;
    teapot.name = "teapot_mirror_diffuse";
    teapot.albedo = {0.75f, 0.72f, 0.65f};
    teapot.reflectance = 0.6f;
    scene.materials[teapot.name] = teapot;
    scene.objects[0].material = teapot.name;
    if (ar)
        return scene;
    scene.objects[1].role = ObjectRole::kVirtual;
    for (bool dark : {true, false}) {
        Material square;
        square.name = dark ? "board_dark" : "board_light";
        square.albedo = Rgb::Constant(dark ? 0.03f : 0.8f);
        square.reflectance = 0.15f;
        scene.materials[square.name] = square;
        SceneObject squares;
        squares.name = square.name;
        squares.role = ObjectRole::kVirtual;
        squares.shape.type = ShapeType::kMesh;
        squares.shape.mesh_data = boardSquares(dark);
        squares.shape.mesh = "chessboard squares (built in code)";
        squares.material = square.name;
        scene.objects.push_back(squares);
    }
    return scene;
}

struct PeerFigures {
    std::string config;
    Size size;
    double mixray_ms = 0;  // full frame, median of the timed frames
    uint64_t mixray_rays = 0;
    double ar_ms = 0;  // the AR frame (footprint on), median
    uint64_t ar_rays = 0;
    PovrayStats povray;                   // the run with the median trace time
    std::vector<double> povray_trace_ms;  // every run's, in the order they ran
    double povray_wall_ms = 0;
    double rmse = 0;             // codes, over every pixel and channel
    double far_off_percent = 0;  // pixels with a channel more than 24 codes apart
};

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

// Median milliseconds of `frames` renders of one pose (after one warm-up), and the rays of one.
Result<std::pair<double, uint64_t>> timeFrames(Renderer& renderer, const RenderInputs& inputs,
                                               int frames, RenderLayers& out) {
    RenderStats stats;
    MIXRAY_RETURN_IF_ERROR(renderer.render(inputs, out, &stats));
    std::vector<double> ms;
    for (int i = 0; i < frames; ++i) {
        const auto start = std::chrono::steady_clock::now();
        MIXRAY_RETURN_IF_ERROR(renderer.render(inputs, out, &stats));
        ms.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count());
    }
    return std::pair{median(std::move(ms)), stats.rays()};
}

// POV-Ray's trace time moves by up to 40 % from one run to the next on a shared machine (its
// threads' share of the cores), mixray's frame by less: each side is the median of its runs,
// mixray's `frames` frames and POV-Ray's `povray_runs` runs.
Result<PeerFigures> benchPeer(const fs::path& shared, const std::string& config_name,
                              const RenderOptions& base, Size size, int frames, int povray_runs,
                              const fs::path& work_dir) {
    PeerFigures fig;
    fig.config = config_name;
    fig.size = size;
    const double f = 0.9 * size.width;
    RenderInputs inputs;
    inputs.camera = calibration::CameraModel::pinhole(
        size.width, size.height, f, f, (size.width - 1) / 2.0, (size.height - 1) / 2.0);
    inputs.T_world_cam = cameraPose(0);
    Image black(ImageDesc::packed(PixelFormat::kRGB8, size.width, size.height));
    inputs.camera_image = black.view();

    const SceneDescription full = peerTeapotScene(shared, false);
    RenderOptions full_options = base;
    full_options.only_virtual_footprint = false;
    auto full_renderer = Renderer::create(full, full_options);
    if (!full_renderer)
        return full_renderer.status();
    RenderLayers full_out;
    auto full_time = timeFrames(**full_renderer, inputs, frames, full_out);
    if (!full_time)
        return full_time.status();
    std::tie(fig.mixray_ms, fig.mixray_rays) = *full_time;

    auto ar_renderer = Renderer::create(peerTeapotScene(shared, true), base);
    if (!ar_renderer)
        return ar_renderer.status();
    Image camera_image(black.desc());
    paintCameraImage(inputs.camera, inputs.T_world_cam, camera_image);
    RenderInputs ar_inputs = inputs;
    ar_inputs.camera_image = camera_image.view();
    RenderLayers ar_out;
    auto ar_time = timeFrames(**ar_renderer, ar_inputs, frames, ar_out);
    if (!ar_time)
        return ar_time.status();
    std::tie(fig.ar_ms, fig.ar_rays) = *ar_time;

    PovrayView view;
    view.camera = inputs.camera;
    view.T_world_cam = inputs.T_world_cam;
    view.max_depth = base.max_depth;
    view.shadows = base.shadows;
    auto text = povrayScene(full, view);
    if (!text)
        return text.status();
    fs::create_directories(work_dir);
    std::vector<PovrayRender> runs;
    for (int r = 0; r < std::max(1, povray_runs); ++r) {
        auto pov = renderWithPovray(
            *text, size.width, size.height,
            base.threads > 0 ? base.threads : static_cast<int>(std::thread::hardware_concurrency()),
            work_dir);
        if (!pov)
            return pov.status();
        fig.povray_trace_ms.push_back(1e3 * pov->stats.trace_s);
        runs.push_back(std::move(pov).value());
    }
    std::vector<size_t> order(runs.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](size_t a, size_t b) { return runs[a].stats.trace_s < runs[b].stats.trace_s; });
    const PovrayRender* const pov = &runs[order[order.size() / 2]];
    fig.povray = pov->stats;
    fig.povray_wall_ms = 1e3 * pov->wall_s;
    MIXRAY_RETURN_IF_ERROR(writePng(full_out.composite.view(), work_dir / "mixray.png"));
    MIXRAY_RETURN_IF_ERROR(writePng(ar_out.composite.view(), work_dir / "mixray_ar.png"));
    // Where the renderers disagree: each pixel's largest channel difference, times 8, in grey.
    auto difference = compareImages(full_out.composite.view(), pov->image.view(), 24);
    if (!difference)
        return difference.status();
    MIXRAY_RETURN_IF_ERROR(writePng(difference->worst_x8.view(), work_dir / "difference_x8.png"));
    fig.rmse = difference->rmse;
    fig.far_off_percent = difference->farOffPercent();
    return fig;
}

double megaRaysPerSecond(uint64_t rays, double ms) {
    return ms > 0 ? static_cast<double>(rays) / ms / 1e3 : 0.0;
}

void printPeer(const PeerFigures& f, const fs::path& work_dir) {
    // The frame's rays are those mixray traced: POV-Ray must trace the same for the same image.
    // Its own counters are printed too, but they also count the reflected rays it stops at its
    // last trace level (with max_trace_level 1, one per reflective pixel).
    const double pov_ms = 1e3 * f.povray.trace_s;
    const double mixray_rate = megaRaysPerSecond(f.mixray_rays, f.mixray_ms);
    const double pov_rate = megaRaysPerSecond(f.mixray_rays, pov_ms);
    std::printf("teapot, %s, %dx%d, %llu rays:\n", f.config.c_str(), f.size.width, f.size.height,
                static_cast<unsigned long long>(f.mixray_rays));
    std::printf("  mixray   full frame %8.2f ms  %7.2f Mrays/s   AR frame %6.2f ms (%llu rays)\n",
                f.mixray_ms, mixray_rate, f.ar_ms, static_cast<unsigned long long>(f.ar_rays));
    std::string runs;
    for (const double ms : f.povray_trace_ms) {
        char text[32];
        std::snprintf(text, sizeof text, "%.0f", ms);
        runs += (runs.empty() ? "" : ", ") + std::string(text);
    }
    std::printf(
        "  POV-Ray  full frame %8.2f ms  %7.2f Mrays/s   (trace, the median of %zu runs: %s ms; "
        "parse %.0f ms, the whole povray run %.0f ms; its counters: %llu rays, %llu shadow "
        "tests)\n",
        pov_ms, pov_rate, f.povray_trace_ms.size(), runs.c_str(), 1e3 * f.povray.parse_s,
        f.povray_wall_ms, static_cast<unsigned long long>(f.povray.rays),
        static_cast<unsigned long long>(f.povray.shadow_rays));
    std::printf(
        "  mixray / POV-Ray: rays/s %.1fx; full frame in %.3fx the time, the AR frame in "
        "%.4fx\n",
        pov_rate > 0 ? mixray_rate / pov_rate : 0.0, pov_ms > 0 ? f.mixray_ms / pov_ms : 0.0,
        pov_ms > 0 ? f.ar_ms / pov_ms : 0.0);
    std::printf("  images: RMSE %.2f codes; %.3f %% of pixels more than 24 codes apart (%s)\n",
                f.rmse, f.far_off_percent, work_dir.c_str());
}

nlohmann::json peerJson(const PeerFigures& f, const fs::path& work_dir) {
    return {{"peer", "povray"},
            {"config", f.config},
            {"width", f.size.width},
            {"height", f.size.height},
            {"mixray_ms", f.mixray_ms},
            {"mixray_rays", f.mixray_rays},
            {"mixray_mrays_per_s", megaRaysPerSecond(f.mixray_rays, f.mixray_ms)},
            {"ar_frame_ms", f.ar_ms},
            {"ar_frame_rays", f.ar_rays},
            {"povray_trace_ms", 1e3 * f.povray.trace_s},
            {"povray_trace_runs_ms", f.povray_trace_ms},
            {"povray_parse_ms", 1e3 * f.povray.parse_s},
            {"povray_wall_ms", f.povray_wall_ms},
            {"povray_mrays_per_s", megaRaysPerSecond(f.mixray_rays, 1e3 * f.povray.trace_s)},
            {"povray_counted_rays", f.povray.rays},
            {"povray_counted_shadow_tests", f.povray.shadow_rays},
            {"rmse_codes", f.rmse},
            {"far_off_percent", f.far_off_percent},
            {"images", work_dir.string()}};
}

// A fresh folder under the system's temporary folder, for files the bench writes.
Result<fs::path> makeWorkDir(const std::string& prefix) {
    std::string dir_template = (fs::temp_directory_path() / (prefix + "-XXXXXX")).string();
    if (mkdtemp(dir_template.data()) == nullptr)
        return Status(ErrorCode::kIoError,
                      "cannot make a folder under " + fs::temp_directory_path().string());
    return fs::path(dir_template);
}

int runBenchPeer(const BenchRenderOptions& options, const std::vector<Size>& sizes,
                 const fs::path& shared) {
    const fs::path teapot = shared / "06_models" / "newell_teapot.obj";
    if (!fs::exists(teapot)) {
        std::printf(
            "peer povray: skipped: %s not found (real data under ../shared/data, see its "
            "MANIFEST.md; or --shared-data)\n",
            teapot.c_str());
        return kExitOk;
    }
    const auto made = makeWorkDir("mixray-bench-povray");
    if (!made)
        return fail("bench render", made.status());
    const fs::path work_dir = *made;
    RenderOptions base;
    base.threads = options.threads;
    base.soft_shadows = SoftShadowMethod::kHard;
    base.samples_per_pixel = 1;
    base.cut_paths_see_environment = false;  // black, as POV-Ray past max_trace_level
    const auto configs = teapotVariants(base);
    if (!options.json)
        std::printf(
            "bench render --peer povray: the RT²AR teapot scene (mirror-and-diffuse teapot, "
            "chessboard table, one point light) in mixray and in POV-Ray, every pixel traced "
            "with 1 ray, both on %d threads; the AR frame traces only what the virtual teapot "
            "can change\n",
            options.threads > 0 ? options.threads
                                : static_cast<int>(std::thread::hardware_concurrency()));
    nlohmann::json results = nlohmann::json::array();
    for (const Size& size : sizes)
        for (const auto& [name, render_options] : configs) {
            const fs::path dir =
                work_dir / (std::to_string(size.width) + "x" + std::to_string(size.height) + "_" +
                            (render_options.max_depth > 0 ? "bounces"
                             : render_options.shadows     ? "shadows"
                                                          : "primary"));
            auto figures =
                benchPeer(shared, name, render_options, size, options.frames, options.repeats, dir);
            if (!figures && figures.status().code() == ErrorCode::kNotFound) {
                std::printf("peer povray: skipped: %s\n", figures.status().message().c_str());
                return kExitOk;
            }
            if (!figures)
                return fail("bench render", figures.status());
            if (options.json) {
                results.push_back(peerJson(*figures, dir));
            } else {
                printPeer(*figures, dir);
                std::fflush(stdout);
            }
        }
    if (options.json)
        std::printf("%s\n", results.dump(2).c_str());
    return kExitOk;
}

int runBenchRender(BenchRenderOptions options) {
    auto sizes = parseSizes(options.sizes);
    if (!sizes)
        return fail("bench render", sizes.status());
    auto isas = parseIsas(options.embree_isas);
    if (!isas)
        return fail("bench render", isas.status());
    auto scenes = parseScenes(options.scenes);
    if (!scenes)
        return fail("bench render", scenes.status());
    std::vector<int> map_sizes;
    for (const std::string& item : splitList(options.map_sizes)) {
        char* end = nullptr;
        const long side = std::strtol(item.c_str(), &end, 10);
        if (item.empty() || *end != '\0' || side < 16 || side > 8192)
            return fail("bench render",
                        {ErrorCode::kInvalidArgument,
                         "--map-sizes: '" + item + "' is not a side of 16..8192 texels"});
        map_sizes.push_back(static_cast<int>(side));
    }
    const fs::path shared =
        options.shared_data.empty() ? defaultSharedDataDir() : fs::path(options.shared_data);
    if (!options.peer.empty())
        return runBenchPeer(options, *sizes, shared);
    const unsigned threads = options.threads > 0
                                 ? static_cast<unsigned>(options.threads)
                                 : std::max(1u, std::thread::hardware_concurrency());
    if (!options.json)
        std::printf(
            "bench render: %u threads; efficiency = bare Embree time / renderer time "
            "for the same rays\n",
            threads);
    nlohmann::json results = nlohmann::json::array();
    for (const std::string& name : *scenes) {
        std::vector<fs::path> needed = {shared / "06_models" / "newell_teapot.obj"};
        if (name == "dragons" || name == "caustics")
            needed.push_back(shared / "06_models" / "photon_dragon_100k.obj");
        const auto missing = std::find_if(needed.begin(), needed.end(),
                                          [](const fs::path& p) { return !fs::exists(p); });
        if (missing != needed.end()) {
            const std::string why = missing->string() +
                                    " not found (real data under ../shared/data, see its "
                                    "MANIFEST.md; or --shared-data)";
            if (options.json)
                results.push_back({{"scene", name}, {"skipped", why}});
            else
                std::printf("%s: skipped: %s\n", name.c_str(), why.c_str());
            continue;
        }
        // dragons: their mesh file is kept beside the mesh cache, so that the cache (keyed by
        // the file's path, size and time) serves the next run; without a cache, in a folder
        // removed when the scene is done.
        std::optional<fs::path> scratch;
        struct RemoveScratch {
            const std::optional<fs::path>& dir;
            ~RemoveScratch() {
                std::error_code ignored;
                if (dir)
                    fs::remove_all(*dir, ignored);
            }
        } remove_scratch{scratch};
        DragonMesh dragon_mesh;
        fs::path dragon_dir = MeshCacheSettings::fromEnvironment().dir;
        if (name == "dragons" && dragon_dir.empty()) {
            auto made = makeWorkDir("mixray-bench-dragons");
            if (!made)
                return fail("bench render", made.status());
            dragon_dir = scratch.emplace(*made);
        } else if (name == "dragons") {
            dragon_dir = dragon_dir.parent_path() / "bench";
        }
        Result<SceneDescription> scene =
            name == "dragons"  ? dragonScene(shared, dragon_dir, dragon_mesh)
            : name == "ladder" ? Result<SceneDescription>(ladderScene(shared))
                               : Result<SceneDescription>(
                                     teapotScene(shared, name == "soft" || name == "shadow-maps"));
        if (!scene)
            return fail("bench render", scene.status());
        if (name == "dragons") {
            if (options.json)
                results.push_back({{"scene", name},
                                   {"mesh_file", dragon_mesh.ply.string()},
                                   {"assimp_import_ms", dragon_mesh.import_ms},
                                   {"mesh_cache_load_ms", dragon_mesh.cached_ms}});
            else {
                const std::string cached =
                    dragon_mesh.cached_ms > 0
                        ? "from the mesh cache it loads in " +
                              std::to_string(std::lround(dragon_mesh.cached_ms)) + " ms"
                        : "no mesh cache (MIXRAY_MESH_CACHE is off)";
                std::printf("dragons: %s: assimp imports it in %.0f ms; %s\n",
                            dragon_mesh.ply.c_str(), dragon_mesh.import_ms, cached.c_str());
            }
        }
        std::vector<Config> configs;
        for (const std::string& isa : *isas) {
            for (Config config : configsFor(name, options.threads, map_sizes)) {
                config.options.embree_isa = isa;
                if (!isa.empty())
                    config.name += " [isa=" + isa + "]";
                configs.push_back(std::move(config));
            }
        }
        // shadow-maps, soft, ladder: each size's first row's composite and frame time, which the
        // others are compared with.
        std::map<std::pair<int, int>, std::pair<Image, double>> references;
        for (const Config& config : configs) {
            SceneDescription with_lens = *scene;
            if (name == "caustics") {
                auto generator_scene = causticScene(shared, config.generator);
                if (!generator_scene)
                    return fail("bench render", generator_scene.status());
                with_lens = std::move(generator_scene).value();
                with_lens.caustics = config.caustics;
            }
            if (config.shadow_map)
                for (Light& light : with_lens.lights)
                    light.shadow_map = config.shadow_map;
            with_lens.lens_effects = config.lens_effects;
            with_lens.camera_matching = config.camera_matching;
            if (config.aperture) {
                with_lens.camera.emplace();
                with_lens.camera->has_pose = false;  // the bench's orbit
                with_lens.camera->aperture = config.aperture;
            }
            auto renderer = Renderer::create(with_lens, config.options);
            if (!renderer)
                return fail("bench render", renderer.status());
            for (const Size& size : *sizes) {
                auto figures = benchOne(**renderer, config, with_lens.lights, size, options.frames,
                                        options.repeats);
                if (!figures)
                    return fail("bench render", figures.status());
                figures->created = bench::creationTimes(**renderer);
                if (name == "shadow-maps" || name == "soft" || name == "ladder") {
                    const auto key = std::pair{size.width, size.height};
                    if (!references.contains(key)) {
                        references[key] = {figures->composite, figures->frame_ms};
                    } else {
                        const auto& [composite, frame_ms] = references[key];
                        figures->rmse_vs_reference =
                            rmse(figures->composite, composite, figures->camera);
                        figures->speedup_vs_reference = frame_ms / figures->frame_ms;
                    }
                }
                if (options.json) {
                    results.push_back(toJson(*figures));
                } else {
                    printFigures(*figures);
                    std::fflush(stdout);
                }
            }
        }
    }
    if (options.json)
        std::printf("%s\n", results.dump(2).c_str());
    return kExitOk;
}

}  // namespace

void registerBenchRender(CLI::App& bench, Commands& commands) {
    auto* render = bench.add_subcommand(
        "render",
        "Frames/s and rays/s of the Embree renderer on RT²AR's scenes (teapot on a chessboard "
        "table; soft shadows; two 1.1M-triangle dragons; depth of field; shadow maps; "
        "caustics; the quality ladder's rungs), against bare Embree tracing the same rays on the "
        "same BVH in the same run");
    auto options = std::make_shared<BenchRenderOptions>();
    render->add_option("--size", options->sizes, "Image sizes, WIDTHxHEIGHT[,WIDTHxHEIGHT...]")
        ->capture_default_str();
    render->add_option("--frames", options->frames, "Timed frames per scene and size")
        ->check(CLI::Range(1, 100'000))
        ->capture_default_str();
    render->add_option("--threads", options->threads, "Render threads (0: all hardware threads)")
        ->check(CLI::Range(0, 1024))
        ->capture_default_str();
    render
        ->add_option("--scenes", options->scenes,
                     "Scenes: teapot, soft, dragons, dof, shadow-maps, caustics, ladder (the "
                     "compositor's quality rungs against full quality) (comma list)")
        ->capture_default_str();
    render
        ->add_option("--repeats", options->repeats,
                     "Runs of the logged frame, on the renderer and on bare Embree; the best "
                     "counts (--peer: POV-Ray's runs, the median counts)")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    render->add_flag("--json", options->json, "Print the figures as JSON");
    render
        ->add_option("--embree-isa", options->embree_isas,
                     "Embree kernels: best (Embree's choice), all (every instruction set this "
                     "machine offers, one after another) or a comma list of sse2, sse4.2, avx, "
                     "avx2, avx512")
        ->capture_default_str();
    render
        ->add_option("--map-sizes", options->map_sizes,
                     "shadow-maps: shadow map sides in texels (comma list, 16..8192)")
        ->capture_default_str();
    render
        ->add_option("--peer", options->peer,
                     "Instead of the scenes: the RT²AR teapot scene rendered full frame by mixray "
                     "and by this renderer (povray: Debian's POV-Ray 3.7) in the same run; trace "
                     "times, rays/s, their ratio and the RMSE between the images")
        ->check(CLI::IsMember({"povray"}));
    render->add_option("--shared-data", options->shared_data,
                       "Real third-party data (default: ../shared/data beside the source tree)");
    commands.push_back({render, [options] { return runBenchRender(*options); }});
}

}  // namespace mixray::cli
