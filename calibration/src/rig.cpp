// calibrateRig(): each camera's own calibration, camera poses seeded through chains of
// simultaneous views (breadth-first over the co-visibility graph), then one Ceres bundle
// adjustment of every camera's pose and the target's pose at every key, optionally with the
// intrinsics, and the poses' covariances.
#include <ceres/problem.h>
#include <ceres/solver.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string>

#include "ceres_util.h"
#include "mixray/calibration/calibrate.h"
#include "reprojection_cost.h"
#include "solve_internal.h"

namespace mixray::calibration {

namespace {

Status invalid(const std::string& message) {
    return Status(ErrorCode::kInvalidArgument, "rig: " + message);
}

// One camera's view of the target at one key, from its own calibration.
struct Sighting {
    size_t camera;
    size_t fit;  // index into CameraCalibration::views
    Eigen::Isometry3d T_camera_target;
};

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

}  // namespace

Result<RigCalibration> calibrateRig(const std::vector<CameraViews>& views,
                                    const RigOptions& options) {
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
    std::map<int64_t, std::vector<Sighting>> keys;
    for (size_t i = 0; i < n; ++i) {
        for (size_t f = 0; f < rig.cameras[i].views.size(); ++f) {
            const ViewFit& fit = rig.cameras[i].views[f];
            const TargetView& view = views[i].views[fit.view];
            keys[view.key].push_back(Sighting{i, f, fit.T_camera_target});
        }
    }

    // Seed the camera poses breadth-first from the reference: each newly reached camera's
    // pose relative to one already placed, averaged over the keys both saw.
    report(own_share, "linking cameras");
    std::vector<std::optional<Eigen::Isometry3d>> T_ref_camera(n);
    T_ref_camera[ref] = Eigen::Isometry3d::Identity();
    std::deque<size_t> queue = {ref};
    while (!queue.empty()) {
        const size_t a = queue.front();
        queue.pop_front();
        std::map<size_t, std::vector<Eigen::Isometry3d>> T_a_b;
        for (const auto& [key, sightings] : keys) {
            const auto in_a = std::find_if(sightings.begin(), sightings.end(),
                                           [&](const Sighting& s) { return s.camera == a; });
            if (in_a == sightings.end())
                continue;
            for (const Sighting& s : sightings) {
                if (!T_ref_camera[s.camera])
                    T_a_b[s.camera].push_back(in_a->T_camera_target * s.T_camera_target.inverse());
            }
        }
        for (const auto& [b, estimates] : T_a_b) {
            T_ref_camera[b] = *T_ref_camera[a] * meanPose(estimates);
            queue.push_back(b);
        }
    }
    std::vector<size_t> unlinked;
    for (size_t i = 0; i < n; ++i) {
        if (!T_ref_camera[i])
            unlinked.push_back(i);
    }
    if (!unlinked.empty())
        return unlinkedError(unlinked, views, ref);

    // The joint problem: T_camera_ref per camera (the reference's is the identity and not a
    // parameter), T_ref_target per key, optionally the intrinsics.
    std::vector<detail::Vector6d> camera_ref(n);
    std::vector<Eigen::VectorXd> intrinsics(n);
    for (size_t i = 0; i < n; ++i) {
        camera_ref[i] = detail::toRt(T_ref_camera[i]->inverse());
        intrinsics[i] = detail::intrinsicsVector(rig.cameras[i].model);
        if (options.refine_intrinsics && options.camera.fix_aspect_ratio)
            intrinsics[i][0] = intrinsics[i][1] = 0.5 * (intrinsics[i][0] + intrinsics[i][1]);
    }
    std::map<int64_t, detail::Vector6d> ref_target;
    for (const auto& [key, sightings] : keys) {
        const Sighting& s = sightings.front();
        ref_target[key] = detail::toRt(*T_ref_camera[s.camera] * s.T_camera_target);
    }

    ceres::Problem problem;
    for (size_t i = 0; i < n; ++i) {
        if (i != ref)
            problem.AddParameterBlock(camera_ref[i].data(), 6);
        if (options.refine_intrinsics) {
            const int size = static_cast<int>(intrinsics[i].size());
            problem.AddParameterBlock(intrinsics[i].data(), size);
            if (options.camera.fix_aspect_ratio)
                problem.SetManifold(intrinsics[i].data(), new detail::EqualFocalManifold(size));
        }
    }
    int residual_count = 0;
    for (auto& [key, sightings] : keys) {
        for (const Sighting& s : sightings) {
            const CameraCalibration& own = rig.cameras[s.camera];
            const ViewFit& fit = own.views[s.fit];
            const TargetView& view = views[s.camera].views[fit.view];
            std::set<int> outliers;
            for (const PointResidual& r : own.residuals) {
                if (r.view == fit.view && r.outlier)
                    outliers.insert(r.id);
            }
            const std::vector<Eigen::Vector3d> points = views[s.camera].target.points();
            for (const Corner& corner : view.corners) {
                if (outliers.count(corner.id))
                    continue;
                std::vector<double*> blocks;
                if (s.camera != ref)
                    blocks.push_back(camera_ref[s.camera].data());
                blocks.push_back(ref_target[key].data());
                if (options.refine_intrinsics)
                    blocks.push_back(intrinsics[s.camera].data());
                problem.AddResidualBlock(
                    detail::newReprojectionCost(own.model, points[static_cast<size_t>(corner.id)],
                                                corner.pixel, corner.weight,
                                                s.camera != ref ? 2 : 1, options.refine_intrinsics),
                    nullptr, blocks);
                residual_count += 2;
            }
        }
    }

    report(own_share + 0.05, "joint bundle adjustment");
    ceres::Solver::Summary summary;
    ceres::Solve(detail::solverOptions(), &problem, &summary);
    if (!summary.IsSolutionUsable() || summary.termination_type != ceres::CONVERGENCE) {
        return Status(detail::kNotConverged,
                      "rig: the joint solve did not converge: " + summary.BriefReport());
    }

    report(0.95, "covariance");
    rig.T_ref_camera.resize(n);
    rig.pose_covariance.assign(n, Eigen::Matrix<double, 6, 6>::Zero());
    for (size_t i = 0; i < n; ++i) {
        rig.T_ref_camera[i] = detail::fromRt(camera_ref[i].data()).inverse();
        if (i == ref)
            rig.T_ref_camera[i] = Eigen::Isometry3d::Identity();
        if (options.refine_intrinsics)
            rig.cameras[i].model = detail::withIntrinsics(rig.cameras[i].model, intrinsics[i]);
    }
    // The RMS as calibrateCamera reports it: plain residual lengths (the cost is weighted).
    double sum2 = 0;
    int count = 0;
    for (const auto& [key, sightings] : keys) {
        const Eigen::Isometry3d T_ref_target = detail::fromRt(ref_target[key].data());
        for (const Sighting& s : sightings) {
            const CameraCalibration& own = rig.cameras[s.camera];
            const ViewFit& fit = own.views[s.fit];
            std::set<int> outliers;
            for (const PointResidual& r : own.residuals) {
                if (r.view == fit.view && r.outlier)
                    outliers.insert(r.id);
            }
            const std::vector<Eigen::Vector3d> points = views[s.camera].target.points();
            const Eigen::Isometry3d T_camera_target =
                rig.T_ref_camera[s.camera].inverse() * T_ref_target;
            for (const Corner& corner : views[s.camera].views[fit.view].corners) {
                if (outliers.count(corner.id))
                    continue;
                const auto projected =
                    own.model.project(T_camera_target * points[static_cast<size_t>(corner.id)]);
                if (!projected)
                    return Status(detail::kNotConverged, "rig: camera '" + own.camera +
                                                             "' cannot project a corner after the "
                                                             "joint solve");
                sum2 += (*projected - corner.pixel).squaredNorm();
                ++count;
            }
        }
    }
    rig.rms_px = std::sqrt(sum2 / std::max(count, 1));

    std::vector<const double*> blocks;
    for (size_t i = 0; i < n; ++i) {
        if (i != ref)
            blocks.push_back(camera_ref[i].data());
    }
    if (!blocks.empty()) {
        int free_parameters = problem.NumParameters();
        if (options.refine_intrinsics && options.camera.fix_aspect_ratio)
            free_parameters -= static_cast<int>(n);
        const int dof = residual_count - free_parameters;
        if (dof <= 0)
            return invalid("too few corners for the joint solve's parameters");
        const double sigma2 = 2 * summary.final_cost / dof;
        const std::optional<Eigen::MatrixXd> covariance = detail::covarianceOf(problem, blocks);
        if (!covariance) {
            return Status(detail::kNotConverged,
                          "rig: the joint solve's covariance is singular (the views do not "
                          "constrain every camera pose)");
        }
        Eigen::Index at = 0;
        for (size_t i = 0; i < n; ++i) {
            if (i == ref)
                continue;
            const Eigen::Matrix<double, 6, 6> J = inverseJacobian(camera_ref[i]);
            rig.pose_covariance[i] = sigma2 * J * covariance->block<6, 6>(at, at) * J.transpose();
            at += 6;
        }
    }
    report(1.0, "done");
    return rig;
}

}  // namespace mixray::calibration
