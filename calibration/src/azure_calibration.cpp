// The Azure Kinect factory calibration (calibration.json) as a DepthRegistration, and the
// comparison of two registrations (own vs factory).
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>

#include "mixray/calibration/depth_registration.h"

namespace mixray::calibration {

namespace {

using nlohmann::json;

// The Azure Kinect SDK's mode table (transformation_get_mode_specific_*_camera_calibration):
// the sensor binned to `binned`, cropped by `crop`, giving an image of `output`.
struct ModeInfo {
    int binned_w, binned_h, crop_x, crop_y, out_w, out_h;
};

std::optional<ModeInfo> depthMode(std::string_view mode) {
    if (mode == "NFOV_2X2BINNED")
        return ModeInfo{512, 512, 96, 90, 320, 288};
    if (mode == "NFOV_UNBINNED")
        return ModeInfo{1024, 1024, 192, 180, 640, 576};
    if (mode == "WFOV_2X2BINNED")
        return ModeInfo{512, 512, 0, 0, 512, 512};
    if (mode == "WFOV_UNBINNED" || mode == "PASSIVE_IR")
        return ModeInfo{1024, 1024, 0, 0, 1024, 1024};
    return std::nullopt;
}

std::optional<ModeInfo> colorMode(std::string_view resolution) {
    // Recording tags name format and resolution ("MJPG_720P").
    if (const size_t us = resolution.rfind('_'); us != std::string_view::npos)
        resolution = resolution.substr(us + 1);
    if (resolution == "720P")
        return ModeInfo{1280, 960, 0, 120, 1280, 720};
    if (resolution == "1080P")
        return ModeInfo{1920, 1440, 0, 180, 1920, 1080};
    if (resolution == "1440P")
        return ModeInfo{2560, 1920, 0, 240, 2560, 1440};
    if (resolution == "1536P")
        return ModeInfo{2048, 1536, 0, 0, 2048, 1536};
    if (resolution == "2160P")
        return ModeInfo{3840, 2880, 0, 360, 3840, 2160};
    if (resolution == "3072P")
        return ModeInfo{4096, 3072, 0, 0, 4096, 3072};
    return std::nullopt;
}

Status corrupt(const std::string& what) {
    return {ErrorCode::kCorruptData, "Azure Kinect calibration: " + what};
}

struct RawCamera {
    double p[14] = {};  // cx cy fx fy k1..k6 codx cody p2 p1, normalised
    int sensor_w = 0, sensor_h = 0;
    double metric_radius = 0;
    Eigen::Isometry3d T_camera_depth = Eigen::Isometry3d::Identity();
};

Result<RawCamera> readCamera(const json& cameras, const std::string& location) {
    for (const json& camera : cameras) {
        if (!camera.is_object() || camera.value("Location", "") != location)
            continue;
        const std::string where = "camera " + location + ": ";
        RawCamera raw;
        const json& intrinsics = camera.value("Intrinsics", json());
        const std::string type = intrinsics.value("ModelType", "");
        if (type != "CALIBRATION_LensDistortionModelBrownConrady") {
            return Status(ErrorCode::kUnsupported,
                          "Azure Kinect calibration: " + where + "ModelType " + type +
                              " (only CALIBRATION_LensDistortionModelBrownConrady is read)");
        }
        const json& params = intrinsics.value("ModelParameters", json());
        if (!params.is_array() || params.size() < 14)
            return corrupt(where + "Intrinsics.ModelParameters must hold 14 numbers");
        for (int i = 0; i < 14; ++i) {
            if (!params[i].is_number())
                return corrupt(where + "Intrinsics.ModelParameters[" + std::to_string(i) +
                               "] is not a number");
            raw.p[i] = params[i].get<double>();
        }
        // Brown–Conrady has its centre of distortion at the principal point.
        if (raw.p[10] != 0 || raw.p[11] != 0)
            return Status(ErrorCode::kUnsupported,
                          "Azure Kinect calibration: " + where +
                              "a centre of distortion (codx, cody) off the principal point");
        if (!camera.contains("SensorWidth") || !camera["SensorWidth"].is_number_integer() ||
            !camera.contains("SensorHeight") || !camera["SensorHeight"].is_number_integer())
            return corrupt(where + "SensorWidth/SensorHeight missing");
        const auto sensor_w = camera["SensorWidth"].get<int64_t>();
        const auto sensor_h = camera["SensorHeight"].get<int64_t>();
        // The aspect checks multiply them; Azure's sensors are a few thousand pixels wide.
        if (sensor_w < 1 || sensor_w > 65535 || sensor_h < 1 || sensor_h > 65535)
            return corrupt(where + "SensorWidth/SensorHeight outside 1..65535");
        raw.sensor_w = static_cast<int>(sensor_w);
        raw.sensor_h = static_cast<int>(sensor_h);
        raw.metric_radius = camera.value("MetricRadius", 0.0);
        const json& rt = camera.value("Rt", json());
        const json& R = rt.value("Rotation", json());
        const json& t = rt.value("Translation", json());
        if (!R.is_array() || R.size() != 9 || !t.is_array() || t.size() != 3)
            return corrupt(where + "Rt needs Rotation (9) and Translation (3)");
        Eigen::Matrix3d rotation;
        for (int i = 0; i < 9; ++i) {
            if (!R[i].is_number())
                return corrupt(where + "Rt.Rotation holds a non-number");
            rotation(i / 3, i % 3) = R[i].get<double>();  // row-major
        }
        Eigen::Vector3d translation;
        for (int i = 0; i < 3; ++i) {
            if (!t[i].is_number())
                return corrupt(where + "Rt.Translation holds a non-number");
            translation[i] = t[i].get<double>();  // metres
        }
        if ((rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).norm() > 1e-4 ||
            rotation.determinant() < 0)
            return corrupt(where + "Rt.Rotation is not a rotation");
        // Stored in float precision: re-orthonormalise so that compositions stay rigid.
        raw.T_camera_depth.linear() = Eigen::Quaterniond(rotation).normalized().toRotationMatrix();
        raw.T_camera_depth.translation() = translation;
        return raw;
    }
    return corrupt("no camera with Location " + location);
}

// The SDK's transformation_get_mode_specific_camera_calibration, to mixray's pixel centres.
CameraModel modeModel(const RawCamera& raw, const ModeInfo& mode, double cx_n, double cy_n,
                      double fx_n, double fy_n) {
    CameraModel m = CameraModel::pinhole(
        mode.out_w, mode.out_h, fx_n * mode.binned_w, fy_n * mode.binned_h,
        cx_n * mode.binned_w - mode.crop_x - 0.5, cy_n * mode.binned_h - mode.crop_y - 0.5);
    const double* p = raw.p;
    // OpenCV order k1 k2 p1 p2 k3 k4 k5 k6; the file has ... codx cody p2 p1.
    m.distortion = {p[4], p[5], p[13], p[12], p[6], p[7], p[8], p[9]};
    return m;
}

// The calibration in a parsed file; json's value() and get() throw (json::type_error) where
// a field has another type than the file's layout.
Result<AzureKinectCalibration> fromJson(const json& root, const ModeInfo& dmode,
                                        const ModeInfo& cmode) {
    const json& info = root.value("CalibrationInformation", json());
    const json& cameras = info.value("Cameras", json());
    if (!cameras.is_array())
        return corrupt("CalibrationInformation.Cameras missing");
    auto depth = readCamera(cameras, "CALIBRATION_CameraLocationD0");
    if (!depth)
        return depth.status();
    auto color = readCamera(cameras, "CALIBRATION_CameraLocationPV0");
    if (!color)
        return color.status();
    if (depth->sensor_w != 1024 || depth->sensor_h != 1024)
        return corrupt("the depth camera's sensor is " + std::to_string(depth->sensor_w) + "x" +
                       std::to_string(depth->sensor_h) + ", expected 1024x1024");

    AzureKinectCalibration out;
    const double* d = depth->p;
    out.registration.depth = modeModel(*depth, dmode, d[0], d[1], d[2], d[3]);
    const double* c = color->p;
    double cx = c[0], cy = c[1], fx = c[2], fy = c[3];
    if (color->sensor_w * 9 / 16 == color->sensor_h) {
        // A legacy 16:9 calibration: the SDK converts it to the 4:3 sensor first.
        cy = (cy * 2304 + 384) / 3072;
        fy = fy * 2304 / 3072;
    } else if (color->sensor_w * 3 / 4 != color->sensor_h) {
        return corrupt("the colour sensor's aspect " + std::to_string(color->sensor_w) + ":" +
                       std::to_string(color->sensor_h) + " is neither 16:9 nor 4:3");
    }
    out.registration.color = modeModel(*color, cmode, cx, cy, fx, fy);
    // Each camera's Rt maps the depth camera's frame into its own.
    out.registration.T_color_depth = color->T_camera_depth * depth->T_camera_depth.inverse();
    out.depth_metric_radius = depth->metric_radius;
    out.color_metric_radius = color->metric_radius;
    out.serial = info.value("Metadata", json()).value("SerialId", "");
    // A file whose numbers make no valid camera is a damaged file, not a caller's mistake.
    if (Status s = out.registration.validate(); !s)
        return corrupt(s.message());
    return out;
}

}  // namespace

Result<AzureKinectCalibration> parseAzureKinectCalibration(std::string_view text,
                                                           std::string_view depth_mode,
                                                           std::string_view color_resolution) {
    const auto dmode = depthMode(depth_mode);
    if (!dmode)
        return Status(ErrorCode::kInvalidArgument,
                      "Azure Kinect calibration: unknown depth mode " + std::string(depth_mode));
    const auto cmode = colorMode(color_resolution);
    if (!cmode)
        return Status(
            ErrorCode::kInvalidArgument,
            "Azure Kinect calibration: unknown colour resolution " + std::string(color_resolution));
    // The recorder pads the attachment with NULs.
    while (!text.empty() &&
           (text.back() == '\0' || std::isspace(static_cast<unsigned char>(text.back()))))
        text.remove_suffix(1);
    json root;
    try {
        root = json::parse(text);
    } catch (const json::exception& e) {
        return corrupt(std::string("not JSON: ") + e.what());
    }
    try {
        return fromJson(root, *dmode, *cmode);
    } catch (const json::exception& e) {
        return corrupt(std::string("a field of another type: ") + e.what());
    }
}

namespace {

CameraComparison compareCamera(std::string name, const CameraModel& own, const CameraModel& ref,
                               double distance_m, double step_px) {
    CameraComparison c;
    c.name = std::move(name);
    c.dfx = own.fx - ref.fx;
    c.dfy = own.fy - ref.fy;
    c.dcx = own.cx - ref.cx;
    c.dcy = own.cy - ref.cy;
    double sum = 0;
    int n = 0;
    for (double y = 0; y <= ref.height - 1; y += step_px)
        for (double x = 0; x <= ref.width - 1; x += step_px) {
            const auto dir = ref.unproject({x, y});
            if (!dir || dir->z() <= 0)
                continue;
            const auto px = own.project(*dir * (distance_m / dir->z()));
            if (!px)
                continue;
            const double e = (*px - Eigen::Vector2d(x, y)).norm();
            sum += e * e;
            c.grid_max_px = std::max(c.grid_max_px, e);
            ++n;
        }
    c.grid_rms_px = n ? std::sqrt(sum / n) : 0;
    return c;
}

}  // namespace

Result<RegistrationComparison> compareRegistrations(const DepthRegistration& own,
                                                    const DepthRegistration& reference,
                                                    double distance_m, double step_px) {
    if (own.depth.width != reference.depth.width || own.depth.height != reference.depth.height ||
        own.color.width != reference.color.width || own.color.height != reference.color.height) {
        return Status(ErrorCode::kInvalidArgument,
                      "compareRegistrations: the image sizes differ (depth " +
                          std::to_string(own.depth.width) + "x" + std::to_string(own.depth.height) +
                          " vs " + std::to_string(reference.depth.width) + "x" +
                          std::to_string(reference.depth.height) + ", colour " +
                          std::to_string(own.color.width) + "x" + std::to_string(own.color.height) +
                          " vs " + std::to_string(reference.color.width) + "x" +
                          std::to_string(reference.color.height) + ")");
    }
    if (!(distance_m > 0) || !(step_px > 0))
        return Status(ErrorCode::kInvalidArgument,
                      "compareRegistrations: distance and step must be > 0");
    RegistrationComparison r;
    r.depth = compareCamera("depth", own.depth, reference.depth, distance_m, step_px);
    r.color = compareCamera("colour", own.color, reference.color, distance_m, step_px);
    r.rotation_deg =
        Eigen::AngleAxisd(own.T_color_depth.linear().transpose() * reference.T_color_depth.linear())
            .angle() *
        180 / std::numbers::pi;
    r.translation_m =
        (own.T_color_depth.translation() - reference.T_color_depth.translation()).norm();
    double sum = 0;
    int n = 0;
    const auto mapped = [&](const DepthRegistration& reg,
                            const Eigen::Vector2d& px) -> std::optional<Eigen::Vector2d> {
        const auto dir = reg.depth.unproject(px);
        if (!dir || dir->z() <= 0)
            return std::nullopt;
        return reg.color.project(reg.T_color_depth * (*dir * (distance_m / dir->z())));
    };
    for (double y = 0; y <= reference.depth.height - 1; y += step_px)
        for (double x = 0; x <= reference.depth.width - 1; x += step_px) {
            const auto a = mapped(own, {x, y});
            const auto b = mapped(reference, {x, y});
            if (!a || !b)
                continue;
            const double e = (*a - *b).norm();
            sum += e * e;
            r.registration_max_px = std::max(r.registration_max_px, e);
            ++n;
        }
    r.registration_rms_px = n ? std::sqrt(sum / n) : 0;
    return r;
}

std::string RegistrationComparison::report() const {
    std::string out;
    char line[256];
    for (const CameraComparison* c : {&depth, &color}) {
        std::snprintf(line, sizeof line,
                      "%-6s dfx %+.2f dfy %+.2f dcx %+.2f dcy %+.2f px; grid through both: "
                      "RMS %.2f px, max %.2f px\n",
                      c->name.c_str(), c->dfx, c->dfy, c->dcx, c->dcy, c->grid_rms_px,
                      c->grid_max_px);
        out += line;
    }
    std::snprintf(line, sizeof line,
                  "T_color_depth: rotation differs by %.3f deg, translation by %.1f mm\n",
                  rotation_deg, translation_m * 1e3);
    out += line;
    std::snprintf(line, sizeof line,
                  "depth pixels in the colour image: RMS %.2f px, max %.2f px apart\n",
                  registration_rms_px, registration_max_px);
    out += line;
    return out;
}

}  // namespace mixray::calibration
