// What tracking found, as shapes in the colour image: marker outlines and ids, axes on each
// tracked target, probe outlines with the directions of their lights, the sun's and the
// fish-eye's lights from the world origin, the tracker's state and why estimates are stale.
// One description, drawn into pictures (mixray track's overlay video) and sent to the live view.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "mixray/tracking/pipeline.h"

namespace mixray::tracking {

using OverlayColour = std::array<uint8_t, 3>;  // sRGB

struct OverlayPolygon {
    std::vector<Eigen::Vector2d> points;  // closed
    OverlayColour colour;
    std::string label;  // drawn beside the first point
};
struct OverlayCircle {
    Eigen::Vector2d centre;
    double radius = 0;
    OverlayColour colour;
};
struct OverlayLine {
    Eigen::Vector2d from, to;
    OverlayColour colour;
    int width = 1;
    bool arrow = false;
};
struct OverlayText {
    Eigen::Vector2d at;  // baseline start
    std::string text;
    OverlayColour colour;
};

// Shapes in the colour image's pixel coordinates. Plain value.
struct TrackingOverlay {
    std::vector<OverlayPolygon> polygons;
    std::vector<OverlayCircle> circles;
    std::vector<OverlayLine> lines;
    std::vector<OverlayText> texts;

    // The live view's overlay JSON (docs/live-view.md): polygons, circles, lines, texts.
    std::string json() const;
};

TrackingOverlay trackingOverlay(const TrackedFrame& frame, const TrackingSetup& setup);

}  // namespace mixray::tracking
