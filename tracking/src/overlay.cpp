// Tracking overlays as shapes (mixray/tracking/overlay.h).
#include "mixray/tracking/overlay.h"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>

namespace mixray::tracking {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr OverlayColour kRed{230, 40, 40}, kGreen{40, 220, 60}, kBlue{60, 110, 255};
constexpr OverlayColour kYellow{250, 220, 40}, kOrange{255, 150, 30}, kCyan{40, 220, 230};
constexpr OverlayColour kGrey{150, 150, 150};

std::optional<Vector2d> project(const calibration::CameraModel& camera,
                                const Isometry3d& T_camera_world, const Vector3d& p_world) {
    const auto px = camera.project(T_camera_world * p_world);
    if (!px || !px->allFinite() || std::abs(px->x()) > 1e5 || std::abs(px->y()) > 1e5)
        return std::nullopt;
    return *px;
}

void addLine(TrackingOverlay& o, const std::optional<Vector2d>& a, const std::optional<Vector2d>& b,
             const OverlayColour& colour, int width, bool arrow = false) {
    if (a && b)
        o.lines.push_back({*a, *b, colour, width, arrow});
}

std::string css(const OverlayColour& c) {
    char text[8];
    std::snprintf(text, sizeof text, "#%02x%02x%02x", c[0], c[1], c[2]);
    return text;
}

nlohmann::json point(const Vector2d& p) {
    return nlohmann::json::array({p.x(), p.y()});
}

}  // namespace

TrackingOverlay trackingOverlay(const TrackedFrame& frame, const TrackingSetup& setup) {
    TrackingOverlay o;
    for (const MarkerDetection& d : frame.track.detections)
        o.polygons.push_back({{d.corners.begin(), d.corners.end()}, kGreen, std::to_string(d.id)});

    const calibration::CameraModel& camera = setup.camera.model;
    const auto& pose = frame.track.pose;
    if (pose.value) {
        const Isometry3d T_camera_world = pose.value->inverse();
        for (const TargetObservation& t : frame.track.targets) {
            const Isometry3d T_camera_target = t.T_camera_target;
            double length = 0.05;
            for (const MarkerTarget& m : setup.targets)
                if (m.name == t.target)
                    length = m.kind == TargetKind::kMarker ? m.size_m : 2 * m.square_m + m.size_m;
            const auto axis = [&](const Vector3d& v) {
                return project(camera, T_camera_target, v);
            };
            const auto origin = axis(Vector3d::Zero());
            addLine(o, origin, axis(Vector3d(length, 0, 0)), kRed, 2);
            addLine(o, origin, axis(Vector3d(0, length, 0)), kGreen, 2);
            addLine(o, origin, axis(Vector3d(0, 0, length)), kBlue, 2);
        }
        for (size_t i = 0; i < frame.probes.size() && i < setup.probes.size(); ++i) {
            const auto& estimate = frame.probes[i];
            const LightProbe& probe = setup.probes[i];
            if (!estimate.value)
                continue;
            const auto& outline = estimate.value->outline;
            o.circles.push_back(
                {outline.centre_px, outline.radius_px, estimate.stale ? kGrey : kYellow});
            for (const EstimatedLight& l : estimate.value->lights)
                addLine(o, project(camera, T_camera_world, probe.centre_world),
                        project(camera, T_camera_world,
                                probe.centre_world + 2.5 * probe.radius_m * l.to_light_world),
                        kOrange, 2, true);
        }
        if (frame.sun.value && !frame.sun.stale)
            addLine(o, project(camera, T_camera_world, Vector3d::Zero()),
                    project(camera, T_camera_world, 0.15 * frame.sun.value->to_light_world),
                    kYellow, 3, true);
        if (frame.environment.value)
            for (const EstimatedLight& l : frame.environment.value->lights)
                addLine(o, project(camera, T_camera_world, Vector3d::Zero()),
                        project(camera, T_camera_world, 0.15 * l.to_light_world), kCyan, 2, true);
    }

    std::string state(toString(frame.track.state));
    OverlayColour colour = kGreen;
    if (frame.track.state != TrackState::kTracking) {
        colour = kRed;
        if (pose.value)
            state += " (stale pose)";
        if (!pose.reason.empty())
            state += ": " + pose.reason;
    } else if (frame.track.reacquired) {
        state += " (re-acquired)";
    }
    o.texts.push_back(
        {Vector2d(8, 18), "frame " + std::to_string(frame.index) + "  " + state, colour});
    double y = 36;
    const auto stale = [&](const std::string& what, bool is_stale, const std::string& reason) {
        if (is_stale && !reason.empty()) {
            o.texts.push_back({Vector2d(8, y), what + ": " + reason, kRed});
            y += 18;
        }
    };
    stale("environment", frame.environment.stale, frame.environment.reason);
    stale("sun", frame.sun.stale, frame.sun.reason);
    for (const auto& probe : frame.probes)
        stale("probe", probe.stale, probe.reason);
    return o;
}

std::string TrackingOverlay::json() const {
    using nlohmann::json;
    json j;
    json polys = json::array();
    for (const auto& p : polygons) {
        json points = json::array();
        for (const auto& q : p.points)
            points.push_back(point(q));
        polys.push_back({{"points", points}, {"color", css(p.colour)}, {"label", p.label}});
    }
    json circ = json::array();
    for (const auto& c : circles)
        circ.push_back(
            {{"centre", point(c.centre)}, {"radius", c.radius}, {"color", css(c.colour)}});
    json ls = json::array();
    for (const auto& l : lines)
        ls.push_back({{"from", point(l.from)}, {"to", point(l.to)}, {"color", css(l.colour)}});
    json ts = json::array();
    for (const auto& t : texts)
        ts.push_back({{"at", point(t.at)}, {"text", t.text}, {"color", css(t.colour)}});
    j["polygons"] = polys;
    j["circles"] = circ;
    j["lines"] = ls;
    j["texts"] = ts;
    return j.dump();
}

}  // namespace mixray::tracking
