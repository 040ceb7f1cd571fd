// Tracking setup files: parse, write and read back, and errors that name the line and field.
#include "mixray/tracking/setup.h"

#include <gtest/gtest.h>

#include <string>

#include "test_data.h"

namespace mixray::tracking {
namespace {

constexpr const char* kSetup = R"(version: 1
camera:
  stream: kinect/color
  model: {lens: pinhole, width: 640, height: 480, fx: 524.8, fy: 525.4, cx: 318.6, cy: 241.9,
          distortion: [0.045, -0.11, 6.0e-04, -4.0e-04, 0.04]}
targets:
  - name: table
    type: marker
    dictionary: DICT_6X6_250
    id: 23
    size_m: 0.1
    pose: {translation: [0, 0, 0], rotation_deg: [0, 0, 90]}
    binds: [teapot, ball]
  - name: board
    type: charuco
    dictionary: DICT_6X6_250
    id: 0
    size_m: 0.037
    squares: [7, 5]
    square_m: 0.05
    pose: {translation: [0.5, 0, 0]}
tracker:
  max_rms_px: 1.5
  reacquire_after_ms: 300
  refine_corners: false
  smoothing: {enabled: true, min_cutoff_hz: 0.5, beta: 3, d_cutoff_hz: 1}
probes:
  - {name: chrome, material: mirror, radius_m: 0.04, centre: [0.15, 0.08, 0.0395]}
  - {name: matte, material: diffuse, radius_m: 0.04, centre: [0.15, -0.08, 0.0395], albedo: 0.7}
probe_options: {domain: sphere, sphere_samples: 64, max_lights: 3}
environment:
  stream: env/color
  model: {lens: fisheye, width: 480, height: 480, fx: 140, fy: 140, cx: 239.2, cy: 240.3,
          distortion: [0.02, -0.005, 0.001, -2.0e-04]}
  pose: {translation: [-0.3, 0.28, 0.12], quaternion: [1, 0, 0, 0]}
  room_radius_m: 3
  threshold: 0.8
  max_lights: 2
  map_width: 256
)";

TEST(TrackingSetup, ParsesEveryField) {
    auto setup = parseTrackingSetup(kSetup, "rig.tracking.yaml");
    ASSERT_TRUE(setup) << setup.status().message();
    EXPECT_EQ(setup->camera.stream, "kinect/color");
    EXPECT_DOUBLE_EQ(setup->camera.model.fx, 524.8);
    ASSERT_EQ(setup->camera.model.distortion.size(), 5u);
    ASSERT_EQ(setup->targets.size(), 2u);
    const MarkerTarget& table = setup->targets[0];
    EXPECT_EQ(table.kind, TargetKind::kMarker);
    EXPECT_EQ(table.id, 23);
    EXPECT_DOUBLE_EQ(table.size_m, 0.1);
    EXPECT_NEAR(
        (table.T_world_target.linear() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY())
            .norm(),
        0, 1e-12);
    EXPECT_EQ(table.bound_objects, (std::vector<std::string>{"teapot", "ball"}));
    const MarkerTarget& board = setup->targets[1];
    EXPECT_EQ(board.kind, TargetKind::kCharucoBoard);
    EXPECT_EQ(board.squares_x, 7);
    EXPECT_EQ(board.squares_y, 5);
    EXPECT_DOUBLE_EQ(board.square_m, 0.05);
    EXPECT_DOUBLE_EQ(setup->tracker.max_rms_px, 1.5);
    EXPECT_EQ(setup->tracker.reacquire_after_ns, 300'000'000);
    EXPECT_FALSE(setup->tracker.detector.refine_corners);
    EXPECT_DOUBLE_EQ(setup->tracker.smoothing.min_cutoff_hz, 0.5);
    EXPECT_DOUBLE_EQ(setup->tracker.smoothing.beta, 3);
    ASSERT_EQ(setup->probes.size(), 2u);
    EXPECT_EQ(setup->probes[0].material, ProbeMaterial::kMirror);
    EXPECT_EQ(setup->probes[1].material, ProbeMaterial::kDiffuse);
    EXPECT_DOUBLE_EQ(setup->probes[1].albedo, 0.7);
    EXPECT_EQ(setup->probe_options.domain, ProbeDomain::kSphere);
    EXPECT_EQ(setup->probe_options.sphere_samples, 64);
    EXPECT_EQ(setup->probe_options.max_lights, 3);
    ASSERT_TRUE(setup->environment);
    EXPECT_EQ(setup->environment->camera.model.lens, calibration::LensModel::kFisheye);
    EXPECT_DOUBLE_EQ(setup->environment->camera.T_world_env.translation().x(), -0.3);
    EXPECT_DOUBLE_EQ(setup->environment->camera.room_radius_m, 3);
    EXPECT_DOUBLE_EQ(setup->environment->lights.threshold, 0.8);
    EXPECT_EQ(setup->environment->lights.max_lights, 2);
    EXPECT_EQ(setup->environment->map_width, 256);
}

TEST(TrackingSetup, WrittenFileReadsBackToTheSameValues) {
    auto setup = parseTrackingSetup(kSetup, "a.yaml");
    ASSERT_TRUE(setup) << setup.status().message();
    const std::string text = trackingSetupYaml(*setup);
    auto again = parseTrackingSetup(text, "b.yaml");
    ASSERT_TRUE(again) << again.status().message() << "\n" << text;
    EXPECT_EQ(trackingSetupYaml(*again), text);
    EXPECT_EQ(again->targets[0].bound_objects, setup->targets[0].bound_objects);
    EXPECT_TRUE(again->targets[0].T_world_target.isApprox(setup->targets[0].T_world_target, 1e-15));
    EXPECT_EQ(again->camera.model.distortion, setup->camera.model.distortion);
    EXPECT_DOUBLE_EQ(again->probes[1].albedo, 0.7);
    EXPECT_EQ(again->environment->map_width, 256);

    // Names are the user's text (tracking_setup_fuzz: one with ": " and bytes above 0x7f was
    // written bare and did not read back): they are written quoted.
    TrackingSetup named = *setup;
    named.targets[0].name = "3\xdc\xed: marker #1";
    named.targets[0].bound_objects = {"tea: pot", "[ball]"};
    named.probes[0].name = "probe, left";
    const std::string named_text = trackingSetupYaml(named);
    auto named_again = parseTrackingSetup(named_text, "c.yaml");
    ASSERT_TRUE(named_again) << named_again.status().message() << "\n" << named_text;
    EXPECT_EQ(named_again->targets[0].name, named.targets[0].name);
    EXPECT_EQ(named_again->targets[0].bound_objects, named.targets[0].bound_objects);
    EXPECT_EQ(named_again->probes[0].name, named.probes[0].name);

    // And the setup the simulator wrote for the bundled session (quaternions with every digit).
    auto simulated =
        loadTrackingSetup(test::fixturesDir() / "sessions" / "sim_tabletop.tracking.yaml");
    ASSERT_TRUE(simulated) << simulated.status().message();
    const std::string written = trackingSetupYaml(*simulated);
    auto reread = parseTrackingSetup(written, "c.yaml");
    ASSERT_TRUE(reread) << reread.status().message();
    // Poses go through a rotation matrix: their quaternions come back to the last bit or two.
    EXPECT_TRUE(reread->environment->camera.T_world_env.isApprox(
        simulated->environment->camera.T_world_env, 1e-15));
    EXPECT_EQ(reread->environment->camera.model.distortion,
              simulated->environment->camera.model.distortion);
    EXPECT_EQ(reread->probes[1].albedo, simulated->probes[1].albedo);
}

// Each bad input names its line and field.
TEST(TrackingSetup, ErrorsNameTheLineAndField) {
    struct Case {
        std::string find, replace, expect;
    };
    const Case cases[] = {
        {"type: marker", "type: cube",
         "a.yaml:8:11: targets[0].type: expected marker, charuco or "
         "gridboard"},
        {"dictionary: DICT_6X6_250\n    id: 23", "dictionary: DICT_9X9\n    id: 23",
         "targets[0].dictionary"},
        {"size_m: 0.1", "size_m: -0.1", "targets[0].size_m"},
        {"material: mirror", "material: glass", "probes[0].material: expected mirror or diffuse"},
        {"stream: env/color", "stream: envcolor", "environment.stream"},
        {"map_width: 256", "map_width: 255", "environment.map_width: expected an even width"},
        {"max_rms_px: 1.5", "max_rms: 1.5", "tracker.max_rms"},
        {"  - name: board", "  - name: table", "a second target named \"table\""},
    };
    for (const Case& c : cases) {
        std::string text = kSetup;
        const size_t at = text.find(c.find);
        ASSERT_NE(at, std::string::npos) << c.find;
        text.replace(at, c.find.size(), c.replace);
        auto setup = parseTrackingSetup(text, "a.yaml");
        ASSERT_FALSE(setup) << c.replace;
        EXPECT_NE(setup.status().message().find(c.expect), std::string::npos)
            << setup.status().message();
    }
    EXPECT_FALSE(parseTrackingSetup("camera: [1", "a.yaml"));
    auto empty = parseTrackingSetup("version: 1\n", "a.yaml");
    ASSERT_FALSE(empty);
    EXPECT_NE(empty.status().message().find("camera"), std::string::npos);
    EXPECT_EQ(loadTrackingSetup("/nonexistent/x.tracking.yaml").status().code(),
              ErrorCode::kNotFound);
}

}  // namespace
}  // namespace mixray::tracking
