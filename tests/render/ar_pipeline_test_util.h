// The bundled simulated session as an AR pipeline's source, with the scene and settings the
// AR pipeline tests share.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>

#include "mixray/render/ar_pipeline.h"
#include "mixray/render/scene_file.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/replay_backend.h"
#include "mixray/tracking/pipeline.h"
#include "test_data.h"

namespace mixray::render {

inline std::filesystem::path session() {
    return test::fixturesDir() / "sessions/sim_tabletop.mkv";
}

// A virtual box and glass ball on the session's table (the table itself a ghost), no lights of
// its own: they come from tracking.
inline SceneDescription testScene() {
    auto scene = parseScene(R"(version: 1
materials:
  table: { type: diffuse, albedo: [0.6, 0.6, 0.6] }
  clay: { type: diffuse, albedo: [0.7, 0.35, 0.2] }
  glass: { type: glass, ior: 1.5 }
objects:
  - name: table
    role: ghost
    shape: { box: { size: [1.2, 0.8, 0.02] } }
    material: table
    pose: { translation: [0, 0, -0.01] }
  - name: box
    shape: { box: { size: [0.04, 0.04, 0.07] } }
    material: clay
    pose: { translation: [-0.06, -0.1, 0.035] }
  - name: ball
    shape: { sphere: { radius: 0.035 } }
    material: glass
    pose: { translation: [0.08, 0.05, 0.035] }
)",
                            "test scene");
    EXPECT_TRUE(scene.isOk()) << scene.status().toString();
    return std::move(scene).value();
}

inline RenderOptions testRenderOptions() {
    RenderOptions o;
    o.samples_per_pixel = 1;
    o.max_depth = 2;
    o.soft_shadows = SoftShadowMethod::kAdaptive;
    o.depth_secondary = DepthSecondaryRays::kNone;
    o.threads = 2;
    return o;
}

inline BackendRegistry replayRegistry() {
    BackendRegistry registry;
    EXPECT_TRUE(registry.add(std::make_unique<replay::ReplayBackend>()).isOk());
    return registry;
}

inline tracking::TrackingSetup sessionSetup(const RecordingReader& reader) {
    auto setup = tracking::findTrackingSetup(session(), reader, "");
    EXPECT_TRUE(setup.isOk()) << setup.status().toString();
    return std::move(setup).value();
}

// The whole pipeline on the bundled session: its tracking setup, the test scene and settings.
inline ArPipelineOptions sessionPipelineOptions() {
    ArPipelineOptions options;
    auto reader = replay::openRecording(session());
    EXPECT_TRUE(reader.isOk()) << reader.status().toString();
    if (reader.isOk())
        options.setup = sessionSetup(**reader);
    options.scene = testScene();
    options.render = testRenderOptions();
    return options;
}

// The bundled session as the pipeline's source, at `pace`, once or `looped`.
inline ArSource sessionSource(ArSource::Pace pace, bool looped = false) {
    ArSource source;
    source.recording = session();
    source.pace = pace;
    source.loop = looped;
    return source;
}

}  // namespace mixray::render
