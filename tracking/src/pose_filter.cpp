// One-Euro smoothing of a pose stream (Casiez, Roussel, Vogel, CHI 2012): translation as a
// vector, rotation on its tangent space about the last smoothed rotation.
#include <cmath>
#include <numbers>
#include <string>

#include "mixray/tracking/markers.h"

namespace mixray::tracking {
namespace {

// Smoothing factor of an exponential low-pass with `cutoff_hz` sampled every `dt_s`.
double alpha(double cutoff_hz, double dt_s) {
    const double tau = 1.0 / (2 * std::numbers::pi * cutoff_hz);
    return 1.0 / (1.0 + tau / dt_s);
}

Eigen::Vector3d logRotation(const Eigen::Quaterniond& q) {
    const Eigen::AngleAxisd aa(q);
    double angle = aa.angle();
    Eigen::Vector3d axis = aa.axis();
    if (angle > std::numbers::pi) {
        angle -= 2 * std::numbers::pi;
    }
    return angle * axis;
}

Eigen::Quaterniond expRotation(const Eigen::Vector3d& w) {
    const double angle = w.norm();
    if (angle < 1e-15)
        return Eigen::Quaterniond::Identity();
    return Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / angle));
}

}  // namespace

Status SmoothingOptions::validate() const {
    const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
    if (!positive(min_cutoff_hz))
        return {ErrorCode::kInvalidArgument,
                "smoothing.min_cutoff_hz must be > 0, got " + std::to_string(min_cutoff_hz)};
    if (!std::isfinite(beta) || beta < 0)
        return {ErrorCode::kInvalidArgument,
                "smoothing.beta must be >= 0, got " + std::to_string(beta)};
    if (!positive(d_cutoff_hz))
        return {ErrorCode::kInvalidArgument,
                "smoothing.d_cutoff_hz must be > 0, got " + std::to_string(d_cutoff_hz)};
    return Status::ok();
}

PoseFilter::PoseFilter(const SmoothingOptions& options) : options_(options) {}

void PoseFilter::reset() {
    primed_ = false;
    dt_.setZero();
    dq_.setZero();
}

Eigen::Isometry3d PoseFilter::filter(const Eigen::Isometry3d& raw, int64_t stamp_ns) {
    const Eigen::Vector3d t_raw = raw.translation();
    const Eigen::Quaterniond q_raw(raw.linear());
    if (!options_.enabled || !primed_ || stamp_ns <= last_stamp_ns_) {
        primed_ = true;
        last_stamp_ns_ = stamp_ns;
        t_ = t_raw;
        q_ = q_raw.normalized();
        dt_.setZero();
        dq_.setZero();
        return raw;
    }
    const double dt_s = static_cast<double>(stamp_ns - last_stamp_ns_) * 1e-9;
    last_stamp_ns_ = stamp_ns;
    const double a_d = alpha(options_.d_cutoff_hz, dt_s);

    // Translation: the speed estimate raises the cutoff, so fast motion passes through.
    const Eigen::Vector3d dt_raw = (t_raw - t_) / dt_s;
    dt_ += a_d * (dt_raw - dt_);
    const double a_t = alpha(options_.min_cutoff_hz + options_.beta * dt_.norm(), dt_s);
    t_ += a_t * (t_raw - t_);

    // Rotation: the same on the tangent space at the smoothed rotation.
    const Eigen::Vector3d delta = logRotation(q_.conjugate() * q_raw.normalized());
    dq_ += a_d * (delta / dt_s - dq_);
    const double a_r = alpha(options_.min_cutoff_hz + options_.beta * dq_.norm(), dt_s);
    q_ = (q_ * expRotation(a_r * delta)).normalized();

    Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
    out.linear() = q_.toRotationMatrix();
    out.translation() = t_;
    return out;
}

}  // namespace mixray::tracking
