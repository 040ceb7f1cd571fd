// The environment camera's pose in the marker frame: per-key PnP seeds, averaged, refined by a
// joint Ceres solve over the shared reprojection cost (environment_alignment.h).
#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "environment_alignment_internal.h"
#include "reprojection_cost.h"

namespace mixray::calibration::detail {

namespace {

// Corners whose rays are farther off the optical axis than this (cos of ~78°) are left out of
// PnP: normalised coordinates blow up there, and the joint solve uses them anyway.
constexpr double kMinRayZ = 0.2;

using Rt = std::array<double, 6>;

Rt toRt(const Eigen::Isometry3d& T) {
    const Eigen::AngleAxisd aa(T.linear());
    const Eigen::Vector3d w = aa.axis() * aa.angle();
    return {w.x(), w.y(), w.z(), T.translation().x(), T.translation().y(), T.translation().z()};
}

Eigen::Isometry3d fromRt(const double* rt) {
    const Eigen::Vector3d w(rt[0], rt[1], rt[2]);
    const double angle = w.norm();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    if (angle > 0)
        T.linear() = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
    T.translation() = Eigen::Vector3d(rt[3], rt[4], rt[5]);
    return T;
}

std::array<Eigen::Vector3d, 4> markerCorners(double size) {
    const double h = size / 2;
    return {Eigen::Vector3d(-h, h, 0), Eigen::Vector3d(h, h, 0), Eigen::Vector3d(h, -h, 0),
            Eigen::Vector3d(-h, -h, 0)};
}

double angleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
    return Eigen::AngleAxisd(a.transpose() * b).angle() * 180 / std::numbers::pi;
}

// Chordal mean of rotations (normalised sum of sign-aligned quaternions) and mean translation.
Eigen::Isometry3d averagePoses(const std::vector<Eigen::Isometry3d>& poses) {
    Eigen::Vector4d sum = Eigen::Vector4d::Zero();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    const Eigen::Quaterniond first(poses.front().linear());
    for (const auto& T : poses) {
        Eigen::Quaterniond q(T.linear());
        if (q.dot(first) < 0)
            q.coeffs() = -q.coeffs();
        sum += q.coeffs();
        t += T.translation();
    }
    Eigen::Isometry3d mean = Eigen::Isometry3d::Identity();
    mean.linear() = Eigen::Quaterniond(sum.normalized()).toRotationMatrix();
    mean.translation() = t / static_cast<double>(poses.size());
    return mean;
}

std::vector<Eigen::Vector3d> pointsOf(const TargetView& view,
                                      const std::vector<Eigen::Vector3d>& board_points,
                                      std::vector<Eigen::Vector2d>& pixels) {
    std::vector<Eigen::Vector3d> points;
    pixels.clear();
    for (const Corner& c : view.corners) {
        if (c.id < 0 || static_cast<size_t>(c.id) >= board_points.size())
            continue;
        points.push_back(board_points[static_cast<size_t>(c.id)]);
        pixels.push_back(c.pixel);
    }
    return points;
}

Status checkViews(const CameraViews& views, const CameraModel& model, const char* which) {
    if (views.width != 0 && (views.width != model.width || views.height != model.height)) {
        return {ErrorCode::kInvalidArgument,
                std::string(which) + " views (" + views.camera + ") are " +
                    std::to_string(views.width) + "x" + std::to_string(views.height) +
                    " but the camera model is " + std::to_string(model.width) + "x" +
                    std::to_string(model.height)};
    }
    return Status::ok();
}

}  // namespace

std::optional<Eigen::Isometry3d> poseFromCorners(const CameraModel& camera,
                                                 const std::vector<Eigen::Vector3d>& points,
                                                 const std::vector<Eigen::Vector2d>& pixels,
                                                 bool square_marker) {
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (size_t i = 0; i < points.size(); ++i) {
        const auto dir = camera.unproject(pixels[i]);
        if (!dir || dir->z() < kMinRayZ)
            continue;
        object.emplace_back(points[i].x(), points[i].y(), points[i].z());
        image.emplace_back(dir->x() / dir->z(), dir->y() / dir->z());
    }
    if (object.size() < 4 || (square_marker && object.size() != 4))
        return std::nullopt;
    cv::Mat rvec, tvec;
    try {
        const bool ok =
            cv::solvePnP(object, image, cv::Mat::eye(3, 3, CV_64F), cv::Mat(), rvec, tvec, false,
                         square_marker ? cv::SOLVEPNP_IPPE_SQUARE : cv::SOLVEPNP_IPPE);
        if (!ok)
            return std::nullopt;
    } catch (const cv::Exception&) {
        return std::nullopt;
    }
    const double rt[6] = {rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2),
                          tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)};
    const Eigen::Isometry3d T = fromRt(rt);
    if (!T.matrix().allFinite() || T.translation().z() <= 0)
        return std::nullopt;
    return T;
}

Result<AlignmentSeed> seedEnvironmentAlignment(const CameraModel& main, const CameraModel& env,
                                               const std::vector<Eigen::Vector3d>& board_points,
                                               const CameraViews& main_board,
                                               const CameraViews& env_board,
                                               const std::vector<MarkerView>& marker,
                                               const EnvironmentAlignmentOptions& options) {
    MIXRAY_RETURN_IF_ERROR(main.validate().withContext("main camera"));
    MIXRAY_RETURN_IF_ERROR(env.validate().withContext("environment camera"));
    MIXRAY_RETURN_IF_ERROR(checkViews(main_board, main, "main camera"));
    MIXRAY_RETURN_IF_ERROR(checkViews(env_board, env, "environment camera"));
    if (!(options.marker_size_m > 0))
        return Status(ErrorCode::kInvalidArgument, "marker_size_m must be > 0");
    if (main_board.target.kind != env_board.target.kind ||
        main_board.target.cols != env_board.target.cols ||
        main_board.target.rows != env_board.target.rows ||
        main_board.target.square_m != env_board.target.square_m) {
        return Status(ErrorCode::kInvalidArgument,
                      "the main and environment cameras' views are of different targets");
    }
    const auto usableByKey = [&](const CameraViews& views) {
        std::map<int64_t, const TargetView*> by_key;
        for (const TargetView& v : views.views)
            if (v.rejection == ViewRejection::kNone &&
                static_cast<int>(v.corners.size()) >= options.min_corners)
                by_key[v.key] = &v;
        return by_key;
    };
    const auto main_views = usableByKey(main_board);
    const auto env_views = usableByKey(env_board);
    const auto corners = markerCorners(options.marker_size_m);
    const std::vector<Eigen::Vector3d> marker_points(corners.begin(), corners.end());

    std::map<int64_t, const MarkerView*> marker_by_key;
    for (const MarkerView& m : marker)
        marker_by_key[m.key] = &m;
    std::map<int64_t, Eigen::Isometry3d> known;
    for (const KnownMainPose& p : options.main_poses) {
        if (!p.T_world_main.matrix().allFinite())
            return Status(
                ErrorCode::kInvalidArgument,
                "main_poses: the pose at key " + std::to_string(p.key) + " is not finite");
        known[p.key] = p.T_world_main;
    }

    AlignmentSeed seed;
    std::vector<Eigen::Vector2d> pixels;
    for (const auto& [key, main_view] : main_views) {
        const auto ev = env_views.find(key);
        if (ev == env_views.end())
            continue;
        const auto mk = marker_by_key.find(key);
        const auto kn = known.find(key);
        std::optional<Eigen::Isometry3d> T_main_marker;
        const MarkerView* m = nullptr;
        if (mk != marker_by_key.end()) {
            m = mk->second;
            T_main_marker = poseFromCorners(
                main, marker_points,
                std::vector<Eigen::Vector2d>(m->corners.begin(), m->corners.end()), true);
        }
        if (!T_main_marker && kn != known.end()) {
            m = nullptr;
            T_main_marker = kn->second.inverse();
        }
        std::vector<Eigen::Vector3d> pts = pointsOf(*main_view, board_points, pixels);
        const auto T_main_board = poseFromCorners(main, pts, pixels, false);
        pts = pointsOf(*ev->second, board_points, pixels);
        const auto T_env_board = poseFromCorners(env, pts, pixels, false);
        if (!T_main_marker || !T_main_board || !T_env_board)
            continue;
        AlignmentKey k;
        k.key = key;
        k.main_view = main_view;
        k.env_view = ev->second;
        k.marker = m;
        k.T_main_world = *T_main_marker;
        k.T_world_board = T_main_marker->inverse() * *T_main_board;
        k.T_env_world = *T_env_board * k.T_world_board.inverse();
        seed.keys.push_back(k);
    }
    if (static_cast<int>(seed.keys.size()) < options.min_views) {
        return Status(ErrorCode::kInvalidArgument,
                      "environment alignment: " + std::to_string(seed.keys.size()) +
                          " keys where the environment camera and the main camera see the board "
                          "and the main camera sees the marker (or its pose is known); at "
                          "least " +
                          std::to_string(options.min_views) + " needed");
    }
    std::vector<Eigen::Isometry3d> poses;
    for (const auto& k : seed.keys)
        poses.push_back(k.T_env_world);
    seed.T_env_world = averagePoses(poses);
    for (const auto& k : seed.keys)
        seed.spread_deg =
            std::max(seed.spread_deg, angleDeg(k.T_env_world.linear(), seed.T_env_world.linear()));
    return seed;
}

Result<EnvironmentAlignment> alignEnvironmentCamera(
    const CameraModel& main, const CameraModel& env,
    const std::vector<Eigen::Vector3d>& board_points, const CameraViews& main_board,
    const CameraViews& env_board, const std::vector<MarkerView>& marker,
    const EnvironmentAlignmentOptions& options) {
    auto seeded =
        seedEnvironmentAlignment(main, env, board_points, main_board, env_board, marker, options);
    if (!seeded)
        return seeded.status();
    const AlignmentSeed& seed = *seeded;
    const size_t n = seed.keys.size();
    Rt rt_env_world = toRt(seed.T_env_world);
    std::vector<Rt> rt_main_world(n), rt_world_board(n);
    for (size_t i = 0; i < n; ++i) {
        rt_main_world[i] = toRt(seed.keys[i].T_main_world);
        rt_world_board[i] = toRt(seed.keys[i].T_world_board);
    }

    ceres::Problem problem;
    int out_known = 0;
    const auto corners = markerCorners(options.marker_size_m);
    enum Group { kEnv, kMain, kMarker };
    struct Block {
        ceres::ResidualBlockId id;
        Group group;
        bool active = true;
    };
    std::vector<Block> blocks;
    for (size_t i = 0; i < n; ++i) {
        const AlignmentKey& k = seed.keys[i];
        for (const Corner& c : k.env_view->corners) {
            if (c.id < 0 || static_cast<size_t>(c.id) >= board_points.size())
                continue;
            blocks.push_back(
                {problem.AddResidualBlock(
                     newReprojectionCost(env, board_points[c.id], c.pixel, c.weight, 2, false),
                     nullptr, rt_env_world.data(), rt_world_board[i].data()),
                 kEnv});
        }
        for (const Corner& c : k.main_view->corners) {
            if (c.id < 0 || static_cast<size_t>(c.id) >= board_points.size())
                continue;
            blocks.push_back(
                {problem.AddResidualBlock(
                     newReprojectionCost(main, board_points[c.id], c.pixel, c.weight, 2, false),
                     nullptr, rt_main_world[i].data(), rt_world_board[i].data()),
                 kMain});
        }
        if (!k.marker) {
            problem.SetParameterBlockConstant(rt_main_world[i].data());
            ++out_known;
            continue;
        }
        for (int j = 0; j < 4; ++j)
            blocks.push_back(
                {problem.AddResidualBlock(
                     newReprojectionCost(main, corners[j], k.marker->corners[j], 1, 1, false),
                     nullptr, rt_main_world[i].data()),
                 kMarker, true});
    }
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    solver_options.max_num_iterations = 200;
    solver_options.function_tolerance = 1e-12;
    solver_options.gradient_tolerance = 1e-12;
    solver_options.parameter_tolerance = 1e-12;
    solver_options.num_threads = 1;
    const auto squaredResidual = [&](const Block& b) {
        double cost = 0;
        problem.EvaluateResidualBlock(b.id, false, &cost, nullptr, nullptr);
        return 2 * cost;  // cost = ½ |r|²
    };
    int outliers = 0;
    for (int round = 0; round < 10; ++round) {
        ceres::Solver::Summary summary;
        ceres::Solve(solver_options, &problem, &summary);
        if (!summary.IsSolutionUsable() || summary.termination_type == ceres::NO_CONVERGENCE)
            return Status(
                ErrorCode::kInternal,
                "environment alignment: the solve did not converge: " + summary.BriefReport());
        double sum = 0;
        int count = 0;
        for (const Block& b : blocks) {
            if (b.active) {
                sum += squaredResidual(b);
                ++count;
            }
        }
        const double limit2 = options.outlier_sigma * options.outlier_sigma * sum / count;
        int dropped = 0;
        for (Block& b : blocks) {
            // The marker's corners fix the world: never dropped.
            if (b.active && b.group != kMarker && squaredResidual(b) > limit2) {
                problem.RemoveResidualBlock(b.id);
                b.active = false;
                ++dropped;
            }
        }
        outliers += dropped;
        if (dropped == 0)
            break;
    }

    EnvironmentAlignment out;
    const Eigen::Isometry3d T_env_world = fromRt(rt_env_world.data());
    out.T_world_env = T_env_world.inverse();
    out.seed_spread_deg = seed.spread_deg;
    out.keys_with_known_pose = out_known;
    for (const auto& k : seed.keys)
        out.keys.push_back(k.key);
    double sums[3] = {0, 0, 0};
    int counts[3] = {0, 0, 0};
    out.outliers = outliers;
    for (const Block& b : blocks) {
        if (!b.active)
            continue;
        sums[b.group] += squaredResidual(b);
        ++counts[b.group];
    }
    const auto rms = [](double s, int c) { return c ? std::sqrt(s / c) : 0.0; };
    out.env_rms_px = rms(sums[kEnv], counts[kEnv]);
    out.main_rms_px = rms(sums[kMain], counts[kMain]);
    out.marker_rms_px = rms(sums[kMarker], counts[kMarker]);
    const int points = counts[0] + counts[1] + counts[2];
    out.rms_px = rms(sums[0] + sums[1] + sums[2], points);

    // σ² (JᵀJ)⁻¹ for T_env_world, then through the inverse's Jacobian to T_world_env.
    const int dof = 2 * points - 6 * static_cast<int>(1 + 2 * n - out_known);
    const double sigma2 = dof > 0 ? (sums[0] + sums[1] + sums[2]) / dof : 0;
    ceres::Covariance::Options cov_options;
    ceres::Covariance covariance(cov_options);
    const std::vector<std::pair<const double*, const double*>> pairs = {
        {rt_env_world.data(), rt_env_world.data()}};
    if (!covariance.Compute(pairs, &problem))
        return Status(ErrorCode::kInvalidArgument,
                      "environment alignment: the environment camera's pose is not observable "
                      "from these views (singular Jacobian)");
    Eigen::Matrix<double, 6, 6, Eigen::RowMajor> cov_env_world;
    covariance.GetCovarianceBlock(rt_env_world.data(), rt_env_world.data(), cov_env_world.data());
    Eigen::Matrix<double, 6, 6> J;
    for (int c = 0; c < 6; ++c) {
        const double h = 1e-7;
        Rt plus = rt_env_world, minus = rt_env_world;
        plus[c] += h;
        minus[c] -= h;
        const Rt a = toRt(fromRt(plus.data()).inverse());
        const Rt b = toRt(fromRt(minus.data()).inverse());
        for (int r = 0; r < 6; ++r)
            J(r, c) = (a[r] - b[r]) / (2 * h);
    }
    out.covariance = sigma2 * J * cov_env_world * J.transpose();
    return out;
}

}  // namespace mixray::calibration::detail
