// Targets and their poses: corner points of markers and OpenCV boards, IPPE starts and a
// Levenberg–Marquardt reprojection fit through the lens model.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "marker_internal.h"

namespace mixray::tracking {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

bool finite(double v) {
    return std::isfinite(v);
}

// OpenCV's board for a board target (its frame is the target's); null for kMarker.
cv::Ptr<cv::aruco::Board> makeBoard(const MarkerTarget& t) {
    if (t.kind == TargetKind::kMarker)
        return {};
    const auto dictionary_id = calibration::openCvDictionaryId(t.dictionary);
    if (!dictionary_id)
        return {};
    try {
        const auto dict = cv::aruco::getPredefinedDictionary(
            static_cast<cv::aruco::PREDEFINED_DICTIONARY_NAME>(*dictionary_id));
        if (t.kind == TargetKind::kGridBoard)
            return cv::aruco::GridBoard::create(t.squares_x, t.squares_y,
                                                static_cast<float>(t.size_m),
                                                static_cast<float>(t.separation_m), dict, t.id);
        cv::Ptr<cv::aruco::CharucoBoard> board = cv::aruco::CharucoBoard::create(
            t.squares_x, t.squares_y, static_cast<float>(t.square_m), static_cast<float>(t.size_m),
            dict);
        // Its markers are numbered from 0; a board printed with later ids shifts them all.
        for (int& id : board->ids)
            id += t.id;
        return board;
    } catch (const cv::Exception&) {
        return {};
    }
}

// T <- exp(delta) * T, rotation first: a small motion of the camera-side frame.
Isometry3d perturb(const Isometry3d& T, const Eigen::Matrix<double, 6, 1>& delta) {
    const Vector3d w = delta.head<3>();
    const double angle = w.norm();
    const Eigen::Matrix3d R = angle > 0 ? Eigen::AngleAxisd(angle, w / angle).toRotationMatrix()
                                        : Eigen::Matrix3d::Identity();
    Isometry3d out = Isometry3d::Identity();
    out.linear() = R * T.linear();
    out.translation() = R * T.translation() + delta.tail<3>();
    return out;
}

bool residuals(const calibration::CameraModel& camera, const std::vector<Vector3d>& points,
               const std::vector<Vector2d>& pixels, const Isometry3d& T, Eigen::VectorXd& r) {
    r.resize(static_cast<Eigen::Index>(2 * points.size()));
    for (size_t i = 0; i < points.size(); ++i) {
        const auto px = camera.project(T * points[i]);
        if (!px)
            return false;
        r.segment<2>(static_cast<Eigen::Index>(2 * i)) = *px - pixels[i];
    }
    return true;
}

}  // namespace

Status MarkerTarget::validate() const {
    const std::string where = "target '" + name + "': ";
    if (name.empty())
        return {ErrorCode::kInvalidArgument, "target: name must not be empty"};
    if (!isKnownDictionary(dictionary))
        return {ErrorCode::kInvalidArgument, where + "unknown dictionary '" + dictionary + "'"};
    if (id < 0)
        return {ErrorCode::kInvalidArgument, where + "id must be >= 0"};
    if (!finite(size_m) || size_m <= 0)
        return {ErrorCode::kInvalidArgument, where + "size_m must be > 0"};
    if (!T_world_target.matrix().allFinite() ||
        !(T_world_target.linear() * T_world_target.linear().transpose())
             .isApprox(Eigen::Matrix3d::Identity(), 1e-6))
        return {ErrorCode::kInvalidArgument,
                where + "T_world_target must be a finite rigid transform"};
    if (kind == TargetKind::kMarker)
        return Status::ok();
    if (dictionary.rfind("apriltag:", 0) == 0)
        return {ErrorCode::kInvalidArgument,
                where + "boards need an OpenCV dictionary, not '" + dictionary + "'"};
    const int min_squares = kind == TargetKind::kCharucoBoard ? 2 : 1;
    if (squares_x < min_squares || squares_y < min_squares || squares_x * squares_y < 2)
        return {ErrorCode::kInvalidArgument,
                where + "squares_x and squares_y must give a board of at least 2 " +
                    (kind == TargetKind::kCharucoBoard ? "squares each way" : "markers")};
    int markers = squares_x * squares_y;
    if (kind == TargetKind::kCharucoBoard) {
        if (!finite(square_m) || square_m <= size_m)
            return {ErrorCode::kInvalidArgument,
                    where + "square_m must be larger than the marker size_m"};
        markers /= 2;
    } else if (!finite(separation_m) || separation_m <= 0) {
        return {ErrorCode::kInvalidArgument, where + "separation_m must be > 0"};
    }
    if (id + markers > calibration::openCvDictionarySize(dictionary))
        return {ErrorCode::kInvalidArgument, where + "ids " + std::to_string(id) + ".." +
                                                 std::to_string(id + markers - 1) +
                                                 " do not all exist in " + dictionary};
    return Status::ok();
}

std::vector<MarkerTarget::Point> MarkerTarget::points() const {
    std::vector<Point> out;
    if (!validate())
        return out;
    if (kind == TargetKind::kMarker) {
        const double h = 0.5 * size_m;
        // +x right, +y up: OpenCV's corner order from the upright marker's top-left.
        const std::array<Vector3d, 4> c = {Vector3d(-h, h, 0), Vector3d(h, h, 0),
                                           Vector3d(h, -h, 0), Vector3d(-h, -h, 0)};
        for (int k = 0; k < 4; ++k)
            out.push_back({id, k, c[static_cast<size_t>(k)]});
        return out;
    }
    const cv::Ptr<cv::aruco::Board> board = makeBoard(*this);
    if (!board)
        return out;
    if (kind == TargetKind::kCharucoBoard) {
        const auto* charuco = static_cast<const cv::aruco::CharucoBoard*>(board.get());
        for (size_t i = 0; i < charuco->chessboardCorners.size(); ++i) {
            const cv::Point3f& p = charuco->chessboardCorners[i];
            out.push_back({-1, static_cast<int>(i), Vector3d(p.x, p.y, p.z)});
        }
        return out;
    }
    for (size_t m = 0; m < board->ids.size(); ++m)
        for (int k = 0; k < 4; ++k) {
            const cv::Point3f& p = board->objPoints[m][static_cast<size_t>(k)];
            out.push_back({board->ids[m], k, Vector3d(p.x, p.y, p.z)});
        }
    return out;
}

namespace detail {

std::optional<PoseFit> refinePose(const calibration::CameraModel& camera,
                                  const std::vector<Vector3d>& points,
                                  const std::vector<Vector2d>& pixels, const Isometry3d& T_init) {
    if (points.empty() || points.size() != pixels.size())
        return std::nullopt;
    Isometry3d T = T_init;
    Eigen::VectorXd r;
    if (!residuals(camera, points, pixels, T, r))
        return std::nullopt;
    double cost = r.squaredNorm();
    double lambda = 1e-3;
    const auto n = static_cast<Eigen::Index>(2 * points.size());
    Eigen::MatrixXd J(n, 6);
    Eigen::VectorXd rp, rm;
    for (int iter = 0; iter < 30; ++iter) {
        // Central differences: the lens models have no analytic Jacobian here, and 6 columns
        // over a few dozen points cost microseconds.
        constexpr double kEps = 1e-6;
        bool ok = true;
        for (int j = 0; j < 6 && ok; ++j) {
            Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
            d[j] = kEps;
            ok = residuals(camera, points, pixels, perturb(T, d), rp) &&
                 residuals(camera, points, pixels, perturb(T, -d), rm);
            if (ok)
                J.col(j) = (rp - rm) / (2 * kEps);
        }
        if (!ok)
            break;
        const Eigen::Matrix<double, 6, 6> H = J.transpose() * J;
        const Eigen::Matrix<double, 6, 1> g = J.transpose() * r;
        bool improved = false;
        Eigen::Matrix<double, 6, 1> step = Eigen::Matrix<double, 6, 1>::Zero();
        while (lambda < 1e10) {
            Eigen::Matrix<double, 6, 6> A = H;
            A.diagonal() += lambda * H.diagonal().cwiseMax(1e-9);
            step = -A.ldlt().solve(g);
            const Isometry3d Tn = perturb(T, step);
            Eigen::VectorXd rn;
            if (residuals(camera, points, pixels, Tn, rn) && rn.squaredNorm() < cost) {
                const double gain = cost - rn.squaredNorm();
                T = Tn;
                r = rn;
                cost = rn.squaredNorm();
                lambda = std::max(lambda * 0.1, 1e-12);
                improved = gain > 1e-14 * (1 + cost);
                break;
            }
            lambda *= 10;
        }
        if (!improved || step.norm() < 1e-12)
            break;
    }
    return PoseFit{T, std::sqrt(cost / static_cast<double>(points.size()))};
}

std::optional<PoseFit> planarPose(const calibration::CameraModel& camera,
                                  const std::vector<Vector3d>& points,
                                  const std::vector<Vector2d>& pixels, bool square) {
    if (points.size() < 4 || points.size() != pixels.size() || (square && points.size() != 4))
        return std::nullopt;
    // IPPE on undistorted, normalised image points: any lens model, an identity camera matrix.
    std::vector<cv::Point3d> obj;
    std::vector<cv::Point2d> img;
    for (size_t i = 0; i < points.size(); ++i) {
        const auto d = camera.unproject(pixels[i]);
        if (!d || d->z() <= 1e-6)
            return std::nullopt;
        obj.emplace_back(points[i].x(), points[i].y(), points[i].z());
        img.emplace_back(d->x() / d->z(), d->y() / d->z());
    }
    std::vector<cv::Mat> rvecs, tvecs;
    try {
        cv::solvePnPGeneric(obj, img, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvecs, tvecs,
                            false, square ? cv::SOLVEPNP_IPPE_SQUARE : cv::SOLVEPNP_IPPE);
    } catch (const cv::Exception&) {
        return std::nullopt;
    }
    std::optional<PoseFit> best;
    for (size_t s = 0; s < rvecs.size(); ++s) {
        cv::Mat R;
        cv::Rodrigues(rvecs[s], R);
        Eigen::Matrix3d Re;
        Eigen::Vector3d te;
        cv::cv2eigen(R, Re);
        cv::cv2eigen(tvecs[s], te);
        Isometry3d T = Isometry3d::Identity();
        T.linear() = Re;
        T.translation() = te;
        const auto fit = refinePose(camera, points, pixels, T);
        if (fit && (!best || fit->rms_px < best->rms_px))
            best = fit;
    }
    return best;
}

Correspondences correspond(const MarkerTarget& target,
                           const std::vector<MarkerDetection>& detections, const ImageView& image) {
    Correspondences out;
    const std::vector<MarkerTarget::Point> pts = target.points();
    if (target.kind == TargetKind::kMarker) {
        // A marker seen twice (a reflection, a second print): the larger view wins.
        const MarkerDetection* best = nullptr;
        double best_area = 0;
        for (const MarkerDetection& d : detections) {
            if (d.dictionary != target.dictionary || d.id != target.id)
                continue;
            const Vector2d a = d.corners[2] - d.corners[0], b = d.corners[3] - d.corners[1];
            const double area = 0.5 * std::abs(a.x() * b.y() - a.y() * b.x());
            if (!best || area > best_area) {
                best = &d;
                best_area = area;
            }
        }
        if (best && pts.size() == 4)
            for (size_t k = 0; k < 4; ++k) {
                out.points.push_back(pts[k].p_target);
                out.pixels.push_back(best->corners[k]);
            }
        return out;
    }
    if (target.kind == TargetKind::kGridBoard) {
        std::map<std::pair<int, int>, Vector3d> lookup;
        for (const MarkerTarget::Point& p : pts)
            lookup[{p.marker_id, p.corner}] = p.p_target;
        for (const MarkerDetection& d : detections) {
            if (d.dictionary != target.dictionary)
                continue;
            for (int k = 0; k < 4; ++k) {
                const auto it = lookup.find({d.id, k});
                if (it == lookup.end())
                    break;
                out.points.push_back(it->second);
                out.pixels.push_back(d.corners[static_cast<size_t>(k)]);
            }
        }
        return out;
    }
    const calibration::CharucoBoardSpec spec{target.squares_x, target.squares_y,  target.square_m,
                                             target.size_m,    target.dictionary, target.id};
    const auto corners = calibration::charucoCorners(image, spec, detections);
    if (!corners)
        return out;
    for (const calibration::Corner& c : *corners) {
        const auto idx = static_cast<size_t>(c.id);
        if (idx >= pts.size())
            continue;
        out.points.push_back(pts[idx].p_target);
        out.pixels.push_back(c.pixel);
    }
    return out;
}

}  // namespace detail
}  // namespace mixray::tracking
