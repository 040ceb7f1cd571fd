// The quality ladder gives up quality, never the picture (render::qualityLadder): the bundled
// session's frame with the demo's metal teapot, glass ball and clay box, lit as tracking
// estimated it, rendered at every rung, is nowhere on the virtual objects much darker than at
// full quality, with the estimated environment and without one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <mutex>

#include "ar_pipeline_test_util.h"
#include "mixray/render/compositor_node.h"
#include "mixray/render/scene_file.h"

namespace mixray::render {
namespace {

namespace fs = std::filesystem;

// One composite of the session: what it was rendered from.
struct Captured {
    FrameRef color, depth;
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    std::vector<Light> lights;
};

// How one rung's virtual pixels compare with rung 0's (Rec. 709 luma of the composite's codes).
struct Darkness {
    double mean_luma = 0;        // over the pixels virtual at both rungs
    double mean_luma_rung0 = 0;  // the same pixels at rung 0
    double dark_fraction = 0;    // of those bright at rung 0, the share under a quarter of it
    size_t pixels = 0;
};

double luma(const Image& image, int x, int y) {
    const uint8_t* p =
        image.bytes().data() + static_cast<size_t>(y) * image.desc().stride_bytes + 3 * x;
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

Darkness compare(const RenderLayers& rung, const RenderLayers& rung0) {
    Darkness d;
    size_t bright = 0, dark = 0;
    for (int y = 0; y < rung.mask.height; ++y)
        for (int x = 0; x < rung.mask.width; ++x) {
            if (rung.mask.at(x, y)[0] < 0.999f || rung0.mask.at(x, y)[0] < 0.999f)
                continue;
            const double l = luma(rung.composite, x, y), l0 = luma(rung0.composite, x, y);
            d.mean_luma += l;
            d.mean_luma_rung0 += l0;
            ++d.pixels;
            if (l0 >= 48) {
                ++bright;
                dark += l < 0.25 * l0;
            }
        }
    if (d.pixels > 0) {
        d.mean_luma /= static_cast<double>(d.pixels);
        d.mean_luma_rung0 /= static_cast<double>(d.pixels);
    }
    d.dark_fraction = bright > 0 ? static_cast<double>(dark) / static_cast<double>(bright) : 0;
    return d;
}

TEST(QualityLadder, EveryRungDrawsMetalAndGlassNoDarkerThanFullQuality) {
    auto composed = composeArScene(test::fixturesDir() / "sessions/sim_tabletop.scene.yaml",
                                   test::fixturesDir() / "scenes/sim_tabletop_demo.yaml");
    ASSERT_TRUE(composed.isOk()) << composed.status().toString();
    for (const SceneObject& o : composed->scene.objects)
        if (o.shape.type == ShapeType::kMesh && !fs::exists(o.shape.mesh))
            GTEST_SKIP() << o.shape.mesh << " is not here (../shared/data)";

    // The session tracked for a few frames, as `mixray run` does: the last composite's frame,
    // pose and estimated lights (the environment map among them).
    ArPipelineOptions options = sessionPipelineOptions();
    ASSERT_TRUE(options.setup.has_value());
    options.scene = composed->scene;
    options.render.max_depth = 0;  // only its inputs are wanted
    std::mutex mutex;
    std::optional<Captured> captured;
    int composites = 0;
    options.on_composite = [&](const CompositeFrame& f) {
        std::lock_guard lock(mutex);
        if (f.rendered && f.lights_used != nullptr && f.pose && composites++ < 8)
            captured = Captured{f.color, f.depth, f.pose->transform(), *f.lights_used};
    };
    auto pipeline =
        ArPipeline::create(replayRegistry(), sessionSource(ArSource::Pace::kFast), options);
    ASSERT_TRUE(pipeline.isOk()) << pipeline.status().toString();
    ASSERT_TRUE((*pipeline)->start().isOk());
    // The eighth lit composite is enough: the rest of the session would only take time.
    const auto enough = [&] {
        std::lock_guard lock(mutex);
        return composites >= 8;
    };
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!enough() && !(*pipeline)->waitDone(std::chrono::milliseconds(50)) &&
           std::chrono::steady_clock::now() < deadline) {
    }
    (*pipeline)->stop();
    ASSERT_TRUE((*pipeline)->status().isOk()) << (*pipeline)->status().toString();
    ASSERT_TRUE(captured.has_value()) << "no composite was rendered with estimated lights";

    std::vector<Light> without_environment;
    for (const Light& l : captured->lights)
        if (l.type != LightType::kEnvironment)
            without_environment.push_back(l);
    ASSERT_LT(without_environment.size(), captured->lights.size())
        << "tracking estimated no environment map";
    ASSERT_FALSE(without_environment.empty()) << "tracking estimated no lights";

    RenderOptions best = testRenderOptions();
    best.samples_per_pixel = 4;
    best.shadow_samples = 8;
    best.max_depth = 3;
    best.keep_layers = true;
    const std::vector<QualityStep> ladder = qualityLadder(best);
    ASSERT_GE(ladder.size(), 4u);
    ASSERT_EQ(ladder.back().max_depth, 0);

    RenderInputs in;
    in.camera_image = captured->color.image();
    in.camera = (*pipeline)->camera();
    in.T_world_cam = captured->T_world_cam;
    const CompositorNode* compositor = (*pipeline)->compositor();
    ASSERT_NE(compositor, nullptr);
    if (captured->depth) {
        in.depth_mm = captured->depth.image();
        if (compositor->options().depth_registration)
            in.depth_registration = &*compositor->options().depth_registration;
    }
    for (const auto& [lights, what] : {std::pair{captured->lights, "estimated environment"},
                                       std::pair{without_environment, "no environment"}}) {
        SCOPED_TRACE(what);
        std::vector<RenderLayers> rendered(ladder.size());
        for (size_t k = 0; k < ladder.size(); ++k) {
            auto renderer = Renderer::create(composed->scene, ladder[k].applied(best));
            ASSERT_TRUE(renderer.isOk()) << renderer.status().toString();
            ASSERT_TRUE((*renderer)->setLights(lights).isOk());
            ASSERT_TRUE((*renderer)->render(in, rendered[k]).isOk());
        }
        for (size_t k = 0; k < ladder.size(); ++k) {
            const Darkness d = compare(rendered[k], rendered[0]);
            std::printf(
                "%s, rung %zu of %zu (%s): %zu virtual pixels, mean luma %.1f vs %.1f at "
                "rung 1 (%.2fx), %.1f %% of the bright ones under a quarter of rung 1\n",
                what, k + 1, ladder.size(), ladder[k].label().c_str(), d.pixels, d.mean_luma,
                d.mean_luma_rung0, d.mean_luma_rung0 > 0 ? d.mean_luma / d.mean_luma_rung0 : 0.0,
                100 * d.dark_fraction);
            SCOPED_TRACE("rung " + std::to_string(k + 1) + ": " + ladder[k].label());
            EXPECT_GT(d.pixels, 2000u);
            // Fewer bounces and samples change the picture, but by a bounded amount: no rung
            // loses more than a fifth of the virtual objects' brightness, and no more than 5 %
            // of their bright pixels go dark.
            EXPECT_GE(d.mean_luma, 0.8 * d.mean_luma_rung0);
            EXPECT_LE(d.dark_fraction, 0.05);
        }
    }
}

}  // namespace
}  // namespace mixray::render
