// calibrateCamera()'s front end: input checks naming the cause (a chessboard larger than
// declared among them), seeding (intrinsics from a focal-length search through per-view PnP,
// OpenCV's homography estimate among the candidates), the outlier loop, the dispatch to the
// Ceres or mrcal back end, and the judgement of the result: its RMS against a corner
// detector's accuracy, and the observability of the intrinsics from the solve's covariance.
#include "mixray/calibration/calibrate.h"

#include <Eigen/Eigenvalues>
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
    if (!(options.max_relative_stddev > 0) || !std::isfinite(options.max_relative_stddev))
        return invalid(camera, "max_relative_stddev must be > 0 and finite");
    if (!(options.min_judged_noise_px >= 0) || !std::isfinite(options.min_judged_noise_px))
        return invalid(camera, "min_judged_noise_px must be >= 0 and finite");
    if (!(options.max_rms_px >= 0) || !std::isfinite(options.max_rms_px))
        return invalid(camera, "max_rms_px must be >= 0 and finite (0: no limit)");
    return Status::ok();
}

// The largest angle between two views' board normals, degrees.
double normalSpreadDeg(const std::vector<Eigen::Isometry3d>& T_camera_target) {
    double spread_rad = 0;
    for (size_t a = 0; a < T_camera_target.size(); ++a) {
        for (size_t b = a + 1; b < T_camera_target.size(); ++b) {
            spread_rad = std::max(spread_rad, angleBetween(T_camera_target[a].linear().col(2),
                                                           T_camera_target[b].linear().col(2)));
        }
    }
    return spread_rad * 180 / std::numbers::pi;
}

std::string fixedText(double value, int decimals) {
    std::ostringstream out;
    out.setf(std::ios::fixed);
    out.precision(decimals);
    out << value;
    return out.str();
}

// Below this spread of the board normals the views are nearly parallel planes, which give a
// calibration the constraints of one view (Zhang 2000, section 3.3): the likely cause of a
// weak solve.
constexpr double kParallelViewsDeg = 10.0;

// Why views leave the intrinsics weak, from their poses: nearly parallel boards, boards tilted
// about one axis only, or else too few and too little varied views.
std::string weakViewsCause(const std::vector<Eigen::Isometry3d>& T_camera_target) {
    const double spread_deg = normalSpreadDeg(T_camera_target);
    const std::string n = std::to_string(T_camera_target.size());
    if (spread_deg < kParallelViewsDeg) {
        return "the board normals of all " + n + " views lie within " + fixedText(spread_deg, 1) +
               " deg of each other (nearly parallel boards constrain the intrinsics like one "
               "view): tilt the board about different axes, 10–30 deg each way";
    }
    // The normals' spread across the image plane: one direction only is a tilt about one
    // axis, which leaves the focal length along the other axis weak.
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Isometry3d& T : T_camera_target)
        mean += T.linear().col(2).head<2>();
    mean /= static_cast<double>(T_camera_target.size());
    for (const Eigen::Isometry3d& T : T_camera_target) {
        const Eigen::Vector2d d = T.linear().col(2).head<2>() - mean;
        scatter += d * d.transpose();
    }
    scatter /= static_cast<double>(T_camera_target.size());
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(scatter);
    const double minor_deg =
        std::asin(std::min(1.0, std::sqrt(std::max(0.0, eigen.eigenvalues()[0])))) * 180 /
        std::numbers::pi;
    if (minor_deg < 0.5 * kParallelViewsDeg) {
        return "the " + n + " views are tilted about one axis only (their normals vary by " +
               fixedText(minor_deg, 1) + " deg across it): tilt the board about the other axis too";
    }
    return "the " + n +
           " views are too few or too alike: add views tilted differently and reaching the "
           "image's corners";
}

const char* const kCoreNames[4] = {"fx", "fy", "cx", "cy"};

// The RMS length of the inliers' residuals, each scaled by its corner's weight as the solve saw
// it (a corner found at mrcal's level l has 2^l times the noise).
double weightedRmsPx(const CameraCalibration& calibration, const CameraViews& views) {
    std::map<std::pair<size_t, int>, double> weight;
    for (const ViewFit& fit : calibration.views)
        for (const Corner& corner : views.views[fit.view].corners)
            weight[{fit.view, corner.id}] = corner.weight;
    double sum2 = 0;
    size_t count = 0;
    for (const PointResidual& point : calibration.residuals) {
        if (point.outlier || !point.residual.allFinite())
            continue;
        sum2 += weight[{point.view, point.id}] * point.residual.squaredNorm();
        ++count;
    }
    return count > 0 ? std::sqrt(sum2 / static_cast<double>(count)) : 0;
}

// Observability (calibrate.h) of a solve: the core intrinsics' covariance with the focal
// lengths as unit, scaled to the noise the judgement assumes.
Observability judgeObservability(const CameraCalibration& calibration, const CameraViews& views,
                                 const CalibrationOptions& options) {
    Observability out;
    std::vector<Eigen::Isometry3d> poses;
    for (const ViewFit& fit : calibration.views)
        poses.push_back(fit.T_camera_target);
    out.normal_spread_deg = normalSpreadDeg(poses);
    if (calibration.covariance.rows() < 4 || calibration.covariance.cols() < 4)
        return out;

    // The residual noise per coordinate as the solve weighted it.
    const double observed = weightedRmsPx(calibration, views) / std::sqrt(2.0);
    out.noise_px = std::max(observed, options.min_judged_noise_px);
    const double scale2 = observed > 0 ? (out.noise_px / observed) * (out.noise_px / observed) : 1;

    const CameraModel& m = calibration.model;
    const Eigen::Vector4d unit(m.fx, m.fy, m.fx, m.fy);
    const Eigen::Matrix4d relative = unit.cwiseInverse().asDiagonal() *
                                     calibration.covariance.topLeftCorner<4, 4>() *
                                     unit.cwiseInverse().asDiagonal() * scale2;
    out.relative_stddev = relative.diagonal().cwiseMax(0.0).cwiseSqrt();

    // The condition over the parameters the solve moved independently: fx = fy (fixed aspect
    // ratio) makes them one, a splined model's fixed core none.
    std::vector<int> free;
    for (int k = 0; k < 4; ++k) {
        if (!(relative(k, k) > 0))
            continue;
        if (k == 1 && options.fix_aspect_ratio && !free.empty() && free.front() == 0)
            continue;
        free.push_back(k);
    }
    if (free.size() >= 2) {
        Eigen::MatrixXd sub(free.size(), free.size());
        for (size_t a = 0; a < free.size(); ++a)
            for (size_t b = 0; b < free.size(); ++b)
                sub(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) =
                    relative(free[a], free[b]);
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(sub);
        const Eigen::VectorXd& lambda = eigen.eigenvalues();
        const Eigen::Index last = lambda.size() - 1;
        out.condition =
            lambda[0] > 0 ? lambda[last] / lambda[0] : std::numeric_limits<double>::infinity();
        for (size_t a = 0; a < free.size(); ++a)
            out.weakest[free[a]] = eigen.eigenvectors()(static_cast<Eigen::Index>(a), last);
        // The sign of the largest component positive, for reading.
        Eigen::Index largest = 0;
        out.weakest.cwiseAbs().maxCoeff(&largest);
        if (out.weakest[largest] < 0)
            out.weakest = -out.weakest;
    }

    std::string names, values;
    for (int k = 0; k < 4; ++k) {
        if (!(out.relative_stddev[k] > options.max_relative_stddev))
            continue;
        out.weak.push_back(kCoreNames[k]);
        names += (names.empty() ? "" : ", ") + std::string(kCoreNames[k]);
        values += (values.empty() ? "" : ", ") + fixedText(100 * out.relative_stddev[k], 1) + " %";
    }
    if (out.weak.empty())
        return out;
    std::string direction;
    for (int k = 0; k < 4; ++k) {
        if (std::abs(out.weakest[k]) < 0.2)
            continue;
        direction += direction.empty() ? (out.weakest[k] < 0 ? "-" : "")
                                       : (out.weakest[k] < 0 ? " - " : " + ");
        direction += fixedText(std::abs(out.weakest[k]), 2) + " " + kCoreNames[k];
    }
    std::ostringstream condition;
    condition.precision(2);
    condition << out.condition;
    out.summary = names + ": 1σ " + values + " of the focal length (limit " +
                  fixedText(100 * options.max_relative_stddev, 1) + " %, at " +
                  fixedText(out.noise_px, 2) + " px corner noise); worst determined: " + direction +
                  " (condition " + condition.str() + "); " + weakViewsCause(poses);
    return out;
}

// A calibration is refused when this share of the views the chessboard was found in show it
// going on beyond the corners found: a few such views among many may be a larger board seen
// nearby, most of them say the target was declared smaller than printed.
constexpr int kLargerBoardShareDenominator = 4;

// kInvalidArgument naming the likely size when enough views are kLargerBoard.
Status checkLargerBoard(const CameraViews& views) {
    int found = 0, larger = 0;
    std::map<std::pair<int, int>, int> sizes;
    std::string example;
    for (const TargetView& view : views.views) {
        if (view.corners.empty() && view.rejection != ViewRejection::kLargerBoard)
            continue;
        ++found;
        if (view.rejection != ViewRejection::kLargerBoard)
            continue;
        ++larger;
        if (example.empty())
            example = view.source + ": " + view.why;
        if (view.seen_cols > 0 && view.seen_rows > 0)
            ++sizes[{view.seen_cols, view.seen_rows}];
    }
    if (larger == 0 || larger * kLargerBoardShareDenominator < found)
        return Status::ok();
    const CalibrationTarget& target = views.target;
    std::string message = "in " + std::to_string(larger) + " of " + std::to_string(found) +
                          " views the chessboard's X-junctions go on beyond the " +
                          std::to_string(target.cols) + "x" + std::to_string(target.rows) +
                          " corners found";
    if (!sizes.empty()) {
        const auto likely =
            std::max_element(sizes.begin(), sizes.end(),
                             [](const auto& a, const auto& b) { return a.second < b.second; });
        CalibrationTarget seen = target;
        seen.cols = likely->first.first;
        seen.rows = likely->first.second;
        message += ": the board looks like " + std::to_string(seen.cols) + "x" +
                   std::to_string(seen.rows) + " inner corners, not " +
                   std::to_string(target.cols) + "x" + std::to_string(target.rows) + " (target " +
                   seen.spec() + ", mixray calibrate --target " + seen.spec() + ")";
    } else {
        message += " (" + example + "): the board is larger than declared";
    }
    return invalid(views.camera, message);
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
    MIXRAY_RETURN_IF_ERROR(checkLargerBoard(views));
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
            // A solve that fails on degenerate views (a singular covariance): the poses a plain
            // solve ends on say whether, and why, they were.
            if (auto poses = detail::solvePosesWithCeres(input, options);
                poses && normalSpreadDeg(*poses) < kParallelViewsDeg) {
                return Status(ErrorCode::kInvalidArgument,
                              result.status().message() + "; " + weakViewsCause(*poses));
            }
        }
        if (!result)
            return result;
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

    // A fit far worse than any corner detector's accuracy is a failure, not a result.
    if (options.max_rms_px > 0) {
        const double rms = weightedRmsPx(*result, views);
        if (rms > options.max_rms_px) {
            return invalid(camera,
                           "RMS reprojection error " + fixedText(rms, 2) + " px over " +
                               std::to_string(result->views.size()) +
                               " views is far above a corner detector's 0.1–0.3 px (limit " +
                               fixedText(options.max_rms_px, 2) +
                               " px): the corners do not fit one camera and board (a board "
                               "declared smaller than printed, found at a different place in "
                               "each view; a lens model that cannot follow the lens; views of "
                               "another camera); raise max_rms_px (mixray calibrate --max-rms) "
                               "only if the corners are known to be this poor");
        }
    }

    // Observability from the solve: the core intrinsics' uncertainty and the condition of
    // their normal equations.
    result->observability = judgeObservability(*result, views, options);
    if (!result->observability.weak.empty() && !options.accept_weak) {
        return invalid(camera, "weakly determined intrinsics: " + result->observability.summary +
                                   "; or keep the result with its uncertainty (accept_weak, "
                                   "mixray calibrate --accept-weak)");
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
