// calibrateCamera()'s front end: input checks naming the cause, seeding (intrinsics from a
// focal-length search through per-view PnP, OpenCV's homography estimate among the
// candidates), the degenerate-views check, the outlier loop and the dispatch to the Ceres or
// mrcal back end.
#include "mixray/calibration/calibrate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <set>
#include <sstream>
#include <string>

#include "ceres_util.h"
#include "solve_internal.h"

namespace mixray::calibration {

namespace {

// The outlier loop stops after this many re-solves even if the threshold still bites (a solve
// that keeps moving as points leave it); it settles in one to three on real data.
constexpr int kMaxOutlierRounds = 10;

// σ of a Gaussian over its median absolute deviation (from 0: the residuals' mean is 0).
constexpr double kMadToSigma = 1.4826;

// Rays further than this from the optical axis are left out of the PnP that seeds a view's
// pose: their pinhole normalised coordinates blow up (tan θ → ∞ at 90°).
constexpr double kMaxSeedRayAngleRad = 80.0 * std::numbers::pi / 180.0;

// Focal lengths tried when seeding, as multiples of the image diagonal: from a 190°
// fish-eye (0.05) to a telephoto (4), a factor 2^(1/4) apart.
constexpr double kMinSeedFocal = 1.0 / 20;
constexpr double kMaxSeedFocal = 4.0;
constexpr double kSeedFocalStep = 1.189207115002721;  // 2^(1/4)

// Views used to score each candidate focal length: enough to outvote a bad view, few enough
// to keep seeding cheap.
constexpr size_t kSeedViews = 8;

struct ModelSpec {
    LensModel lens = LensModel::kPinhole;
    int distortion = 0;
    bool ceres = true;  // Ceres has it (else mrcal only)
};

std::optional<ModelSpec> parseModel(std::string_view name) {
    if (name == "opencv4" || name == "LENSMODEL_OPENCV4")
        return ModelSpec{LensModel::kPinhole, 4, true};
    if (name == "opencv5" || name == "LENSMODEL_OPENCV5")
        return ModelSpec{LensModel::kPinhole, 5, true};
    if (name == "opencv8" || name == "LENSMODEL_OPENCV8")
        return ModelSpec{LensModel::kPinhole, 8, true};
    if (name == "fisheye")
        return ModelSpec{LensModel::kFisheye, 4, true};
    // mrcal's own models (stereographic, splined): seeded as a stereographic lens, whose core
    // they share and which, unlike a pinhole, sees wide fields of view.
    if (detail::mrcalHasModel(name))
        return ModelSpec{LensModel::kStereographic, 0, false};
    return std::nullopt;
}

Status invalid(const std::string& camera, const std::string& message) {
    return Status(ErrorCode::kInvalidArgument, "camera '" + camera + "': " + message);
}

void report(const CalibrationOptions& options, double fraction, std::string_view stage) {
    if (options.progress)
        options.progress(fraction, stage);
}

// A view's pose by PnP through `model` (its distortion included), and its RMS reprojection
// error through the model; nullopt when the view cannot be posed.
struct SeedPose {
    Eigen::Isometry3d T_camera_target;
    double rms_px;
};

std::optional<SeedPose> poseView(const CameraModel& model, const TargetView& view,
                                 const std::vector<Eigen::Vector3d>& points) {
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> normalised;
    for (const Corner& corner : view.corners) {
        const auto ray = model.unproject(corner.pixel);
        if (!ray || !(ray->z() > std::cos(kMaxSeedRayAngleRad)))
            continue;
        const Eigen::Vector3d& p = points[static_cast<size_t>(corner.id)];
        object.emplace_back(p.x(), p.y(), p.z());
        normalised.emplace_back(ray->x() / ray->z(), ray->y() / ray->z());
    }
    if (object.size() < 4)
        return std::nullopt;
    cv::Mat rvec, tvec;
    try {
        if (!cv::solvePnP(object, normalised, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvec, tvec,
                          false, cv::SOLVEPNP_IPPE))
            return std::nullopt;
    } catch (const cv::Exception&) {
        return std::nullopt;
    }
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    SeedPose out;
    out.T_camera_target = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c)
            out.T_camera_target.linear()(r, c) = R.at<double>(r, c);
        out.T_camera_target.translation()[r] = tvec.at<double>(r);
    }
    if (!out.T_camera_target.matrix().allFinite())
        return std::nullopt;
    double sum2 = 0;
    for (const Corner& corner : view.corners) {
        const auto projected =
            model.project(out.T_camera_target * points[static_cast<size_t>(corner.id)]);
        if (!projected)
            return std::nullopt;
        sum2 += (*projected - corner.pixel).squaredNorm();
    }
    out.rms_px = std::sqrt(sum2 / static_cast<double>(view.corners.size()));
    return out;
}

// How well a candidate model explains the views: the median per-view RMS after PnP (views
// that cannot be posed count as infinitely bad).
double seedScore(const CameraModel& model, const std::vector<const TargetView*>& views,
                 const std::vector<Eigen::Vector3d>& points) {
    std::vector<double> rms;
    for (const TargetView* view : views) {
        const auto pose = poseView(model, *view, points);
        rms.push_back(pose ? pose->rms_px : std::numeric_limits<double>::infinity());
    }
    std::nth_element(rms.begin(), rms.begin() + static_cast<std::ptrdiff_t>(rms.size() / 2),
                     rms.end());
    return rms[rms.size() / 2];
}

// OpenCV's closed-form focal length from the views' homographies (principal point at the
// centre); nullopt when it is not a usable number (degenerate views).
std::optional<double> homographyFocal(const std::vector<const TargetView*>& views,
                                      const std::vector<Eigen::Vector3d>& points, int width,
                                      int height) {
    std::vector<std::vector<cv::Point3f>> object;
    std::vector<std::vector<cv::Point2f>> image;
    for (const TargetView* view : views) {
        object.emplace_back();
        image.emplace_back();
        for (const Corner& corner : view->corners) {
            const Eigen::Vector3d& p = points[static_cast<size_t>(corner.id)];
            object.back().emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                       static_cast<float>(p.z()));
            image.back().emplace_back(static_cast<float>(corner.pixel.x()),
                                      static_cast<float>(corner.pixel.y()));
        }
    }
    try {
        const cv::Mat K = cv::initCameraMatrix2D(object, image, cv::Size(width, height), 1.0);
        const double f = K.at<double>(0, 0);
        if (std::isfinite(f) && f > 0)
            return f;
    } catch (const cv::Exception&) {
    }
    return std::nullopt;
}

// Views spread evenly over `views`, at most `count`.
std::vector<const TargetView*> spread(const std::vector<const TargetView*>& views, size_t count) {
    if (views.size() <= count)
        return views;
    std::vector<const TargetView*> out;
    for (size_t i = 0; i < count; ++i)
        out.push_back(views[i * views.size() / count]);
    return out;
}

double angleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::atan2(a.cross(b).norm(), a.dot(b));
}

std::string describeRejections(const std::map<std::string, int>& counts) {
    std::string out;
    for (const auto& [why, count] : counts)
        out += (out.empty() ? "" : ", ") + std::to_string(count) + " " + why;
    return out;
}

Status validateOptions(const CalibrationOptions& options, const std::string& camera) {
    if (options.min_views < 1)
        return invalid(camera, "min_views must be >= 1");
    if (options.min_corners_per_view < 4)
        return invalid(camera, "min_corners_per_view must be >= 4 (a pose needs 4 points)");
    if (!std::isfinite(options.outlier_sigma))
        return invalid(camera, "outlier_sigma must be finite (<= 0 disables outlier rejection)");
    if (!(options.min_tilt_spread_deg >= 0))
        return invalid(camera, "min_tilt_spread_deg must be >= 0");
    return Status::ok();
}

// kInvalidArgument when the board normals of all views lie within min_tilt_spread_deg.
Status checkTiltSpread(const std::vector<Eigen::Isometry3d>& T_camera_target,
                       const CalibrationOptions& options, const std::string& camera) {
    double spread_rad = 0;
    for (size_t a = 0; a < T_camera_target.size(); ++a) {
        for (size_t b = a + 1; b < T_camera_target.size(); ++b) {
            spread_rad = std::max(spread_rad, angleBetween(T_camera_target[a].linear().col(2),
                                                           T_camera_target[b].linear().col(2)));
        }
    }
    const double spread_deg = spread_rad * 180 / std::numbers::pi;
    if (spread_deg >= options.min_tilt_spread_deg)
        return Status::ok();
    std::ostringstream message;
    message.precision(3);
    message << "degenerate views: the board normals of all " << T_camera_target.size()
            << " usable views lie within " << spread_deg << " deg of each other (need "
            << options.min_tilt_spread_deg
            << "): fronto-parallel views leave the focal length unobservable; tilt the board";
    return invalid(camera, message.str());
}

}  // namespace

std::string_view toString(Solver solver) {
    switch (solver) {
        case Solver::kAuto:
            return "auto";
        case Solver::kCeres:
            return "ceres";
        case Solver::kMrcal:
            return "mrcal";
    }
    return "unknown";
}

std::optional<Solver> solverFromString(std::string_view name) {
    for (Solver solver : {Solver::kAuto, Solver::kCeres, Solver::kMrcal}) {
        if (name == toString(solver))
            return solver;
    }
    return std::nullopt;
}

Eigen::VectorXd CameraCalibration::intrinsicsStddev() const {
    const Eigen::Index n =
        std::min<Eigen::Index>(static_cast<Eigen::Index>(4 + model.distortion.size()),
                               std::min(covariance.rows(), covariance.cols()));
    return covariance.diagonal().head(n).cwiseMax(0.0).cwiseSqrt();
}

Result<CameraCalibration> calibrateCamera(const CameraViews& views,
                                          const CalibrationOptions& options) {
    const std::string& camera = views.camera;
    report(options, 0.0, "checking views");
    MIXRAY_RETURN_IF_ERROR(validateOptions(options, camera));

    const std::optional<ModelSpec> spec = parseModel(options.model);
    if (!spec) {
        return invalid(camera, "unknown lens model '" + options.model +
                                   "' (opencv4, opencv5, opencv8, fisheye, stereographic or "
                                   "a mrcal LENSMODEL_... name that mrcal has)");
    }
    const bool mrcal_has = detail::mrcalHasModel(options.model);
    Solver solver = options.solver;
    if (solver == Solver::kAuto)
        solver = mrcal_has && (!spec->ceres || !options.fix_aspect_ratio) ? Solver::kMrcal
                                                                          : Solver::kCeres;
    if (solver == Solver::kCeres && !spec->ceres) {
        return invalid(camera, "the Ceres solver does not have lens model '" + options.model +
                                   "' (mrcal does: use the mrcal solver)");
    }
    if (solver == Solver::kMrcal && !mrcal_has) {
        return invalid(camera, "the mrcal solver does not have lens model '" + options.model +
                                   "' (use the Ceres solver)");
    }
    if (solver == Solver::kMrcal && options.fix_aspect_ratio)
        return invalid(camera, "fix_aspect_ratio is supported by the Ceres solver only");

    // Without a single readable image the size is unknown: the view count below says why.
    if ((views.width <= 0 || views.height <= 0) && !views.usable().empty()) {
        return invalid(camera, "image size " + std::to_string(views.width) + "x" +
                                   std::to_string(views.height) + " must be positive");
    }
    if (Status target = views.target.validate(); !target)
        return invalid(camera, target.message());
    const std::vector<Eigen::Vector3d> points = views.target.points();

    // Which views can be used, and why the others cannot.
    detail::SolveInput input;
    input.views = &views;
    std::map<std::string, int> rejected;
    std::vector<const TargetView*> used_views;
    for (size_t v = 0; v < views.views.size(); ++v) {
        const TargetView& view = views.views[v];
        if (view.rejection != ViewRejection::kNone) {
            ++rejected[std::string(toString(view.rejection))];
            continue;
        }
        std::set<int> ids;
        for (const Corner& corner : view.corners) {
            if (corner.id < 0 || corner.id >= static_cast<int>(points.size())) {
                return invalid(camera, "view '" + view.source + "': corner id " +
                                           std::to_string(corner.id) + " is not on the " +
                                           std::string(toString(views.target.kind)) + " target (" +
                                           std::to_string(points.size()) + " points)");
            }
            if (!ids.insert(corner.id).second) {
                return invalid(camera, "view '" + view.source + "': corner id " +
                                           std::to_string(corner.id) + " appears twice");
            }
            if (!corner.pixel.allFinite() || !(corner.weight > 0)) {
                return invalid(camera, "view '" + view.source + "': corner " +
                                           std::to_string(corner.id) +
                                           " has a non-finite pixel or a weight <= 0");
            }
            // Pixel centres are integers, so the image spans [-0.5, size - 0.5].
            if (corner.pixel.x() < -0.5 || corner.pixel.y() < -0.5 ||
                corner.pixel.x() > views.width - 0.5 || corner.pixel.y() > views.height - 0.5) {
                std::ostringstream where;
                where << "(" << corner.pixel.x() << ", " << corner.pixel.y() << ")";
                return invalid(camera, "view '" + view.source + "': corner " +
                                           std::to_string(corner.id) + " at " + where.str() +
                                           " lies outside the " + std::to_string(views.width) +
                                           "x" + std::to_string(views.height) +
                                           " image: mismatched image sizes");
            }
        }
        if (static_cast<int>(view.corners.size()) < options.min_corners_per_view) {
            ++rejected["with too few corners (< " + std::to_string(options.min_corners_per_view) +
                       ")"];
            continue;
        }
        input.used.push_back(v);
        used_views.push_back(&view);
    }
    auto tooFew = [&](size_t usable) {
        std::string message = "too few usable views: " + std::to_string(usable) + " of " +
                              std::to_string(views.views.size()) + ", need " +
                              std::to_string(options.min_views);
        if (!rejected.empty())
            message += " (left out: " + describeRejections(rejected) + ")";
        return invalid(camera, message);
    };
    if (static_cast<int>(used_views.size()) < options.min_views)
        return tooFew(used_views.size());

    // Seed: the focal length whose per-view PnP explains the corners best, principal point at
    // the centre, no distortion. OpenCV's homography estimate joins the candidates for pinhole
    // lenses; the fish-eye is seeded as an ideal equidistant lens.
    report(options, 0.05, "seeding");
    CameraModel candidate = CameraModel::pinhole(views.width, views.height, 1, 1,
                                                 0.5 * (views.width - 1), 0.5 * (views.height - 1));
    candidate.lens = spec->lens;
    if (spec->lens == LensModel::kFisheye)
        candidate.distortion.assign(4, 0.0);
    const double diagonal = std::hypot(views.width, views.height);
    std::vector<double> focals;
    for (double f = kMinSeedFocal; f <= kMaxSeedFocal; f *= kSeedFocalStep)
        focals.push_back(f * diagonal);
    if (spec->lens == LensModel::kPinhole) {
        if (auto f = homographyFocal(used_views, points, views.width, views.height))
            focals.push_back(*f);
    }
    const std::vector<const TargetView*> scoring = spread(used_views, kSeedViews);
    double best_score = std::numeric_limits<double>::infinity();
    double best_focal = 0;
    for (double f : focals) {
        candidate.fx = candidate.fy = f;
        const double score = seedScore(candidate, scoring, points);
        if (score < best_score) {
            best_score = score;
            best_focal = f;
        }
    }
    if (!std::isfinite(best_score))
        return invalid(camera,
                       "no focal length poses the views: the corners do not fit the "
                       "target");
    candidate.fx = candidate.fy = best_focal;
    input.seed = candidate;
    if (spec->ceres && spec->lens == LensModel::kPinhole)
        input.seed.distortion.assign(static_cast<size_t>(spec->distortion), 0.0);

    std::vector<size_t> posed;
    for (size_t u = 0; u < input.used.size(); ++u) {
        const auto pose = poseView(candidate, *used_views[u], points);
        if (!pose) {
            ++rejected["that could not be posed"];
            continue;
        }
        posed.push_back(input.used[u]);
        input.T_camera_target.push_back(pose->T_camera_target);
    }
    input.used = posed;
    if (static_cast<int>(input.used.size()) < options.min_views)
        return tooFew(input.used.size());

    // The focal length is observable only from views whose boards are tilted differently. The
    // seed's poses ignore the distortion, so the check repeats on the solved poses.
    MIXRAY_RETURN_IF_ERROR(checkTiltSpread(input.T_camera_target, options, camera));

    for (size_t v : input.used)
        input.inlier.emplace_back(views.views[v].corners.size(), true);

    // Solve, drop the corners beyond outlier_sigma standard deviations, repeat.
    Result<CameraCalibration> result = Status(ErrorCode::kInternal, "not solved");
    for (int round = 0; round <= kMaxOutlierRounds; ++round) {
        // Round r takes the progress from 1 − 2^−r to 1 − 2^−(r+1) of the solving share, so
        // the fractions keep rising however many rounds it takes; the back end reports
        // within its round's share.
        const double lo = 0.1 + 0.85 * (1 - std::ldexp(1.0, -round));
        const double hi = 0.1 + 0.85 * (1 - std::ldexp(1.0, -round - 1));
        report(options, lo, round == 0 ? "solving" : "solving without outliers");
        CalibrationOptions solve_options = options;
        if (options.progress) {
            solve_options.progress = [&](double fraction, std::string_view stage) {
                options.progress(lo + (hi - lo) * std::clamp(fraction, 0.0, 1.0), stage);
            };
        }
        result = solver == Solver::kMrcal ? detail::solveWithMrcal(input, solve_options)
                                          : detail::solveWithCeres(input, solve_options);
        if (!result && round == 0) {
            // A solve that fails on views that only look tilted through the undistorted seed:
            // the poses a plain solve ends on say whether they were degenerate.
            if (auto poses = detail::solvePosesWithCeres(input, options))
                MIXRAY_RETURN_IF_ERROR(checkTiltSpread(*poses, options, camera));
        }
        if (!result)
            return result;
        if (round == 0) {
            std::vector<Eigen::Isometry3d> solved;
            for (const ViewFit& fit : result->views)
                solved.push_back(fit.T_camera_target);
            MIXRAY_RETURN_IF_ERROR(checkTiltSpread(solved, options, camera));
        }
        // The mrcal back end rejects outliers inside mrcal_optimize, as mrcal-calibrate-cameras
        // does; a second rejection here would drop corners mrcal keeps.
        if (options.outlier_sigma <= 0 || solver == Solver::kMrcal || round == kMaxOutlierRounds)
            break;
        // σ per coordinate over the inliers, each residual scaled by its corner's weight as
        // the solve saw it. Estimated from the median absolute residual (σ = 1.4826 MAD for
        // Gaussian noise), which the tail being dropped hardly moves: the loop then settles in
        // a round or two instead of trimming a little more of the Gaussian's tail each round.
        std::map<std::pair<size_t, int>, Eigen::Vector2d> residual;
        for (const PointResidual& point : result->residuals)
            residual[{point.view, point.id}] = point.residual;
        std::vector<double> absolute;
        std::vector<std::vector<double>> scaled(input.used.size());
        for (size_t u = 0; u < input.used.size(); ++u) {
            const TargetView& view = views.views[input.used[u]];
            for (size_t c = 0; c < view.corners.size(); ++c) {
                const auto found = residual.find({input.used[u], view.corners[c].id});
                const Eigen::Vector2d r =
                    found != residual.end()
                        ? Eigen::Vector2d(found->second * std::sqrt(view.corners[c].weight))
                        : Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
                scaled[u].push_back(r.cwiseAbs().maxCoeff());
                if (input.inlier[u][c] && r.allFinite()) {
                    absolute.push_back(std::abs(r.x()));
                    absolute.push_back(std::abs(r.y()));
                }
            }
        }
        if (absolute.empty())
            break;
        const auto middle = absolute.begin() + static_cast<std::ptrdiff_t>(absolute.size() / 2);
        std::nth_element(absolute.begin(), middle, absolute.end());
        const double threshold = options.outlier_sigma * kMadToSigma * *middle;
        bool dropped = false;
        for (size_t u = 0; u < input.used.size(); ++u) {
            for (size_t c = 0; c < scaled[u].size(); ++c) {
                if (input.inlier[u][c] && !(scaled[u][c] <= threshold)) {
                    input.inlier[u][c] = false;
                    dropped = true;
                }
            }
        }
        if (!dropped)
            break;
        input.seed = result->model;
        for (const ViewFit& fit : result->views) {
            const auto u = std::find(input.used.begin(), input.used.end(), fit.view);
            if (u != input.used.end())
                input.T_camera_target[static_cast<size_t>(u - input.used.begin())] =
                    fit.T_camera_target;
        }
    }
    report(options, 1.0, "done");
    return result;
}

namespace detail {

std::optional<std::pair<size_t, size_t>> fillResiduals(
    const SolveInput& input, const std::vector<Eigen::Isometry3d>& T_camera_target,
    const std::vector<Eigen::Vector3d>& points, CameraCalibration& out) {
    const CameraViews& views = *input.views;
    std::optional<std::pair<size_t, size_t>> unprojected;
    double sum2 = 0;
    int inliers = 0;
    for (size_t u = 0; u < input.used.size(); ++u) {
        const TargetView& view = views.views[input.used[u]];
        ViewFit fit;
        fit.view = input.used[u];
        fit.T_camera_target = T_camera_target[u];
        fit.corners = static_cast<int>(view.corners.size());
        double view_sum2 = 0;
        int view_inliers = 0;
        for (size_t c = 0; c < view.corners.size(); ++c) {
            const Corner& corner = view.corners[c];
            PointResidual point;
            point.view = input.used[u];
            point.id = corner.id;
            point.observed = corner.pixel;
            point.outlier = !input.inlier[u][c];
            const auto projected =
                out.model.project(fit.T_camera_target * points[static_cast<size_t>(corner.id)]);
            point.residual =
                projected ? Eigen::Vector2d(*projected - corner.pixel)
                          : Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
            if (point.outlier) {
                ++fit.outliers;
            } else if (projected) {
                view_sum2 += point.residual.squaredNorm();
                ++view_inliers;
            } else if (!unprojected) {
                unprojected = std::pair{u, c};
            }
            out.residuals.push_back(point);
        }
        fit.rms_px = view_inliers > 0 ? std::sqrt(view_sum2 / view_inliers) : 0;
        sum2 += view_sum2;
        inliers += view_inliers;
        out.outliers += fit.outliers;
        out.views.push_back(fit);
    }
    out.rms_px = inliers > 0 ? std::sqrt(sum2 / inliers) : 0;
    return unprojected;
}

}  // namespace detail

}  // namespace mixray::calibration
