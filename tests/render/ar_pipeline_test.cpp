// The AR pipeline as one device graph (mixray/render/ar_pipeline.h): on the bundled simulated
// session, the graph gives the same composites, poses and lights as tracking and rendering the
// recording frame by frame in a loop (what mixray demo, track and render did before), and its
// records stream, record and replay like any other.
#include "mixray/render/ar_pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "ar_pipeline_test_util.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/pose.h"
#include "mixray/tracking/light_record.h"
#include "mixray/tracking/pipeline.h"
#include "recording_edit.h"

namespace mixray::render {
namespace {

namespace fs = std::filesystem;
using tracking::TrackedFrame;

// What one colour frame gave.
struct FrameResult {
    std::vector<uint8_t> composite;
    std::optional<Eigen::Isometry3d> pose;
    bool pose_stale = true;
    std::vector<tracking::EstimatedLight> lights;
    bool rendered = false;
};

// Builds the pipeline, runs it until the source ended and everything downstream finished,
// and stops it; fails the test on any error. `out` keeps it for its stats.
void runToEnd(const ArSource& source, ArPipelineOptions options, std::unique_ptr<ArPipeline>& out,
              std::chrono::seconds timeout = std::chrono::seconds(120)) {
    auto pipeline = ArPipeline::create(replayRegistry(), source, std::move(options));
    ASSERT_TRUE(pipeline.isOk()) << pipeline.status().toString();
    out = std::move(pipeline).value();
    ASSERT_TRUE(out->start().isOk());
    ASSERT_TRUE(out->waitDone(timeout));
    out->stop();
    ASSERT_TRUE(out->status().isOk()) << out->status().toString();
}

// The loop the graph replaces, written with the library's building blocks: every frame in
// recording order; a colour frame is tracked and rendered when the next one arrives (by then
// its depth frame was read), lit by the fish-eye estimate of the newest environment image
// stamped at or before it.
std::map<uint64_t, FrameResult> referenceLoop() {
    std::map<uint64_t, FrameResult> out;
    auto reader = replay::openRecording(session());
    EXPECT_TRUE(reader.isOk());
    const tracking::TrackingSetup setup = sessionSetup(**reader);
    auto tracker =
        tracking::MarkerTracker::create(setup.camera.model, setup.targets, setup.tracker);
    EXPECT_TRUE(tracker.isOk()) << tracker.status().toString();
    EXPECT_TRUE(setup.environment.has_value());
    tracking::EnvironmentEstimator environment(setup.environment->camera, setup.environment->lights,
                                               setup.environment->map_width);
    auto renderer = Renderer::create(testScene(), testRenderOptions());
    EXPECT_TRUE(renderer.isOk()) << renderer.status().toString();
    StreamId depth_stream = kInvalidStream, color_stream = kInvalidStream,
             env_stream = kInvalidStream;
    for (StreamId i = 0; i < (*reader)->streams().size(); ++i) {
        const StreamInfo& info = (*reader)->streams()[i];
        if (info.kind == StreamKind::kDepth)
            depth_stream = i;
        if (info.name == setup.camera.stream)
            color_stream = i;
        if (info.name == setup.environment->stream)
            env_stream = i;
    }
    FrameRef depth, pending;
    std::vector<FrameRef> env_frames;
    std::vector<tracking::Estimate<tracking::ProbeResult>> probes(setup.probes.size());
    tracking::Estimate<tracking::IntensityFit> intensities;
    RenderLayers layers;
    std::vector<Light> last_lights;
    bool lights_set = false;
    const auto process = [&] {
        const int64_t stamp = pending.meta().host_stamp_ns;
        auto track = (*tracker)->track(pending.image(), stamp);
        ASSERT_TRUE(track.isOk()) << track.status().toString();
        while (!env_frames.empty() && env_frames.front().meta().host_stamp_ns <= stamp) {
            environment.estimate(env_frames.front().image(),
                                 env_frames.front().meta().host_stamp_ns);
            env_frames.erase(env_frames.begin());
        }
        TrackedFrame f;
        f.track = std::move(track).value();
        f.environment = environment.latest();
        f.probes = probes;
        f.intensities = intensities;
        if (f.track.state == tracking::TrackState::kTracking && f.track.pose.value) {
            // The light node sees the pose through its record.
            PoseRecord record;
            record.setTransform(*f.track.pose.value);
            tracking::estimateFrameProbes(setup, pending.image(), record.transform(), stamp, f);
            probes = f.probes;
            intensities = f.intensities;
        }
        FrameResult r;
        r.pose = f.track.pose.value;
        r.pose_stale = f.track.pose.stale || f.track.state != tracking::TrackState::kTracking;
        r.lights = tracking::renderLights(setup, f);
        // The map of the newest good environment image, as the map stream carries it.
        std::vector<Light> lights = lightsFromEstimates(
            r.lights, f.environment.value ? f.environment.value->environment_map : nullptr);
        if (!lights_set || lights.size() != last_lights.size() || [&] {
                for (size_t i = 0; i < lights.size(); ++i)
                    if (lights[i].direction != last_lights[i].direction ||
                        !(lights[i].intensity == last_lights[i].intensity) ||
                        lights[i].environment_image != last_lights[i].environment_image)
                        return true;
                return false;
            }()) {
            ASSERT_TRUE((*renderer)->setLights(lights).isOk());
            last_lights = lights;
            lights_set = true;
        }
        ImageView composite = pending.image();
        if (f.track.pose.value) {
            RenderInputs in;
            in.camera_image = pending.image();
            in.camera = setup.camera.model;
            in.T_world_cam = *f.track.pose.value;
            if (depth && depth.meta().host_stamp_ns == stamp)
                in.depth_mm = depth.image();
            ASSERT_TRUE((*renderer)->render(in, layers).isOk());
            composite = layers.composite.view();
            r.rendered = true;
        }
        r.composite.assign(composite.data, composite.data + composite.size_bytes);
        out[pending.meta().sequence] = std::move(r);
        pending = FrameRef();
    };
    while (true) {
        auto next = (*reader)->next();
        if (!next)
            break;
        FrameRef frame = std::move(next).value();
        if (frame.meta().stream == depth_stream) {
            depth = frame;
        } else if (frame.meta().stream == color_stream) {
            if (pending)
                process();
            pending = frame;
        } else if (frame.meta().stream == env_stream) {
            env_frames.push_back(frame);
        }
    }
    if (pending)
        process();
    return out;
}

TEST(ArPipeline, FastPaceGivesTheSameCompositesPosesAndLightsAsTheFrameLoop) {
    const std::map<uint64_t, FrameResult> reference = referenceLoop();
    ASSERT_EQ(reference.size(), 36u);

    ArPipelineOptions options = sessionPipelineOptions();
    ASSERT_TRUE(options.setup.has_value());
    std::mutex mutex;
    std::map<uint64_t, FrameResult> got;
    std::vector<tracking::LightRecord> light_records;
    options.on_composite = [&](const CompositeFrame& c) {
        FrameResult r;
        const ImageView image = c.composite.image();
        r.composite.assign(image.data, image.data + image.size_bytes);
        r.rendered = c.rendered;
        if (c.pose && c.pose->status != PoseStatus::kLost)
            r.pose = c.pose->transform();
        r.pose_stale = !c.pose || c.pose->status != PoseStatus::kValid;
        if (c.lights)
            for (const auto& g : c.lights->groups)
                if (g.name == "render")
                    r.lights = g.lights;
        std::lock_guard lock(mutex);
        got[c.color.meta().sequence] = std::move(r);
    };
    const ArSource source = sessionSource(ArSource::Pace::kFast);
    std::unique_ptr<ArPipeline> pipeline;
    ASSERT_NO_FATAL_FAILURE(runToEnd(source, std::move(options), pipeline));

    ASSERT_EQ(got.size(), reference.size());
    int rendered = 0;
    for (const auto& [sequence, want] : reference) {
        SCOPED_TRACE("colour frame " + std::to_string(sequence));
        const FrameResult& have = got.at(sequence);
        ASSERT_EQ(have.pose.has_value(), want.pose.has_value());
        if (want.pose) {
            // Pose records hold the transform as translation + quaternion in doubles.
            EXPECT_LT((have.pose->translation() - want.pose->translation()).norm(), 1e-12);
            EXPECT_LT((have.pose->linear() - want.pose->linear()).norm(), 1e-12);
        }
        EXPECT_EQ(have.pose_stale, want.pose_stale);
        ASSERT_EQ(have.lights.size(), want.lights.size());
        for (size_t i = 0; i < want.lights.size(); ++i) {
            EXPECT_EQ(have.lights[i].to_light_world, want.lights[i].to_light_world);
            EXPECT_EQ(have.lights[i].intensity, want.lights[i].intensity);
        }
        EXPECT_EQ(have.rendered, want.rendered);
        rendered += have.rendered;
        EXPECT_TRUE(have.composite == want.composite) << "composites differ";
    }
    EXPECT_GT(rendered, 30);
    const ArPipelineStats stats = pipeline->stats();
    ASSERT_TRUE(stats.compositor.has_value());
    EXPECT_EQ(stats.compositor->composites, 36u);
    EXPECT_EQ(stats.compositor->skipped_superseded, 0u);
    EXPECT_EQ(stats.compositor->sync.framesDropped(), 0u);
    EXPECT_EQ(stats.compositor->latency.count, 36u);
    // Every object drawn in every rendered composite, the input whole: nothing to warn of.
    EXPECT_TRUE(stats.input) << stats.input.toString();
    ASSERT_FALSE(stats.compositor->objects.empty());
    for (const auto& o : stats.compositor->objects)
        EXPECT_EQ(o.frames, stats.compositor->rendered) << o.name;
    EXPECT_TRUE(stats.warnings().empty());
}

// What the compositor says of objects it never drew, and why.
TEST(CompositorStats, NamesEachObjectNeverDrawnWithWhy) {
    CompositorStats c;
    EXPECT_TRUE(c.neverDrawn().empty()) << "nothing composited yet: nothing to say";
    c.composites = 36;
    c.rendered = 36;
    c.objects = {{"teapot", "marker:0", 0}, {"box", "world", 36}};
    ASSERT_EQ(c.neverDrawn().size(), 1u);
    EXPECT_EQ(c.neverDrawn()[0],
              "object 'teapot' (anchor marker:0) was never drawn: marker 0 had no pose in any of "
              "36 composites");
    c.rendered = 0;
    c.objects[1].frames = 0;
    ASSERT_EQ(c.neverDrawn().size(), 2u);
    EXPECT_EQ(c.neverDrawn()[1],
              "object 'box' (anchor world) was never drawn: the camera had no pose in any of 36 "
              "composites");
    ArPipelineStats stats;
    stats.compositor = c;
    stats.input = Status(ErrorCode::kCorruptData, "cut.mkv: file is cut off");
    ASSERT_EQ(stats.warnings().size(), 3u);
    EXPECT_EQ(stats.warnings()[0], "input incomplete: cut.mkv: file is cut off");
}

// camera_matching.motion_blur through the compositor: from the second measured pose on, each
// composite is blurred over the exposure by the camera's motion since the last frame; without
// an exposure (the session's frames carry none, and exposure_ms 0) nothing changes.
TEST(ArPipeline, MotionBlurFollowsTheTrackedCamerasMotion) {
    const auto composites = [](std::optional<float> exposure_ms) {
        ArPipelineOptions options = sessionPipelineOptions();
        options.scene->camera_matching.motion_blur_exposure_ms = exposure_ms;
        std::mutex mutex;
        std::map<uint64_t, std::vector<uint8_t>> got;
        options.on_composite = [&](const CompositeFrame& c) {
            const ImageView image = c.composite.image();
            std::lock_guard lock(mutex);
            got[c.color.meta().sequence].assign(image.data, image.data + image.size_bytes);
        };
        std::unique_ptr<ArPipeline> pipeline;
        runToEnd(sessionSource(ArSource::Pace::kFast), std::move(options), pipeline);
        return got;
    };
    const auto still = composites(std::nullopt);
    const auto unknown_exposure = composites(0.f);
    const auto blurred = composites(30.f);
    ASSERT_EQ(still.size(), 36u);
    ASSERT_EQ(blurred.size(), 36u);
    EXPECT_TRUE(unknown_exposure == still);
    EXPECT_TRUE(blurred.at(0) == still.at(0)) << "no motion known before the second frame";
    for (uint64_t i = 1; i < 36; i += 5) {
        size_t differ = 0;
        for (size_t b = 0; b < still.at(i).size(); ++b)
            differ += still.at(i)[b] != blurred.at(i)[b];
        EXPECT_GT(differ, 300u) << "frame " << i;
    }
}

TEST(ArPipeline, RecordsRawStreamsPosesLightsAndTheCompositeIntoOneRecording) {
    const fs::path out = fs::path(::testing::TempDir()) / "ar_pipeline_record.mkv";
    ArPipelineOptions options = sessionPipelineOptions();
    ASSERT_TRUE(options.setup.has_value());
    options.render.max_depth = 0;
    options.record = out;
    const ArSource source = sessionSource(ArSource::Pace::kFast);
    std::unique_ptr<ArPipeline> pipeline;
    ASSERT_NO_FATAL_FAILURE(runToEnd(source, std::move(options), pipeline));

    auto recorded = replay::openRecording(out);
    ASSERT_TRUE(recorded.isOk()) << recorded.status().toString();
    std::map<std::string, StreamId> ids;
    for (StreamId i = 0; i < (*recorded)->streams().size(); ++i)
        ids[(*recorded)->streams()[i].name] = i;
    for (const char* name :
         {"kinect/color", "kinect/depth", "env/color", "tracking/pose", "tracking/lights",
          "tracking/environment_lights", "tracking/environment_map", "composite/color"})
        EXPECT_TRUE(ids.count(name)) << name << " is not in the recording";
    std::map<StreamId, int> counts;
    std::set<std::string> groups;
    while (true) {
        auto frame = (*recorded)->next();
        if (!frame)
            break;
        const StreamId s = frame->meta().stream;
        ++counts[s];
        if (s == ids["tracking/pose"]) {
            EXPECT_TRUE(decodePoseRecord(frame->image()).isOk());
        }
        if (s == ids["tracking/lights"]) {
            auto lights = tracking::decodeLightRecord(frame->image());
            ASSERT_TRUE(lights.isOk()) << lights.status().toString();
            for (const auto& g : lights->groups)
                groups.insert(g.name);
        }
        if (s == ids["tracking/environment_map"]) {
            EXPECT_TRUE(tracking::decodeEnvironmentMapRecord(frame->image()).isOk());
        }
    }
    // Every captured frame reached the file, and one pose, light record and composite each.
    EXPECT_EQ(counts[ids["kinect/color"]], 36);
    EXPECT_EQ(counts[ids["kinect/depth"]], 36);
    EXPECT_EQ(counts[ids["env/color"]], 3);
    EXPECT_EQ(counts[ids["tracking/pose"]], 36);
    EXPECT_EQ(counts[ids["tracking/lights"]], 36);
    EXPECT_EQ(counts[ids["composite/color"]], 36);
    EXPECT_GE(counts[ids["tracking/environment_map"]], 1);
    // Each estimator's answer, and the lights the compositor rendered with.
    EXPECT_EQ(groups, (std::set<std::string>{"render", "probe:probe_mirror", "probe:probe_diffuse",
                                             "environment"}));
}

// The bundled session played twice into one file, its environment camera silent in the second
// pass (it died after its frame at 1.0 s) and the last colour frames black (the markers lost).
fs::path sessionWithDeadEnvironmentCamera(size_t blank_last_colour_frames) {
    const fs::path out = fs::path(::testing::TempDir()) / "ar_pipeline_dead_env.mkv";
    auto first = replay::openRecording(session());
    EXPECT_TRUE(first.isOk());
    RecordingHeader header;
    header.streams = (*first)->streams();
    header.attachments = (*first)->attachments();
    header.tags = (*first)->tags();
    auto writer = createMkvWriter(out, header);
    EXPECT_TRUE(writer.isOk()) << writer.status().toString();
    int64_t first_ns = -1;
    int64_t last_ns = 0;
    size_t colour_total = 0;
    for (int pass = 0; pass < 2; ++pass) {
        // Frame by frame: the reader's pools hold a few frames per stream.
        auto reader = replay::openRecording(session());
        EXPECT_TRUE(reader.isOk());
        size_t colour_seen = 0;
        while (true) {
            auto next = (*reader)->next();
            if (!next) {
                EXPECT_EQ(next.status().code(), ErrorCode::kEndOfStream)
                    << next.status().toString();
                break;
            }
            FrameRef frame = std::move(next).value();
            const std::string& name = header.streams[frame.meta().stream].name;
            if (pass == 0) {
                if (first_ns < 0)
                    first_ns = frame.meta().host_stamp_ns;
                last_ns = std::max(last_ns, frame.meta().host_stamp_ns);
                colour_total += name == "kinect/color";
            } else {
                if (name == "env/color")
                    continue;
                WritableFrame w = WritableFrame::reclaim(frame);
                EXPECT_TRUE(w) << "the reader kept a handle on its frame";
                const int64_t shift_ns = last_ns - first_ns + 33'333'333;
                w.meta().host_stamp_ns += shift_ns;
                w.meta().device_stamp_ns += shift_ns;
                w.meta().sequence += 1000;
                if (name == "kinect/color" &&
                    ++colour_seen > colour_total - blank_last_colour_frames)
                    std::memset(w.image().data, 0, w.image().desc.bufferBytes());
                frame = std::move(w).publish();
            }
            EXPECT_TRUE((*writer)->write(frame).isOk());
        }
    }
    EXPECT_TRUE((*writer)->close().isOk());
    return out;
}

// Issue 13, faults while live: the environment camera dies while the colour camera goes on.
// Every colour frame is still composited; the light records mark the environment group stale
// once the camera has been silent longer than the limit, saying why, and the pose records say
// why the marker pose is not current on the frames where the markers are not seen.
TEST(ArPipeline, EstimatesOfADeadCameraAndALostMarkerGoStaleWithTheirReason) {
    const fs::path input = sessionWithDeadEnvironmentCamera(4);
    ASSERT_FALSE(HasFailure());
    const fs::path out = fs::path(::testing::TempDir()) / "ar_pipeline_dead_env_out.mkv";
    ArPipelineOptions options = sessionPipelineOptions();
    ASSERT_TRUE(options.setup.has_value());
    options.render.max_depth = 0;
    options.record = out;
    ASSERT_EQ(options.tracking.environment_max_age_ms, 1000);
    ArSource source;
    source.recording = input;
    source.pace = ArSource::Pace::kFast;
    std::unique_ptr<ArPipeline> pipeline;
    ASSERT_NO_FATAL_FAILURE(runToEnd(source, std::move(options), pipeline));
    // The composite goes on: one per colour frame, both passes.
    EXPECT_EQ(pipeline->stats().compositor->composites, 72u);

    auto recorded = replay::openRecording(out);
    ASSERT_TRUE(recorded.isOk()) << recorded.status().toString();
    std::map<std::string, StreamId> ids;
    for (StreamId i = 0; i < (*recorded)->streams().size(); ++i)
        ids[(*recorded)->streams()[i].name] = i;
    int64_t last_env_ns = 0;
    int silent_fresh = 0, silent_stale = 0, talking_aged = 0;
    int pose_not_valid = 0;
    while (true) {
        auto frame = (*recorded)->next();
        if (!frame)
            break;
        const StreamId s = frame->meta().stream;
        if (s == ids["env/color"])
            last_env_ns = std::max(last_env_ns, frame->meta().host_stamp_ns);
        if (s == ids["tracking/pose"]) {
            auto pose = decodePoseRecord(frame->image());
            ASSERT_TRUE(pose.isOk());
            if (pose->status != PoseStatus::kValid) {
                ++pose_not_valid;
                EXPECT_FALSE(pose->reason.empty()) << "a pose that is not current says why";
            }
        }
        if (s != ids["tracking/lights"])
            continue;
        auto lights = tracking::decodeLightRecord(frame->image());
        ASSERT_TRUE(lights.isOk()) << lights.status().toString();
        const int64_t silent_ns = frame->meta().host_stamp_ns - last_env_ns;
        for (const auto& g : lights->groups) {
            if (g.name != "environment")
                continue;
            if (silent_ns > 1'050'000'000) {
                if (g.stale && g.reason.find("the environment camera sent no image for") == 0)
                    ++silent_stale;
                else
                    ++silent_fresh;
                // Its last lights are kept, from the last image it sent.
                EXPECT_FALSE(g.lights.empty());
                EXPECT_LE(g.good_stamp_ns, last_env_ns);
            } else if (silent_ns < 950'000'000 &&
                       g.reason.find("sent no image") != std::string::npos) {
                ++talking_aged;
            }
        }
    }
    EXPECT_GE(silent_stale, 5) << "the dead camera's estimate was never marked stale";
    EXPECT_EQ(silent_fresh, 0) << "a dead camera's estimate claimed to be current";
    EXPECT_EQ(talking_aged, 0) << "an estimate marked stale while its camera still sent images";
    EXPECT_GE(pose_not_valid, 1) << "the blacked-out frames still gave a current pose";
}

// Issue 31's fault matrix: a damaged pose record (a bit flipped in its translation: the
// record's CRC no longer holds) and a colour frame its driver marked corrupt, mid-replay. Each
// costs its own set, said in the warnings, never the run.
TEST(ArPipeline, ADamagedPoseRecordAndACorruptColourFrameMidReplayCostTheirSetsNotTheRun) {
    const fs::path input = fs::path(::testing::TempDir()) / "ar_pipeline_damaged_records.mkv";
    int poses = 0;
    test::copyRecordingEditing(session(), input,
                               [&](const std::string& stream, int n, WritableFrame& frame) {
                                   if (stream == "kinect/color" && n == 12)
                                       frame.meta().status = FrameStatus::kCorrupt;
                                   if (stream != "truth/pose")
                                       return;
                                   poses = n;
                                   if (n == 20)
                                       frame.image().data[40] ^= 0x10;  // in the translation
                               });
    ASSERT_FALSE(HasFatalFailure());
    ASSERT_GE(poses, 20);
    // The session's recorded poses instead of tracking (as bench pipeline's graph-only run):
    // the damaged record is the one the compositor reads.
    ArPipelineOptions options = sessionPipelineOptions();
    ASSERT_TRUE(options.setup.has_value());
    FixedCamera camera = options.scene->camera.value_or(FixedCamera{});
    if (!camera.model)
        camera.model = options.setup->camera.model;
    camera.has_pose = false;
    options.scene->camera = camera;
    options.setup.reset();
    options.pose_stream = "truth/pose";
    ArSource source;
    source.recording = input;
    source.pace = ArSource::Pace::kFast;
    std::unique_ptr<ArPipeline> pipeline;
    ASSERT_NO_FATAL_FAILURE(runToEnd(source, std::move(options), pipeline));
    const ArPipelineStats stats = pipeline->stats();
    ASSERT_TRUE(stats.compositor.has_value());
    const CompositorStats& c = *stats.compositor;
    EXPECT_EQ(c.skipped_corrupt, 1u);
    EXPECT_EQ(c.composites + c.skipped_corrupt + c.skipped_without_pose, c.sets);
    EXPECT_EQ(c.sets, 36u) << "one set per colour frame of the session";
    EXPECT_EQ(c.damaged_records, 1u);
    EXPECT_NE(c.first_damaged_record.find("truth/pose record"), std::string::npos)
        << c.first_damaged_record;
    // The damaged pose's set is the camera image as is (no pose); the others are rendered.
    EXPECT_EQ(c.passed_through, 1u);
    std::string warnings;
    for (const std::string& line : stats.warnings())
        warnings += line + "\n";
    EXPECT_NE(warnings.find("1 colour frame marked corrupt by its driver was not composited"),
              std::string::npos)
        << warnings;
    EXPECT_NE(warnings.find("1 pose or light record was damaged and composited past (first: "),
              std::string::npos)
        << warnings;
}

// Issue 14, the environment from the camera itself: with the fish-eye left out, the light node
// builds the environment from the tracked colour frames, publishes a map after the first frame
// and then every `interval`, and every light record names the map in use; the compositor lights
// the virtual objects with it, so the glass ball shows the room instead of black. With the
// fish-eye in, its maps win and none is built.
TEST(ArPipeline, WithoutAFisheyeTheCompositorUsesTheEnvironmentTheCameraBuilt) {
    struct Run {
        std::map<uint64_t, std::vector<uint8_t>> composites;
        std::map<uint64_t, int64_t> map_stamps;  // colour frame → camera map in use (0: none)
        std::map<uint64_t, int64_t> frame_stamps;
        std::map<uint64_t, bool> lit_by_map;  // the renderer had an environment light
        uint64_t maps = 0;
        bool fisheye_group = false;
    };
    const auto run = [](bool fisheye, bool camera_environment) {
        ArPipelineOptions options = sessionPipelineOptions();
        options.tracking.environment = fisheye;
        if (camera_environment)
            options.tracking.camera_environment = tracking::CameraEnvironmentOptions{.width = 64};
        options.tracking.camera_environment_interval = 10;
        auto r = std::make_shared<Run>();
        std::mutex mutex;
        options.on_composite = [&mutex, r](const CompositeFrame& c) {
            const uint64_t i = c.color.meta().sequence;
            const ImageView image = c.composite.image();
            std::lock_guard lock(mutex);
            r->composites[i].assign(image.data, image.data + image.size_bytes);
            r->frame_stamps[i] = c.color.meta().host_stamp_ns;
            r->map_stamps[i] = 0;
            if (c.lights)
                for (const auto& g : c.lights->groups) {
                    if (g.name == "camera_environment")
                        r->map_stamps[i] = g.good_stamp_ns;
                    r->fisheye_group = r->fisheye_group || g.name == "environment";
                }
            r->lit_by_map[i] = false;
            if (c.lights_used)
                for (const Light& l : *c.lights_used)
                    r->lit_by_map[i] = r->lit_by_map[i] ||
                                       (l.type == LightType::kEnvironment && l.environment_image);
        };
        std::unique_ptr<ArPipeline> pipeline;
        runToEnd(sessionSource(ArSource::Pace::kFast), std::move(options), pipeline);
        r->maps = pipeline ? pipeline->stats().tracking->environment_maps : 0;
        return r;
    };
    const auto black = run(false, false);
    const auto built = run(false, true);
    ASSERT_FALSE(HasFailure());
    ASSERT_EQ(built->composites.size(), 36u);
    ASSERT_EQ(black->composites.size(), 36u);

    // Every session frame has a fresh pose: maps after frames 0, 10, 20 and 30.
    EXPECT_EQ(built->maps, 4u);
    EXPECT_EQ(black->maps, 0u);
    EXPECT_FALSE(built->fisheye_group);
    for (uint64_t i = 0; i < 36; ++i) {
        SCOPED_TRACE("colour frame " + std::to_string(i));
        EXPECT_EQ(built->map_stamps.at(i), built->frame_stamps.at(i / 10 * 10));
        EXPECT_TRUE(built->lit_by_map.at(i));
        EXPECT_FALSE(black->lit_by_map.at(i));
        EXPECT_EQ(black->map_stamps.at(i), 0);
    }
    // The room the camera saw lights the objects and shows in the glass: the composite is
    // brighter where it changed, on every frame.
    for (uint64_t i = 0; i < 36; i += 5) {
        const std::vector<uint8_t>& a = black->composites.at(i);
        const std::vector<uint8_t>& b = built->composites.at(i);
        ASSERT_EQ(a.size(), b.size());
        int64_t changed = 0, gain = 0;
        for (size_t k = 0; k < a.size(); ++k)
            if (a[k] != b[k]) {
                ++changed;
                gain += int64_t{b[k]} - int64_t{a[k]};
            }
        std::printf(
            "frame %2llu: %lld bytes changed by the camera's environment, mean %+.1f codes\n",
            static_cast<unsigned long long>(i), static_cast<long long>(changed),
            changed ? static_cast<double>(gain) / static_cast<double>(changed) : 0.0);
        EXPECT_GT(changed, 1000) << "frame " << i;
        EXPECT_GT(gain, 10 * changed) << "frame " << i << ": " << changed << " bytes changed";
    }

    // The fish-eye in the graph: its maps, not the camera's.
    const auto with_fisheye = run(true, true);
    ASSERT_FALSE(HasFailure());
    EXPECT_EQ(with_fisheye->maps, 3u) << "one per fish-eye image";
    EXPECT_TRUE(with_fisheye->fisheye_group);
    for (const auto& [i, stamp] : with_fisheye->map_stamps)
        EXPECT_EQ(stamp, 0) << "frame " << i << " named a camera-built map";
}

TEST(ArPipeline, RealPaceKeepsUpAndReportsLatency) {
    // The colour stream only (no tracking, a fixed camera): the compositor at the recording's
    // own pace takes the newest set and reports latency from each frame's arrival.
    ArPipelineOptions options;
    options.scene = testScene();
    options.scene->camera = FixedCamera{};
    auto reader = replay::openRecording(session());
    ASSERT_TRUE(reader.isOk());
    options.scene->camera->model = sessionSetup(**reader).camera.model;
    options.scene->camera->T_world_cam.translation() = Eigen::Vector3d(0, -0.5, 0.4);
    options.scene->camera->T_world_cam.linear() =
        Eigen::AngleAxisd(-2.2, Eigen::Vector3d::UnitX()).toRotationMatrix();
    options.render = testRenderOptions();
    options.target_fps = -1;
    const ArSource source = sessionSource(ArSource::Pace::kReal);
    std::unique_ptr<ArPipeline> pipeline;
    ASSERT_NO_FATAL_FAILURE(
        runToEnd(source, std::move(options), pipeline, std::chrono::seconds(30)));
    const ArPipelineStats stats = pipeline->stats();
    ASSERT_TRUE(stats.compositor.has_value());
    const CompositorStats& c = *stats.compositor;
    // Every set is composited or counted as skipped for a newer one: none vanishes.
    EXPECT_EQ(c.composites + c.skipped_superseded, c.sets);
    EXPECT_GT(c.composites, 0u);
    EXPECT_EQ(c.latency.count, c.composites);
    EXPECT_GT(c.latency.p50_ms, 0);
    EXPECT_LE(c.latency.p50_ms, c.latency.p99_ms);
    EXPECT_GE(c.quality_steps, 2);
    const std::string json = stats.json();
    for (const char* key : {"\"latency_ms\"", "\"p99\"", "\"ladder\"", "\"rung\"", "\"devices\""})
        EXPECT_NE(json.find(key), std::string::npos) << key << " missing in " << json;
}

TEST(ArPipeline, RefusesWhatItCannotBuild) {
    ArSource none;
    EXPECT_EQ(ArPipeline::create(replayRegistry(), none, {}).status().code(),
              ErrorCode::kInvalidArgument);
    ArSource missing;
    missing.recording = "/nonexistent/session.mkv";
    auto opened = ArPipeline::create(replayRegistry(), missing, {});
    EXPECT_FALSE(opened.isOk());
    EXPECT_NE(opened.status().message().find("/nonexistent/session.mkv"), std::string::npos)
        << opened.status().toString();
    // A scene without a camera pose and no tracking: the camera must come from a pose stream,
    // and the session has exactly one (truth/pose), so that one is used; naming a stream that
    // is not there is an error.
    ArPipelineOptions options;
    options.scene = testScene();
    options.pose_stream = "no/such/pose";
    const ArSource source = sessionSource(ArSource::Pace::kFast);
    auto bad = ArPipeline::create(replayRegistry(), source, std::move(options));
    EXPECT_FALSE(bad.isOk());
}

// Real pace, looped, tracking and recording on, and a target rate no machine reaches: the
// invariants that do not depend on the machine's speed. Every set the synchronizer gave is
// composited or counted with its reason; every composite has a latency; the ladder went down;
// every frame a recorded stream published is in the file, read back.
TEST(ArPipeline, RealPaceAccountsForEverySetAndRecordsEveryCapturedFrame) {
    const fs::path out = fs::path(::testing::TempDir()) / "ar_pipeline_real_pace.mkv";
    ArPipelineOptions options = sessionPipelineOptions();
    ASSERT_TRUE(options.setup.has_value());
    options.render.samples_per_pixel = 4;
    options.target_fps = 1000;
    options.record = out;
    std::mutex mutex;
    uint64_t callbacks = 0, with_latency = 0;
    int lowest_rung = 0;
    options.on_composite = [&](const CompositeFrame& f) {
        std::lock_guard lock(mutex);
        ++callbacks;
        with_latency += f.latency_ms > 0;
        lowest_rung = std::max(lowest_rung, f.quality_step);
    };
    const ArSource source = sessionSource(ArSource::Pace::kReal, true);
    auto created = ArPipeline::create(replayRegistry(), source, std::move(options));
    ASSERT_TRUE(created.isOk()) << created.status().toString();
    const std::unique_ptr<ArPipeline> pipeline = std::move(created).value();
    ASSERT_TRUE(pipeline->start().isOk());
    // Past the end of the 1.2 s session, so the loop restarts it at least once, and until the
    // ladder had the 3 rendered frames it needs to judge a rung (a slow machine takes longer).
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(40);
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));
    while (pipeline->stats().compositor->rendered < 5 &&
           std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    EXPECT_FALSE(pipeline->waitDone(std::chrono::milliseconds(1))) << "a looped source ended";
    pipeline->stop();
    ASSERT_TRUE(pipeline->status().isOk()) << pipeline->status().toString();
    const ArPipelineStats stats = pipeline->stats();
    ASSERT_TRUE(stats.compositor.has_value());
    const CompositorStats& c = *stats.compositor;
    EXPECT_GT(c.sets, 0u);
    EXPECT_EQ(c.composites + c.skipped_superseded + c.skipped_for_recording +
                  c.skipped_without_pose + c.skipped_corrupt + c.publish_failures +
                  c.skipped_at_stop,
              c.sets);
    EXPECT_EQ(callbacks, c.composites);
    EXPECT_EQ(with_latency, c.composites);
    EXPECT_EQ(c.latency.count, std::min<uint64_t>(c.composites, 1024));
    // How much is rendered is the machine's speed: on one busy with other work the recorder's
    // backlog may hold the compositor back for the whole run (the policy: composites give way,
    // never captured frames). Then that is the reason said, and the ladder cannot be judged.
    if (c.rendered >= 5) {
        EXPECT_GT(lowest_rung, 0) << "the ladder never went down at a target of 1000 fps";
    } else {
        EXPECT_GT(c.skipped_for_recording, 0u)
            << c.rendered << " rendered in 40 s, and not for the recorder";
    }

    // Every frame published on a recorded stream is in the file or counted as dropped by the
    // recorder's live queue (a recorder behind the sources must not slow capture): none is lost
    // silently. How many are dropped depends on the machine; bench pipeline reports it.
    ASSERT_TRUE(stats.recorder.has_value());
    auto recorded = replay::openRecording(out);
    ASSERT_TRUE(recorded.isOk()) << recorded.status().toString();
    std::map<std::string, uint64_t> in_file;
    while (true) {
        auto frame = (*recorded)->next();
        if (!frame) {
            EXPECT_EQ(frame.status().code(), ErrorCode::kEndOfStream) << frame.status().toString();
            break;
        }
        ++in_file[(*recorded)->streams().at(frame->meta().stream).name];
    }
    Graph& graph = pipeline->graph();
    ASSERT_FALSE(stats.recorder->streams.empty());
    uint64_t colour = 0;
    for (const RecorderStreamStats& r : stats.recorder->streams) {
        const auto id = graph.findStream(r.stream);
        ASSERT_TRUE(id.has_value()) << r.stream;
        EXPECT_EQ(in_file[r.stream], r.written) << r.stream;
        EXPECT_EQ(r.written + r.dropped + r.discarded, graph.publishedCount(*id)) << r.stream;
        if (r.stream == "kinect/color")
            colour = graph.publishedCount(*id);
    }
    // More colour frames than the session has: the loop went round.
    EXPECT_GT(colour, 36u);
}

// The ladder's rule alone, with made-up render times: down a rung at a time while frames are
// too slow for the rate, back up a rung at a time after two seconds of fast frames.
TEST(QualityController, GoesDownWhenFramesAreSlowAndBackUpWhenTheyAreFast) {
    QualityController q(4, 30);
    EXPECT_EQ(q.step(), 0);
    const double period = 1.0 / 30;
    int frames = 0;
    while (q.step() < 3 && frames < 100) {
        q.update(2 * period);
        ++frames;
    }
    EXPECT_EQ(q.step(), 3);
    EXPECT_LE(frames, 3 * 3 + 3);
    for (int i = 0; i < 10; ++i)
        EXPECT_EQ(q.update(2 * period), 3) << "there is no rung below the last";
    // Frames a little under the period: no reason to move either way.
    for (int i = 0; i < 200; ++i)
        EXPECT_EQ(q.update(0.7 * period), 3);
    // Fast frames: up one rung per two seconds' worth (60 frames at 30 fps), plus the time the
    // average takes to fall.
    frames = 0;
    while (q.step() > 0 && frames < 1000) {
        q.update(0.1 * period);
        ++frames;
    }
    EXPECT_EQ(q.step(), 0);
    EXPECT_GE(frames, 3 * 60);
    EXPECT_LE(frames, 3 * 70);
    // Without a target rate it never moves.
    QualityController fixed(4, 0);
    for (int i = 0; i < 100; ++i)
        EXPECT_EQ(fixed.update(10.0), 0);
}

TEST(LightEstimationNode, EstimatesTheProbesAtMostOncePerInterval) {
    // Offline every colour frame estimates the probes; with an interval (as live), the last
    // estimates stand in between, fresh, and tracking itself still runs on every frame.
    for (const int64_t interval_ms : {int64_t{0}, int64_t{500}}) {
        SCOPED_TRACE("probe_interval_ms " + std::to_string(interval_ms));
        ArPipelineOptions options = sessionPipelineOptions();
        ASSERT_TRUE(options.setup.has_value());
        options.scene.reset();
        options.tracking.probe_interval_ms = interval_ms;
        std::vector<int64_t> probe_updates;  // written on the light node's thread only
        options.on_tracked = [&](const TrackedFrame& f) {
            EXPECT_TRUE(f.probes.at(0).value.has_value());
            EXPECT_TRUE(f.track.pose.value.has_value());
            probe_updates.push_back(f.probes.at(0).updates);
        };
        std::unique_ptr<ArPipeline> pipeline;
        ASSERT_NO_FATAL_FAILURE(runToEnd(sessionSource(ArSource::Pace::kFast), std::move(options),
                                         pipeline, std::chrono::seconds(60)));
        ASSERT_EQ(probe_updates.size(), 36u);
        // 36 frames over 1.17 s: every one, or one per started 500 ms.
        EXPECT_EQ(probe_updates.back(), interval_ms == 0 ? 36 : 3);
        EXPECT_EQ(pipeline->stats().tracking->light_records, 36u);
    }
}

TEST(LightEstimationNode, OfflineEachFrameTakesTheNewestEnvironmentImageBeforeIt) {
    // The fish-eye runs on a node of its own; offline a colour frame must still get the
    // estimate of exactly the newest environment image stamped at or before it, every run.
    std::vector<int64_t> env_stamps;
    {
        auto reader = replay::openRecording(session());
        ASSERT_TRUE(reader.isOk());
        while (auto frame = (*reader)->next())
            if ((*reader)->streams()[frame->meta().stream].name == "env/color")
                env_stamps.push_back(frame->meta().host_stamp_ns);
    }
    ASSERT_EQ(env_stamps.size(), 3u);
    for (int run = 0; run < 2; ++run) {
        SCOPED_TRACE("run " + std::to_string(run));
        ArPipelineOptions options = sessionPipelineOptions();
        ASSERT_TRUE(options.setup.has_value());
        options.scene.reset();
        options.tracking.probes = false;  // only the fish-eye matters here
        int frames = 0;
        options.on_tracked = [&](const TrackedFrame& f) {
            ++frames;
            const int64_t stamp = f.color.meta().host_stamp_ns;
            int64_t newest = 0;
            for (int64_t e : env_stamps)
                if (e <= stamp)
                    newest = e;
            EXPECT_EQ(f.environment.stamp_ns, newest) << "colour frame at " << stamp;
            EXPECT_EQ(f.environment.value.has_value(), newest > 0);
        };
        std::unique_ptr<ArPipeline> pipeline;
        ASSERT_NO_FATAL_FAILURE(runToEnd(sessionSource(ArSource::Pace::kFast), std::move(options),
                                         pipeline, std::chrono::seconds(60)));
        EXPECT_EQ(frames, 36);
        const tracking::TrackingNodeStats stats = *pipeline->stats().tracking;
        EXPECT_EQ(stats.environment_frames, 3u);
        EXPECT_EQ(stats.light_records, 36u);
    }
}

TEST(QualityLadder, GoesDownFromWhatWasAskedAndLeavesOutRungsThatChangeNothing) {
    RenderOptions best;
    best.samples_per_pixel = 4;
    best.shadow_samples = 20;
    best.max_depth = 3;
    const auto ladder = qualityLadder(best);
    ASSERT_GE(ladder.size(), 4u);
    EXPECT_EQ(ladder.front().samples_per_pixel, 4);
    EXPECT_EQ(ladder.back().soft_shadows, SoftShadowMethod::kHard);
    EXPECT_EQ(ladder.back().max_depth, 0);
    // People count rungs from 1, full quality first.
    EXPECT_EQ(rungText(0, static_cast<int>(ladder.size()), ladder.front().label()),
              "rung 1 of " + std::to_string(ladder.size()) + " (" + ladder.front().label() + ")");
    EXPECT_EQ(rungText(1, 5, ""), "rung 2 of 5");
    RenderOptions cheap;
    cheap.samples_per_pixel = 1;
    cheap.shadow_samples = 4;
    cheap.max_depth = 0;
    cheap.soft_shadows = SoftShadowMethod::kHard;
    EXPECT_EQ(qualityLadder(cheap).size(), 1u);
}

}  // namespace
}  // namespace mixray::render
