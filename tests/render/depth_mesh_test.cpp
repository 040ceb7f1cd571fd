// Real depth surfaces as geometry (DepthSecondaryRays::kMesh) and depth occlusion through the
// whole Renderer: analytic depth maps (a floor, a wall, a step) with virtual spheres, mirrors
// and lights, and real Kinect frames with a virtual box half behind a real surface.
#include <embree3/rtcore.h>
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "depth_mesh_geometry.h"
#include "mixray/render/depth_occlusion.h"
#include "renderer_test_util.h"
#include "test_data.h"

namespace mixray::render::test {
namespace {

using calibration::CameraModel;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr int kW = 160, kH = 120;
constexpr double kF = 200;

CameraModel camera(int w = kW, int h = kH) {
    return CameraModel::pinhole(w, h, kF, kF, (w - 1) / 2.0, (h - 1) / 2.0);
}

// A depth16 image: z_mm(x, y) per pixel (0 = none).
Image depthImage(int w, int h, const std::function<uint16_t(int, int)>& z_mm) {
    Image image(ImageDesc::packed(PixelFormat::kDepth16, w, h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            image.mutableView().row<uint16_t>(y)[x] = z_mm(x, y);
    return image;
}

Image noiseImage(uint8_t lo) {
    return filledImage(kW, kH, [lo](int x, int y) {
        const uint32_t h =
            (static_cast<uint32_t>(x) * 73856093u) ^ (static_cast<uint32_t>(y) * 19349663u);
        const auto channel = [&](int shift) {
            return static_cast<uint8_t>(lo + ((h >> shift) & 0xff) * (255 - lo) / 255);
        };
        return std::array<uint8_t, 3>{channel(0), channel(8), channel(16)};
    });
}

Image gradientImage() {
    return filledImage(kW, kH, [](int x, int y) {
        return std::array<uint8_t, 3>{static_cast<uint8_t>(40 + x), static_cast<uint8_t>(60 + y),
                                      100};
    });
}

std::unique_ptr<Renderer> makeRenderer(const SceneDescription& scene, const RenderOptions& o) {
    auto renderer = Renderer::create(scene, o);
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    return renderer ? std::move(renderer).value() : nullptr;
}

SceneObject ball(const Vector3d& centre, float radius, const std::string& material = "white") {
    SceneObject o = object("ball", ObjectRole::kVirtual, ShapeType::kSphere, material, centre);
    o.shape.radius = radius;
    return o;
}

// Distance along the unit ray o + t·u to the sphere; nullopt when it misses.
std::optional<double> sphereHit(const Vector3d& o, const Vector3d& u, const Vector3d& c, double r) {
    const Vector3d oc = o - c;
    const double b = oc.dot(u);
    const double disc = b * b - (oc.squaredNorm() - r * r);
    if (disc < 0)
        return std::nullopt;
    const double t = -b - std::sqrt(disc);
    return t > 0 ? std::optional<double>(t) : std::nullopt;
}

struct Rendered {
    RenderLayers out;
    RenderStats stats;
};

Rendered render(const SceneDescription& scene, RenderOptions options, const Image& color,
                const Image* depth, const CameraModel& model, const Eigen::Isometry3d& T) {
    Rendered r;
    options.keep_layers = true;
    auto renderer = makeRenderer(scene, options);
    if (!renderer)
        return r;
    RenderInputs in;
    in.camera_image = color.view();
    if (depth != nullptr)
        in.depth_mm = depth->view();
    in.camera = model;
    in.T_world_cam = T;
    const Status status = renderer->render(in, r.out, &r.stats);
    EXPECT_TRUE(status) << status.toString();
    return r;
}

// ---- the depth mesh, frame after frame ----

TEST(DepthMesh, MesherAndEmbreeGeometryReuseTheirBuffersBetweenFrames) {
    const CameraModel model = camera();
    const Image wall = depthImage(kW, kH, [](int, int) { return uint16_t{2000}; });
    const Image step =
        depthImage(kW, kH, [](int x, int) { return static_cast<uint16_t>(x < 70 ? 1200 : 2500); });
    DepthMesher mesher;
    TriangleMesh mesh;
    mesher.build({wall.view(), model}, {}, mesh);
    ASSERT_FALSE(mesh.empty());
    const auto* positions = mesh.positions.data();
    const auto* triangles = mesh.triangles.data();

    RTCDevice device = rtcNewDevice(nullptr);
    ASSERT_NE(device, nullptr);
    {
        detail::DepthMeshGeometry geometry(device);
        EXPECT_FALSE(geometry.update(mesh));  // the first frame sizes the buffers
        mesher.build({step.view(), model}, {}, mesh);
        EXPECT_EQ(mesh.positions.data(), positions);
        EXPECT_EQ(mesh.triangles.data(), triangles);
        EXPECT_TRUE(geometry.update(mesh));
        // The same mesh as depthToMesh, vertex for vertex.
        const TriangleMesh fresh = depthToMesh({step.view(), model});
        ASSERT_EQ(fresh.positions.size(), mesh.positions.size());
        ASSERT_EQ(fresh.triangles, mesh.triangles);
        for (size_t v = 0; v < mesh.positions.size(); ++v) {
            ASSERT_EQ(fresh.positions[v], mesh.positions[v]);
            ASSERT_EQ(fresh.normals[v], mesh.normals[v]);
            ASSERT_EQ(fresh.uvs[v], mesh.uvs[v]);
        }
        // The BVH holds the second frame: the step's two depths along two pixel rays.
        for (const auto& [x, z] : {std::pair{20, 1.2}, std::pair{140, 2.5}}) {
            const Vector3d u = *model.unproject(Vector2d(x, 60));
            RTCIntersectContext context;
            rtcInitIntersectContext(&context);
            RTCRayHit rh{};
            rh.ray.dir_x = static_cast<float>(u.x());
            rh.ray.dir_y = static_cast<float>(u.y());
            rh.ray.dir_z = static_cast<float>(u.z());
            rh.ray.tfar = 100;
            rh.ray.mask = 0xFFFFFFFFu;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(geometry.scene(), &context, &rh);
            ASSERT_NE(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID) << x;
            EXPECT_NEAR(rh.ray.tfar * u.z(), z, 1e-5) << x;
        }
        // An empty frame leaves nothing to hit.
        geometry.update(TriangleMesh{});
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        RTCRayHit rh{};
        rh.ray.dir_z = 1;
        rh.ray.tfar = 100;
        rh.ray.mask = 0xFFFFFFFFu;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(geometry.scene(), &context, &rh);
        EXPECT_EQ(rh.hit.geomID, RTC_INVALID_GEOMETRY_ID);
    }
    rtcReleaseDevice(device);
}

// ---- shadows of virtual objects on the depth surface ----

// A floor seen only through the depth map (camera 2 m above it, looking down), a virtual ball
// above it, two suns; the ball blocks sun a. In kMesh the floor pixels in its shadow become the
// camera pixel times E_b / (E_a cos θ_a + E_b), whatever colour the camera saw; all other floor
// pixels stay the camera's bit for bit. Without the mesh nothing real is there to shade.
TEST(DepthMesh, VirtualShadowOnTheDepthSurfaceDarkensCameraPixelsByThePredictedRatio) {
    const Vector3d dir_a(1, 0, -2);
    const float e_a = 2, e_b = 1;
    const Vector3d centre(0, 0, 0.5);
    const double radius = 0.1;
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    scene.objects.push_back(ball(centre, static_cast<float>(radius)));
    scene.lights.push_back(directionalLight("a", dir_a, e_a));
    scene.lights.push_back(directionalLight("b", {0, 0, -1}, e_b));
    const double cos_a = 2 / std::sqrt(5.0);
    const double ratio = e_b / (e_a * cos_a + e_b);

    const Eigen::Isometry3d T = lookDown({0, 0, 2});
    const CameraModel model = camera();
    const Image color = noiseImage(110);
    const Image depth = depthImage(kW, kH, [](int, int) { return uint16_t{2000}; });
    const Vector3d to_a = -dir_a.normalized();
    for (const DepthSecondaryRays mode :
         {DepthSecondaryRays::kMesh, DepthSecondaryRays::kScreenSpace}) {
        RenderOptions options;
        options.soft_shadows = SoftShadowMethod::kHard;
        options.depth_secondary = mode;
        const Rendered r = render(scene, options, color, &depth, model, T);
        int shadowed = 0, lit = 0;
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                const Vector3d u = T.linear() * *model.unproject(Vector2d(x, y));
                if (sphereHit(T.translation(), u, centre, radius + 0.01))
                    continue;  // the ball and its rim
                const Vector3d p = T.translation() + (-T.translation().z() / u.z()) * u;
                // Distance from the ball centre to the ray from p towards sun a.
                const Vector3d cp = centre - p;
                const double miss = (cp - cp.dot(to_a) * to_a).norm() - radius;
                ASSERT_EQ(r.out.mask.at(x, y)[0], 0.f) << x << "," << y;
                const uint8_t* got = pixelBytes(r.out.composite, x, y);
                const uint8_t* cam = pixelBytes(color, x, y);
                if (miss < -0.015 && mode == DepthSecondaryRays::kMesh) {
                    for (int c = 0; c < 3; ++c) {
                        const float in = optics::srgbToLinear(cam[c] / 255.f);
                        const float out = optics::srgbToLinear(got[c] / 255.f);
                        // One 8-bit step of the darkened value, relative.
                        EXPECT_NEAR(out / in, ratio, 0.03 * ratio) << x << "," << y << " " << c;
                    }
                    ++shadowed;
                } else if (miss > 0.015 || mode != DepthSecondaryRays::kMesh) {
                    ASSERT_TRUE(got[0] == cam[0] && got[1] == cam[1] && got[2] == cam[2])
                        << x << "," << y << " mode " << static_cast<int>(mode);
                    ++lit;
                }
            }
        if (mode == DepthSecondaryRays::kMesh) {
            EXPECT_GT(shadowed, 200);
        }
        EXPECT_GT(lit, kW * kH / 2);
    }
}

// The depth surface mirrors virtual objects (scene depth_surface.reflectance): in kMesh a ball
// lit from below appears in the floor where its mirror image projects, added to the camera
// pixel; elsewhere the floor stays the camera's.
TEST(DepthMesh, ReflectiveDepthSurfaceShowsTheVirtualObject) {
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    scene.objects.push_back(ball({0, 0, 0.5}, 0.1f));
    Light lamp;
    lamp.type = LightType::kPoint;
    lamp.position = {0, 0, 0.2};
    lamp.intensity = Rgb::Constant(1);
    scene.lights.push_back(lamp);
    scene.depth_surface.reflectance = 0.5f;
    const Eigen::Isometry3d T = lookDown({1, 0, 3});
    const CameraModel model = camera();
    const Image color = filledImage(kW, kH, [](int, int) {
        return std::array<uint8_t, 3>{90, 90, 90};
    });
    const Image depth = depthImage(kW, kH, [](int, int) { return uint16_t{3000}; });
    RenderOptions options;
    options.depth_secondary = DepthSecondaryRays::kMesh;
    const Rendered r = render(scene, options, color, &depth, model, T);
    const auto image = model.project(T.inverse() * Vector3d(0, 0, -0.5));
    ASSERT_TRUE(image);
    const int x = static_cast<int>(std::lround(image->x()));
    const int y = static_cast<int>(std::lround(image->y()));
    EXPECT_EQ(r.out.mask.at(x, y)[0], 0.f);
    EXPECT_GT(pixelBytes(r.out.composite, x, y)[0], 95);
    EXPECT_EQ(pixelBytes(r.out.composite, kW - 5, y)[0], 90);
    scene.depth_surface.reflectance = 0;
    const Rendered matte = render(scene, options, color, &depth, model, T);
    EXPECT_EQ(pixelBytes(matte.out.composite, x, y)[0], 90);
}

// Tracing only the pixels virtual content can touch gives the same composite as tracing all of
// them, also when that content is a shadow on the depth mesh (soft, from a spherical light) and
// a mirror's view of it; and it traces fewer pixels.
TEST(DepthMesh, FootprintTracingGivesTheSameImageAsTracingEverything) {
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    scene.materials["mirror"] = material(MaterialType::kMirror, "mirror");
    scene.objects.push_back(ball({0, 0, 1}, 0.12f));
    scene.objects.push_back(
        object("mirror", ObjectRole::kVirtual, ShapeType::kBox, "mirror", {1.3, 0.3, 0.1}));
    Light lamp;
    lamp.type = LightType::kSphere;
    lamp.position = {-1, 0, 2};
    lamp.radius = 0.08f;
    lamp.intensity = Rgb::Constant(4);
    scene.lights.push_back(lamp);
    scene.lights.push_back(directionalLight("sun", {0.3, 0.2, -1}, 1));
    const Eigen::Isometry3d T = lookDown({1, 0, 3});
    const CameraModel model =
        CameraModel::pinhole(kW, kH, 120, 120, (kW - 1) / 2.0, (kH - 1) / 2.0);
    // The floor 3 m below, with a real 20 cm step on the right.
    const Image depth =
        depthImage(kW, kH, [](int x, int) { return static_cast<uint16_t>(x < 110 ? 3000 : 2800); });
    const Image color = noiseImage(60);
    Image images[2];
    RenderStats stats[2];
    for (int i = 0; i < 2; ++i) {
        RenderOptions options;
        options.depth_secondary = DepthSecondaryRays::kMesh;
        options.only_virtual_footprint = i == 0;
        options.samples_per_pixel = 4;
        options.shadow_samples = 8;
        auto renderer = makeRenderer(scene, options);
        ASSERT_TRUE(renderer);
        RenderInputs in;
        in.camera_image = color.view();
        in.depth_mm = depth.view();
        in.camera = model;
        in.T_world_cam = T;
        RenderLayers out;
        ASSERT_TRUE(renderer->render(in, out, &stats[i]));
        images[i] = out.composite;
    }
    EXPECT_TRUE(sameImage(images[0].view(), images[1].view()));
    EXPECT_LT(stats[0].pixels_traced, stats[1].pixels_traced);
    EXPECT_EQ(stats[1].pixels_traced, static_cast<uint64_t>(kW * kH));
    // The shadow on the mesh is there: some floor pixels changed.
    size_t changed = 0;
    for (size_t i = 0; i < color.bytes().size(); ++i)
        changed += images[0].bytes()[i] != color.bytes()[i];
    EXPECT_GT(changed, 3000u);
}

// ---- the depth surface seen in a virtual mirror ----

// Camera 1 m high looking along +y at a real wall 5 m away that only the depth map knows, over
// a virtual mirror on the ground: mirror pixels show the camera's own pixel of the wall point the
// reflected ray meets, in kMesh (the mesh textured from the camera) as in kScreenSpace.
TEST(DepthMesh, VirtualMirrorShowsTheDepthSurfaceTexturedFromTheCamera) {
    SceneDescription scene;
    scene.materials["mirror"] = material(MaterialType::kMirror, "mirror");
    SceneObject mirror =
        object("mirror", ObjectRole::kVirtual, ShapeType::kPlane, "mirror", {0, 0, 0});
    mirror.shape.size = {4, 2, 0};
    scene.objects.push_back(mirror);
    const Vector3d eye(0, -3, 1);
    const Eigen::Isometry3d T = lookAlongY(eye);
    const CameraModel model =
        CameraModel::pinhole(kW, kH, 100, 100, (kW - 1) / 2.0, (kH - 1) / 2.0);
    const Image color = gradientImage();
    const Image depth = depthImage(kW, kH, [](int, int) { return uint16_t{5000}; });
    for (const DepthSecondaryRays mode :
         {DepthSecondaryRays::kMesh, DepthSecondaryRays::kScreenSpace}) {
        RenderOptions options;
        options.depth_secondary = mode;
        const Rendered r = render(scene, options, color, &depth, model, T);
        int checked = 0;
        for (int y = 0; y < kH; ++y)
            for (int x = 1; x + 1 < kW; ++x) {
                const Vector3d d = T.linear() * *model.unproject(Vector2d(x, y));
                if (d.z() >= 0)
                    continue;
                const Vector3d p = eye + (-eye.z() / d.z()) * d;  // on the mirror
                if (std::abs(p.x()) > 1.9 || std::abs(p.y()) > 0.95)
                    continue;
                EXPECT_EQ(r.out.mask.at(x, y)[0], 1.f);
                const Vector3d reflected(d.x(), d.y(), -d.z());
                const Vector3d q = p + ((2 - p.y()) / reflected.y()) * reflected;  // the wall
                const auto pixel = model.project(T.inverse() * q);
                ASSERT_TRUE(pixel);
                if (!(pixel->x() > 1 && pixel->x() < kW - 2 && pixel->y() > 1 &&
                      pixel->y() < kH - 2))
                    continue;  // the mesh ends a pixel inside the image
                const uint8_t* got = pixelBytes(r.out.composite, x, y);
                EXPECT_NEAR(got[0], 40 + pixel->x(), 1.5) << x << "," << y;
                EXPECT_NEAR(got[1], 60 + pixel->y(), 1.5) << x << "," << y;
                ++checked;
            }
        EXPECT_GT(checked, 500);
    }
}

// ---- real surfaces from the depth map shadow virtual objects ----

// Camera 1.5 m in front of a virtual ball (looking along +y); the depth map holds a real panel
// 15 cm behind the ball on the left of the image and a far wall elsewhere. Sun l comes from
// the left, behind the panel; sun r from the right, where nothing real is in the way. With
// kScreenSpace (RT²AR's traversal of the shadow ray) and kMesh (the mesh in the BVH) the ball
// loses sun l exactly where its shadow ray meets the panel: there it matches a render lit by sun
// r alone, elsewhere one lit by both without depth shadows.
TEST(DepthMesh, RealDepthStepShadowsAVirtualObject) {
    const Vector3d centre(0, 0, 0.5);
    const double radius = 0.12;
    const Vector3d eye(0, -1.5, 0.5);
    const Eigen::Isometry3d T = lookAlongY(eye);
    const int w = 2 * kW, h = 2 * kH;
    const CameraModel model =
        CameraModel::pinhole(w, h, 2 * kF, 2 * kF, (w - 1) / 2.0, (h - 1) / 2.0);
    const double panel_y = 0.15, panel_x = -0.47;  // the panel: y = 0.15, x < -0.47
    const int edge_px =
        static_cast<int>(std::floor(model.cx + panel_x / (panel_y - eye.y()) * model.fx));
    const Image depth = depthImage(
        w, h, [&](int x, int) { return static_cast<uint16_t>(x <= edge_px ? 1650 : 4500); });
    Image color(ImageDesc::packed(PixelFormat::kRGB8, w, h));
    std::fill(color.bytes().begin(), color.bytes().end(), uint8_t{50});
    const Vector3d dir_l(1, -0.6, 0), dir_r(-1, -0.6, 0);  // travel directions
    SceneDescription both;
    both.materials["white"] = material(MaterialType::kDiffuse, "white");
    both.objects.push_back(ball(centre, static_cast<float>(radius)));
    both.lights.push_back(directionalLight("l", dir_l, 1.5f));
    both.lights.push_back(directionalLight("r", dir_r, 1.5f));
    SceneDescription right_only = both;
    right_only.lights.erase(right_only.lights.begin());
    RenderOptions plain;
    plain.soft_shadows = SoftShadowMethod::kHard;
    plain.depth_thickness_m = 0.02f;
    plain.depth_secondary = DepthSecondaryRays::kNone;
    const Rendered lit = render(both, plain, color, &depth, model, T);
    const Rendered half = render(right_only, plain, color, &depth, model, T);

    const Vector3d to_l = -dir_l.normalized();
    for (const DepthSecondaryRays mode :
         {DepthSecondaryRays::kScreenSpace, DepthSecondaryRays::kMesh}) {
        RenderOptions options = plain;
        options.depth_secondary = mode;
        const Rendered r = render(both, options, color, &depth, model, T);
        int blocked = 0, open = 0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const Vector3d u = T.linear() * *model.unproject(Vector2d(x, y));
                const auto t = sphereHit(eye, u, centre, radius);
                if (!t || !sphereHit(eye, u, centre, radius - 0.01))
                    continue;  // off the ball or on its rim
                ASSERT_EQ(r.out.mask.at(x, y)[0], 1.f);
                const Vector3d p = eye + *t * u;
                const Vector3d n = (p - centre).normalized();
                const uint8_t got = pixelBytes(r.out.composite, x, y)[0];
                if (n.dot(to_l) <= 0) {  // sun l does not reach it anyway
                    EXPECT_NEAR(got, pixelBytes(lit.out.composite, x, y)[0], 1)
                        << x << "," << y << " mode " << static_cast<int>(mode);
                    continue;
                }
                // Where the shadow ray towards sun l meets the panel's plane, and its pixel.
                const Vector3d q = p + ((panel_y - p.y()) / to_l.y()) * to_l;
                const auto q_px = model.project(T.inverse() * q);
                ASSERT_TRUE(q_px);
                ASSERT_TRUE(q_px->x() > 2 && q_px->y() > 2 && q_px->y() < h - 3)
                    << "the panel crossing must be inside the image";
                if (q.x() < panel_x - 0.01) {
                    EXPECT_NEAR(got, pixelBytes(half.out.composite, x, y)[0], 1)
                        << x << "," << y << " mode " << static_cast<int>(mode);
                    if (n.dot(to_l) > 0.3) {
                        EXPECT_LT(got + 10, pixelBytes(lit.out.composite, x, y)[0]);
                    }
                    ++blocked;
                } else if (q.x() > panel_x + 0.05) {
                    // Past the panel's edge by more than the 2 cm shell kScreenSpace gives a
                    // depth sample (the ray is that far behind the panel when it reaches it).
                    EXPECT_NEAR(got, pixelBytes(lit.out.composite, x, y)[0], 1) << x << "," << y;
                    ++open;
                }
            }
        EXPECT_GT(blocked, 30) << static_cast<int>(mode);
        EXPECT_GT(open, 30) << static_cast<int>(mode);
        RecordProperty("blocked_open_" + std::to_string(static_cast<int>(mode)),
                       std::to_string(blocked) + "/" + std::to_string(open));
    }
}

// ---- primary occlusion ----

// The virtual object is visible exactly where its distance along the pixel's ray is below the
// depth's (rayDistanceAt), hidden where above: M per pixel against that rule, with a band of
// `band_m` around the crossing left out. Returns {visible, hidden} pixel counts.
std::pair<int, int> checkOcclusion(const RenderLayers& out, const Image& depth_image,
                                   const CameraModel& model,
                                   const std::function<std::optional<double>(const Vector3d&)>& hit,
                                   double band_m) {
    const DepthView depth{depth_image.view(), model};
    int visible = 0, hidden = 0;
    for (int y = 0; y < model.height; ++y)
        for (int x = 0; x < model.width; ++x) {
            const Vector3d u = *model.unproject(Vector2d(x, y));
            const auto t = hit(u);
            const float m = out.mask.at(x, y)[0];
            if (!t) {
                EXPECT_EQ(m, 0.f) << x << "," << y;
                continue;
            }
            const auto limit = rayDistanceAt(depth, x, y);
            if (limit && std::abs(*t - *limit) < band_m)
                continue;
            if (!limit || *t < *limit) {
                EXPECT_EQ(m, 1.f) << x << "," << y << " t " << *t;
                ++visible;
            } else {
                EXPECT_EQ(m, 0.f) << x << "," << y << " t " << *t << " depth " << *limit;
                ++hidden;
            }
        }
    return {visible, hidden};
}

// A virtual ball 2 m ahead, cut by a real wall at z = 2 m on the left of the image: kNone,
// kScreenSpace and kMesh hide the same pixels, the ones rayDistanceAt says.
TEST(DepthMesh, AllDepthModesAgreeOnPrimaryOcclusion) {
    const Vector3d centre(0, 0, 2);
    const double radius = 0.3;
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    scene.objects.push_back(ball(centre, static_cast<float>(radius)));
    scene.lights.push_back(directionalLight("sun", {0.2, 0.3, 1}, 2));
    const CameraModel model = camera();
    const Image depth = depthImage(kW, kH, [](int x, int y) {
        return static_cast<uint16_t>(x < kW / 2 + 7 && y > 10 ? 1700 + x : 0);
    });
    const Image color = noiseImage(0);
    std::optional<std::vector<float>> first;
    for (const DepthSecondaryRays mode :
         {DepthSecondaryRays::kNone, DepthSecondaryRays::kScreenSpace, DepthSecondaryRays::kMesh}) {
        RenderOptions options;
        options.depth_secondary = mode;
        const Rendered r =
            render(scene, options, color, &depth, model, Eigen::Isometry3d::Identity());
        const auto [visible, hidden] = checkOcclusion(
            r.out, depth, model,
            [&](const Vector3d& u) { return sphereHit(Vector3d::Zero(), u, centre, radius); },
            1e-4);
        EXPECT_GT(visible, 500);
        EXPECT_GT(hidden, 500);
        if (!first) {
            first = r.out.mask.pixels;
        } else {
            EXPECT_EQ(*first, r.out.mask.pixels) << static_cast<int>(mode);
        }
    }
}

// ---- real Kinect frames ----

struct KinectFrame {
    Image color;
    Image depth_mm;
    CameraModel camera;
};

// An rgb8 colour image and a depth16 image in millimetres (`units_per_mm` raw units each).
std::optional<KinectFrame> readKinect(const std::filesystem::path& color_path,
                                      const std::filesystem::path& depth_path, double units_per_mm,
                                      const CameraModel& model) {
    const cv::Mat bgr = cv::imread(color_path.string(), cv::IMREAD_COLOR);
    const cv::Mat raw = cv::imread(depth_path.string(), cv::IMREAD_UNCHANGED);
    EXPECT_FALSE(bgr.empty()) << color_path;
    EXPECT_FALSE(raw.empty()) << depth_path;
    if (bgr.empty() || raw.empty() || raw.type() != CV_16UC1)
        return std::nullopt;
    EXPECT_EQ(bgr.cols, model.width);
    EXPECT_EQ(raw.cols, model.width);
    EXPECT_EQ(raw.rows, model.height);
    cv::Mat rgb;
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    KinectFrame frame{Image(ImageDesc::packed(PixelFormat::kRGB8, rgb.cols, rgb.rows)),
                      Image(ImageDesc::packed(PixelFormat::kDepth16, raw.cols, raw.rows)), model};
    for (int y = 0; y < rgb.rows; ++y) {
        std::memcpy(frame.color.mutableView().row<uint8_t>(y), rgb.ptr<uint8_t>(y), 3 * rgb.cols);
        for (int x = 0; x < raw.cols; ++x)
            frame.depth_mm.mutableView().row<uint16_t>(y)[x] =
                static_cast<uint16_t>(std::lround(raw.at<uint16_t>(y, x) / units_per_mm));
    }
    return frame;
}

// A virtual box (camera frame, axis-aligned) half behind a real object: centred on the largest
// depth step of the frame's middle rows (a foreground object's silhouette), between the near
// and the far surface. Rendered in every depth mode, its mask must follow rayDistanceAt pixel by
// pixel (a 2 mm band at the crossing aside, for float against double).
void checkBoxStraddlingRealSurface(const KinectFrame& frame) {
    const DepthView depth{frame.depth_mm.view(), frame.camera};
    const int w = frame.camera.width, h = frame.camera.height;
    float jump = 0, z_mid = 0;
    int px = 0, py = 0;
    for (int y = h * 3 / 10; y < h * 7 / 10; y += 4)
        for (int x = w / 6; x + 4 < w * 5 / 6; ++x) {
            const auto a = depth.zAt(x, y), b = depth.zAt(x + 4, y);
            if (a && b && std::abs(*a - *b) > jump) {
                jump = std::abs(*a - *b);
                z_mid = 0.5f * (*a + *b);
                px = x + 2;
                py = y;
            }
        }
    ASSERT_GT(jump, 0.2f) << "no depth step in the frame";
    ::testing::Test::RecordProperty("step_px", std::to_string(px) + "," + std::to_string(py));
    ::testing::Test::RecordProperty("step_m", std::to_string(jump));
    const Vector3d u0 = *frame.camera.unproject(Vector2d(px, py));
    const Vector3d centre = u0 * (z_mid / u0.z());
    const double half_z = std::min(0.15, 0.4 * jump);
    const Vector3d half(0.12, 0.09, half_z);
    SceneDescription scene;
    scene.materials["white"] = material(MaterialType::kDiffuse, "white");
    SceneObject box = object("box", ObjectRole::kVirtual, ShapeType::kBox, "white", centre);
    box.shape.size = (2 * half).cast<float>();
    scene.objects.push_back(box);
    Light lamp;
    lamp.type = LightType::kPoint;
    lamp.position = {0.3, -0.4, 0};
    lamp.intensity = Rgb::Constant(0.5f);
    scene.lights.push_back(lamp);
    const auto boxHit = [&](const Vector3d& u) -> std::optional<double> {
        double t0 = 0, t1 = 1e9;
        for (int k = 0; k < 3; ++k) {
            double a = (centre[k] - half[k]) / u[k], b = (centre[k] + half[k]) / u[k];
            if (a > b)
                std::swap(a, b);
            t0 = std::max(t0, a);
            t1 = std::min(t1, b);
        }
        return t0 <= t1 && t0 > 0 ? std::optional<double>(t0) : std::nullopt;
    };
    std::optional<std::vector<float>> first;
    for (const DepthSecondaryRays mode :
         {DepthSecondaryRays::kNone, DepthSecondaryRays::kScreenSpace, DepthSecondaryRays::kMesh}) {
        RenderOptions options;
        options.depth_secondary = mode;
        const Rendered r = render(scene, options, frame.color, &frame.depth_mm, frame.camera,
                                  Eigen::Isometry3d::Identity());
        const auto [visible, hidden] =
            checkOcclusion(r.out, frame.depth_mm, frame.camera, boxHit, 2e-3);
        EXPECT_GT(visible, 500) << static_cast<int>(mode);
        EXPECT_GT(hidden, 500) << static_cast<int>(mode);
        ::testing::Test::RecordProperty("visible_" + std::to_string(static_cast<int>(mode)),
                                        visible);
        ::testing::Test::RecordProperty("hidden_" + std::to_string(static_cast<int>(mode)), hidden);
        if (!first) {
            first = r.out.mask.pixels;
        } else {
            EXPECT_EQ(*first, r.out.mask.pixels) << static_cast<int>(mode);
        }
    }
}

// The TUM frame as Open3D ships it, with the intrinsics Open3D pairs it with (the PrimeSense
// default 525/525/319.5/239.5): the source does not say which TUM sequence (fr1/fr2/fr3, each
// calibrated differently) it comes from, and TUM's depth is registered to the colour image.
// Depth PNG: 5000 units per metre, 5 per millimetre.
TEST(DepthMeshReal, TumFrameHidesTheVirtualBoxExactlyWhereTheDepthIsNearer) {
    const auto dir = mixray::test::sharedDataDir() / "02_rgbd_single_frames_open3d";
    MIXRAY_REQUIRE_SHARED_DATA(dir / "TUM_depth.png");
    const auto frame = readKinect(dir / "TUM_color.png", dir / "TUM_depth.png", 5.0,
                                  CameraModel::pinhole(640, 480, 525, 525, 319.5, 239.5));
    ASSERT_TRUE(frame);
    checkBoxStraddlingRealSurface(*frame);
}

// PCL's OpenNI TIFF frame with the intrinsics its grabber test deprojects it with.
TEST(DepthMeshReal, PclTiffFrameHidesTheVirtualBoxExactlyWhereTheDepthIsNearer) {
    const auto dir = mixray::test::sharedDataDir() / "02_rgbd_pcl_openni_tiff";
    MIXRAY_REQUIRE_SHARED_DATA(dir / "frame_20121214T142255.814212_depth.tiff");
    const auto frame = readKinect(dir / "frame_20121214T142255.814212_rgb.tiff",
                                  dir / "frame_20121214T142255.814212_depth.tiff", 1.0,
                                  CameraModel::pinhole(640, 480, 525, 525, 320, 240));
    ASSERT_TRUE(frame);
    checkBoxStraddlingRealSurface(*frame);
}

}  // namespace
}  // namespace mixray::render::test
