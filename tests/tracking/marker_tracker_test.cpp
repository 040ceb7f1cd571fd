// The marker tracker (tracking/src/marker_tracker.cpp) on the committed simulated tabletop
// session against its ground truth, through loss and re-acquisition, with several targets, and
// against bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/aruco.hpp>

#include "marker_test_util.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/pose.h"
#include "mixray/render/simulator.h"
#include "mixray/tracking/markers.h"
#include "test_data.h"

namespace mixray::tracking {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;
namespace fs = std::filesystem;

struct SimFrame {
    Image color;
    int64_t stamp_ns = 0;
    Isometry3d T_world_color = Isometry3d::Identity();
};

struct Session {
    calibration::CameraModel camera;
    std::vector<SimFrame> frames;
};

// fixtures/sessions/sim_tabletop.mkv: its colour frames and truth/pose records, and the colour
// camera of the simulator that made it (SimulatorOptions{kTabletop, frames 36, seed 1}).
const Session& session() {
    static const Session* shared = [] {
        auto* s = new Session;
        render::SimulatorOptions o;
        o.frames = 36;
        o.env_map_width = 64;  // the truth's poses and intrinsics do not depend on it
        auto sim = render::Simulator::create(o);
        EXPECT_TRUE(sim) << sim.status().toString();
        if (!sim)
            return s;
        s->camera = (*sim)->truth().color;
        auto reader = openMkv(mixray::test::fixturesDir() / "sessions" / "sim_tabletop.mkv");
        EXPECT_TRUE(reader) << reader.status().toString();
        if (!reader)
            return s;
        std::map<uint64_t, SimFrame> by_sequence;
        while (true) {
            auto frame = (*reader)->next();
            if (!frame)
                break;
            const std::string& name = (*reader)->streams()[frame->meta().stream].name;
            if (name == "kinect/color") {
                SimFrame& f = by_sequence[frame->meta().sequence];
                f.color = Image::copyOf(frame->image());
                f.stamp_ns = frame->meta().device_stamp_ns;
            } else if (name == "truth/pose") {
                auto record = decodePoseRecord(frame->image());
                EXPECT_TRUE(record);
                if (record)
                    by_sequence[record->frame_sequence].T_world_color = record->transform();
            }
        }
        for (auto& [seq, f] : by_sequence)
            s->frames.push_back(std::move(f));
        return s;
    }();
    return *shared;
}

MarkerTarget simMarker() {
    MarkerTarget t;
    t.name = "table";
    t.id = 23;
    t.size_m = 0.1;
    t.bound_objects = {"teapot"};
    return t;
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0 : v[v.size() / 2];
}

TEST(MarkerTracker, SimulatedSessionMeetsMillimetreAccuracy) {
    const Session& s = session();
    ASSERT_EQ(s.frames.size(), 36u);
    for (bool smoothing : {false, true}) {
        TrackerOptions o;
        o.smoothing.enabled = smoothing;
        auto tracker = MarkerTracker::create(s.camera, {simMarker()}, o);
        ASSERT_TRUE(tracker) << tracker.status().toString();
        std::vector<double> t_err_mm, r_err_deg, cam_raw_mm, cam_mm, cam_deg, out_mm, out_deg;
        for (const SimFrame& f : s.frames) {
            auto track = (*tracker)->track(f.color.view(), f.stamp_ns);
            ASSERT_TRUE(track) << track.status().toString();
            ASSERT_EQ(track->state, TrackState::kTracking) << track->pose.reason;
            ASSERT_EQ(track->targets.size(), 1u);
            // The marker in the camera frame, as the fit saw it.
            const Isometry3d truth = f.T_world_color.inverse();  // T_camera_marker, marker = world
            const Isometry3d& est = track->targets[0].T_camera_target;
            t_err_mm.push_back(1e3 * (est.translation() - truth.translation()).norm());
            r_err_deg.push_back(synth::angleDeg(est, truth));
            // The camera in the world: unsmoothed and as handed on.
            cam_raw_mm.push_back(
                1e3 *
                (track->raw_T_world_camera->translation() - f.T_world_color.translation()).norm());
            ASSERT_TRUE(track->pose.value);
            EXPECT_FALSE(track->pose.stale);
            cam_mm.push_back(
                1e3 * (track->pose.value->translation() - f.T_world_color.translation()).norm());
            cam_deg.push_back(synth::angleDeg(*track->pose.value, f.T_world_color));
            // The marker in the camera frame from the pose handed on (smoothed when on).
            const Isometry3d out = track->pose.value->inverse();
            out_mm.push_back(1e3 * (out.translation() - truth.translation()).norm());
            out_deg.push_back(synth::angleDeg(out, truth));
        }
        std::printf(
            "sim_tabletop.mkv, 36 frames, smoothing %s: T_camera_marker median error %.3f mm "
            "%.4f deg (max %.3f mm %.4f deg); camera position in the world: raw median %.3f mm, "
            "output median %.3f mm (max %.3f mm), output rotation median %.4f deg; "
            "T_camera_marker from the output pose: median %.3f mm %.4f deg\n",
            smoothing ? "on " : "off", median(t_err_mm), median(r_err_deg),
            *std::max_element(t_err_mm.begin(), t_err_mm.end()),
            *std::max_element(r_err_deg.begin(), r_err_deg.end()), median(cam_raw_mm),
            median(cam_mm), *std::max_element(cam_mm.begin(), cam_mm.end()), median(cam_deg),
            median(out_mm), median(out_deg));
        EXPECT_LT(median(t_err_mm), 2.0);
        EXPECT_LT(median(r_err_deg), 0.2);
        EXPECT_LT(median(out_mm), 2.0);
        EXPECT_LT(median(out_deg), 0.2);
    }
}

// The marker's image region (its projected print, quiet zone included) painted black.
Image coverMarker(const SimFrame& f, const calibration::CameraModel& camera) {
    Image out = Image::copyOf(f.color.view());
    const double h = 0.0625 + 0.01;
    double x0 = 1e9, y0 = 1e9, x1 = -1e9, y1 = -1e9;
    for (const Vector3d& c :
         {Vector3d(-h, -h, 0), Vector3d(h, -h, 0), Vector3d(h, h, 0), Vector3d(-h, h, 0)}) {
        const auto px = camera.project(f.T_world_color.inverse() * c);
        if (!px)
            continue;
        x0 = std::min(x0, px->x());
        y0 = std::min(y0, px->y());
        x1 = std::max(x1, px->x());
        y1 = std::max(y1, px->y());
    }
    const MutableImageView v = out.mutableView();
    for (int y = std::max(0, static_cast<int>(y0));
         y <= std::min(v.desc.height - 1, static_cast<int>(y1)); ++y)
        for (int x = std::max(0, static_cast<int>(x0));
             x <= std::min(v.desc.width - 1, static_cast<int>(x1)); ++x)
            std::fill_n(v.row<uint8_t>(y) + 3 * x, 3, uint8_t{0});
    return out;
}

TEST(MarkerTracker, LosesTheMarkerKeepsTheLastPoseAndReacquiresWithoutLag) {
    const Session& s = session();
    ASSERT_EQ(s.frames.size(), 36u);
    auto tracker = MarkerTracker::create(s.camera, {simMarker()});
    ASSERT_TRUE(tracker);
    Isometry3d last_good = Isometry3d::Identity();
    int64_t last_good_stamp = 0;
    for (int i = 0; i < 36; ++i) {
        const SimFrame& f = s.frames[static_cast<size_t>(i)];
        const bool covered = i >= 10 && i < 20;  // a third of a second: beyond 200 ms
        const Image img = covered ? coverMarker(f, s.camera) : Image::copyOf(f.color.view());
        auto track = (*tracker)->track(img.view(), f.stamp_ns);
        ASSERT_TRUE(track) << track.status().toString();
        if (covered) {
            EXPECT_EQ(track->state, TrackState::kLost) << i;
            EXPECT_TRUE(track->pose.stale);
            EXPECT_EQ(track->pose.reason, "marker 23 not seen");
            ASSERT_TRUE(track->pose.value);
            EXPECT_TRUE(track->pose.value->isApprox(last_good, 1e-12)) << "stale pose changed";
            EXPECT_EQ(track->pose.good_stamp_ns, last_good_stamp);
            EXPECT_EQ(track->pose.stamp_ns, f.stamp_ns);
            EXPECT_FALSE(track->raw_T_world_camera);
            EXPECT_TRUE(track->targets.empty());
            EXPECT_EQ(toString(track->state), "lost");
        } else {
            EXPECT_EQ(track->state, TrackState::kTracking) << i;
            EXPECT_EQ(track->reacquired, i == 20) << i;
            ASSERT_TRUE(track->pose.value);
            const double err_mm =
                1e3 * (track->pose.value->translation() - f.T_world_color.translation()).norm();
            if (i == 20) {
                // The smoothing restarted: the first fresh pose is the raw one, on the truth.
                EXPECT_TRUE(track->pose.value->isApprox(*track->raw_T_world_camera, 1e-12));
                const Isometry3d out = track->pose.value->inverse();
                const Isometry3d truth = f.T_world_color.inverse();
                const double marker_mm = 1e3 * (out.translation() - truth.translation()).norm();
                std::printf(
                    "re-acquired at frame 20: T_camera_marker error %.3f mm %.4f deg, "
                    "camera position error %.3f mm\n",
                    marker_mm, synth::angleDeg(out, truth), err_mm);
                EXPECT_LT(marker_mm, 2.0);
                EXPECT_LT(synth::angleDeg(out, truth), 0.2);
                EXPECT_LT(err_mm, 4.0);
            }
            last_good = *track->pose.value;
            last_good_stamp = f.stamp_ns;
        }
    }
    EXPECT_EQ(toString(TrackState::kSearching), "searching");
    EXPECT_EQ(toString(TrackState::kTracking), "tracking");
}

TEST(MarkerTracker, SearchesUntilTheFirstMarkerAndRejectsBadInput) {
    const Session& s = session();
    ASSERT_FALSE(s.frames.empty());
    auto tracker = MarkerTracker::create(s.camera, {simMarker()});
    ASSERT_TRUE(tracker);
    const SimFrame& f = s.frames[0];
    auto track = (*tracker)->track(coverMarker(f, s.camera).view(), f.stamp_ns);
    ASSERT_TRUE(track);
    EXPECT_EQ(track->state, TrackState::kSearching);
    EXPECT_FALSE(track->pose.value);
    EXPECT_EQ(track->pose.reason, "marker 23 not seen");

    Image small(ImageDesc::packed(PixelFormat::kRGB8, 320, 240));
    EXPECT_EQ((*tracker)->track(small.view(), 1).status().code(), ErrorCode::kInvalidArgument);
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 640, 480));
    EXPECT_EQ((*tracker)->track(depth.view(), 2).status().code(), ErrorCode::kInvalidArgument);
    EXPECT_EQ((*tracker)->track(ImageView{}, 3).status().code(), ErrorCode::kInvalidArgument);
    ImageView empty = f.color.view();
    empty.data = nullptr;
    EXPECT_EQ((*tracker)->track(empty, 4).status().code(), ErrorCode::kInvalidArgument);
    ImageView truncated = f.color.view();
    truncated.size_bytes = 1000;
    EXPECT_EQ((*tracker)->track(truncated, 5).status().code(), ErrorCode::kInvalidArgument);

    // After bad input it still tracks; reset() forgets everything.
    auto good = (*tracker)->track(f.color.view(), f.stamp_ns + 1);
    ASSERT_TRUE(good);
    EXPECT_EQ(good->state, TrackState::kTracking);
    EXPECT_FALSE(good->reacquired);
    (*tracker)->reset();
    auto again = (*tracker)->track(coverMarker(f, s.camera).view(), f.stamp_ns + 2);
    ASSERT_TRUE(again);
    EXPECT_EQ(again->state, TrackState::kSearching);
    EXPECT_FALSE(again->pose.value);
}

TEST(MarkerTracker, TwoMarkersBothVoteForOneCameraPose) {
    // Two printed markers at known world poses, rendered through a lens with distortion.
    auto camera = calibration::CameraModel::pinhole(640, 480, 520, 521, 322.3, 238.1);
    camera.distortion = {0.05, -0.1, 0.0005, -0.0003, 0.03};
    synth::PrintedMarker a, b;
    a.id = 23;
    a.size_m = 0.08;
    b.id = 42;
    b.size_m = 0.06;
    b.T_world_marker.translation() = Vector3d(0.16, 0.05, 0);
    b.T_world_marker.linear() = Eigen::AngleAxisd(0.6, Vector3d::UnitZ()).toRotationMatrix();
    const Isometry3d T_world_camera =
        synth::lookAt(Vector3d(0.05, -0.35, 0.42), Vector3d(0.08, 0.02, 0));
    const Image img = synth::renderMarkers(camera, T_world_camera, {a, b}, 3);

    std::vector<MarkerTarget> targets(2);
    targets[0].name = "left";
    targets[0].id = 23;
    targets[0].size_m = 0.08;
    targets[0].bound_objects = {"teapot", "bunny"};
    targets[1].name = "right";
    targets[1].id = 42;
    targets[1].size_m = 0.06;
    targets[1].T_world_target = b.T_world_marker;
    targets[1].bound_objects = {"lamp"};
    TrackerOptions o;
    o.smoothing.enabled = false;
    auto tracker = MarkerTracker::create(camera, targets, o);
    ASSERT_TRUE(tracker) << tracker.status().toString();
    ASSERT_EQ((*tracker)->targets().size(), 2u);
    EXPECT_EQ((*tracker)->targets()[0].bound_objects, targets[0].bound_objects);
    EXPECT_EQ((*tracker)->targets()[1].bound_objects, targets[1].bound_objects);

    auto track = (*tracker)->track(img.view(), 1'000'000);
    ASSERT_TRUE(track) << track.status().toString();
    ASSERT_EQ(track->state, TrackState::kTracking) << track->pose.reason;
    ASSERT_EQ(track->targets.size(), 2u);
    EXPECT_EQ(track->detections.size(), 2u);
    const Isometry3d truth_cam = T_world_camera;
    for (const TargetObservation& obs : track->targets) {
        const MarkerTarget& t = obs.target == "left" ? targets[0] : targets[1];
        const Isometry3d truth = T_world_camera.inverse() * t.T_world_target;
        const double err_mm =
            1e3 * (obs.T_camera_target.translation() - truth.translation()).norm();
        std::printf("two markers: %s alone %.3f mm %.4f deg, rms %.3f px\n", obs.target.c_str(),
                    err_mm, synth::angleDeg(obs.T_camera_target, truth), obs.rms_px);
        EXPECT_EQ(obs.points, 4);
        EXPECT_LT(err_mm, 3.0);
        // Each target's own pose puts the camera where the joint fit does.
        const Isometry3d T_world_camera_alone = t.T_world_target * obs.T_camera_target.inverse();
        EXPECT_LT((T_world_camera_alone.translation() - track->pose.value->translation()).norm(),
                  0.01);
    }
    const double joint_mm =
        1e3 * (track->pose.value->translation() - truth_cam.translation()).norm();
    std::printf("two markers: joint camera position error %.3f mm, %.4f deg\n", joint_mm,
                synth::angleDeg(*track->pose.value, truth_cam));
    EXPECT_LT(joint_mm, 2.0);
    EXPECT_LT(synth::angleDeg(*track->pose.value, truth_cam), 0.2);

    // One target moved without telling the tracker: the two disagree, and it says so.
    targets[1].T_world_target.translation().x() += 0.05;
    auto confused = MarkerTracker::create(camera, targets, o);
    ASSERT_TRUE(confused);
    auto bad = (*confused)->track(img.view(), 1'000'000);
    ASSERT_TRUE(bad);
    EXPECT_EQ(bad->state, TrackState::kSearching);
    EXPECT_NE(bad->pose.reason.find("disagree"), std::string::npos) << bad->pose.reason;
}

TEST(MarkerTracker, GridBoardPoseFromAllItsCorners) {
    // A 5x7 GridBoard printed from id 10, as drawn by OpenCV, seen through a distorted lens.
    auto camera = calibration::CameraModel::pinhole(640, 480, 520, 521, 322.3, 238.1);
    camera.distortion = {0.05, -0.1, 0.0005, -0.0003, 0.03};
    MarkerTarget grid;
    grid.name = "grid";
    grid.kind = TargetKind::kGridBoard;
    grid.id = 10;
    grid.squares_x = 5;
    grid.squares_y = 7;
    grid.size_m = 0.04;
    grid.separation_m = 0.01;
    auto board = cv::aruco::GridBoard::create(
        5, 7, 0.04f, 0.01f, cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250), 10);
    synth::PrintedPlane plane;
    cv::Mat drawn;
    board->draw(cv::Size(240, 340), drawn, 0, 1);            // 1 mm per pixel
    plane.grey = cv::Mat(380, 280, CV_8U, cv::Scalar(255));  // 2 cm of white paper round it
    drawn.copyTo(plane.grey(cv::Rect(20, 20, 240, 340)));
    plane.width_m = 0.28;
    plane.height_m = 0.38;
    // The board frame (top-left marker corner, +y down, +z in) in the plane's (centre, +y up).
    grid.T_world_target.linear() = Vector3d(1, -1, -1).asDiagonal();
    grid.T_world_target.translation() = Vector3d(-0.12, 0.17, 0);
    const Isometry3d T_world_camera =
        synth::lookAt(Vector3d(0.15, -0.35, 0.45), Vector3d(0.01, 0.02, 0));
    const Image img = synth::renderPlanes(camera, T_world_camera, {plane}, 3);
    TrackerOptions o;
    o.smoothing.enabled = false;
    auto tracker = MarkerTracker::create(camera, {grid}, o);
    ASSERT_TRUE(tracker) << tracker.status().toString();
    auto track = (*tracker)->track(img.view(), 1);
    ASSERT_TRUE(track) << track.status().toString();
    ASSERT_EQ(track->state, TrackState::kTracking) << track->pose.reason;
    ASSERT_EQ(track->targets.size(), 1u);
    const double err_mm =
        1e3 * (track->pose.value->translation() - T_world_camera.translation()).norm();
    std::printf("synthetic GridBoard: %d corners, rms %.3f px, camera %.3f mm %.4f deg\n",
                track->targets[0].points, track->targets[0].rms_px, err_mm,
                synth::angleDeg(*track->pose.value, T_world_camera));
    EXPECT_GE(track->targets[0].points, 120);
    EXPECT_LT(err_mm, 1.0);
    EXPECT_LT(synth::angleDeg(*track->pose.value, T_world_camera), 0.05);
}

TEST(MarkerTracker, OptionsAndTargetsAreValidated) {
    const auto camera = calibration::CameraModel::pinhole(640, 480, 500, 500, 319.5, 239.5);
    EXPECT_TRUE(TrackerOptions{}.validate());
    EXPECT_TRUE(SmoothingOptions{}.validate());
    EXPECT_TRUE(DetectorOptions{}.validate());
    TrackerOptions o;
    o.max_rms_px = 0;
    EXPECT_EQ(o.validate().code(), ErrorCode::kInvalidArgument);
    EXPECT_FALSE(MarkerTracker::create(camera, {simMarker()}, o));
    o = TrackerOptions{};
    o.smoothing.min_cutoff_hz = -1;
    EXPECT_FALSE(o.validate());
    o = TrackerOptions{};
    o.smoothing.beta = std::nan("");
    EXPECT_FALSE(o.validate());
    o = TrackerOptions{};
    o.reacquire_after_ns = -1;
    EXPECT_FALSE(o.validate());

    EXPECT_FALSE(MarkerTracker::create(camera, {}));
    EXPECT_FALSE(MarkerTracker::create(calibration::CameraModel{}, {simMarker()}));
    EXPECT_FALSE(MarkerTracker::create(camera, {simMarker(), simMarker()}));  // same name

    MarkerTarget t = simMarker();
    EXPECT_TRUE(t.validate());
    EXPECT_EQ(t.points().size(), 4u);
    EXPECT_EQ(t.points()[0].p_target, Vector3d(-0.05, 0.05, 0));
    t.dictionary = "DICT_NOPE";
    EXPECT_FALSE(t.validate());
    EXPECT_TRUE(t.points().empty());
    t = simMarker();
    t.size_m = 0;
    EXPECT_FALSE(t.validate());
    t = simMarker();
    t.name.clear();
    EXPECT_FALSE(t.validate());

    MarkerTarget charuco = synth::tutorialCharucoBoard();
    ASSERT_TRUE(charuco.validate());
    const auto cp = charuco.points();
    ASSERT_EQ(cp.size(), 24u);  // (5-1) x (7-1) inner corners
    EXPECT_EQ(cp[0].marker_id, -1);
    EXPECT_TRUE(cp[0].p_target.isApprox(Vector3d(0.04, 0.04, 0), 1e-6));
    charuco.square_m = 0.01;
    EXPECT_FALSE(charuco.validate());
    charuco.square_m = 0.04;
    charuco.id = 240;  // 17 markers from 240 overrun DICT_6X6_250
    EXPECT_FALSE(charuco.validate());
    charuco.id = 0;
    charuco.dictionary = "apriltag:tag36h11";
    EXPECT_FALSE(charuco.validate());

    MarkerTarget grid;
    grid.name = "grid";
    grid.kind = TargetKind::kGridBoard;
    grid.squares_x = 5;
    grid.squares_y = 7;
    grid.size_m = 0.04;
    grid.separation_m = 0.01;
    grid.id = 100;
    ASSERT_TRUE(grid.validate());
    const auto gp = grid.points();
    ASSERT_EQ(gp.size(), 140u);
    EXPECT_EQ(gp[0].marker_id, 100);
    // OpenCV 4.6's frame: the first marker's top-left corner at the origin, +y down the board.
    EXPECT_TRUE(gp[0].p_target.isApprox(Vector3d(0, 0, 0)));
    EXPECT_TRUE(gp[1].p_target.isApprox(Vector3d(0.04, 0, 0), 1e-6));
    EXPECT_TRUE(gp[3].p_target.isApprox(Vector3d(0, 0.04, 0), 1e-6));
    grid.separation_m = 0;
    EXPECT_FALSE(grid.validate());
}

}  // namespace
}  // namespace mixray::tracking
