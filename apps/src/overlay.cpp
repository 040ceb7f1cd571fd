// Tracking overlays (overlay.h), drawn with OpenCV.
#include "overlay.h"

#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>

namespace mixray::cli {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;

const cv::Scalar kRed(230, 40, 40), kGreen(40, 220, 60), kBlue(60, 110, 255);
const cv::Scalar kYellow(250, 220, 40), kOrange(255, 150, 30), kCyan(40, 220, 230);

std::optional<cv::Point2d> project(const calibration::CameraModel& camera,
                                   const Isometry3d& T_camera_world, const Vector3d& p_world) {
    const auto px = camera.project(T_camera_world * p_world);
    if (!px || !px->allFinite() || std::abs(px->x()) > 1e5 || std::abs(px->y()) > 1e5)
        return std::nullopt;
    return cv::Point2d(px->x(), px->y());
}

void line(cv::Mat& m, const std::optional<cv::Point2d>& a, const std::optional<cv::Point2d>& b,
          const cv::Scalar& colour, int thickness, bool arrow = false) {
    if (!a || !b)
        return;
    if (arrow)
        cv::arrowedLine(m, *a, *b, colour, thickness, cv::LINE_AA, 0, 0.2);
    else
        cv::line(m, *a, *b, colour, thickness, cv::LINE_AA);
}

void text(cv::Mat& m, const std::string& s, cv::Point at, const cv::Scalar& colour) {
    cv::putText(m, s, at, cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(m, s, at, cv::FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv::LINE_AA);
}

}  // namespace

Image drawTrackingOverlay(const tracking::TrackedFrame& frame,
                          const tracking::TrackingSetup& setup) {
    const ImageView in = frame.color.image();
    Image out(ImageDesc::packed(PixelFormat::kRGB8, in.desc.width, in.desc.height));
    cv::Mat m(in.desc.height, in.desc.width, CV_8UC3, out.mutableView().data,
              static_cast<size_t>(out.view().desc.stride_bytes));
    const cv::Mat src(in.desc.height, in.desc.width, CV_8UC3, const_cast<uint8_t*>(in.data),
                      static_cast<size_t>(in.desc.stride_bytes));
    if (in.desc.format == PixelFormat::kBGR8)
        cv::cvtColor(src, m, cv::COLOR_BGR2RGB);
    else
        src.copyTo(m);

    for (const tracking::MarkerDetection& d : frame.track.detections) {
        std::vector<cv::Point> poly;
        for (const Eigen::Vector2d& c : d.corners)
            poly.emplace_back(static_cast<int>(std::lround(c.x())),
                              static_cast<int>(std::lround(c.y())));
        cv::polylines(m, poly, true, kGreen, 1, cv::LINE_AA);
        text(m, std::to_string(d.id), poly[0] + cv::Point(2, -4), kGreen);
    }

    const calibration::CameraModel& camera = setup.camera.model;
    const auto& pose = frame.track.pose;
    if (pose.value) {
        const Isometry3d T_camera_world = pose.value->inverse();
        for (const tracking::TargetObservation& o : frame.track.targets) {
            const Isometry3d T_camera_target = o.T_camera_target;
            const auto origin = camera.project(T_camera_target.translation());
            double length = 0.05;
            for (const tracking::MarkerTarget& t : setup.targets)
                if (t.name == o.target)
                    length = t.kind == tracking::TargetKind::kMarker ? t.size_m
                                                                     : 2 * t.square_m + t.size_m;
            const auto axis = [&](const Vector3d& v) -> std::optional<cv::Point2d> {
                const auto px = camera.project(T_camera_target * v);
                if (!px)
                    return std::nullopt;
                return cv::Point2d(px->x(), px->y());
            };
            if (origin) {
                const cv::Point2d o2(origin->x(), origin->y());
                line(m, o2, axis(Vector3d(length, 0, 0)), kRed, 2);
                line(m, o2, axis(Vector3d(0, length, 0)), kGreen, 2);
                line(m, o2, axis(Vector3d(0, 0, length)), kBlue, 2);
            }
        }
        for (size_t i = 0; i < frame.probes.size() && i < setup.probes.size(); ++i) {
            const auto& estimate = frame.probes[i];
            const tracking::LightProbe& probe = setup.probes[i];
            const cv::Scalar colour = estimate.stale ? cv::Scalar(150, 150, 150) : kYellow;
            if (estimate.value) {
                const auto& outline = estimate.value->outline;
                cv::circle(m, cv::Point2d(outline.centre_px.x(), outline.centre_px.y()),
                           static_cast<int>(std::lround(outline.radius_px)), colour, 1,
                           cv::LINE_AA);
                for (const tracking::EstimatedLight& l : estimate.value->lights)
                    line(m, project(camera, T_camera_world, probe.centre_world),
                         project(camera, T_camera_world,
                                 probe.centre_world + 2.5 * probe.radius_m * l.to_light_world),
                         kOrange, 2, true);
            }
        }
        if (frame.sun.value && !frame.sun.stale)
            line(m, project(camera, T_camera_world, Vector3d::Zero()),
                 project(camera, T_camera_world, 0.15 * frame.sun.value->to_light_world), kYellow,
                 3, true);
        if (frame.environment.value) {
            const Vector3d origin = Vector3d::Zero();
            for (const tracking::EstimatedLight& l : frame.environment.value->lights)
                line(m, project(camera, T_camera_world, origin),
                     project(camera, T_camera_world, origin + 0.15 * l.to_light_world), kCyan, 2,
                     true);
        }
    }

    std::string state(tracking::toString(frame.track.state));
    cv::Scalar colour = kGreen;
    if (frame.track.state != tracking::TrackState::kTracking) {
        colour = kRed;
        if (pose.value)
            state += " (stale pose)";
        if (!pose.reason.empty())
            state += ": " + pose.reason;
    } else if (frame.track.reacquired) {
        state += " (re-acquired)";
    }
    char head[64];
    std::snprintf(head, sizeof head, "frame %llu  ", static_cast<unsigned long long>(frame.index));
    text(m, head + state, cv::Point(8, 18), colour);
    int y = 36;
    if (frame.environment.stale && !frame.environment.reason.empty()) {
        text(m, "environment: " + frame.environment.reason, cv::Point(8, y), kRed);
        y += 18;
    }
    if (frame.sun.stale && !frame.sun.reason.empty()) {
        text(m, "sun: " + frame.sun.reason, cv::Point(8, y), kRed);
        y += 18;
    }
    for (size_t i = 0; i < frame.probes.size(); ++i) {
        if (frame.probes[i].stale && !frame.probes[i].reason.empty()) {
            text(m, "probe: " + frame.probes[i].reason, cv::Point(8, y), kRed);
            y += 18;
        }
    }
    return out;
}

}  // namespace mixray::cli
