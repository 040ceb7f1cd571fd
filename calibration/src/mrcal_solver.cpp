// calibrateCamera()'s mrcal back end: the seeded problem solved by mrcal_optimize, staged as
// mrcal-calibrate-cameras stages it, and the state covariance from mrcal's own Jacobian.
#include <suitesparse/cholmod.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "mrcal_lens.h"
#include "solve_internal.h"

namespace mixray::calibration::detail {
namespace {

// The lens mrcal fits for a CalibrationOptions::model name; nullopt when mrcal lacks it.
std::optional<mrcal_lensmodel_t> lensForModelName(std::string_view name) {
    if (name == "opencv4" || name == "LENSMODEL_OPENCV4")
        return makeMrcalLensModel(MRCAL_LENSMODEL_OPENCV4);
    if (name == "opencv5" || name == "LENSMODEL_OPENCV5")
        return makeMrcalLensModel(MRCAL_LENSMODEL_OPENCV5);
    if (name == "opencv8" || name == "LENSMODEL_OPENCV8")
        return makeMrcalLensModel(MRCAL_LENSMODEL_OPENCV8);
    if (name == "stereographic" || name == "LENSMODEL_STEREOGRAPHIC")
        return makeMrcalLensModel(MRCAL_LENSMODEL_STEREOGRAPHIC);
    if (const std::optional<SplineConfig> config = splineConfigFromString(name)) {
        // validate() checks the configuration; the rest of this stand-in only satisfies it.
        CameraModel model = CameraModel::pinhole(1, 1, 1, 1, 0, 0);
        model.lens = LensModel::kSplinedStereographic;
        model.spline = *config;
        model.distortion.assign(2 * static_cast<size_t>(config->nx) * config->ny, 0.0);
        if (!model.validate().isOk())
            return std::nullopt;
        return mrcalLensModel(model);
    }
    return std::nullopt;
}

// mrcal's calibration object: a W × H grid of points `spacing` apart, point (i, j) (row i,
// column j) at (j, i, 0)·spacing. mixray's targets put it at `origin` in their own frame.
struct BoardGrid {
    int width_n = 0, height_n = 0;
    double spacing = 0;
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();
};

Result<BoardGrid> boardGrid(const CalibrationTarget& target) {
    BoardGrid grid;
    grid.spacing = target.square_m;
    switch (target.kind) {
        case TargetKind::kChessboard:
            grid.width_n = target.cols;
            grid.height_n = target.rows;
            break;
        case TargetKind::kCharuco:
            // OpenCV's ChArUco corner ids run row-major over the inner chessboard corners, the
            // first one square in from the board's corner.
            grid.width_n = target.cols - 1;
            grid.height_n = target.rows - 1;
            grid.origin = Eigen::Vector3d(target.square_m, target.square_m, 0);
            break;
        case TargetKind::kAprilGrid:
            return Status(ErrorCode::kInvalidArgument,
                          "mrcal solver: an AprilGrid's corners are not one evenly spaced grid, "
                          "which mrcal's calibration object must be; use the Ceres solver");
    }
    if (grid.width_n < 2 || grid.height_n < 2 || !(grid.spacing > 0)) {
        return Status(ErrorCode::kInvalidArgument,
                      "mrcal solver: the target of " + std::to_string(target.cols) + "x" +
                          std::to_string(target.rows) + " has no grid of at least 2x2 corners");
    }
    return grid;
}

mrcal_pose_t poseFromIsometry(const Eigen::Isometry3d& T) {
    const Eigen::AngleAxisd aa(T.rotation());
    const Eigen::Vector3d r = aa.axis() * aa.angle();
    mrcal_pose_t pose;
    std::memset(&pose, 0, sizeof pose);
    for (int k = 0; k < 3; ++k) {
        pose.r.xyz[k] = r[k];
        pose.t.xyz[k] = T.translation()[k];
    }
    return pose;
}

Eigen::Isometry3d isometryFromPose(const mrcal_pose_t& pose) {
    const Eigen::Vector3d r(pose.r.x, pose.r.y, pose.r.z);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const double angle = r.norm();
    if (angle > 0)
        T.linear() = Eigen::AngleAxisd(angle, r / angle).toRotationMatrix();
    T.translation() = Eigen::Vector3d(pose.t.x, pose.t.y, pose.t.z);
    return T;
}

mrcal_problem_selections_t selections(bool core, bool distortions, bool regularization,
                                      bool outlier_rejection) {
    mrcal_problem_selections_t s;
    std::memset(&s, 0, sizeof s);
    s.do_optimize_intrinsics_core = core;
    s.do_optimize_intrinsics_distortions = distortions;
    s.do_optimize_extrinsics = false;  // one camera, at the reference
    s.do_optimize_frames = true;
    s.do_optimize_calobject_warp = false;  // mixray's boards are flat
    s.do_apply_regularization = regularization;
    // mrcal's own rejection (markOutliers in mrcal.c: re-solve while a weighted residual lies
    // beyond 5σ, dropping those beyond 4σ, σ over the inliers), so the same corners give the
    // same lens and the same outliers as mrcal-calibrate-cameras. Corners already out of the
    // solve come in with negative weights, which mrcal keeps out.
    s.do_apply_outlier_rejection = outlier_rejection;
    return s;
}

// One camera's board observations in mrcal's arrays.
struct Problem {
    BoardGrid grid;
    int nframes = 0;
    std::vector<mrcal_observation_board_t> observations;
    std::vector<mrcal_point3_t> pool;  // nframes × H × W: x, y, weight (< 0: not in the solve)
    std::vector<mrcal_pose_t> frames;  // T_camera_board per frame, mrcal's board frame
    int imagersize[2] = {0, 0};
    mrcal_problem_constants_t constants{-1.0, -1.0};

    mrcal_stats_t optimize(const mrcal_lensmodel_t& lens, std::vector<double>& intrinsics,
                           mrcal_problem_selections_t s) {
        return mrcal_optimize(nullptr, 0, nullptr, 0, intrinsics.data(), nullptr, frames.data(),
                              nullptr, nullptr, 1, 0, nframes, 0, 0, observations.data(), nullptr,
                              nframes, 0, pool.data(), &lens, imagersize, s, &constants,
                              grid.spacing, grid.width_n, grid.height_n, false, false);
    }
};

bool converged(const mrcal_stats_t& stats) {
    return std::isfinite(stats.rms_reproj_error__pixels) && stats.rms_reproj_error__pixels >= 0;
}

// The covariance of the solved state, in calibrate.h's layout, by mrcal's uncertainty model
// (mrcal docs "Projection uncertainty"): Var(b) = σ² M J_obsᵀ J_obs M with M = (JᵀJ)⁻¹, J
// including the regularisation rows (which carry no noise), evaluated in mrcal's packed,
// unitless state b* = D⁻¹ b and unpacked with D. σ is the standard deviation of the solved
// board residuals over the inliers (mrcal's "observed_pixel_uncertainty" inferred from them).
Result<Eigen::MatrixXd> stateCovariance(Problem& problem, const mrcal_lensmodel_t& lens,
                                        const std::vector<double>& intrinsics,
                                        mrcal_problem_selections_t s, size_t nintrinsics_full) {
    const int nframes = problem.nframes;
    const int W = problem.grid.width_n, H = problem.grid.height_n;
    const int nstate = mrcal_num_states(1, 0, nframes, 0, 0, nframes, s, &lens);
    const int nmeasurements =
        mrcal_num_measurements(nframes, 0, W, H, 1, 0, nframes, 0, 0, s, &lens);
    const int nboard = mrcal_num_measurements_boards(nframes, W, H);
    const int nnonzero = _mrcal_num_j_nonzero(nframes, 0, W, H, 1, 0, nframes, 0, 0,
                                              problem.observations.data(), nullptr, s, &lens);

    std::vector<double> b_packed(static_cast<size_t>(nstate));
    std::vector<double> x(static_cast<size_t>(nmeasurements));
    std::vector<int> Jp(static_cast<size_t>(nmeasurements) + 1), Ji(static_cast<size_t>(nnonzero));
    std::vector<double> Jx(static_cast<size_t>(nnonzero));
    cholmod_sparse Jt;
    std::memset(&Jt, 0, sizeof Jt);
    Jt.nrow = static_cast<size_t>(nstate);
    Jt.ncol = static_cast<size_t>(nmeasurements);
    Jt.nzmax = static_cast<size_t>(nnonzero);
    Jt.p = Jp.data();
    Jt.i = Ji.data();
    Jt.x = Jx.data();
    Jt.stype = 0;
    Jt.itype = CHOLMOD_INT;
    Jt.xtype = CHOLMOD_REAL;
    Jt.dtype = CHOLMOD_DOUBLE;
    Jt.sorted = 1;
    Jt.packed = 1;
    if (!mrcal_optimizer_callback(
            b_packed.data(), nstate * static_cast<int>(sizeof(double)), x.data(),
            nmeasurements * static_cast<int>(sizeof(double)), &Jt, intrinsics.data(), nullptr,
            problem.frames.data(), nullptr, nullptr, 1, 0, nframes, 0, 0,
            problem.observations.data(), nullptr, nframes, 0, problem.pool.data(), &lens,
            problem.imagersize, s, &problem.constants, problem.grid.spacing, W, H, false)) {
        return Status(kNotConverged,
                      "mrcal solver: mrcal_optimizer_callback failed at the solution");
    }

    // JᵀJ and its board-observation part J_obsᵀJ_obs, accumulated from the sparse rows: each
    // measurement touches only the intrinsics and one board pose, so this costs a few million
    // operations where a dense J would cost billions for tens of views.
    Eigen::MatrixXd JtJ = Eigen::MatrixXd::Zero(nstate, nstate);
    Eigen::MatrixXd JotJo = Eigen::MatrixXd::Zero(nstate, nstate);
    for (int m = 0; m < nmeasurements; ++m) {
        const int begin = Jp[static_cast<size_t>(m)], end = Jp[static_cast<size_t>(m) + 1];
        Eigen::MatrixXd& target = m < nboard ? JotJo : JtJ;
        for (int a = begin; a < end; ++a) {
            const int row = Ji[static_cast<size_t>(a)];
            const double value = Jx[static_cast<size_t>(a)];
            for (int b = begin; b < end; ++b)
                target(row, Ji[static_cast<size_t>(b)]) += value * Jx[static_cast<size_t>(b)];
        }
    }
    JtJ += JotJo;

    // σ over the inlier board measurements: outliers have weight < 0 and x = 0.
    double sum = 0, sum2 = 0;
    size_t n = 0;
    for (size_t p = 0; p < problem.pool.size(); ++p) {
        if (problem.pool[p].z < 0)
            continue;
        for (size_t k = 0; k < 2; ++k) {
            const double v = x[2 * p + k];
            sum += v;
            sum2 += v * v;
            ++n;
        }
    }
    if (n < 2) {
        return Status(kNotConverged, "mrcal solver: too few inliers for a covariance");
    }
    const double mean = sum / static_cast<double>(n);
    const double variance = std::max(0.0, sum2 / static_cast<double>(n) - mean * mean);

    const Eigen::LDLT<Eigen::MatrixXd> ldlt(JtJ);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) {
        return Status(kNotConverged,
                      "mrcal solver: the solution's JᵀJ is singular (the views do not determine "
                      "the model)");
    }
    // M J_obsᵀJ_obs M with M = (JᵀJ)⁻¹ symmetric: X = M·J_obsᵀJ_obs, then (M·Xᵀ)ᵀ = X·M.
    const Eigen::MatrixXd X = ldlt.solve(JotJo);
    const Eigen::MatrixXd covariance_packed =
        Eigen::MatrixXd(ldlt.solve(X.transpose()).transpose()) * variance;

    // Unpack: b = D b*, with D's diagonal the unpacking of a vector of ones.
    Eigen::VectorXd D = Eigen::VectorXd::Ones(nstate);
    mrcal_unpack_solver_state_vector(D.data(), 1, 0, nframes, 0, 0, s, &lens);
    const Eigen::MatrixXd covariance_state = D.asDiagonal() * covariance_packed * D.asDiagonal();

    // From mrcal's state to calibrate.h's layout: the optimised intrinsics land at their model
    // index (the fixed core of a splined model stays 0), and each frame's pose in mrcal's board
    // frame becomes T_camera_target's: R unchanged, t_target = t_board − R·origin.
    const size_t nout = nintrinsics_full + 6 * static_cast<size_t>(nframes);
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(nout), nstate);
    const int istate_intrinsics =
        mrcal_state_index_intrinsics(0, 1, 0, nframes, 0, 0, nframes, s, &lens);
    const int nstate_intrinsics = mrcal_num_states_intrinsics(1, s, &lens);
    const int first_intrinsic = s.do_optimize_intrinsics_core ? 0 : 4;
    for (int k = 0; k < nstate_intrinsics; ++k)
        A(first_intrinsic + k, istate_intrinsics + k) = 1;
    const int istate_frames = mrcal_state_index_frames(0, 1, 0, nframes, 0, 0, nframes, s, &lens);
    const Eigen::Vector3d origin = problem.grid.origin;
    for (int f = 0; f < nframes; ++f) {
        const Eigen::Index row = static_cast<Eigen::Index>(nintrinsics_full) + 6 * f;
        const int col = istate_frames + 6 * f;
        A.block(row, col, 6, 6).setIdentity();
        double rotated[3];
        double dR_dr[9];
        mrcal_rotate_point_r(rotated, dR_dr, nullptr, problem.frames[static_cast<size_t>(f)].r.xyz,
                             origin.data());
        const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> J_r(dR_dr);
        A.block(row + 3, col, 3, 3) = -J_r;
    }
    return Eigen::MatrixXd(A * covariance_state * A.transpose());
}

}  // namespace

bool mrcalHasModel(std::string_view model) {
    return lensForModelName(model).has_value();
}

Result<CameraCalibration> solveWithMrcal(const SolveInput& input,
                                         const CalibrationOptions& options) {
    auto fail = [](ErrorCode code, std::string message) {
        return Status(code, "mrcal solver: " + std::move(message));
    };
    if (!input.views)
        return fail(ErrorCode::kInvalidArgument, "no views");
    const CameraViews& views = *input.views;
    const std::optional<mrcal_lensmodel_t> lens = lensForModelName(options.model);
    if (!lens) {
        return fail(ErrorCode::kInvalidArgument,
                    "mrcal has no model \"" + options.model +
                        "\" (it fits opencv4, opencv5, opencv8, stereographic and "
                        "LENSMODEL_SPLINED_STEREOGRAPHIC_order=..._Nx=..._Ny=..._fov_x_deg=...)");
    }
    if (input.used.empty() || input.used.size() != input.inlier.size() ||
        input.used.size() != input.T_camera_target.size()) {
        return fail(ErrorCode::kInvalidArgument,
                    "the used views, their inlier flags and their seeded poses differ in count");
    }
    auto grid = boardGrid(views.target);
    if (!grid)
        return grid.status();
    auto progress = [&](double fraction, std::string_view stage) {
        if (options.progress)
            options.progress(fraction, stage);
    };

    Problem problem;
    problem.grid = *grid;
    problem.nframes = static_cast<int>(input.used.size());
    problem.imagersize[0] = views.width;
    problem.imagersize[1] = views.height;
    const size_t npoints = static_cast<size_t>(grid->width_n) * grid->height_n;
    mrcal_point3_t missing;
    missing.x = missing.y = 0;
    missing.z = -1;
    problem.pool.assign(npoints * input.used.size(), missing);
    const Eigen::Isometry3d T_target_board(Eigen::Translation3d(grid->origin));
    for (size_t f = 0; f < input.used.size(); ++f) {
        if (input.used[f] >= views.views.size())
            return fail(ErrorCode::kInvalidArgument, "a used view index is out of range");
        const TargetView& view = views.views[input.used[f]];
        if (input.inlier[f].size() != view.corners.size()) {
            return fail(ErrorCode::kInvalidArgument,
                        "view " + view.source + ": inlier flags and corners differ in count");
        }
        mrcal_observation_board_t observation;
        observation.icam.intrinsics = 0;
        observation.icam.extrinsics = -1;
        observation.iframe = static_cast<int>(f);
        problem.observations.push_back(observation);
        problem.frames.push_back(poseFromIsometry(input.T_camera_target[f] * T_target_board));
        for (size_t c = 0; c < view.corners.size(); ++c) {
            const Corner& corner = view.corners[c];
            if (corner.id < 0 || static_cast<size_t>(corner.id) >= npoints) {
                return fail(ErrorCode::kInvalidArgument,
                            "view " + view.source + ": corner id " + std::to_string(corner.id) +
                                " is not on the target's " + std::to_string(npoints) +
                                "-point grid");
            }
            mrcal_point3_t& slot = problem.pool[f * npoints + static_cast<size_t>(corner.id)];
            slot.x = corner.pixel.x();
            slot.y = corner.pixel.y();
            slot.z = input.inlier[f][c] && corner.weight > 0 ? corner.weight : -1.0;
        }
    }

    // Stage 1, as mrcal-calibrate-cameras: the intrinsics core and the board poses with the
    // distortion held (splined models: a plain stereographic lens, whose core they share).
    const bool splined = lens->type == MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC;
    const int nparams = mrcal_lensmodel_num_params(&*lens);
    std::vector<double> intrinsics = {input.seed.fx, input.seed.fy, input.seed.cx, input.seed.cy};
    const std::optional<mrcal_lensmodel_t> seed_lens = mrcalLensModel(input.seed);
    const bool seed_matches = seed_lens &&
                              mrcalLensModelName(*seed_lens) == mrcalLensModelName(*lens) &&
                              static_cast<int>(input.seed.distortion.size()) + 4 == nparams;
    progress(0.0, "mrcal: intrinsics core and board poses");
    // A splined seed of the same configuration already holds a core and a spline made for each
    // other: a stereographic pre-solve would move the core under the spline.
    if (splined && !seed_matches) {
        const mrcal_lensmodel_t stereographic = makeMrcalLensModel(MRCAL_LENSMODEL_STEREOGRAPHIC);
        const mrcal_stats_t stats =
            problem.optimize(stereographic, intrinsics, selections(true, false, false, false));
        if (!converged(stats))
            return fail(kNotConverged, "the stereographic pre-solve failed");
    }
    if (seed_matches) {
        intrinsics.insert(intrinsics.end(), input.seed.distortion.begin(),
                          input.seed.distortion.end());
    } else {
        intrinsics.resize(static_cast<size_t>(nparams), 0.0);
    }
    if (!splined && nparams > 4) {
        const mrcal_stats_t stats =
            problem.optimize(*lens, intrinsics, selections(true, false, false, false));
        if (!converged(stats))
            return fail(kNotConverged, "the intrinsics-core pre-solve failed");
    }

    // Stage 2: the full model, regularised as mrcal does by default (the splined model's core
    // stays fixed: the spline can absorb it, so it is not observable). With outlier rejection
    // mrcal-calibrate-cameras solves it twice, the second time from the first one's optimum
    // and outliers: σ, now over fewer corners, can put more of them past the threshold.
    progress(0.4, "mrcal: full model");
    const bool reject = options.outlier_sigma > 0;
    const mrcal_problem_selections_t full = selections(!splined, true, true, reject);
    for (int pass = 0; pass < (reject ? 2 : 1); ++pass) {
        const mrcal_stats_t stats = problem.optimize(*lens, intrinsics, full);
        if (!converged(stats))
            return fail(kNotConverged, "mrcal_optimize did not converge");
    }

    progress(0.8, "mrcal: covariance");
    CameraCalibration result;
    result.camera = views.camera;
    result.solver = Solver::kMrcal;
    const std::optional<CameraModel> model =
        cameraModelFromMrcal(*lens, intrinsics.data(), views.width, views.height);
    if (!model)
        return fail(kNotConverged, "no mixray lens for " + mrcalLensModelName(*lens));
    result.model = *model;
    if (Status valid = result.model.validate(); !valid.isOk())
        return fail(kNotConverged, "the solved model: " + valid.message());

    auto covariance =
        stateCovariance(problem, *lens, intrinsics, full, static_cast<size_t>(nparams));
    if (!covariance)
        return covariance.status();
    result.covariance = std::move(*covariance);

    // The corners mrcal rejected leave the inliers (their weights in the pool are negative).
    SolveInput solved = input;
    for (size_t f = 0; f < solved.used.size(); ++f) {
        const TargetView& view = views.views[solved.used[f]];
        for (size_t c = 0; c < view.corners.size(); ++c) {
            const size_t slot = f * npoints + static_cast<size_t>(view.corners[c].id);
            if (problem.pool[slot].z < 0)
                solved.inlier[f][c] = false;
        }
    }

    // An inlier the solved model cannot project is left out of the RMS values, not refused:
    // mrcal judged the solve itself.
    std::vector<Eigen::Isometry3d> T_camera_target;
    for (size_t f = 0; f < input.used.size(); ++f)
        T_camera_target.push_back(isometryFromPose(problem.frames[f]) * T_target_board.inverse());
    std::vector<Eigen::Vector3d> points;
    for (size_t id = 0; id < npoints; ++id) {
        const int i = static_cast<int>(id);
        points.emplace_back(grid->origin.x() + grid->spacing * (i % grid->width_n),
                            grid->origin.y() + grid->spacing * (i / grid->width_n), 0);
    }
    fillResiduals(solved, T_camera_target, points, result);
    progress(1.0, "mrcal: done");
    return result;
}

}  // namespace mixray::calibration::detail
