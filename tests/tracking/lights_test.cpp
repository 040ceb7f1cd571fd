// Light estimation (tracking/src/light_probe.cpp, environment_light.cpp, environment_map.cpp,
// environment_estimator.cpp) on the committed simulated session: frames from
// fixtures/sessions/sim_tabletop.mkv, truth from the simulator built with the options that made
// it, true camera poses.
#include "mixray/tracking/lights.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <numbers>
#include <vector>

#include "mixray/graph/graph.h"
#include "mixray/graph/mkv.h"
#include "mixray/render/assets.h"
#include "mixray/render/simulator.h"
#include "mixray/tracking/camera_environment.h"
#include "mixray/tracking/environment_light_node.h"
#include "mixray/tracking/light_record.h"
#include "test_data.h"

namespace mixray::tracking {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

constexpr double kDeg = std::numbers::pi / 180;

// The truth of the committed session: the simulator built with the options that made it.
const render::SimTruth& truth() {
    static const std::unique_ptr<render::Simulator> sim = [] {
        render::SimulatorOptions o;
        o.scenario = render::SimScenario::kTabletop;
        o.frames = 36;
        o.seed = 1;
        auto created = render::Simulator::create(o);
        if (!created)
            throw std::runtime_error(created.status().toString());
        return std::move(created).value();
    }();
    return sim->truth();
}

struct Frames {
    std::vector<Image> color;  // by frame index from 0
    std::vector<Image> env;    // the environment frames in order
};

// The session's frames from the start; reading stops once `colors` colour and `envs`
// environment frames are in (decoding the whole file is most of a test's time).
Frames readFrames(size_t colors, size_t envs) {
    Frames out;
    auto reader = openMkv(test::fixturesDir() / "sessions" / "sim_tabletop.mkv");
    if (!reader)
        throw std::runtime_error(reader.status().toString());
    while (out.color.size() < colors || out.env.size() < envs) {
        auto frame = (*reader)->next();
        if (!frame)
            break;
        const std::string& name = (*reader)->streams()[frame->meta().stream].name;
        if (name == "kinect/color") {
            if (frame->meta().sequence != out.color.size())
                throw std::runtime_error("colour frames out of order");
            out.color.push_back(Image::copyOf(frame->image()));
        } else if (name == "env/color") {
            out.env.push_back(Image::copyOf(frame->image()));
        }
    }
    return out;
}

const Frames& allFrames() {
    static const Frames frames = readFrames(SIZE_MAX, SIZE_MAX);
    return frames;
}

// Colour frame 0 and the environment frame taken with it.
const Frames& firstFrames() {
    static const Frames frames = readFrames(1, 1);
    return frames;
}

const Image& firstColor() {
    return firstFrames().color.at(0);
}
const Image& firstEnv() {
    return firstFrames().env.at(0);
}

Vector3d toLight(const render::Light& light) {
    return -light.direction.normalized();
}

double angleDeg(const Vector3d& a, const Vector3d& b) {
    return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) / kDeg;
}

// The estimate nearest to `truth`, in degrees; +inf when there is none.
double nearestDeg(const std::vector<EstimatedLight>& lights, const Vector3d& truth) {
    double best = INFINITY;
    for (const EstimatedLight& l : lights)
        best = std::min(best, angleDeg(l.to_light_world, truth));
    return best;
}

double median(std::vector<double> v) {
    if (v.empty())
        return INFINITY;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

LightProbe probeOf(const render::SimProbe& p) {
    LightProbe probe;
    probe.name = p.name;
    probe.material = p.material == render::MaterialType::kMirror ? ProbeMaterial::kMirror
                                                                 : ProbeMaterial::kDiffuse;
    probe.radius_m = p.radius_m;
    probe.centre_world = p.centre_world;
    return probe;
}

const render::SimProbe& simProbe(render::MaterialType material) {
    for (const render::SimProbe& p : truth().probes)
        if (p.material == material)
            return p;
    throw std::runtime_error("no such probe");
}

EnvironmentCamera envCamera() {
    EnvironmentCamera camera;
    camera.model = truth().env;
    camera.T_world_env = truth().T_world_env;
    return camera;
}

struct ProbeErrors {
    std::vector<double> key, fill;
    int found = 0;
    double min_radius_px = INFINITY, max_radius_px = 0;
};

ProbeErrors probeErrors(render::MaterialType material, ProbeDomain domain) {
    const std::vector<Image>& color = allFrames().color;
    const render::SimTruth& t = truth();
    const LightProbe probe = probeOf(simProbe(material));
    ProbeOptions options;
    options.domain = domain;
    ProbeErrors e;
    for (size_t i = 0; i < t.frames.size(); i += 2) {
        auto r = estimateProbeLights(color.at(i).view(), t.color, t.frames[i].T_world_color, probe,
                                     options);
        if (!r) {
            EXPECT_EQ(r.status().code(), ErrorCode::kNotFound) << r.status().toString();
            continue;
        }
        ++e.found;
        EXPECT_FALSE(r->lights.empty());
        EXPECT_LE(r->lights.size(), 2u);
        EXPECT_GT(r->outline.radius_px, 10);
        e.min_radius_px = std::min(e.min_radius_px, r->outline.radius_px);
        e.max_radius_px = std::max(e.max_radius_px, r->outline.radius_px);
        e.key.push_back(nearestDeg(r->lights, toLight(t.lights[0])));
        e.fill.push_back(nearestDeg(r->lights, toLight(t.lights[1])));
    }
    return e;
}

void expectProbeAccuracy(render::MaterialType material, ProbeDomain domain, const char* what) {
    const ProbeErrors e = probeErrors(material, domain);
    std::cout << what << ": " << e.found << " frames, key median " << median(e.key) << " deg (max "
              << *std::max_element(e.key.begin(), e.key.end()) << "), fill median "
              << median(e.fill) << " deg; probe radius " << e.min_radius_px << " to "
              << e.max_radius_px << " px\n";
    EXPECT_GE(e.found, 15) << "of 18 frames";
    EXPECT_LT(median(e.key), 3.0) << what;
    EXPECT_LT(median(e.fill), 3.0) << what;
}

TEST(LightProbe, MirrorImageDomainFindsTheKeyLight) {
    expectProbeAccuracy(render::MaterialType::kMirror, ProbeDomain::kImage, "mirror/image");
}

TEST(LightProbe, MirrorSphereDomainFindsTheKeyLight) {
    expectProbeAccuracy(render::MaterialType::kMirror, ProbeDomain::kSphere, "mirror/sphere");
}

TEST(LightProbe, DiffuseImageDomainFindsTheKeyLight) {
    expectProbeAccuracy(render::MaterialType::kDiffuse, ProbeDomain::kImage, "diffuse/image");
}

TEST(LightProbe, DiffuseSphereDomainFindsTheKeyLight) {
    expectProbeAccuracy(render::MaterialType::kDiffuse, ProbeDomain::kSphere, "diffuse/sphere");
}

TEST(LightProbe, DiffuseRanksTheKeyFirst) {
    const render::SimTruth& t = truth();
    auto r = estimateProbeLights(firstColor().view(), t.color, t.frames[0].T_world_color,
                                 probeOf(simProbe(render::MaterialType::kDiffuse)));
    ASSERT_TRUE(r) << r.status().toString();
    ASSERT_FALSE(r->lights.empty());
    EXPECT_LT(angleDeg(r->lights[0].to_light_world, toLight(t.lights[0])), 3.0);
    ASSERT_EQ(r->lights.size(), 2u);
    EXPECT_LT(angleDeg(r->lights[1].to_light_world, toLight(t.lights[1])), 3.0);
    // Relative intensities in linear RGB: the key 1 in luminance, warm; the fill cool, at the
    // truth's ratio of luminances.
    auto luminance = [](const Eigen::Vector3d& c) {
        return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z();
    };
    EXPECT_NEAR(luminance(r->lights[0].intensity), 1.0, 1e-9);
    EXPECT_GT(r->lights[0].intensity.x(), r->lights[0].intensity.z());
    EXPECT_LT(r->lights[1].intensity.x(), r->lights[1].intensity.z());
    const double ratio = luminance(t.lights[1].intensity.cast<double>()) /
                         luminance(t.lights[0].intensity.cast<double>());
    EXPECT_NEAR(luminance(r->lights[1].intensity), ratio, 0.1 * ratio);
    EXPECT_EQ(r->lights[0].source, LightSource::kProbeDiffuse);
}

TEST(LightProbe, OutOfViewDarkAndFlatAreNotFound) {
    const render::SimTruth& t = truth();
    const LightProbe probe = probeOf(simProbe(render::MaterialType::kMirror));
    // The camera turned round: the probe is behind it.
    Isometry3d away = t.frames[0].T_world_color;
    away.linear() = away.linear() * Eigen::AngleAxisd(std::numbers::pi, Vector3d::UnitY());
    auto r = estimateProbeLights(firstColor().view(), t.color, away, probe);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(r.status().message().find("out of view"), std::string::npos) << r.status().message();
    // Turned 70° sideways: the probe leaves the image.
    Isometry3d aside = t.frames[0].T_world_color;
    aside.linear() = aside.linear() * Eigen::AngleAxisd(70 * kDeg, Vector3d::UnitY());
    r = estimateProbeLights(firstColor().view(), t.color, aside, probe);
    ASSERT_FALSE(r);
    EXPECT_NE(r.status().message().find("out of view"), std::string::npos) << r.status().message();

    Image black(ImageDesc::packed(PixelFormat::kRGB8, t.color.width, t.color.height));
    for (const ProbeMaterial material : {ProbeMaterial::kMirror, ProbeMaterial::kDiffuse}) {
        LightProbe p = probe;
        p.material = material;
        r = estimateProbeLights(black.view(), t.color, t.frames[0].T_world_color, p);
        ASSERT_FALSE(r);
        EXPECT_EQ(r.status().code(), ErrorCode::kNotFound);
        EXPECT_NE(r.status().message().find("too dark"), std::string::npos) << r.status().message();
    }
    Image grey = black;
    std::fill(grey.bytes().begin(), grey.bytes().end(), 128);
    r = estimateProbeLights(grey.view(), t.color, t.frames[0].T_world_color, probe);
    ASSERT_FALSE(r);
    EXPECT_NE(r.status().message().find("no highlight"), std::string::npos) << r.status().message();
}

TEST(LightProbe, BadInputsAreInvalidArguments) {
    const render::SimTruth& t = truth();
    const LightProbe probe = probeOf(simProbe(render::MaterialType::kMirror));
    const Isometry3d& T = t.frames[0].T_world_color;
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, t.color.width, t.color.height));
    EXPECT_EQ(estimateProbeLights(depth.view(), t.color, T, probe).status().code(),
              ErrorCode::kInvalidArgument);
    Image small(ImageDesc::packed(PixelFormat::kRGB8, 32, 24));
    EXPECT_EQ(estimateProbeLights(small.view(), t.color, T, probe).status().code(),
              ErrorCode::kInvalidArgument);
    LightProbe bad = probe;
    bad.radius_m = 0;
    EXPECT_EQ(estimateProbeLights(firstColor().view(), t.color, T, bad).status().code(),
              ErrorCode::kInvalidArgument);
    ProbeOptions options;
    options.max_lights = 0;
    EXPECT_EQ(estimateProbeLights(firstColor().view(), t.color, T, probe, options).status().code(),
              ErrorCode::kInvalidArgument);
    // Mono and BGR images of the same frame give the same key light as RGB.
    Image bgr(ImageDesc::packed(PixelFormat::kBGR8, t.color.width, t.color.height));
    Image mono(ImageDesc::packed(PixelFormat::kMono8, t.color.width, t.color.height));
    const std::vector<uint8_t>& rgb = firstColor().bytes();
    for (size_t i = 0; i < static_cast<size_t>(t.color.width) * t.color.height; ++i) {
        for (size_t c = 0; c < 3; ++c)
            bgr.bytes()[3 * i + c] = rgb[3 * i + 2 - c];
        mono.bytes()[i] = rgb[3 * i + 1];
    }
    auto rgb_result = estimateProbeLights(firstColor().view(), t.color, T, probe);
    auto bgr_result = estimateProbeLights(bgr.view(), t.color, T, probe);
    auto mono_result = estimateProbeLights(mono.view(), t.color, T, probe);
    ASSERT_TRUE(rgb_result && bgr_result && mono_result);
    EXPECT_LT(angleDeg(rgb_result->lights[0].to_light_world, bgr_result->lights[0].to_light_world),
              1e-9);
    EXPECT_LT(nearestDeg(mono_result->lights, toLight(t.lights[0])), 3.0);
}

// ---- the fish-eye environment camera ----

TEST(EnvironmentLights, FindTheLightsThroughTheFisheye) {
    const std::vector<Image>& envs = allFrames().env;
    const render::SimTruth& t = truth();
    ASSERT_EQ(envs.size(), 3u);
    EnvironmentCamera camera = envCamera();
    camera.room_radius_m = 3;
    std::vector<double> key, fill;
    for (const Image& env : envs) {
        auto lights = estimateEnvironmentLights(env.view(), camera);
        ASSERT_TRUE(lights) << lights.status().toString();
        ASSERT_GE(lights->size(), 2u);
        key.push_back(nearestDeg(*lights, toLight(t.lights[0])));
        fill.push_back(nearestDeg(*lights, toLight(t.lights[1])));
        for (const EstimatedLight& l : *lights) {
            EXPECT_EQ(l.source, LightSource::kEnvironment);
            ASSERT_TRUE(l.position_world);
            EXPECT_NEAR((*l.position_world - t.T_world_env.translation()).norm(), 3, 1e-9);
            EXPECT_LT(angleDeg(*l.position_world - t.T_world_env.translation(), l.to_light_world),
                      1e-6);
            // The discs are 4° in radius; clipping hides their radiance, not their size.
            EXPECT_GT(l.angular_radius_rad, 2 * kDeg);
            EXPECT_LT(l.angular_radius_rad, 6 * kDeg);
            EXPECT_GT(l.intensity.minCoeff(), 0);
        }
    }
    std::cout << "fisheye: " << envs.size() << " frames, key median " << median(key)
              << " deg, fill median " << median(fill) << " deg\n";
    EXPECT_LT(median(key), 3.0);
    EXPECT_LT(median(fill), 3.0);
}

Image filled(const calibration::CameraModel& model, uint8_t value) {
    Image image(ImageDesc::packed(PixelFormat::kRGB8, model.width, model.height));
    std::fill(image.bytes().begin(), image.bytes().end(), value);
    return image;
}

// A synthetic fish-eye image of a dim room with one unclipped round lamp: the estimate's
// irradiance is the lamp's radiance times its solid angle, scaled by the exposure.
TEST(EnvironmentLights, IntensityIsRadianceOverTheSolidAngle) {
    EnvironmentCamera camera = envCamera();
    camera.exposure_scale = 2;
    const calibration::CameraModel& model = camera.model;
    const Vector3d lamp = Vector3d(0.3, 0.2, 1).normalized();
    const double radius = 5 * kDeg;
    Image image(ImageDesc::packed(PixelFormat::kRGB8, model.width, model.height));
    for (int y = 0; y < model.height; ++y)
        for (int x = 0; x < model.width; ++x) {
            const auto d = model.unproject(Eigen::Vector2d(x, y));
            const bool lit = d && angleDeg(camera.T_world_env.linear() * *d, lamp) * kDeg < radius;
            std::fill_n(image.bytes().begin() + 3 * (static_cast<size_t>(y) * model.width + x), 3,
                        lit ? 245 : 60);
        }
    auto lights = estimateEnvironmentLights(image.view(), camera);
    ASSERT_TRUE(lights) << lights.status().toString();
    ASSERT_EQ(lights->size(), 1u);
    const EstimatedLight& l = lights->front();
    EXPECT_LT(angleDeg(l.to_light_world, lamp), 0.3);
    const double radiance = std::pow((245 / 255.0 + 0.055) / 1.055, 2.4);
    const double expected = 2 * radiance * 2 * std::numbers::pi * (1 - std::cos(radius));
    EXPECT_NEAR(l.intensity.x(), expected, 0.04 * expected);
    EXPECT_NEAR(l.angular_radius_rad, radius, 0.3 * kDeg);
    EXPECT_FALSE(l.position_world) << "no room size: directional";
}

TEST(EnvironmentLights, BlackOverExposedAndFeaturelessAreNotFound) {
    const EnvironmentCamera camera = envCamera();
    const std::map<uint8_t, std::string> cases = {
        {0, "black"}, {255, "over-exposed"}, {120, "featureless"}};
    for (const auto& [value, reason] : cases) {
        auto lights = estimateEnvironmentLights(filled(camera.model, value).view(), camera);
        ASSERT_FALSE(lights) << reason;
        EXPECT_EQ(lights.status().code(), ErrorCode::kNotFound);
        EXPECT_NE(lights.status().message().find(reason), std::string::npos)
            << lights.status().message();
    }
    Image wrong(ImageDesc::packed(PixelFormat::kRGB8, 64, 64));
    EXPECT_EQ(estimateEnvironmentLights(wrong.view(), camera).status().code(),
              ErrorCode::kInvalidArgument);
    EnvironmentCamera bad = camera;
    bad.exposure_scale = 0;
    EXPECT_EQ(estimateEnvironmentLights(filled(camera.model, 0).view(), bad).status().code(),
              ErrorCode::kInvalidArgument);
}

// Radiance-weighted mean direction of the map's texels above `threshold` near `around`, with
// the renderer's own texel-to-direction convention.
Vector3d brightSpot(const render::EnvironmentMap& map, const Vector3d& around, float threshold) {
    const render::Texture& tex = map.texture();
    Vector3d sum = Vector3d::Zero();
    for (int y = 0; y < tex.height(); ++y)
        for (int x = 0; x < tex.width(); ++x) {
            const Eigen::Vector3f d =
                map.directionOf({static_cast<float>(x), static_cast<float>(y)});
            const float value = tex.texel(x, y).mean();
            if (value < threshold || angleDeg(d.cast<double>(), around) > 15)
                continue;
            const double solid_angle = std::sin(std::numbers::pi * (y + 0.5) / tex.height());
            sum += solid_angle * value * d.cast<double>();
        }
    return sum;
}

render::EnvironmentMap asRendererMap(const FloatImage& image) {
    std::vector<render::Rgb> texels(static_cast<size_t>(image.width) * image.height);
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x)
            texels[static_cast<size_t>(y) * image.width + x] =
                render::Rgb(image.at(x, y)[0], image.at(x, y)[1], image.at(x, y)[2]);
    return render::EnvironmentMap(render::Texture(image.width, image.height, std::move(texels)));
}

TEST(EnvironmentMap, LightsLandWhereTheRendererLooksThemUp) {
    const render::SimTruth& t = truth();
    auto map = environmentMapFromFisheye(firstEnv().view(), envCamera(), 512);
    ASSERT_TRUE(map) << map.status().toString();
    ASSERT_EQ(map->width, 512);
    ASSERT_EQ(map->height, 256);
    const render::EnvironmentMap env = asRendererMap(*map);
    for (const render::Light& light : t.lights) {
        const Vector3d truth = toLight(light);
        const Vector3d spot = brightSpot(env, truth, 0.9f);
        ASSERT_GT(spot.norm(), 0) << light.name;
        const double error = angleDeg(spot, truth);
        std::cout << "environment map: " << light.name << " spot " << error << " deg off\n";
        EXPECT_LT(error, 3.0) << light.name;
        EXPECT_GT(env.radiance(truth.cast<float>()).minCoeff(), 0.9f) << light.name;
        // Mirrored about any vertical plane or turned about +z, the light is not there.
        const Vector3d mirrored(truth.x(), -truth.y(), truth.z());
        const Vector3d turned(-truth.x(), -truth.y(), truth.z());
        EXPECT_LT(env.radiance(mirrored.cast<float>()).maxCoeff(), 0.6f) << light.name;
        EXPECT_LT(env.radiance(turned.cast<float>()).maxCoeff(), 0.6f) << light.name;
    }
    // The upper hemisphere is the simulator's room as the renderer reads its own map
    // (clipped, as the 8-bit camera clips it).
    auto truth_map = render::EnvironmentMap::load(t.environment_map);
    ASSERT_TRUE(truth_map) << truth_map.status().toString();
    std::vector<double> differences;
    for (int k = 0; k < 2000; ++k) {
        const double z = 0.1 + 0.85 * ((k * 0.618034) - std::floor(k * 0.618034));
        const double a = 2 * std::numbers::pi * k / 2000.0 * 7;
        const Eigen::Vector3f d(static_cast<float>(std::sqrt(1 - z * z) * std::cos(a)),
                                static_cast<float>(std::sqrt(1 - z * z) * std::sin(a)),
                                static_cast<float>(z));
        const render::Rgb expected = truth_map->radiance(d).cwiseMin(1.f);
        differences.push_back((env.radiance(d) - expected).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(median(differences), 0.02);
}

TEST(EnvironmentMap, LowerHemisphereMirrorsTheUpper) {
    for (const int width : {512, 66}) {
        auto map = environmentMapFromFisheye(firstEnv().view(), envCamera(), width);
        ASSERT_TRUE(map);
        for (int y = 0; y < map->height; ++y)
            for (int x = 0; x < map->width; ++x)
                for (int c = 0; c < 3; ++c)
                    ASSERT_EQ(map->at(x, y)[c], map->at(x, map->height - 1 - y)[c])
                        << width << ": " << x << "," << y;
        // Every texel has a value: the rim the lens misses is filled.
        double darkest = 1e9;
        for (float v : map->pixels)
            darkest = std::min(darkest, static_cast<double>(v));
        EXPECT_GT(darkest, 0.0) << width;
    }
    EXPECT_EQ(environmentMapFromFisheye(firstEnv().view(), envCamera(), 15).status().code(),
              ErrorCode::kInvalidArgument);
}

// ---- the estimator, image after image ----

TEST(EnvironmentEstimator, FreshThenStaleKeepsTheLastGoodValue) {
    const EnvironmentCamera camera = envCamera();
    EnvironmentEstimator estimator(camera, {}, 64);
    Estimate<EnvironmentEstimate> e = estimator.latest();
    EXPECT_FALSE(e.value);
    EXPECT_TRUE(e.stale);

    e = estimator.estimate(firstEnv().view(), 100);
    ASSERT_TRUE(e.value);
    EXPECT_FALSE(e.stale);
    EXPECT_TRUE(e.reason.empty());
    EXPECT_EQ(e.stamp_ns, 100);
    EXPECT_EQ(e.good_stamp_ns, 100);
    EXPECT_GE(e.value->lights.size(), 2u);
    ASSERT_TRUE(e.value->environment_map);
    EXPECT_EQ(e.value->environment_map->width, 64);
    EXPECT_LT(nearestDeg(e.value->lights, toLight(truth().lights[0])), 3.0);

    e = estimator.estimate(filled(camera.model, 0).view(), 200);
    ASSERT_TRUE(e.value) << "the last good value stays";
    EXPECT_TRUE(e.stale);
    EXPECT_NE(e.reason.find("black"), std::string::npos) << e.reason;
    EXPECT_EQ(e.stamp_ns, 200);
    EXPECT_EQ(e.good_stamp_ns, 100);
    EXPECT_EQ(e.updates, 1);
    EXPECT_EQ(e.stale_updates, 1);

    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 8, 8));
    e = estimator.estimate(depth.view(), 300);
    EXPECT_TRUE(e.stale);
    EXPECT_NE(e.reason.find("pixel format"), std::string::npos) << e.reason;
    EXPECT_EQ(e.good_stamp_ns, 100);
    EXPECT_EQ(estimator.latest().stamp_ns, 300);
}

TEST(EnvironmentEstimator, BadCameraGoesStaleWithTheReason) {
    EnvironmentCamera camera = envCamera();
    camera.room_radius_m = -1;
    EnvironmentEstimator estimator(camera);
    const Estimate<EnvironmentEstimate> e = estimator.estimate(firstEnv().view(), 7);
    EXPECT_TRUE(e.stale);
    EXPECT_FALSE(e.value);
    EXPECT_NE(e.reason.find("room_radius_m"), std::string::npos) << e.reason;
}

// ---- the environment light node ----

// The fish-eye stream of a graph the test publishes into, the node estimating it, and a
// consumer of its light records and maps.
struct EnvironmentGraph {
    Graph graph;
    PooledStream images;
    EnvironmentLightNode* node = nullptr;
    std::shared_ptr<FrameQueue> records, maps;
    uint64_t published = 0;

    explicit EnvironmentGraph(bool lossless) {
        auto reader = openMkv(test::fixturesDir() / "sessions" / "sim_tabletop.mkv");
        EXPECT_TRUE(reader.isOk()) << reader.status().toString();
        StreamInfo env;
        for (const StreamInfo& s : (*reader)->streams())
            if (s.name == "env/color")
                env = s;
        auto setup =
            findTrackingSetup(test::fixturesDir() / "sessions" / "sim_tabletop.mkv", **reader, "");
        EXPECT_TRUE(setup.isOk()) << setup.status().toString();
        auto options = std::make_shared<TrackingNodeOptions>();
        options->setup = *setup;
        options->setup.environment->map_width = 32;
        options->lossless = lossless;
        auto added = addPooledStream(graph, env, 8);
        EXPECT_TRUE(added.isOk());
        images = *added;
        auto created = EnvironmentLightNode::create(options);
        EXPECT_TRUE(created.isOk()) << created.status().toString();
        node = created->get();
        EXPECT_TRUE(graph.addNode(std::move(created).value()).isOk());
        records = *graph.subscribe(*graph.findStream(options->environment_light_stream),
                                   {64, QueuePolicy::kLossless, "test"});
        maps = *graph.subscribe(*graph.findStream(options->environment_map_stream),
                                {64, QueuePolicy::kLossless, "test"});
        EXPECT_TRUE(graph.start().isOk());
    }
    ~EnvironmentGraph() { graph.stop(); }

    // Publishes `image` stamped `stamp_ns`; false when the pool had no free buffer.
    bool publish(const Image& image, int64_t stamp_ns, bool corrupt = false) {
        FrameMetadata meta;
        meta.stream = images.id;
        meta.sequence = published;
        meta.host_stamp_ns = meta.device_stamp_ns = stamp_ns;
        meta.status = corrupt ? FrameStatus::kCorrupt : FrameStatus::kOk;
        FrameRef frame = copyIntoPool(*images.pool, image.view(), meta);
        if (!frame)
            return false;
        graph.publish(frame);
        ++published;
        return true;
    }
    // The node's records (and maps) once the stream ended.
    std::vector<LightGroup> finish(std::vector<int64_t>* map_stamps = nullptr) {
        graph.endStream(images.id);
        EXPECT_TRUE(node->waitDone(std::chrono::seconds(20)));
        std::vector<LightGroup> out;
        while (auto frame = records->tryPop()) {
            auto record = decodeLightRecord(frame->image());
            EXPECT_TRUE(record.isOk()) << record.status().toString();
            if (!record)
                continue;
            EXPECT_EQ(record->groups.size(), 1u);
            EXPECT_EQ(frame->meta().host_stamp_ns, record->groups.at(0).stamp_ns);
            out.push_back(record->groups.at(0));
        }
        while (auto frame = maps->tryPop())
            if (map_stamps)
                map_stamps->push_back(frame->meta().host_stamp_ns);
        return out;
    }
};

TEST(EnvironmentLightNode, LosslessEveryImageGivesARecordInOrderAndABadOneGoesStale) {
    EnvironmentGraph g(true);
    const Image black = filled(envCamera().model, 0);
    ASSERT_TRUE(g.publish(firstEnv(), 100));
    ASSERT_TRUE(g.publish(black, 200));
    ASSERT_TRUE(g.publish(firstEnv(), 300, /*corrupt=*/true));
    ASSERT_TRUE(g.publish(firstEnv(), 400));
    std::vector<int64_t> map_stamps;
    const std::vector<LightGroup> groups = g.finish(&map_stamps);
    ASSERT_EQ(groups.size(), 4u);
    const bool stale[] = {false, true, true, false};
    const int64_t good[] = {100, 100, 100, 400};
    for (size_t i = 0; i < 4; ++i) {
        SCOPED_TRACE("image " + std::to_string(i));
        EXPECT_EQ(groups[i].name, "environment");
        EXPECT_EQ(groups[i].stamp_ns, static_cast<int64_t>(100 * (i + 1)));
        EXPECT_EQ(groups[i].stale, stale[i]);
        EXPECT_EQ(groups[i].good_stamp_ns, good[i]);
        EXPECT_GE(groups[i].lights.size(), 2u) << "the last good lights stay";
    }
    EXPECT_NE(groups[1].reason.find("black"), std::string::npos) << groups[1].reason;
    EXPECT_NE(groups[2].reason.find("corrupt"), std::string::npos) << groups[2].reason;
    EXPECT_LT(nearestDeg(groups[3].lights, toLight(truth().lights[0])), 3.0);
    // A map for each image that gave one.
    EXPECT_EQ(map_stamps, (std::vector<int64_t>{100, 400}));
    const EnvironmentLightStats stats = g.node->stats();
    EXPECT_EQ(stats.environment_frames, 4u);
    EXPECT_EQ(stats.environment_skipped, 0u);
    EXPECT_EQ(stats.environment_maps, 2u);
    EXPECT_EQ(stats.publish_failures, 0u);
}

TEST(EnvironmentLightNode, LiveTheNewestImageWins) {
    EnvironmentGraph g(false);
    const Image black = filled(envCamera().model, 0);
    // Far faster than the node estimates: most images are replaced before it takes them.
    for (int64_t stamp = 1; stamp <= 40; ++stamp)
        g.publish(stamp % 2 ? black : firstEnv(), stamp);
    ASSERT_TRUE(g.publish(firstEnv(), 1000));  // the last word, never replaced
    const std::vector<LightGroup> groups = g.finish();
    ASSERT_FALSE(groups.empty());
    EXPECT_LT(groups.size(), g.published) << "every image estimated: nothing was replaced";
    for (size_t i = 1; i < groups.size(); ++i)
        EXPECT_GT(groups[i].stamp_ns, groups[i - 1].stamp_ns) << "records go forward";
    EXPECT_EQ(groups.back().stamp_ns, 1000);
    EXPECT_FALSE(groups.back().stale);
    // What the node did not estimate, it skipped or its queue of one dropped.
    uint64_t dropped = 0;
    for (const EdgeStats& e : g.graph.edgeStats())
        if (e.consumer == g.node->name())
            dropped += e.queue.dropped;
    const EnvironmentLightStats stats = g.node->stats();
    EXPECT_EQ(stats.environment_frames, groups.size());
    EXPECT_EQ(stats.environment_frames + stats.environment_skipped + dropped, g.published);
}

// The environment from the colour camera alone, frame after frame of the session at the true
// poses. Looking down at the table, the camera sees the room only past the table's far edge: the
// test compares the map with the simulator's room there (directions whose ray, from every
// frame's camera, misses the table by 5 cm or more), as frames accumulate.
TEST(CameraEnvironment, OnTheSimulatedSessionItConvergesToTheTrueRoom) {
    const render::SimTruth& t = truth();
    const Frames& frames = allFrames();
    ASSERT_EQ(frames.color.size(), t.frames.size());
    auto truth_map = render::EnvironmentMap::load(t.environment_map);
    ASSERT_TRUE(truth_map) << truth_map.status().toString();
    auto environment = CameraEnvironment::create({.width = 256});
    ASSERT_TRUE(environment) << environment.status().toString();
    std::vector<FloatImage> maps;
    for (size_t i = 0; i < frames.color.size(); ++i) {
        ASSERT_TRUE(
            environment->add(frames.color[i].view(), t.color, t.frames[i].T_world_color).isOk());
        maps.push_back(environment->map());
    }
    const render::EnvironmentMap lookup = asRendererMap(maps.back());
    // The table: the plane z = table_z_m, 1.6 m x 1.2 m about the marker (simulator.cpp).
    const auto missesTheTable = [&](const Eigen::Vector3d& d) {
        for (const render::SimFrameTruth& f : t.frames) {
            const Vector3d c = f.T_world_color.translation();
            if (d.z() >= 0)
                continue;
            const Vector3d hit = c + (t.table_z_m - c.z()) / d.z() * d;
            if (std::abs(hit.x()) < 0.85 && std::abs(hit.y()) < 0.65)
                return false;
        }
        return true;
    };
    std::vector<std::pair<int, int>> room;  // texels seen by the end whose ray misses the table
    for (int y = 0; y < environment->height(); ++y)
        for (int x = 0; x < environment->width(); ++x)
            if (environment->seen(x, y) &&
                missesTheTable(
                    lookup.directionOf(Eigen::Vector2f(x + 0.5f, y + 0.5f)).cast<double>()))
                room.emplace_back(x, y);
    ASSERT_GT(room.size(), 200u) << "the camera never saw the room";
    // Mean |map − truth| there, the truth clipped as the 8-bit camera clips it.
    const auto error = [&](const FloatImage& map) {
        double sum = 0;
        for (const auto& [x, y] : room) {
            const Eigen::Vector3f d = lookup.directionOf(Eigen::Vector2f(x + 0.5f, y + 0.5f));
            const render::Rgb expected = truth_map->radiance(d).cwiseMin(1.f);
            sum += (render::Rgb(map.at(x, y)[0], map.at(x, y)[1], map.at(x, y)[2]) - expected)
                       .cwiseAbs()
                       .mean();
        }
        return sum / static_cast<double>(room.size());
    };
    for (size_t i = 0; i < maps.size(); ++i)
        if (i % 7 == 0 || i + 1 == maps.size())
            std::cout << "camera environment: frame " << i << ", room error " << error(maps[i])
                      << "\n";
    std::cout << "camera environment: " << room.size() << " room texels, coverage "
              << environment->coverage() << "\n";
    EXPECT_LT(error(maps.back()), 0.02);                  // what it saw is the room
    EXPECT_LT(error(maps.back()), 0.5 * error(maps[0]));  // closer as the camera moves
}

TEST(CameraEnvironment, RefusesBadInput) {
    EXPECT_FALSE(CameraEnvironment::create({.width = 15}));
    EXPECT_FALSE(CameraEnvironment::create({.width = 64, .radius_m = -1}));
    auto environment = CameraEnvironment::create({.width = 64});
    ASSERT_TRUE(environment);
    const Image& color = firstColor();
    calibration::CameraModel other = truth().color;
    other.width /= 2;
    EXPECT_EQ(environment->add(color.view(), other, Isometry3d::Identity()).code(),
              ErrorCode::kInvalidArgument);
    Isometry3d skewed = Isometry3d::Identity();
    skewed.linear()(0, 1) = 0.5;
    EXPECT_EQ(environment->add(color.view(), truth().color, skewed).code(),
              ErrorCode::kInvalidArgument);
    EXPECT_EQ(environment->frames(), 0u);
    EXPECT_EQ(environment->coverage(), 0);
}

}  // namespace
}  // namespace mixray::tracking
