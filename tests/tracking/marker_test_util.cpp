// Antialiased ray-cast renders of printed markers for the marker tests.
#include "marker_test_util.h"

#include <algorithm>
#include <cmath>
#include <opencv2/aruco.hpp>

namespace mixray::tracking::synth {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

cv::Ptr<cv::aruco::Dictionary> dictionaryFor(const std::string& name) {
    if (name == "DICT_APRILTAG_36h11" || name == "apriltag:tag36h11")
        return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
    if (name == "DICT_4X4_50")
        return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50);
    return cv::aruco::getPredefinedDictionary(cv::aruco::DICT_6X6_250);
}

double srgbEncode(double linear) {
    const double c = std::clamp(linear, 0.0, 1.0);
    return 255 * (c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1 / 2.4) - 0.055);
}

}  // namespace

PrintedPlane printed(const PrintedMarker& m) {
    const auto dict = dictionaryFor(m.dictionary);
    const int cells = dict->markerSize + 2;
    cv::Mat marker;
    cv::aruco::drawMarker(dict, m.id, cells, marker, 1);
    PrintedPlane p;
    // Two cells of quiet zone: with one, OpenCV takes the white frame's outline for a candidate
    // too close to the marker's and drops the marker.
    p.grey = cv::Mat(cells + 4, cells + 4, CV_8U, cv::Scalar(255));
    marker.copyTo(p.grey(cv::Rect(2, 2, cells, cells)));
    p.width_m = p.height_m = m.size_m * (cells + 4) / cells;
    p.T_world_plane = m.T_world_marker;
    return p;
}

Image renderPlanes(const calibration::CameraModel& camera, const Isometry3d& T_world_camera,
                   const std::vector<PrintedPlane>& planes, int samples) {
    std::vector<Isometry3d> T_plane_camera;
    for (const PrintedPlane& p : planes)
        T_plane_camera.push_back(p.T_world_plane.inverse() * T_world_camera);
    Image img(ImageDesc::packed(PixelFormat::kRGB8, camera.width, camera.height));
    for (int y = 0; y < camera.height; ++y) {
        uint8_t* row = img.mutableView().row<uint8_t>(y);
        for (int x = 0; x < camera.width; ++x) {
            double acc = 0;
            for (int j = 0; j < samples; ++j)
                for (int i = 0; i < samples; ++i) {
                    const Vector2d px(x - 0.5 + (i + 0.5) / samples, y - 0.5 + (j + 0.5) / samples);
                    double value = 0.6;  // a light table: no dark frame round the quiet zone
                    double nearest = 1e30;
                    const auto ray = camera.unproject(px);
                    for (size_t k = 0; ray && k < planes.size(); ++k) {
                        const Vector3d o = T_plane_camera[k].translation();
                        const Vector3d d = T_plane_camera[k].linear() * *ray;
                        if (std::abs(d.z()) < 1e-12)
                            continue;
                        const double t = -o.z() / d.z();
                        if (t <= 0 || t >= nearest)
                            continue;
                        const Vector3d p = o + t * d;
                        const PrintedPlane& pl = planes[k];
                        const double u = (p.x() / pl.width_m + 0.5) * pl.grey.cols;
                        const double v = (0.5 - p.y() / pl.height_m) * pl.grey.rows;
                        if (u < 0 || v < 0 || u >= pl.grey.cols || v >= pl.grey.rows)
                            continue;
                        nearest = t;
                        value =
                            pl.grey.at<uint8_t>(static_cast<int>(v), static_cast<int>(u)) / 255.0;
                    }
                    acc += value;
                }
            const auto s = static_cast<uint8_t>(std::lround(srgbEncode(acc / (samples * samples))));
            row[3 * x] = row[3 * x + 1] = row[3 * x + 2] = s;
        }
    }
    return img;
}

Image renderMarkers(const calibration::CameraModel& camera, const Isometry3d& T_world_camera,
                    const std::vector<PrintedMarker>& markers, int samples) {
    std::vector<PrintedPlane> planes;
    for (const PrintedMarker& m : markers)
        planes.push_back(printed(m));
    return renderPlanes(camera, T_world_camera, planes, samples);
}

std::vector<Vector2d> projectCorners(const calibration::CameraModel& camera,
                                     const Isometry3d& T_world_camera, const PrintedMarker& m) {
    const double h = 0.5 * m.size_m;
    std::vector<Vector2d> out;
    for (const Vector3d& c :
         {Vector3d(-h, h, 0), Vector3d(h, h, 0), Vector3d(h, -h, 0), Vector3d(-h, -h, 0)}) {
        const auto px = camera.project(T_world_camera.inverse() * m.T_world_marker * c);
        out.push_back(px ? *px : Vector2d(-1e9, -1e9));
    }
    return out;
}

Isometry3d lookAt(const Vector3d& eye, const Vector3d& target) {
    const Vector3d z = (target - eye).normalized();
    Vector3d x = z.cross(Vector3d::UnitZ());
    if (x.norm() < 1e-6)
        x = Vector3d::UnitX();
    x.normalize();
    const Vector3d y = z.cross(x);
    Isometry3d T = Isometry3d::Identity();
    T.linear().col(0) = x;
    T.linear().col(1) = y;
    T.linear().col(2) = z;
    T.translation() = eye;
    return T;
}

double angleDeg(const Isometry3d& a, const Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180 / M_PI;
}

MarkerTarget tutorialCharucoBoard() {
    MarkerTarget board;
    board.name = "charuco";
    board.kind = TargetKind::kCharucoBoard;
    board.squares_x = 5;
    board.squares_y = 7;
    board.square_m = 0.04;
    board.size_m = 0.02;
    return board;
}

}  // namespace mixray::tracking::synth
