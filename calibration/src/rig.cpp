// calibrateRig(): each camera's own calibration, camera poses seeded through chains of
// simultaneous views (breadth-first over the co-visibility graph, by the consensus of the
// shared views in their agreeing board symmetry), every key's views put in one corner order,
// then Ceres bundle adjustments of every camera's pose and the target's pose at every key,
// optionally with the intrinsics, dropping views that disagree, and the poses' covariances.
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <utility>

#include "ceres_util.h"
#include "mixray/calibration/calibrate.h"
#include "reprojection_cost.h"
#include "solve_internal.h"

namespace mixray::calibration {

namespace {

Status invalid(const std::string& message) {
    return Status(ErrorCode::kInvalidArgument, "rig: " + message);
}

// Views of one instant agree when their poses differ by less than this rotation and this
// fraction of the board's distance: several times what the per-view poses of converged solves
// differ by, and far below the 90° between a board's symmetric corner orders.
constexpr double kAgreeDeg = 5.0;
constexpr double kAgreeFraction = 0.1;

// A turn of the board in its plane that maps its point grid onto itself. A chessboard's corners
// alone do not say which way round it lies: OpenCV's detector numbers some views from the
// opposite corner, which a camera's own solve cannot notice (the view's pose just turns).
struct BoardSymmetry {
    int rotation_deg = 0;
    Eigen::Isometry3d S = Eigen::Isometry3d::Identity();  // point id i → the point of perm[i]
    std::vector<int> perm;
};

// The identity, and for chessboards the turn by 180° and on square ones by 90° and 270°.
// ChArUco and AprilGrid points have unique ids: only the identity.
std::vector<BoardSymmetry> boardSymmetries(const CalibrationTarget& target) {
    const std::vector<Eigen::Vector3d> points = target.points();
    std::vector<BoardSymmetry> out(1);
    out[0].perm.resize(points.size());
    for (size_t i = 0; i < points.size(); ++i)
        out[0].perm[i] = static_cast<int>(i);
    if (target.kind != TargetKind::kChessboard || target.square_m <= 0)
        return out;
    const Eigen::Vector3d centre((target.cols - 1) * target.square_m / 2,
                                 (target.rows - 1) * target.square_m / 2, 0);
    for (int deg : {90, 180, 270}) {
        if (deg != 180 && target.cols != target.rows)
            continue;
        BoardSymmetry symmetry;
        symmetry.rotation_deg = deg;
        symmetry.S.linear() =
            Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        symmetry.S.translation() = centre - symmetry.S.linear() * centre;
        for (const Eigen::Vector3d& p : points) {
            const Eigen::Vector3d q = symmetry.S * p;
            const long col = std::lround(q.x() / target.square_m);
            const long row = std::lround(q.y() / target.square_m);
            symmetry.perm.push_back(static_cast<int>(row * target.cols + col));
        }
        out.push_back(std::move(symmetry));
    }
    return out;
}

// One camera's view of the target at one key, from its own calibration.
struct Sighting {
    size_t camera;
    size_t fit;                         // index into CameraCalibration::views
    Eigen::Isometry3d T_camera_target;  // its own solve's, in the detector's corner order
    std::set<int> outliers;             // corner ids its own solve rejected
    size_t symmetry = 0;                // index into the camera's boardSymmetries()
    bool dropped = false;
    double rms_px = 0;  // in the latest joint solve
};

// The pose in the corner order of `symmetry`: the detector's label i is the point perm[i].
Eigen::Isometry3d reordered(const Sighting& s, const BoardSymmetry& symmetry) {
    return s.T_camera_target * symmetry.S.inverse();
}

struct PoseGap {
    double deg = 0;
    double m = 0;
};

PoseGap gapOf(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return {Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180 / M_PI,
            (a.translation() - b.translation()).norm()};
}

bool agrees(const PoseGap& gap, double scale_m) {
    return gap.deg < kAgreeDeg && gap.m <= kAgreeFraction * scale_m;
}

// Estimates of one pose, several candidates each (one per board symmetry): the hypothesis
// (one item's candidate; only its first with `any_anchor` false) that most items have a
// candidate agreeing with, and for each item its closest agreeing candidate (-1: none).
struct Consensus {
    Eigen::Isometry3d hypothesis = Eigen::Isometry3d::Identity();
    std::vector<int> choice;
    size_t agreeing = 0;
};

Consensus consensus(const std::vector<std::vector<Eigen::Isometry3d>>& candidates,
                    const std::vector<double>& scale_m, bool any_anchor) {
    Consensus best;
    double best_sum = 0;
    for (size_t h = 0; h < candidates.size(); ++h) {
        const size_t anchors = any_anchor ? candidates[h].size() : 1;
        for (size_t a = 0; a < anchors; ++a) {
            Consensus trial{candidates[h][a], std::vector<int>(candidates.size(), -1), 0};
            double sum = 0;
            for (size_t i = 0; i < candidates.size(); ++i) {
                double closest = 0;
                for (size_t s = 0; s < candidates[i].size(); ++s) {
                    const PoseGap gap = gapOf(candidates[i][s], trial.hypothesis);
                    if (agrees(gap, std::max(scale_m[i], scale_m[h])) &&
                        (trial.choice[i] < 0 || gap.deg < closest)) {
                        trial.choice[i] = static_cast<int>(s);
                        closest = gap.deg;
                    }
                }
                if (trial.choice[i] >= 0) {
                    ++trial.agreeing;
                    sum += closest;
                }
            }
            // Among anchors of their own order, ties keep the first (the lower camera index).
            if (trial.agreeing > best.agreeing ||
                (any_anchor && trial.agreeing == best.agreeing && sum < best_sum)) {
                best = std::move(trial);
                best_sum = sum;
            }
        }
    }
    return best;
}

// The mean of several estimates of one pose: quaternions averaged on the first one's
// hemisphere (the estimates agree to noise, where that is the chordal mean), translations
// averaged.
Eigen::Isometry3d meanPose(const std::vector<Eigen::Isometry3d>& poses) {
    const Eigen::Quaterniond first(poses.front().linear());
    Eigen::Vector4d q_sum = Eigen::Vector4d::Zero();
    Eigen::Vector3d t_sum = Eigen::Vector3d::Zero();
    for (const Eigen::Isometry3d& T : poses) {
        const Eigen::Quaterniond q(T.linear());
        q_sum += (q.coeffs().dot(first.coeffs()) < 0 ? -1.0 : 1.0) * q.coeffs();
        t_sum += T.translation();
    }
    Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
    out.linear() = Eigen::Quaterniond(q_sum.normalized()).toRotationMatrix();
    out.translation() = t_sum / static_cast<double>(poses.size());
    return out;
}

// d(rt of T⁻¹)/d(rt of T) at `rt`, by central differences: carries a pose covariance from
// T_camera_ref to T_ref_camera.
Eigen::Matrix<double, 6, 6> inverseJacobian(const detail::Vector6d& rt) {
    Eigen::Matrix<double, 6, 6> J;
    constexpr double h = 1e-7;
    for (int i = 0; i < 6; ++i) {
        detail::Vector6d plus = rt, minus = rt;
        plus[i] += h;
        minus[i] -= h;
        J.col(i) = (detail::toRt(detail::fromRt(plus.data()).inverse()) -
                    detail::toRt(detail::fromRt(minus.data()).inverse())) /
                   (2 * h);
    }
    return J;
}

Status unlinkedError(const std::vector<size_t>& unlinked, const std::vector<CameraViews>& views,
                     size_t ref) {
    std::string names;
    for (size_t i : unlinked)
        names += (names.empty() ? "'" : ", '") + views[i].camera + "'";
    return invalid("camera(s) " + names + " never linked to the reference '" + views[ref].camera +
                   "': no chain of views of the target at equal keys joins them");
}

// Breadth-first over cameras that share keys: every camera must be reached from `ref`.
Status checkLinked(const std::map<int64_t, std::set<size_t>>& keys,
                   const std::vector<CameraViews>& views, size_t ref) {
    std::vector<bool> reached(views.size(), false);
    reached[ref] = true;
    std::deque<size_t> queue = {ref};
    while (!queue.empty()) {
        const size_t a = queue.front();
        queue.pop_front();
        for (const auto& [key, cameras] : keys) {
            if (!cameras.count(a))
                continue;
            for (size_t b : cameras) {
                if (!reached[b]) {
                    reached[b] = true;
                    queue.push_back(b);
                }
            }
        }
    }
    std::vector<size_t> unlinked;
    for (size_t i = 0; i < views.size(); ++i) {
        if (!reached[i])
            unlinked.push_back(i);
    }
    return unlinked.empty() ? Status::ok() : unlinkedError(unlinked, views, ref);
}

bool costHasLens(LensModel lens) {
    return lens == LensModel::kPinhole || lens == LensModel::kFisheye;
}

std::string fixed(double v, int digits) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.*f", digits, v);
    return buffer;
}

using Keys = std::map<int64_t, std::vector<Sighting>>;

size_t liveCount(const std::vector<Sighting>& sightings) {
    return static_cast<size_t>(std::count_if(sightings.begin(), sightings.end(),
                                             [](const Sighting& s) { return !s.dropped; }));
}

const TargetView& viewOf(const std::vector<CameraViews>& views, const RigCalibration& rig,
                         const Sighting& s) {
    return views[s.camera].views[rig.cameras[s.camera].views[s.fit].view];
}

std::string viewName(const std::vector<CameraViews>& views, const RigCalibration& rig,
                     const Sighting& s) {
    const TargetView& view = viewOf(views, rig, s);
    return "camera '" + views[s.camera].camera + "', view '" + view.source + "' (key " +
           std::to_string(view.key) + ")";
}

void recordChange(RigCalibration& rig, RigViewChange::Kind kind, const Sighting& s, int64_t key,
                  int rotation_deg, std::string message) {
    RigViewChange change;
    change.kind = kind;
    change.camera = s.camera;
    change.view = rig.cameras[s.camera].views[s.fit].view;
    change.key = key;
    change.rotation_deg = rotation_deg;
    change.message = std::move(message);
    rig.changes.push_back(std::move(change));
}

// Puts every key's views in the corner order in which they agree on the board's pose in the
// reference frame (seeded camera poses): the first camera's order where it agrees with others,
// each other view in the board symmetry closest to it. Views no order makes agree are dropped.
void resolveKeys(Keys& keys, const std::vector<Eigen::Isometry3d>& T_ref_camera,
                 const std::vector<std::vector<BoardSymmetry>>& symmetries,
                 const std::vector<CameraViews>& views, RigCalibration& rig) {
    for (auto& [key, sightings] : keys) {
        if (sightings.size() < 2)
            continue;
        std::vector<std::vector<Eigen::Isometry3d>> candidates;
        std::vector<double> scale_m;
        for (const Sighting& s : sightings) {
            std::vector<Eigen::Isometry3d> poses;
            for (const BoardSymmetry& symmetry : symmetries[s.camera])
                poses.push_back(T_ref_camera[s.camera] * reordered(s, symmetry));
            candidates.push_back(std::move(poses));
            scale_m.push_back(s.T_camera_target.translation().norm());
        }
        const Consensus agreed = consensus(candidates, scale_m, false);
        // How far each view is from the agreed pose in its closest order.
        std::vector<PoseGap> closest(sightings.size(), PoseGap{360, 0});
        PoseGap worst;
        for (size_t i = 0; i < sightings.size(); ++i) {
            for (const Eigen::Isometry3d& pose : candidates[i]) {
                const PoseGap gap = gapOf(pose, agreed.hypothesis);
                if (gap.deg < closest[i].deg)
                    closest[i] = gap;
            }
            if (closest[i].deg > worst.deg)
                worst = closest[i];
        }
        for (size_t i = 0; i < sightings.size(); ++i) {
            Sighting& s = sightings[i];
            if (agreed.agreeing >= 2 && agreed.choice[i] >= 0) {
                s.symmetry = static_cast<size_t>(agreed.choice[i]);
                const int deg = symmetries[s.camera][s.symmetry].rotation_deg;
                if (deg != 0) {
                    recordChange(rig, RigViewChange::Kind::kReordered, s, key, deg,
                                 viewName(views, rig, s) +
                                     ": corners renumbered as the board turned by " +
                                     std::to_string(deg) +
                                     "°, the order in which it agrees with the other cameras' "
                                     "views of that instant");
                }
                continue;
            }
            s.dropped = true;
            recordChange(
                rig, RigViewChange::Kind::kDropped, s, key, 0,
                viewName(views, rig, s) + ": dropped, " +
                    (agreed.agreeing >= 2
                         ? "in every corner order its board pose is " + fixed(closest[i].deg, 1) +
                               "° and " + fixed(closest[i].m * 1000, 0) +
                               " mm from the one the other cameras' views of that instant "
                               "agree on"
                         : "the " + std::to_string(sightings.size()) +
                               " cameras' views of that instant disagree in every corner order "
                               "(by up to " +
                               fixed(worst.deg, 1) + "° and " + fixed(worst.m * 1000, 0) + " mm)"));
        }
    }
}

// What the views left after dropping still have to show: no camera lost more than
// max_dropped_fraction of the views it shares with other cameras, and every camera is still
// linked to the reference.
Status checkConsensus(const Keys& keys, const std::vector<CameraViews>& views,
                      const RigCalibration& rig, const RigOptions& options, size_t ref) {
    const size_t n = views.size();
    std::vector<size_t> shared(n, 0);
    std::vector<std::vector<std::string>> dropped(n);
    std::map<int64_t, std::set<size_t>> live;
    for (const auto& [key, sightings] : keys) {
        for (const Sighting& s : sightings) {
            if (sightings.size() >= 2)
                ++shared[s.camera];
            if (s.dropped && sightings.size() >= 2)
                dropped[s.camera].push_back(viewOf(views, rig, s).source);
            if (!s.dropped)
                live[key].insert(s.camera);
        }
    }
    for (size_t c = 0; c < n; ++c) {
        if (static_cast<double>(dropped[c].size()) <=
            options.max_dropped_fraction * static_cast<double>(shared[c]))
            continue;
        std::string list;
        for (size_t k = 0; k < dropped[c].size() && k < 5; ++k)
            list += (k ? ", '" : "'") + dropped[c][k] + "'";
        if (dropped[c].size() > 5)
            list += ", …";
        return invalid("camera '" + views[c].camera + "': " + std::to_string(dropped[c].size()) +
                       " of the " + std::to_string(shared[c]) +
                       " views it shares with other cameras disagree with them (" + list +
                       "), more than " + fixed(100 * options.max_dropped_fraction, 0) +
                       " %: no consensus on the rig's geometry is left (do equal keys pair "
                       "views of one instant? did a camera move?)");
    }
    return checkLinked(live, views, ref);
}

// The joint problem from the seeds, over the views not dropped: T_camera_ref per camera (the
// reference's is the identity and not a parameter), T_ref_target per key, optionally the
// intrinsics.
struct Joint {
    std::vector<detail::Vector6d> camera_ref;
    std::vector<Eigen::VectorXd> intrinsics;
    std::map<int64_t, detail::Vector6d> ref_target;
    std::unique_ptr<ceres::Problem> problem;
    ceres::Solver::Summary summary;
    int residual_count = 0;
};

// The target point a corner of `s` is, in the order its key agreed on; -1 when out of range.
int targetId(const Sighting& s, const std::vector<BoardSymmetry>& symmetries, int id) {
    const std::vector<int>& perm = symmetries[s.symmetry].perm;
    return id >= 0 && static_cast<size_t>(id) < perm.size() ? perm[static_cast<size_t>(id)] : -1;
}

// One joint bundle adjustment from the seeds; then the rig's poses (and refined models) and
// every live view's, camera's and the rig's RMS in `rig`.
Status solveJoint(const std::vector<CameraViews>& views, const RigOptions& options, size_t ref,
                  const std::vector<Eigen::Isometry3d>& T_ref_camera,
                  const std::vector<CameraModel>& own_models,
                  const std::vector<std::vector<BoardSymmetry>>& symmetries, Keys& keys,
                  RigCalibration& rig, Joint& joint) {
    const size_t n = views.size();
    joint.camera_ref.resize(n);
    joint.intrinsics.resize(n);
    for (size_t i = 0; i < n; ++i) {
        joint.camera_ref[i] = detail::toRt(T_ref_camera[i].inverse());
        joint.intrinsics[i] = detail::intrinsicsVector(own_models[i]);
        if (options.refine_intrinsics && options.camera.fix_aspect_ratio)
            joint.intrinsics[i][0] = joint.intrinsics[i][1] =
                0.5 * (joint.intrinsics[i][0] + joint.intrinsics[i][1]);
    }
    for (const auto& [key, sightings] : keys) {
        for (const Sighting& s : sightings) {
            if (!s.dropped) {
                joint.ref_target[key] = detail::toRt(
                    T_ref_camera[s.camera] * reordered(s, symmetries[s.camera][s.symmetry]));
                break;
            }
        }
    }

    joint.problem = std::make_unique<ceres::Problem>();
    ceres::Problem& problem = *joint.problem;
    for (size_t i = 0; i < n; ++i) {
        if (i != ref)
            problem.AddParameterBlock(joint.camera_ref[i].data(), 6);
        if (options.refine_intrinsics) {
            const int size = static_cast<int>(joint.intrinsics[i].size());
            problem.AddParameterBlock(joint.intrinsics[i].data(), size);
            if (options.camera.fix_aspect_ratio)
                problem.SetManifold(joint.intrinsics[i].data(),
                                    new detail::EqualFocalManifold(size));
        }
    }
    for (auto& [key, sightings] : keys) {
        for (const Sighting& s : sightings) {
            if (s.dropped)
                continue;
            const std::vector<Eigen::Vector3d> points = views[s.camera].target.points();
            for (const Corner& corner : viewOf(views, rig, s).corners) {
                const int id = targetId(s, symmetries[s.camera], corner.id);
                if (s.outliers.count(corner.id) || id < 0)
                    continue;
                std::vector<double*> blocks;
                if (s.camera != ref)
                    blocks.push_back(joint.camera_ref[s.camera].data());
                blocks.push_back(joint.ref_target[key].data());
                if (options.refine_intrinsics)
                    blocks.push_back(joint.intrinsics[s.camera].data());
                problem.AddResidualBlock(
                    detail::newReprojectionCost(
                        own_models[s.camera], points[static_cast<size_t>(id)], corner.pixel,
                        corner.weight, s.camera != ref ? 2 : 1, options.refine_intrinsics),
                    nullptr, blocks);
                joint.residual_count += 2;
            }
        }
    }
    ceres::Solve(detail::solverOptions(), &problem, &joint.summary);
    if (!joint.summary.IsSolutionUsable() || joint.summary.termination_type != ceres::CONVERGENCE) {
        return Status(detail::kNotConverged,
                      "rig: the joint solve did not converge: " + joint.summary.BriefReport());
    }

    rig.T_ref_camera.resize(n);
    for (size_t i = 0; i < n; ++i) {
        rig.T_ref_camera[i] = i == ref ? Eigen::Isometry3d::Identity()
                                       : detail::fromRt(joint.camera_ref[i].data()).inverse();
        if (options.refine_intrinsics)
            rig.cameras[i].model = detail::withIntrinsics(own_models[i], joint.intrinsics[i]);
    }
    // The RMS values as calibrateCamera reports them: plain residual lengths (the cost is
    // weighted).
    double sum2 = 0;
    int count = 0;
    std::vector<double> camera_sum2(n, 0);
    std::vector<int> camera_count(n, 0);
    for (auto& [key, sightings] : keys) {
        for (Sighting& s : sightings) {
            if (s.dropped)
                continue;
            const Eigen::Isometry3d T_ref_target = detail::fromRt(joint.ref_target[key].data());
            const CameraModel& model = rig.cameras[s.camera].model;
            const std::vector<Eigen::Vector3d> points = views[s.camera].target.points();
            const Eigen::Isometry3d T_camera_target =
                rig.T_ref_camera[s.camera].inverse() * T_ref_target;
            double view_sum2 = 0;
            int view_count = 0;
            for (const Corner& corner : viewOf(views, rig, s).corners) {
                const int id = targetId(s, symmetries[s.camera], corner.id);
                if (s.outliers.count(corner.id) || id < 0)
                    continue;
                const auto projected =
                    model.project(T_camera_target * points[static_cast<size_t>(id)]);
                if (!projected)
                    return Status(detail::kNotConverged, "rig: camera '" + views[s.camera].camera +
                                                             "' cannot project a corner after "
                                                             "the joint solve");
                view_sum2 += (*projected - corner.pixel).squaredNorm();
                ++view_count;
            }
            s.rms_px = std::sqrt(view_sum2 / std::max(view_count, 1));
            camera_sum2[s.camera] += view_sum2;
            camera_count[s.camera] += view_count;
            sum2 += view_sum2;
            count += view_count;
        }
    }
    rig.rms_px = std::sqrt(sum2 / std::max(count, 1));
    rig.camera_rms_px.resize(n);
    for (size_t i = 0; i < n; ++i)
        rig.camera_rms_px[i] = std::sqrt(camera_sum2[i] / std::max(camera_count[i], 1));
    return Status::ok();
}

// The limit of a view's or a camera's RMS in the joint solve: `ratio` × its camera's own.
double rmsLimit(const RigCalibration& rig, const RigOptions& options, size_t camera, double ratio) {
    return ratio * std::max(rig.cameras[camera].rms_px, options.rms_floor_px);
}

// Drops the views above their limit at the key whose worst view exceeds it most; false when no
// view does. One key at a time: a view that disagrees pulls the others at its key, and with it
// the camera poses, off.
bool dropWorstKey(Keys& keys, const std::vector<CameraViews>& views, const RigOptions& options,
                  RigCalibration& rig) {
    if (options.view_outlier_ratio <= 0)
        return false;
    const auto limit = [&](const Sighting& s) {
        return rmsLimit(rig, options, s.camera, options.view_outlier_ratio);
    };
    std::vector<Sighting>* worst = nullptr;
    int64_t worst_key = 0;
    double worst_excess = 1;
    for (auto& [key, sightings] : keys) {
        if (liveCount(sightings) < 2)
            continue;
        for (const Sighting& s : sightings) {
            if (!s.dropped && s.rms_px / limit(s) > worst_excess) {
                worst_excess = s.rms_px / limit(s);
                worst = &sightings;
                worst_key = key;
            }
        }
    }
    if (!worst)
        return false;
    for (Sighting& s : *worst) {
        if (s.dropped || s.rms_px <= limit(s))
            continue;
        s.dropped = true;
        recordChange(rig, RigViewChange::Kind::kDropped, s, worst_key, 0,
                     viewName(views, rig, s) + ": dropped, " + fixed(s.rms_px, 2) +
                         " px RMS in the joint solve, over " + fixed(limit(s), 2) + " px (" +
                         fixed(options.view_outlier_ratio, 1) + "× its camera's own " +
                         fixed(rig.cameras[s.camera].rms_px, 3) + " px)");
    }
    return true;
}

}  // namespace

Result<RigCalibration> calibrateRig(const std::vector<CameraViews>& views,
                                    const RigOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    if (views.empty())
        return invalid("no cameras");
    const size_t n = views.size();
    std::set<std::string> names;
    for (const CameraViews& camera : views) {
        if (camera.camera.empty())
            return invalid("a camera has no name");
        if (!names.insert(camera.camera).second)
            return invalid("camera '" + camera.camera + "' appears twice");
    }
    size_t ref = 0;
    if (!options.reference.empty()) {
        for (ref = 0; ref < n && views[ref].camera != options.reference; ++ref) {
        }
        if (ref == n) {
            std::string list;
            for (const CameraViews& camera : views)
                list += (list.empty() ? "" : ", ") + camera.camera;
            return invalid("the reference camera '" + options.reference +
                           "' is not one of the rig's cameras (" + list + ")");
        }
    }
    for (const auto& [name, model] : options.models) {
        if (!names.count(name))
            return invalid("a lens model ('" + model + "') is given for camera '" + name +
                           "', which the rig does not have");
    }
    // Fail fast on what the keys alone show, before any camera is solved: repeated keys, and
    // cameras no chain of shared keys reaches (re-checked after the solves, which may leave
    // views out).
    std::map<int64_t, std::set<size_t>> raw_keys;
    for (size_t i = 0; i < n; ++i) {
        std::map<int64_t, const std::string*> seen;
        for (const TargetView& view : views[i].views) {
            if (view.rejection != ViewRejection::kNone)
                continue;
            if (const auto [it, fresh] = seen.emplace(view.key, &view.source); !fresh) {
                return invalid("camera '" + views[i].camera + "': views '" + *it->second +
                               "' and '" + view.source + "' have the same key " +
                               std::to_string(view.key) + " (one target pose per instant)");
            }
            raw_keys[view.key].insert(i);
        }
    }
    if (Status linked = checkLinked(raw_keys, views, ref); !linked)
        return linked;
    const ProgressCallback& progress = options.camera.progress;
    auto report = [&](double fraction, std::string_view stage) {
        if (progress)
            progress(fraction, stage);
    };

    // Each camera alone.
    RigCalibration rig;
    rig.reference = views[ref].camera;
    const double own_share = 0.7;  // of the progress, for the cameras' own solves
    for (size_t i = 0; i < n; ++i) {
        CalibrationOptions camera_options = options.camera;
        if (const auto model = options.models.find(views[i].camera); model != options.models.end())
            camera_options.model = model->second;
        if (progress) {
            camera_options.progress = [&, i](double fraction, std::string_view stage) {
                progress(own_share * (static_cast<double>(i) + fraction) / static_cast<double>(n),
                         std::string(views[i].camera) + ": " + std::string(stage));
            };
        }
        const auto done = options.solved.find(views[i].camera);
        Result<CameraCalibration> own = done != options.solved.end()
                                            ? Result<CameraCalibration>(done->second)
                                            : calibrateCamera(views[i], camera_options);
        if (!own)
            return own.status().withContext("rig");
        if (options.refine_intrinsics && !costHasLens(own->model.lens)) {
            return invalid("camera '" + views[i].camera +
                           "': refine_intrinsics needs a pinhole or " +
                           "fisheye lens, the joint solve cannot refine " +
                           std::string(toString(own->model.lens)));
        }
        rig.cameras.push_back(std::move(*own));
    }

    // Who saw the target at which key.
    Keys keys;
    std::vector<std::vector<BoardSymmetry>> symmetries(n);
    for (size_t i = 0; i < n; ++i) {
        symmetries[i] = boardSymmetries(views[i].target);
        const CameraCalibration& own = rig.cameras[i];
        for (size_t f = 0; f < own.views.size(); ++f) {
            const ViewFit& fit = own.views[f];
            Sighting s{i, f, fit.T_camera_target, {}, 0, false, 0};
            for (const PointResidual& r : own.residuals) {
                if (r.view == fit.view && r.outlier)
                    s.outliers.insert(r.id);
            }
            keys[views[i].views[fit.view].key].push_back(std::move(s));
        }
    }

    // Seed the camera poses breadth-first from the reference: each newly reached camera's
    // pose relative to one already placed, averaged over the keys both saw that agree with the
    // most others, each in the board symmetry that agrees (the corner orders of the two views
    // of a key may differ).
    report(own_share, "linking cameras");
    std::vector<std::optional<Eigen::Isometry3d>> T_ref_camera(n);
    T_ref_camera[ref] = Eigen::Isometry3d::Identity();
    std::deque<size_t> queue = {ref};
    while (!queue.empty()) {
        const size_t a = queue.front();
        queue.pop_front();
        std::map<size_t, std::vector<std::pair<const Sighting*, const Sighting*>>> shared;
        for (const auto& [key, sightings] : keys) {
            const auto in_a = std::find_if(sightings.begin(), sightings.end(),
                                           [&](const Sighting& s) { return s.camera == a; });
            if (in_a == sightings.end())
                continue;
            for (const Sighting& s : sightings) {
                if (!T_ref_camera[s.camera])
                    shared[s.camera].emplace_back(&*in_a, &s);
            }
        }
        for (const auto& [b, pairs] : shared) {
            std::vector<std::vector<Eigen::Isometry3d>> T_a_b;
            std::vector<double> scale_m;
            for (const auto& [in_a, in_b] : pairs) {
                std::vector<Eigen::Isometry3d> candidates;
                for (const BoardSymmetry& symmetry : symmetries[b])
                    candidates.push_back(in_a->T_camera_target *
                                         reordered(*in_b, symmetry).inverse());
                T_a_b.push_back(std::move(candidates));
                scale_m.push_back(in_a->T_camera_target.translation().norm());
            }
            const Consensus agreed = consensus(T_a_b, scale_m, true);
            std::vector<Eigen::Isometry3d> estimates;
            for (size_t k = 0; k < T_a_b.size(); ++k) {
                if (agreed.choice[k] >= 0)
                    estimates.push_back(T_a_b[k][static_cast<size_t>(agreed.choice[k])]);
            }
            T_ref_camera[b] = *T_ref_camera[a] * meanPose(estimates);
            queue.push_back(b);
        }
    }
    std::vector<size_t> unlinked;
    std::vector<Eigen::Isometry3d> seeds(n);
    for (size_t i = 0; i < n; ++i) {
        if (!T_ref_camera[i])
            unlinked.push_back(i);
        else
            seeds[i] = *T_ref_camera[i];
    }
    if (!unlinked.empty())
        return unlinkedError(unlinked, views, ref);

    report(own_share + 0.02, "matching corner orders");
    resolveKeys(keys, seeds, symmetries, views, rig);
    MIXRAY_RETURN_IF_ERROR(checkConsensus(keys, views, rig, options, ref));

    // The joint solve, again without the key whose views fit worst until every view fits.
    std::vector<CameraModel> own_models;
    for (const CameraCalibration& own : rig.cameras)
        own_models.push_back(own.model);
    Joint joint;
    for (size_t round = 0;; ++round) {
        report(own_share + 0.05, round == 0 ? "joint bundle adjustment"
                                            : "joint bundle adjustment, round " +
                                                  std::to_string(round + 1) +
                                                  " without views that disagree");
        joint = Joint{};
        MIXRAY_RETURN_IF_ERROR(
            solveJoint(views, options, ref, seeds, own_models, symmetries, keys, rig, joint));
        if (!dropWorstKey(keys, views, options, rig))
            break;
        MIXRAY_RETURN_IF_ERROR(checkConsensus(keys, views, rig, options, ref));
    }
    std::sort(rig.changes.begin(), rig.changes.end(),
              [](const RigViewChange& a, const RigViewChange& b) {
                  return std::tie(a.camera, a.view, a.kind) < std::tie(b.camera, b.view, b.kind);
              });
    for (size_t i = 0; i < n; ++i) {
        const double limit = rmsLimit(rig, options, i, options.max_rms_ratio);
        if (rig.camera_rms_px[i] <= limit)
            continue;
        return invalid("camera '" + views[i].camera + "' fits the joint solve at " +
                       fixed(rig.camera_rms_px[i], 2) + " px RMS, over " + fixed(limit, 2) +
                       " px (" + fixed(options.max_rms_ratio, 1) + "× its own " +
                       fixed(rig.cameras[i].rms_px, 3) +
                       " px): its views disagree with the other cameras' on the rig's geometry "
                       "(a corner order no board symmetry explains, views paired at the wrong "
                       "keys, or a camera that moved)");
    }

    report(0.95, "covariance");
    rig.pose_covariance.assign(n, Eigen::Matrix<double, 6, 6>::Zero());
    std::vector<const double*> blocks;
    for (size_t i = 0; i < n; ++i) {
        if (i != ref)
            blocks.push_back(joint.camera_ref[i].data());
    }
    if (!blocks.empty()) {
        int free_parameters = joint.problem->NumParameters();
        if (options.refine_intrinsics && options.camera.fix_aspect_ratio)
            free_parameters -= static_cast<int>(n);
        const int dof = joint.residual_count - free_parameters;
        if (dof <= 0)
            return invalid("too few corners for the joint solve's parameters");
        const double sigma2 = 2 * joint.summary.final_cost / dof;
        const std::optional<Eigen::MatrixXd> covariance =
            detail::covarianceOf(*joint.problem, blocks);
        if (!covariance) {
            return Status(detail::kNotConverged,
                          "rig: the joint solve's covariance is singular (the views do not "
                          "constrain every camera pose)");
        }
        Eigen::Index at = 0;
        for (size_t i = 0; i < n; ++i) {
            if (i == ref)
                continue;
            const Eigen::Matrix<double, 6, 6> J = inverseJacobian(joint.camera_ref[i]);
            rig.pose_covariance[i] = sigma2 * J * covariance->block<6, 6>(at, at) * J.transpose();
            at += 6;
        }
    }
    report(1.0, "done");
    return rig;
}

Status RigOptions::validate() const {
    const auto bad = [](const std::string& field, const std::string& why) {
        return Status(ErrorCode::kInvalidArgument, "rig options: " + field + " " + why);
    };
    if (!(view_outlier_ratio == 0 || view_outlier_ratio >= 1))
        return bad("view_outlier_ratio", "must be 0 (keep every view) or at least 1");
    if (!(max_rms_ratio >= 1))
        return bad("max_rms_ratio", "must be at least 1");
    if (!(rms_floor_px > 0))
        return bad("rms_floor_px", "must be above 0");
    if (!(max_dropped_fraction >= 0 && max_dropped_fraction <= 1))
        return bad("max_dropped_fraction", "must be within [0, 1]");
    return Status::ok();
}

}  // namespace mixray::calibration
