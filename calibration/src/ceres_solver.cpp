// calibrateCamera()'s Ceres back end: weighted least squares of the reprojection error over the
// inlier corners, intrinsics and one pose per view, then residuals, per-view fits and the
// covariance in calibrate.h's layout.
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "ceres_util.h"
#include "reprojection_cost.h"
#include "solve_internal.h"

namespace mixray::calibration::detail {

namespace {

// The solve itself: the problem over the inliers, solved in place.
struct Solved {
    CameraModel seed;
    Eigen::VectorXd intrinsics;
    std::vector<Vector6d> poses;
    std::unique_ptr<ceres::Problem> problem;
    ceres::Solver::Summary summary;
    int residual_count = 0;
};

Result<std::unique_ptr<Solved>> solve(const SolveInput& input, const CalibrationOptions& options) {
    const CameraViews& views = *input.views;
    const std::vector<Eigen::Vector3d> points = views.target.points();
    auto s = std::make_unique<Solved>();
    s->seed = input.seed;
    if (options.fix_aspect_ratio)
        s->seed.fx = s->seed.fy = 0.5 * (s->seed.fx + s->seed.fy);
    s->intrinsics = intrinsicsVector(s->seed);
    for (const Eigen::Isometry3d& T : input.T_camera_target)
        s->poses.push_back(toRt(T));

    s->problem = std::make_unique<ceres::Problem>();
    ceres::Problem& problem = *s->problem;
    problem.AddParameterBlock(s->intrinsics.data(), static_cast<int>(s->intrinsics.size()));
    if (options.fix_aspect_ratio) {
        problem.SetManifold(s->intrinsics.data(),
                            new EqualFocalManifold(static_cast<int>(s->intrinsics.size())));
    }
    for (size_t u = 0; u < input.used.size(); ++u) {
        const TargetView& view = views.views[input.used[u]];
        problem.AddParameterBlock(s->poses[u].data(), 6);
        for (size_t c = 0; c < view.corners.size(); ++c) {
            if (!input.inlier[u][c])
                continue;
            const Corner& corner = view.corners[c];
            problem.AddResidualBlock(
                newReprojectionCost(s->seed, points[static_cast<size_t>(corner.id)], corner.pixel,
                                    corner.weight, 1, true),
                nullptr, s->poses[u].data(), s->intrinsics.data());
            s->residual_count += 2;
        }
    }
    ceres::Solve(solverOptions(), &problem, &s->summary);
    if (!s->summary.IsSolutionUsable() || s->summary.termination_type != ceres::CONVERGENCE) {
        return Status(kNotConverged,
                      "camera '" + views.camera +
                          "': the Ceres solve did not converge: " + s->summary.BriefReport());
    }
    return s;
}

}  // namespace

Result<std::vector<Eigen::Isometry3d>> solvePosesWithCeres(const SolveInput& input,
                                                           const CalibrationOptions& options) {
    Result<std::unique_ptr<Solved>> solved = solve(input, options);
    if (!solved)
        return solved.status();
    std::vector<Eigen::Isometry3d> out;
    for (const Vector6d& pose : (*solved)->poses)
        out.push_back(fromRt(pose.data()));
    return out;
}

Result<CameraCalibration> solveWithCeres(const SolveInput& input,
                                         const CalibrationOptions& options) {
    const CameraViews& views = *input.views;
    const std::vector<Eigen::Vector3d> points = views.target.points();
    Result<std::unique_ptr<Solved>> solved = solve(input, options);
    if (!solved)
        return solved.status();
    Solved& s = **solved;
    ceres::Problem& problem = *s.problem;
    const CameraModel& seed = s.seed;
    const Eigen::VectorXd& intrinsics = s.intrinsics;
    const std::vector<Vector6d>& poses = s.poses;
    const ceres::Solver::Summary& summary = s.summary;
    const int residual_count = s.residual_count;

    CameraCalibration out;
    out.camera = views.camera;
    out.solver = Solver::kCeres;
    out.model = withIntrinsics(seed, intrinsics);
    if (Status valid = out.model.validate(); !valid) {
        return Status(kNotConverged, "camera '" + views.camera +
                                         "': the solve ended on an invalid model (" +
                                         valid.message() + ")");
    }

    std::vector<Eigen::Isometry3d> T_camera_target;
    for (const Vector6d& pose : poses)
        T_camera_target.push_back(fromRt(pose.data()));
    if (const auto unprojected = fillResiduals(input, T_camera_target, points, out)) {
        const TargetView& view = views.views[input.used[unprojected->first]];
        return Status(kNotConverged, "camera '" + views.camera + "': view '" + view.source +
                                         "': corner " +
                                         std::to_string(view.corners[unprojected->second].id) +
                                         " does not project through the solved model");
    }

    // σ² from the weighted residuals the solve minimised, with the degrees of freedom it used.
    const int free_parameters = problem.NumParameters() - (options.fix_aspect_ratio ? 1 : 0);
    const int dof = residual_count - free_parameters;
    if (dof <= 0) {
        return Status(kNotConverged, "camera '" + views.camera +
                                         "': " + std::to_string(residual_count / 2) +
                                         " corners cannot determine " +
                                         std::to_string(free_parameters) + " parameters");
    }
    const double sigma2 = 2 * summary.final_cost / dof;
    std::vector<const double*> blocks = {intrinsics.data()};
    for (const Vector6d& pose : poses)
        blocks.push_back(pose.data());
    const std::optional<Eigen::MatrixXd> covariance = covarianceOf(problem, blocks);
    if (!covariance) {
        return Status(kNotConverged,
                      "camera '" + views.camera +
                          "': the solution's covariance is singular (the views do not "
                          "constrain every parameter)");
    }
    out.covariance = sigma2 * *covariance;
    return out;
}

}  // namespace mixray::calibration::detail
