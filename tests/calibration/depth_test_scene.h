// Generated depth scenes for the depth tests: planes and boxes ray-cast exactly through
// CameraModel, so depth images and their ground truth in any camera come from one geometry.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/depth_registration.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/image.h"

namespace mixray::calibration::test {

// A scene in a reference frame (the colour camera's): infinite planes n·p = d and boxes.
struct Scene {
    struct Plane {
        Eigen::Vector3d n;  // unit
        double d = 0;
    };
    struct Box {
        Eigen::Isometry3d T_ref_box = Eigen::Isometry3d::Identity();
        Eigen::Vector3d half{0.1, 0.1, 0.1};
    };
    std::vector<Plane> planes;
    std::vector<Box> boxes;

    // Distance along the unit ray (origin o, direction r, reference frame) to the first
    // surface, and which one: planes by index, then each box's six faces
    // (planes.size() + 6 · box + face).
    std::optional<std::pair<double, int>> hit(const Eigen::Vector3d& o,
                                              const Eigen::Vector3d& r) const {
        double best = std::numeric_limits<double>::infinity();
        int id = -1;
        for (size_t i = 0; i < planes.size(); ++i) {
            const double denom = planes[i].n.dot(r);
            if (std::abs(denom) < 1e-12)
                continue;
            const double t = (planes[i].d - planes[i].n.dot(o)) / denom;
            if (t > 1e-6 && t < best) {
                best = t;
                id = static_cast<int>(i);
            }
        }
        for (size_t i = 0; i < boxes.size(); ++i) {
            const Eigen::Isometry3d T_box_ref = boxes[i].T_ref_box.inverse();
            const Eigen::Vector3d ob = T_box_ref * o;
            const Eigen::Vector3d rb = T_box_ref.linear() * r;
            double t0 = -std::numeric_limits<double>::infinity();
            double t1 = std::numeric_limits<double>::infinity();
            int face = 0;
            for (int a = 0; a < 3; ++a) {
                if (std::abs(rb[a]) < 1e-15) {
                    if (std::abs(ob[a]) > boxes[i].half[a])
                        t0 = std::numeric_limits<double>::infinity();
                    continue;
                }
                double ta = (-boxes[i].half[a] - ob[a]) / rb[a];
                double tb = (boxes[i].half[a] - ob[a]) / rb[a];
                int entry = 2 * a;
                if (ta > tb) {
                    std::swap(ta, tb);
                    entry = 2 * a + 1;
                }
                if (ta > t0)
                    face = entry;
                t0 = std::max(t0, ta);
                t1 = std::min(t1, tb);
            }
            if (t0 <= t1 && t0 > 1e-6 && t0 < best) {
                best = t0;
                id = static_cast<int>(planes.size() + 6 * i) + face;
            }
        }
        if (id < 0)
            return std::nullopt;
        return std::make_pair(best, id);
    }
};

// What a camera at T_ref_cam sees: z (camera frame, metres; 0 none) and surface id per pixel.
struct Rendered {
    int width = 0, height = 0;
    std::vector<double> z;
    std::vector<int> id;
    double at(int x, int y) const { return z[static_cast<size_t>(y) * width + x]; }
    int idAt(int x, int y) const { return id[static_cast<size_t>(y) * width + x]; }
};

// The camera's pixel rays (NaN where unproject fails), kept for the last camera asked.
inline const std::vector<Eigen::Vector3d>& pixelRays(const CameraModel& camera) {
    static thread_local CameraModel cached;
    static thread_local std::vector<Eigen::Vector3d> rays;
    const bool same = cached.lens == camera.lens && cached.width == camera.width &&
                      cached.height == camera.height && cached.fx == camera.fx &&
                      cached.fy == camera.fy && cached.cx == camera.cx && cached.cy == camera.cy &&
                      cached.distortion == camera.distortion;
    if (!same || rays.empty()) {
        cached = camera;
        rays.assign(static_cast<size_t>(camera.width) * camera.height,
                    Eigen::Vector3d::Constant(std::nan("")));
        for (int y = 0; y < camera.height; ++y)
            for (int x = 0; x < camera.width; ++x)
                if (const auto dir = camera.unproject({double(x), double(y)}))
                    rays[static_cast<size_t>(y) * camera.width + x] = *dir;
    }
    return rays;
}

inline Rendered render(const Scene& scene, const CameraModel& camera,
                       const Eigen::Isometry3d& T_ref_cam) {
    const std::vector<Eigen::Vector3d>& rays = pixelRays(camera);
    Rendered out;
    out.width = camera.width;
    out.height = camera.height;
    out.z.assign(static_cast<size_t>(camera.width) * camera.height, 0.0);
    out.id.assign(out.z.size(), -1);
    for (int y = 0; y < camera.height; ++y) {
        for (int x = 0; x < camera.width; ++x) {
            const size_t i = static_cast<size_t>(y) * camera.width + x;
            const Eigen::Vector3d& dir = rays[i];
            if (!std::isfinite(dir.x()))
                continue;
            const auto h = scene.hit(T_ref_cam.translation(), T_ref_cam.linear() * dir);
            if (!h)
                continue;
            out.z[i] = h->first * dir.z();
            out.id[i] = h->second;
        }
    }
    return out;
}

// A depth16 image of `rendered` in mm; with `correction`, the raw readings that the correction
// maps back onto the true depth (its inverse, by fixed-point iteration).
inline Image depthImage(const Rendered& rendered, const DepthCorrection* correction = nullptr) {
    Image image(ImageDesc::packed(PixelFormat::kDepth16, rendered.width, rendered.height));
    const MutableImageView view = image.mutableView();
    for (int y = 0; y < rendered.height; ++y) {
        uint16_t* row = view.row<uint16_t>(y);
        for (int x = 0; x < rendered.width; ++x) {
            const double z_true = rendered.at(x, y);
            double raw = z_true;
            if (correction && z_true > 0) {
                for (int k = 0; k < 50; ++k) {
                    const double f = correctedDepth(*correction, raw, x, y, rendered.width);
                    raw += (z_true - f) / correction->scale;
                    if (std::abs(z_true - f) < 1e-9)
                        break;
                }
            }
            row[x] = z_true > 0 ? static_cast<uint16_t>(std::lround(raw * 1e3)) : 0;
        }
    }
    return image;
}

// The depth tests' board: a chessboard of 9x6 inner corners, 60 mm squares, so the corners'
// outline is 0.48 m x 0.30 m.
inline CalibrationTarget depthBoard() {
    CalibrationTarget board;
    board.kind = TargetKind::kChessboard;
    board.cols = 9;
    board.rows = 6;
    board.square_m = 0.06;
    return board;
}

inline std::vector<Eigen::Vector3d> boardPoints() {
    return depthBoard().points();
}

}  // namespace mixray::calibration::test
