// Generated calibration views for the Ceres solver tests.
#include "ceres_synthetic.h"

#include <cmath>
#include <numbers>

namespace mixray::calibration::test {

namespace {

constexpr double kDeg = std::numbers::pi / 180;

Eigen::Vector3d centre(const CalibrationTarget& target) {
    return Eigen::Vector3d((target.cols - 1) * target.square_m / 2,
                           (target.rows - 1) * target.square_m / 2, 0);
}

}  // namespace

CalibrationTarget chessboard(int cols, int rows, double square_m) {
    CalibrationTarget target;
    target.kind = TargetKind::kChessboard;
    target.cols = cols;
    target.rows = rows;
    target.square_m = square_m;
    return target;
}

double visibleFraction(const CameraModel& model, const CalibrationTarget& target,
                       const Eigen::Isometry3d& T_camera_target) {
    const std::vector<Eigen::Vector3d> points = target.points();
    int inside = 0;
    for (const Eigen::Vector3d& p : points) {
        const auto pixel = model.project(T_camera_target * p);
        if (pixel && pixel->x() >= 0 && pixel->y() >= 0 && pixel->x() <= model.width - 1 &&
            pixel->y() <= model.height - 1)
            ++inside;
    }
    return static_cast<double>(inside) / static_cast<double>(points.size());
}

Eigen::Isometry3d randomBoardPose(const CameraModel& model, const CalibrationTarget& target,
                                  std::mt19937& rng) {
    std::uniform_real_distribution<double> uniform(0, 1);
    const double board_width = (target.cols - 1) * target.square_m;
    for (;;) {
        const Eigen::Vector2d pixel((0.1 + 0.8 * uniform(rng)) * model.width,
                                    (0.1 + 0.8 * uniform(rng)) * model.height);
        const auto ray = model.unproject(pixel);
        if (!ray)
            continue;
        const double span = 0.40 + 0.30 * uniform(rng);
        const double distance = board_width * model.fx / (span * model.width);
        // Face the camera, then tilt about a random in-plane axis and turn in the plane.
        const Eigen::Matrix3d facing =
            Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), *ray).toRotationMatrix();
        const double axis_angle = 2 * std::numbers::pi * uniform(rng);
        const Eigen::Vector3d axis(std::cos(axis_angle), std::sin(axis_angle), 0);
        const double tilt = (20 + 30 * uniform(rng)) * kDeg;
        const double turn = (60 * uniform(rng) - 30) * kDeg;
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = facing * Eigen::AngleAxisd(tilt, axis).toRotationMatrix() *
                     Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        T.translation() = distance * *ray - T.linear() * centre(target);
        if (visibleFraction(model, target, T) >= 0.8)
            return T;
    }
}

TargetView observe(const CameraModel& model, const CalibrationTarget& target,
                   const Eigen::Isometry3d& T_camera_target, double noise_px, std::mt19937& rng,
                   int64_t key, const std::string& source) {
    std::normal_distribution<double> noise(0, noise_px);
    TargetView view;
    view.source = source;
    view.key = key;
    const std::vector<Eigen::Vector3d> points = target.points();
    for (size_t i = 0; i < points.size(); ++i) {
        const auto pixel = model.project(T_camera_target * points[i]);
        if (!pixel)
            continue;
        const Eigen::Vector2d noisy = *pixel + Eigen::Vector2d(noise(rng), noise(rng));
        if (noisy.x() < 0 || noisy.y() < 0 || noisy.x() > model.width - 1 ||
            noisy.y() > model.height - 1)
            continue;
        view.corners.push_back(Corner{static_cast<int>(i), noisy, 1.0});
    }
    return view;
}

CameraViews generateViews(const std::string& camera, const CameraModel& model,
                          const CalibrationTarget& target, int count, double noise_px,
                          std::mt19937& rng, std::vector<Eigen::Isometry3d>* poses) {
    CameraViews views;
    views.camera = camera;
    views.width = model.width;
    views.height = model.height;
    views.target = target;
    for (int i = 0; i < count; ++i) {
        const Eigen::Isometry3d T = randomBoardPose(model, target, rng);
        views.views.push_back(
            observe(model, target, T, noise_px, rng, i, camera + "/view" + std::to_string(i)));
        if (poses)
            poses->push_back(T);
    }
    return views;
}

double rotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() / kDeg;
}

}  // namespace mixray::calibration::test
