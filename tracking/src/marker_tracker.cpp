// The camera tracker: every target seen votes for T_world_camera in one reprojection fit;
// One-Euro smoothing; searching, tracking and lost with the last good pose kept.
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>

#include "marker_internal.h"

namespace mixray::tracking {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

std::string describe(const MarkerTarget& t) {
    if (t.kind == TargetKind::kMarker)
        return "marker " + std::to_string(t.id);
    return std::string(t.kind == TargetKind::kCharucoBoard ? "ChArUco board '" : "grid board '") +
           t.name + "'";
}

std::string format1(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f", v);
    return buf;
}

class MarkerTrackerImpl final : public MarkerTracker {
public:
    MarkerTrackerImpl(const calibration::CameraModel& camera, std::vector<MarkerTarget> targets,
                      const TrackerOptions& options)
        : camera_(camera),
          targets_(std::move(targets)),
          options_(options),
          filter_(options.smoothing) {
        std::set<std::string> seen;
        for (const MarkerTarget& t : targets_)
            if (seen.insert(t.dictionary).second)
                dictionaries_.push_back(t.dictionary);
    }

    const std::vector<MarkerTarget>& targets() const override { return targets_; }

    void reset() override {
        state_ = TrackState::kSearching;
        pose_ = {};
        filter_.reset();
    }

    Result<CameraTrack> track(const ImageView& image, int64_t stamp_ns) override {
        if (image.desc.width != camera_.width || image.desc.height != camera_.height)
            return Status(ErrorCode::kInvalidArgument,
                          "image is " + std::to_string(image.desc.width) + "x" +
                              std::to_string(image.desc.height) + ", the camera model " +
                              std::to_string(camera_.width) + "x" + std::to_string(camera_.height));
        CameraTrack out;
        for (const std::string& dict : dictionaries_) {
            auto found = calibration::detectMarkers(image, dict, options_.detector, &camera_);
            if (!found)
                return found.status();
            for (MarkerDetection& d : *found)
                out.detections.push_back(std::move(d));
        }

        // Each target alone first: its own pose (reported, and the joint fit's start) and a
        // check that it fits; a target fitting badly (a misdetection, a bent print) is left out.
        std::vector<std::string> problems;
        std::vector<Vector3d> world_points;
        std::vector<Vector2d> pixels;
        std::optional<Isometry3d> start;
        int start_points = 0;
        for (const MarkerTarget& t : targets_) {
            const detail::Correspondences c = detail::correspond(t, out.detections, image);
            if (c.points.size() < 4) {
                problems.push_back(describe(t) + " not seen");
                continue;
            }
            const auto fit =
                detail::planarPose(camera_, c.points, c.pixels, t.kind == TargetKind::kMarker);
            if (!fit || fit->rms_px > options_.max_rms_px) {
                problems.push_back(describe(t) + " fits badly (" +
                                   (fit ? "rms " + format1(fit->rms_px) + " px" : "no pose") + ")");
                continue;
            }
            TargetObservation obs;
            obs.target = t.name;
            obs.T_camera_target = fit->T_camera_points;
            obs.points = static_cast<int>(c.points.size());
            obs.rms_px = fit->rms_px;
            out.targets.push_back(obs);
            for (size_t i = 0; i < c.points.size(); ++i) {
                world_points.push_back(t.T_world_target * c.points[i]);
                pixels.push_back(c.pixels[i]);
            }
            if (obs.points > start_points) {
                start_points = obs.points;
                start = fit->T_camera_points * t.T_world_target.inverse();
            }
        }

        std::optional<detail::PoseFit> joint;
        if (start) {
            joint = detail::refinePose(camera_, world_points, pixels, *start);
            if (joint && joint->rms_px > options_.max_rms_px) {
                problems.push_back("the targets disagree about the camera (rms " +
                                   format1(joint->rms_px) + " px): has one moved?");
                joint.reset();
            }
        }

        if (joint) {
            const Isometry3d raw = joint->T_camera_points.inverse();
            const bool was_lost = state_ == TrackState::kLost;
            // A long gap restarts the smoothing: sliding from a pose that old would lag.
            if (!pose_.value || stamp_ns - pose_.good_stamp_ns > options_.reacquire_after_ns)
                filter_.reset();
            out.raw_T_world_camera = raw;
            pose_.update(filter_.filter(raw, stamp_ns), stamp_ns);
            state_ = TrackState::kTracking;
            out.reacquired = was_lost;
        } else {
            std::string why;
            for (const std::string& p : problems)
                why += (why.empty() ? "" : "; ") + p;
            pose_.keep(why.empty() ? "no target seen" : why, stamp_ns);
            if (state_ == TrackState::kTracking)
                state_ = TrackState::kLost;
        }
        out.state = state_;
        out.pose = pose_;
        return out;
    }

private:
    calibration::CameraModel camera_;
    std::vector<MarkerTarget> targets_;
    TrackerOptions options_;
    std::vector<std::string> dictionaries_;
    PoseFilter filter_;
    TrackState state_ = TrackState::kSearching;
    Estimate<Isometry3d> pose_;
};

}  // namespace

Status TrackerOptions::validate() const {
    MIXRAY_RETURN_IF_ERROR(detector.validate());
    MIXRAY_RETURN_IF_ERROR(smoothing.validate());
    if (!std::isfinite(max_rms_px) || max_rms_px <= 0)
        return {ErrorCode::kInvalidArgument,
                "tracker.max_rms_px must be > 0, got " + std::to_string(max_rms_px)};
    if (reacquire_after_ns < 0)
        return {ErrorCode::kInvalidArgument, "tracker.reacquire_after_ns must be >= 0"};
    return Status::ok();
}

std::string_view toString(TrackState state) {
    switch (state) {
        case TrackState::kSearching:
            return "searching";
        case TrackState::kTracking:
            return "tracking";
        case TrackState::kLost:
            return "lost";
    }
    return "unknown";
}

Result<std::unique_ptr<MarkerTracker>> MarkerTracker::create(const calibration::CameraModel& camera,
                                                             std::vector<MarkerTarget> targets,
                                                             const TrackerOptions& options) {
    MIXRAY_RETURN_IF_ERROR(camera.validate().withContext("marker tracker camera"));
    MIXRAY_RETURN_IF_ERROR(options.validate());
    if (targets.empty())
        return Status(ErrorCode::kInvalidArgument, "marker tracker: no targets to track");
    std::set<std::string> names;
    for (const MarkerTarget& t : targets) {
        MIXRAY_RETURN_IF_ERROR(t.validate());
        if (!names.insert(t.name).second)
            return Status(ErrorCode::kInvalidArgument,
                          "marker tracker: two targets are named '" + t.name + "'");
    }
    return std::unique_ptr<MarkerTracker>(
        new MarkerTrackerImpl(camera, std::move(targets), options));
}

}  // namespace mixray::tracking
