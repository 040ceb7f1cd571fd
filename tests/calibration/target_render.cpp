// Antialiased ray-cast renders of calibration targets (target_render.h).
#include "target_render.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <opencv2/aruco/charuco.hpp>
#include <optional>
#include <random>
#include <vector>

#include "mixray/calibration/marker_detection.h"

namespace mixray::calibration::synth {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

double srgbEncode(double linear) {
    const double c = std::clamp(linear, 0.0, 1.0);
    return 255 * (c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055);
}

// Reflectance of the print at board point (x, y); -1 off the print.
class Print {
public:
    explicit Print(const CalibrationTarget& t) : t_(t) {
        if (t.kind == TargetKind::kCharuco) {
            auto dict = cv::aruco::getPredefinedDictionary(
                static_cast<cv::aruco::PREDEFINED_DICTIONARY_NAME>(
                    *openCvDictionaryId(t.dictionary)));
            auto board =
                cv::aruco::CharucoBoard::create(t.cols, t.rows, static_cast<float>(t.square_m),
                                                static_cast<float>(t.marker_m), dict);
            board->draw(cv::Size(t.cols * kTexels, t.rows * kTexels), charuco_, 0, 1);
        }
        if (t.kind == TargetKind::kAprilGrid) {
            std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)> tf(tag36h11_create(),
                                                                                tag36h11_destroy);
            for (int id = 0; id < t.cols * t.rows; ++id) {
                image_u8_t* im = apriltag_to_image(tf.get(), id);
                cv::Mat m(im->height, im->width, CV_8U);
                for (int y = 0; y < im->height; ++y)
                    for (int x = 0; x < im->width; ++x)
                        m.at<uint8_t>(y, x) = im->buf[y * im->stride + x];
                // libapriltag does not export image_u8_destroy; its images are two callocs.
                std::free(im->buf);
                std::free(im);
                tags_.push_back(m);
            }
        }
    }

    double at(double x, double y) const {
        const double s = t_.square_m;
        switch (t_.kind) {
            case TargetKind::kChessboard: {
                // Squares i = 0..cols span x in [(i − 1) s, i s); a white margin of one square.
                const int i = static_cast<int>(std::floor(x / s)) + 1;
                const int j = static_cast<int>(std::floor(y / s)) + 1;
                if (i < -1 || j < -1 || i > t_.cols + 1 || j > t_.rows + 1)
                    return -1;
                if (i < 0 || j < 0 || i > t_.cols || j > t_.rows)
                    return 1;
                return (i + j) % 2 == 0 ? 0.02 : 0.9;
            }
            case TargetKind::kCharuco: {
                if (x < -s || y < -s || x > (t_.cols + 1) * s || y > (t_.rows + 1) * s)
                    return -1;
                const int u = static_cast<int>(std::floor(x / s * kTexels));
                const int v = static_cast<int>(std::floor(y / s * kTexels));
                if (u < 0 || v < 0 || u >= charuco_.cols || v >= charuco_.rows)
                    return 1;
                return charuco_.at<uint8_t>(v, u) > 127 ? 0.9 : 0.02;
            }
            case TargetKind::kAprilGrid: {
                const double pitch = (1 + t_.tag_spacing) * s, gap = t_.tag_spacing * s;
                if (x < -pitch || y < -pitch || x > t_.cols * pitch + s || y > t_.rows * pitch + s)
                    return -1;
                const int tc = static_cast<int>(std::floor(x / pitch));
                const int tr = static_cast<int>(std::floor(y / pitch));
                const double lx = x - tc * pitch, ly = y - tr * pitch;
                const bool in_x = lx < s, in_y = ly < s;
                if (!in_x && !in_y && tc >= -1 && tr >= -1 && tc < t_.cols && tr < t_.rows &&
                    lx < s + gap && ly < s + gap)
                    return 0.02;  // Kalibr's black squares where the gaps cross
                if (!(in_x && in_y) || tc < 0 || tr < 0 || tc >= t_.cols || tr >= t_.rows)
                    return 0.9;
                const cv::Mat& tag = tags_[static_cast<size_t>(tr * t_.cols + tc)];
                // Kalibr's two-cell border: libapriltag's 10-cell image with its white ring
                // black. +y up the print is up the tag image.
                const int cells = tag.cols;
                const int col =
                    std::clamp(static_cast<int>(std::floor(lx / s * cells)), 0, cells - 1);
                const int row =
                    cells - 1 -
                    std::clamp(static_cast<int>(std::floor(ly / s * cells)), 0, cells - 1);
                if (row == 0 || col == 0 || row == cells - 1 || col == cells - 1)
                    return 0.02;
                return tag.at<uint8_t>(row, col) > 127 ? 0.9 : 0.02;
            }
        }
        return -1;
    }

private:
    static constexpr int kTexels = 200;  // per ChArUco square
    CalibrationTarget t_;
    cv::Mat charuco_;
    std::vector<cv::Mat> tags_;
};

}  // namespace

Image renderTarget(const CameraModel& camera, const CalibrationTarget& target,
                   const Isometry3d& T_camera_board, int samples, double noise) {
    const Print print(target);
    const Isometry3d T_board_camera = T_camera_board.inverse();
    const Vector3d o = T_board_camera.translation();
    std::mt19937 rng(7);
    std::normal_distribution<double> gauss(0, noise);
    // The print's reflectance along the ray `d` from the camera's centre (board frame).
    const auto trace = [&](const Vector3d& d) {
        const double t = std::abs(d.z()) > 1e-12 ? -o.z() / d.z() : -1;
        if (t > 0) {
            const Vector3d p = o + t * d;
            const double r = print.at(p.x(), p.y());
            if (r >= 0)
                return r;
        }
        return 0.5;
    };
    // Rays are unprojected at pixel corners and interpolated bilinearly inside each pixel: the
    // lens bends a ray by far less than a thousandth of a pixel across one, and the exact
    // unprojection per subsample was most of the time of the calibration tests (16 per pixel,
    // iterative, and 10x slower under the sanitizers). A pixel with a corner the model cannot
    // unproject (a fish-eye's rim) takes the exact rays.
    const auto cornerRays = [&](int y, std::vector<std::optional<Vector3d>>& out) {
        out.resize(static_cast<size_t>(camera.width) + 1);
        for (int x = 0; x <= camera.width; ++x) {
            out[static_cast<size_t>(x)] = camera.unproject(Vector2d(x - 0.5, y - 0.5));
            if (out[static_cast<size_t>(x)])
                *out[static_cast<size_t>(x)] =
                    T_board_camera.linear() * *out[static_cast<size_t>(x)];
        }
    };
    std::vector<std::optional<Vector3d>> above, below;
    cornerRays(0, above);
    Image img(ImageDesc::packed(PixelFormat::kMono8, camera.width, camera.height));
    for (int y = 0; y < camera.height; ++y) {
        cornerRays(y + 1, below);
        uint8_t* row = img.mutableView().row<uint8_t>(y);
        for (int x = 0; x < camera.width; ++x) {
            const auto& c00 = above[static_cast<size_t>(x)];
            const auto& c10 = above[static_cast<size_t>(x) + 1];
            const auto& c01 = below[static_cast<size_t>(x)];
            const auto& c11 = below[static_cast<size_t>(x) + 1];
            const bool interpolate = c00 && c10 && c01 && c11;
            double acc = 0;
            for (int j = 0; j < samples; ++j)
                for (int i = 0; i < samples; ++i) {
                    const double u = (i + 0.5) / samples;
                    const double v = (j + 0.5) / samples;
                    if (interpolate) {
                        acc += trace((1 - v) * ((1 - u) * *c00 + u * *c10) +
                                     v * ((1 - u) * *c01 + u * *c11));
                    } else if (const auto ray =
                                   camera.unproject(Vector2d(x - 0.5 + u, y - 0.5 + v))) {
                        acc += trace(T_board_camera.linear() * *ray);
                    } else {
                        acc += 0.5;
                    }
                }
            const double value =
                srgbEncode(acc / (samples * samples)) + (noise > 0 ? gauss(rng) : 0);
            row[x] = static_cast<uint8_t>(std::clamp(std::lround(value), 0L, 255L));
        }
        std::swap(above, below);
    }
    return img;
}

std::vector<Vector2d> projectPoints(const CameraModel& camera, const CalibrationTarget& target,
                                    const Isometry3d& T_camera_board) {
    std::vector<Vector2d> out;
    for (const Vector3d& p : target.points()) {
        const auto px = camera.project(T_camera_board * p);
        out.push_back(px ? *px : Vector2d(-1e9, -1e9));
    }
    return out;
}

Isometry3d boardPose(const CalibrationTarget& target, double distance_m, double tilt_deg,
                     double yaw_deg) {
    Vector3d centre = Vector3d::Zero();
    const auto pts = target.points();
    for (const Vector3d& p : pts)
        centre += p;
    centre /= static_cast<double>(pts.size());
    Isometry3d T = Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(tilt_deg * M_PI / 180, Vector3d::UnitX()) *
                  Eigen::AngleAxisd(yaw_deg * M_PI / 180, Vector3d::UnitY()))
                     .toRotationMatrix();
    // Kalibr's frame has +z out of the print and +y up it: turned half round x, the camera
    // sees the print's front, upright.
    if (target.kind == TargetKind::kAprilGrid)
        T.linear() = T.linear() * Eigen::Vector3d(1, -1, -1).asDiagonal();
    T.translation() = Vector3d(0, 0, distance_m) - T.linear() * centre;
    return T;
}

CameraModel testCamera() {
    CameraModel m = CameraModel::pinhole(640, 480, 600, 600, 319.5, 239.5);
    m.distortion = {-0.08, 0.05, 0.0005, -0.0003, 0};
    return m;
}

}  // namespace mixray::calibration::synth
