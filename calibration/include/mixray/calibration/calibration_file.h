// The rig calibration file (YAML, docs/calibration.md#calibration-files): every camera's model
// and pose with their uncertainty and the depth registrations, read by every other module; and
// import/export of the formats other tools read (OpenCV FileStorage, mrcal .cameramodel,
// Kalibr camchain.yaml, ROS camera_info).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/depth_registration.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// One calibrated camera. Plain value.
// The lens's own settings for the session, which a calibration cannot measure: written into the
// file by whoever set the lens (the renderer's depth of field follows them, Kán & Kaufmann
// §3.1).
struct LensSettings {
    double f_number = 0;          // > 0
    double focal_length_mm = 0;   // the lens's own focal length, > 0
    double focus_distance_m = 0;  // where it is focused, > 0
};

struct CalibratedCamera {
    std::string name;  // the stream it calibrates ("kinect/color"), or a user's name
    CameraModel model;
    // The frame its pose is given in: another camera's name, "world" (the marker frame,
    // docs/conventions.md), or empty when the camera's pose is not calibrated.
    std::string parent;
    Eigen::Isometry3d T_parent_camera = Eigen::Isometry3d::Identity();
    // Covariance of T_parent_camera as [rotation vector (rad), translation (m)]; absent when
    // not known.
    std::optional<Eigen::Matrix<double, 6, 6>> pose_covariance;
    // 1σ of the intrinsics in the model's order (fx fy cx cy, then distortion); empty when not
    // known.
    std::vector<double> intrinsics_stddev;
    double rms_px = 0;  // 0: not known
    int views = 0;
    // What the views left weakly determined, kept on purpose (Observability::summary of a
    // solve accepted with CalibrationOptions::accept_weak); empty: nothing, or not known.
    std::string weak;
    std::optional<LensSettings> lens;  // absent: not known
};

// A depth stream and how it registers into a colour camera.
struct CalibratedDepth {
    std::string stream;        // "kinect/depth"
    std::string depth_camera;  // the calibrated IR camera the depth image is aligned with
    std::string color_camera;  // the colour camera it registers into
    DepthCorrection correction;
};

struct CalibrationFile {
    std::vector<CalibratedCamera> cameras;
    std::vector<CalibratedDepth> depth;
    std::string target;   // the target's spec (CalibrationTarget::spec()), empty if not known
    std::string created;  // ISO 8601 UTC and the tool that made it

    const CalibratedCamera* find(std::string_view name) const;
    // The camera's pose in `frame` (a camera, or a frame some camera names as its parent) by
    // composing parents; kNotFound naming both chains when they are not linked or a name is
    // unknown, kCorruptData when parents form a cycle.
    Result<Eigen::Isometry3d> pose(std::string_view frame, std::string_view camera) const;
    // The registration of a depth stream: its cameras and T_color_depth.
    Result<DepthRegistration> depthRegistration(std::string_view stream) const;
};

// Errors name the file, line and field.
Result<CalibrationFile> readCalibrationFile(const std::filesystem::path& path);
Status writeCalibrationFile(const std::filesystem::path& path, const CalibrationFile& file);

enum class CalibrationFormat : uint8_t {
    kMixray,  // the file above
    kOpenCV,  // cv::FileStorage YAML as OpenCV's calibration samples write it
    kMrcal,   // mrcal .cameramodel
    kKalibr,  // Kalibr camchain.yaml
    kRos,     // ROS camera_info YAML (camera_calibration_parsers)
};

std::string_view toString(CalibrationFormat format);
std::optional<CalibrationFormat> calibrationFormatFromString(std::string_view name);

// Reads any of the formats, recognised from the content when `format` is absent. Formats
// with one camera name it after the file unless the file names it. An OpenCV file without
// image_width/image_height gives a model of width = height = 0 (not known): set the size
// before writing it anywhere. kNotFound for a missing file; kCorruptData naming the file (and
// line and field where the format has them) for content mixray cannot read or hold, but
// kUnsupported naming the file for an mrcal model in a lens mixray has none for (CAHVOR, ...).
Result<CalibrationFile> importCalibration(const std::filesystem::path& path,
                                          std::optional<CalibrationFormat> format = {});
// Writes `file` in `format`. Single-camera formats (OpenCV, mrcal, ROS) write `camera`, which
// may be left empty when the file has one; the multi-camera formats (mixray, Kalibr) write
// every camera and take no `camera`. kInvalidArgument when the format cannot hold the model
// (Kalibr's radtan has no k3..k6; ROS and OpenCV's pinhole YAML take no splined model) naming
// both; depth registrations are written by the mixray format only.
Status exportCalibration(const std::filesystem::path& path, const CalibrationFile& file,
                         CalibrationFormat format, std::string_view camera = {});

}  // namespace mixray::calibration
