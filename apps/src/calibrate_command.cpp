// mixray calibrate: camera models and poses from views of a calibration target — image folders,
// recordings, corners caches — written as a calibration file with the report a person checks
// it by (docs/calibration.md#mixray-calibrate).
#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "calibrate_live.h"
#include "calibration_report.h"
#include "cli.h"
#include "console.h"
#include "mixray/calibration/calibrate.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/corners_cache.h"
#include "mixray/calibration/depth_registration.h"
#include "mixray/calibration/detect.h"
#include "mixray/calibration/environment_alignment.h"
#include "size_option.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using namespace calibration;

struct CalibrateCommandOptions {
    std::vector<std::string> inputs;
    std::string target;
    std::vector<std::string> models;  // MODEL (every camera) or CAMERA=MODEL
    std::string solver = "auto";
    bool fix_aspect_ratio = false;
    double outlier_sigma = 3.0;
    int min_views = 4;
    std::string image_size;  // WxH of mrcal's corners caches; empty: from their images
    bool accept_weak = false;
    double max_rms_px = 2.0;
    std::vector<std::string> cameras;  // empty: every camera that saw the target
    std::string pattern = "*";
    std::vector<std::string> rigs;  // "A,B[,C]": cameras rigidly mounted together
    std::string marker;             // DICT:ID:SIZE_M, the world marker
    std::string main_camera;        // the camera that sees the marker; empty: found
    bool depth_per_pixel = false;
    std::string intrinsics;  // a calibration file whose cameras are taken, not solved
    std::vector<std::string> exports;
    std::string output = "out/calibration";
    bool report = true;
    // --live: the one input is a rig file; a session on its devices (calibrate_live.h).
    bool live = false;
    bool solve_live = false;  // after the session, calibrate its recording as below
    LiveCalibrateOptions live_options;
};

// What the inputs gave: every camera's views, and from recordings the depth streams' frames at
// the keys the target was seen at.
struct Inputs {
    std::vector<CameraViews> cameras;
    std::vector<RecordedDepth> depth;
};

struct WorldMarker {
    std::string dictionary;
    int id = 0;
    double size_m = 0;
};

Result<WorldMarker> parseMarker(const std::string& text) {
    const auto bad = [&] {
        return Status(
            ErrorCode::kInvalidArgument,
            "--marker " + text + ": expected DICTIONARY:ID:SIZE_M, e.g. DICT_6X6_250:23:0.1");
    };
    const size_t a = text.rfind(':');
    if (a == std::string::npos || a == 0)
        return bad();
    const size_t b = text.rfind(':', a - 1);
    if (b == std::string::npos || b == 0)
        return bad();
    WorldMarker m;
    m.dictionary = text.substr(0, b);
    char* end = nullptr;
    const std::string id = text.substr(b + 1, a - b - 1), size = text.substr(a + 1);
    m.id = static_cast<int>(std::strtol(id.c_str(), &end, 10));
    if (id.empty() || *end != '\0' || m.id < 0)
        return bad();
    m.size_m = std::strtod(size.c_str(), &end);
    if (size.empty() || *end != '\0' || !(m.size_m > 0 && m.size_m < 10))
        return bad();
    if (!isKnownDictionary(m.dictionary))
        return Status(ErrorCode::kInvalidArgument,
                      "--marker " + text + ": unknown dictionary " + m.dictionary);
    return m;
}

std::string deviceOf(const std::string& camera) {
    const size_t slash = camera.find('/');
    return slash == std::string::npos ? std::string() : camera.substr(0, slash);
}

std::string fixed(double v, int digits) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.*f", digits, v);
    return buffer;
}

std::string nowIso8601() {
    const std::time_t now = std::time(nullptr);
    std::tm utc{};
    gmtime_r(&now, &utc);
    char buffer[32];
    std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", &utc);
    return buffer;
}

double rotationDeg(const Eigen::Matrix<double, 6, 6>& covariance) {
    return std::sqrt(std::max(0.0, covariance.topLeftCorner<3, 3>().trace())) * 180 / M_PI;
}

double translationMm(const Eigen::Matrix<double, 6, 6>& covariance) {
    return std::sqrt(std::max(0.0, covariance.bottomRightCorner<3, 3>().trace())) * 1000;
}

// Progress of one stage on the status line: "detecting 12/40".
ProgressCallback stageProgress(StatusLine& status, const std::string& what) {
    return [&status, what](double fraction, std::string_view stage) {
        std::string text = what + ": " + std::to_string(static_cast<int>(fraction * 100)) + " %";
        if (!stage.empty())
            text += " (" + std::string(stage) + ")";
        status.update(text);
    };
}

Result<Inputs> collectInputs(const CalibrateCommandOptions& o, const CalibrationTarget& target,
                             const std::optional<ImageSize>& image_size,
                             const std::optional<WorldMarker>& marker, StatusLine& status) {
    Inputs inputs;
    DetectionOptions detection;
    if (marker)
        detection.marker_dictionary = marker->dictionary;
    for (const std::string& input : o.inputs) {
        const fs::path path(input);
        std::error_code ec;
        if (fs::is_directory(path, ec)) {
            auto views = detectInFolder(path, target, o.pattern, detection,
                                        stageProgress(status, "detecting in " + input));
            if (!views)
                return views.status();
            inputs.cameras.push_back(std::move(views).value());
        } else if (path.extension() == ".vnl") {
            auto cameras = readCornersCache(path, target, image_size);
            if (!cameras)
                return cameras.status();
            for (CameraViews& c : *cameras)
                inputs.cameras.push_back(std::move(c));
        } else if (path.extension() == ".mkv") {
            auto found = detectInRecording(path, target, detection,
                                           stageProgress(status, "detecting in " + input));
            if (!found)
                return found.status();
            for (CameraViews& c : found->cameras)
                inputs.cameras.push_back(std::move(c));
            for (RecordedDepth& d : found->depth)
                inputs.depth.push_back(std::move(d));
        } else if (!fs::exists(path, ec)) {
            return Status(ErrorCode::kNotFound, input + ": no such file or folder");
        } else {
            return Status(ErrorCode::kInvalidArgument,
                          input +
                              ": expected an image folder, a .mkv recording or a .vnl corners "
                              "cache");
        }
    }
    std::set<std::string> names;
    for (const CameraViews& c : inputs.cameras)
        if (!names.insert(c.camera).second)
            return Status(ErrorCode::kInvalidArgument,
                          "two inputs give camera " + c.camera +
                              "; calibrate them separately or give the folders distinct names");
    if (!o.cameras.empty()) {
        for (const std::string& wanted : o.cameras)
            if (!names.count(wanted))
                return Status(ErrorCode::kInvalidArgument,
                              "--camera " + wanted + ": no such camera in the inputs");
        std::erase_if(inputs.cameras, [&](const CameraViews& c) {
            return std::find(o.cameras.begin(), o.cameras.end(), c.camera) == o.cameras.end();
        });
    }
    return inputs;
}

// "opencv5" for every camera, "env/color=fisheye" for one.
Result<std::map<std::string, std::string>> cameraModels(const CalibrateCommandOptions& o,
                                                        const std::vector<CameraViews>& cameras) {
    std::string all = "opencv5";
    std::map<std::string, std::string> per_camera;
    for (const std::string& m : o.models) {
        const size_t eq = m.find('=');
        if (eq == std::string::npos) {
            all = m;
            continue;
        }
        const std::string camera = m.substr(0, eq);
        if (std::none_of(cameras.begin(), cameras.end(),
                         [&](const CameraViews& c) { return c.camera == camera; }))
            return Status(ErrorCode::kInvalidArgument,
                          "--model " + m + ": no camera " + camera + " in the inputs");
        per_camera[camera] = m.substr(eq + 1);
    }
    std::map<std::string, std::string> out;
    for (const CameraViews& c : cameras)
        out[c.camera] = per_camera.count(c.camera) ? per_camera[c.camera] : all;
    return out;
}

const CameraViews* findViews(const Inputs& inputs, const std::string& camera) {
    for (const CameraViews& c : inputs.cameras)
        if (c.camera == camera)
            return &c;
    return nullptr;
}

// The world marker's corners as the main camera saw them, by key.
std::vector<MarkerView> markerViews(const CameraViews& main, const WorldMarker& marker) {
    std::vector<MarkerView> out;
    for (const TargetView& v : main.views)
        for (const SeenMarker& d : v.markers)
            if (d.id == marker.id) {
                MarkerView m;
                m.key = v.key;
                m.corners = d.corners;
                out.push_back(m);
            }
    return out;
}

bool isWideAngle(const CameraModel& model) {
    return model.lens != LensModel::kPinhole;
}

struct Outcome {
    CalibrationFile file;
    std::map<std::string, CameraModel> models;         // every camera, solved or given
    std::map<std::string, CameraCalibration> cameras;  // the solved ones
    std::vector<RigCalibration> rigs;
    std::vector<std::string> failures;  // "camera: why"
    std::vector<std::string> notes;     // report lines on rigs, depth, alignment
};

CalibratedCamera calibratedCamera(const CameraCalibration& c) {
    CalibratedCamera out;
    out.name = c.camera;
    out.model = c.model;
    const Eigen::VectorXd stddev = c.intrinsicsStddev();
    out.intrinsics_stddev.assign(stddev.data(), stddev.data() + stddev.size());
    out.rms_px = c.rms_px;
    out.views = static_cast<int>(c.views.size());
    out.weak = c.observability.summary;
    return out;
}

void setPose(CalibrationFile& file, const std::string& camera, const std::string& parent,
             const Eigen::Isometry3d& T_parent_camera,
             const Eigen::Matrix<double, 6, 6>& covariance) {
    for (CalibratedCamera& c : file.cameras)
        if (c.name == camera) {
            c.parent = parent;
            c.T_parent_camera = T_parent_camera;
            c.pose_covariance = covariance;
        }
}

void noteRig(Outcome& outcome, const RigCalibration& rig) {
    for (size_t i = 0; i < rig.cameras.size(); ++i) {
        if (rig.cameras[i].camera == rig.reference)
            continue;
        const Eigen::Isometry3d& T = rig.T_ref_camera[i];
        const Eigen::AngleAxisd r(T.linear());
        outcome.notes.push_back("T_" + rig.reference + "_" + rig.cameras[i].camera +
                                ": translation [" + fixed(T.translation().x() * 1000, 2) + ", " +
                                fixed(T.translation().y() * 1000, 2) + ", " +
                                fixed(T.translation().z() * 1000, 2) + "] mm ± " +
                                fixed(translationMm(rig.pose_covariance[i]), 3) + " mm, rotation " +
                                fixed(r.angle() * 180 / M_PI, 3) + "° ± " +
                                fixed(rotationDeg(rig.pose_covariance[i]), 4) + "°; joint RMS " +
                                fixed(rig.rms_px, 3) + " px");
    }
    // Views the joint solve renumbered or left out: a user checks them (a detector's corner
    // order, a frame paired with the wrong instant).
    for (const RigViewChange& change : rig.changes)
        outcome.notes.push_back("rig of " + rig.reference + ": " + change.message);
}

Outcome solve(const CalibrateCommandOptions& o, const Inputs& inputs,
              const std::map<std::string, std::string>& models, const CalibrationFile& given,
              Solver solver, const std::optional<WorldMarker>& marker, StatusLine& status) {
    Outcome outcome;
    outcome.file.target = inputs.cameras.empty() ? "" : inputs.cameras.front().target.spec();
    outcome.file.created = nowIso8601() + " mixray calibrate";
    CalibrationOptions base;
    base.solver = solver;
    base.fix_aspect_ratio = o.fix_aspect_ratio;
    base.outlier_sigma = o.outlier_sigma;
    base.min_views = o.min_views;
    base.accept_weak = o.accept_weak;
    base.max_rms_px = o.max_rms_px;

    // Every camera on its own, unless its intrinsics are given.
    for (const CameraViews& views : inputs.cameras) {
        if (const CalibratedCamera* known = given.find(views.camera)) {
            CalibratedCamera entry = *known;
            entry.parent.clear();
            entry.pose_covariance.reset();
            outcome.file.cameras.push_back(entry);
            outcome.models[views.camera] = known->model;
            continue;
        }
        CalibrationOptions options = base;
        options.model = models.at(views.camera);
        options.progress = stageProgress(status, "calibrating " + views.camera);
        auto result = calibrateCamera(views, options);
        if (!result) {
            outcome.failures.push_back(views.camera + ": " + result.status().message());
            continue;
        }
        outcome.file.cameras.push_back(calibratedCamera(*result));
        outcome.models[views.camera] = result->model;
        outcome.cameras[views.camera] = std::move(result).value();
    }

    // Kinect-like devices: a depth stream aligned with a calibrated IR camera, and a colour
    // camera on the same device.
    std::set<std::string> in_rig;
    for (const RecordedDepth& recorded : inputs.depth) {
        if (recorded.aligned_with.empty())
            continue;  // registered depth, or nothing says which camera it is aligned with
        const std::string& stream = recorded.stream;
        const std::string& ir_name = recorded.aligned_with;
        const std::string color_name = deviceOf(ir_name) + "/color";
        const CameraViews* ir = findViews(inputs, ir_name);
        const CameraViews* color = findViews(inputs, color_name);
        if (!ir || !color || !outcome.cameras.count(ir_name) ||
            !outcome.cameras.count(color_name)) {
            outcome.notes.push_back(stream + ": not calibrated (needs " + ir_name + " and " +
                                    color_name + " calibrated)");
            continue;
        }
        std::vector<KeyedDepth> depth;
        for (const KeyedDepthImage& d : recorded.frames)
            depth.push_back({d.key, d.depth_mm.view()});
        KinectCalibrationOptions options;
        options.rig.camera = base;
        options.rig.camera.model = models.at(color_name);
        options.rig.models[ir_name] = models.at(ir_name);
        options.rig.reference = color_name;
        options.rig.solved = {{color_name, outcome.cameras.at(color_name)},
                              {ir_name, outcome.cameras.at(ir_name)}};
        options.depth.per_pixel = o.depth_per_pixel;
        status.update("calibrating " + stream + " (depth↔colour)");
        auto kinect = calibrateKinect(*color, *ir, depth, options);
        if (!kinect) {
            outcome.failures.push_back(stream + ": " + kinect.status().message());
            continue;
        }
        for (size_t i = 0; i < kinect->rig.cameras.size(); ++i)
            if (kinect->rig.cameras[i].camera != color_name)
                setPose(outcome.file, kinect->rig.cameras[i].camera, color_name,
                        kinect->rig.T_ref_camera[i], kinect->rig.pose_covariance[i]);
        CalibratedDepth entry;
        entry.stream = stream;
        entry.depth_camera = ir_name;
        entry.color_camera = color_name;
        entry.correction = kinect->registration.correction;
        outcome.file.depth.push_back(entry);
        noteRig(outcome, kinect->rig);
        const DepthCorrectionFit& fit = kinect->depth_fit;
        outcome.notes.push_back(
            stream + ": depth correction z' = " + fixed(fit.correction.scale, 5) + " z + " +
            fixed(fit.correction.offset_m * 1000, 2) + " mm" +
            (fit.correction.distortion.empty() ? "" : " + per-pixel term") + "; " +
            std::to_string(fit.samples) + " readings, RMS to the board planes " +
            fixed(fit.rms_before_m * 1000, 2) + " mm → " + fixed(fit.rms_after_m * 1000, 2) +
            " mm");
        in_rig.insert(ir_name);
        in_rig.insert(color_name);
        outcome.rigs.push_back(std::move(kinect->rig));
    }

    // Rigs the user names.
    for (const std::string& list : o.rigs) {
        std::vector<CameraViews> members;
        std::stringstream names(list);
        std::string name;
        bool complete = true;
        while (std::getline(names, name, ',')) {
            const CameraViews* v = findViews(inputs, name);
            if (!v || !outcome.cameras.count(name)) {
                outcome.failures.push_back("--rig " + list + ": " + name +
                                           (v ? " did not calibrate" : " is not in the inputs"));
                complete = false;
                break;
            }
            members.push_back(*v);
        }
        if (!complete)
            continue;
        RigOptions options;
        options.camera = base;
        for (const CameraViews& m : members)
            options.models[m.camera] = models.at(m.camera);
        options.camera.model = models.at(members.front().camera);
        for (const CameraViews& m : members)
            options.solved[m.camera] = outcome.cameras.at(m.camera);
        status.update("calibrating rig " + list);
        auto rig = calibrateRig(members, options);
        if (!rig) {
            outcome.failures.push_back("--rig " + list + ": " + rig.status().message());
            continue;
        }
        for (size_t i = 0; i < rig->cameras.size(); ++i) {
            in_rig.insert(rig->cameras[i].camera);
            if (rig->cameras[i].camera != rig->reference)
                setPose(outcome.file, rig->cameras[i].camera, rig->reference, rig->T_ref_camera[i],
                        rig->pose_covariance[i]);
        }
        noteRig(outcome, *rig);
        outcome.rigs.push_back(std::move(rig).value());
    }

    // Wide-angle environment cameras aligned to the world marker through the main camera.
    if (marker) {
        std::string main_name = o.main_camera;
        std::vector<MarkerView> marker_views;
        if (main_name.empty()) {
            for (const CameraViews& c : inputs.cameras)
                if (outcome.models.count(c.camera) && !isWideAngle(outcome.models.at(c.camera)) &&
                    !markerViews(c, *marker).empty()) {
                    main_name = c.camera;
                    break;
                }
        }
        const CameraViews* main = main_name.empty() ? nullptr : findViews(inputs, main_name);
        if (main)
            marker_views = markerViews(*main, *marker);
        if (!main || !outcome.models.count(main_name) || marker_views.empty()) {
            outcome.failures.push_back(
                "--marker: " +
                (main_name.empty()
                     ? std::string("no calibrated camera sees marker ") + std::to_string(marker->id)
                     : main_name + " is not calibrated or never sees marker " +
                           std::to_string(marker->id)));
        } else {
            for (const CameraViews& env : inputs.cameras) {
                if (env.camera == main_name || !outcome.models.count(env.camera) ||
                    deviceOf(env.camera) == deviceOf(main_name) ||
                    !isWideAngle(outcome.models.at(env.camera)))
                    continue;
                EnvironmentAlignmentOptions options;
                options.marker_size_m = marker->size_m;
                status.update("aligning " + env.camera + " to the marker");
                auto aligned = alignEnvironmentCamera(outcome.models.at(main_name),
                                                      outcome.models.at(env.camera), *main, env,
                                                      marker_views, options);
                if (!aligned) {
                    outcome.failures.push_back(env.camera +
                                               " alignment: " + aligned.status().message());
                    continue;
                }
                setPose(outcome.file, env.camera, "world", aligned->T_world_env,
                        aligned->covariance);
                const Eigen::Isometry3d& T = aligned->T_world_env;
                outcome.notes.push_back(
                    "T_world_" + env.camera + ": translation [" +
                    fixed(T.translation().x() * 1000, 1) + ", " +
                    fixed(T.translation().y() * 1000, 1) + ", " +
                    fixed(T.translation().z() * 1000, 1) + "] mm ± " +
                    fixed(translationMm(aligned->covariance), 2) + " mm, rotation ± " +
                    fixed(rotationDeg(aligned->covariance), 4) + "°; " +
                    std::to_string(aligned->keys.size()) + " views, RMS " +
                    fixed(aligned->rms_px, 3) + " px (environment " +
                    fixed(aligned->env_rms_px, 3) + ", main " + fixed(aligned->main_rms_px, 3) +
                    ", marker " + fixed(aligned->marker_rms_px, 3) + ")");
            }
        }
    }
    return outcome;
}

std::string intrinsicsLine(const CameraCalibration& c) {
    const Eigen::VectorXd s = c.intrinsicsStddev();
    const auto pm = [&](double v, Eigen::Index i) {
        return fixed(v, 2) + (i < s.size() ? " ± " + fixed(s[i], 2) : std::string());
    };
    return "fx " + pm(c.model.fx, 0) + ", fy " + pm(c.model.fy, 1) + ", cx " + pm(c.model.cx, 2) +
           ", cy " + pm(c.model.cy, 3);
}

// The pictures and tables: per camera residuals, coverage, uncertainty and views; per rig a
// diagram; report.md ties them together.
Status writeReport(const fs::path& dir, const Inputs& inputs, const Outcome& outcome,
                   StatusLine& status) {
    std::ostringstream md;
    md << "# Calibration report\n\n"
       << outcome.file.created << ", target `" << outcome.file.target << "`\n\n";
    md << "| camera | model | views used | corners rejected as outliers | RMS (px) | "
          "intrinsics |\n|---|---|---|---|---|---|\n";
    for (const auto& [name, c] : outcome.cameras)
        md << "| " << name << " | " << toString(c.model.lens) << " (" << c.model.distortion.size()
           << " coefficients, " << toString(c.solver) << ") | " << c.views.size() << " | "
           << c.outliers << " | " << fixed(c.rms_px, 3) << " | " << intrinsicsLine(c) << " |\n";
    for (const auto& [name, c] : outcome.cameras) {
        const std::string stem = reportFileStem(name);
        status.update("report: " + name);
        md << "\n## " << name << "\n\n";
        MIXRAY_RETURN_IF_ERROR(writeResidualPlot(dir / (stem + "_residuals.png"), c));
        MIXRAY_RETURN_IF_ERROR(writeCoverageMap(dir / (stem + "_coverage.png"), c));
        md << "![residuals](" << stem << "_residuals.png) ![coverage](" << stem << "_coverage.png)";
        auto uncertainty = projectionUncertainty(c);
        if (uncertainty) {
            MIXRAY_RETURN_IF_ERROR(writeUncertaintyMap(
                dir / (stem + "_uncertainty.png"), *uncertainty, c.model.width, c.model.height));
            md << " ![uncertainty](" << stem << "_uncertainty.png)";
        } else {
            md << "\n\nNo uncertainty map: " << uncertainty.status().message();
        }
        md << "\n\n" << viewTable(c, findViews(inputs, name));
    }
    for (size_t i = 0; i < outcome.rigs.size(); ++i) {
        const std::string png = "rig_" + reportFileStem(outcome.rigs[i].reference) + ".png";
        MIXRAY_RETURN_IF_ERROR(writeRigDiagram(dir / png, outcome.rigs[i]));
        md << "\n## Rig of " << outcome.rigs[i].reference << "\n\n![rig](" << png << ")\n";
    }
    if (!outcome.notes.empty()) {
        md << "\n## Poses, depth and alignment\n\n";
        for (const std::string& n : outcome.notes)
            md << "- " << n << "\n";
    }
    if (!outcome.failures.empty()) {
        md << "\n## Not calibrated\n\n";
        for (const std::string& f : outcome.failures)
            md << "- " << f << "\n";
    }
    std::ofstream out(dir / "report.md");
    out << md.str();
    if (!out.flush())
        return Status(ErrorCode::kIoError, (dir / "report.md").string() + ": cannot be written");
    return Status::ok();
}

Status writeExports(const fs::path& dir, const CalibrationFile& file,
                    const std::vector<std::string>& formats) {
    for (const std::string& name : formats) {
        const auto format = calibrationFormatFromString(name);
        if (!format || *format == CalibrationFormat::kMixray)
            return Status(ErrorCode::kInvalidArgument,
                          "--export " + name + ": expected opencv, mrcal, kalibr or ros");
        if (*format == CalibrationFormat::kKalibr) {
            MIXRAY_RETURN_IF_ERROR(exportCalibration(dir / "camchain.yaml", file, *format));
            continue;
        }
        for (const CalibratedCamera& c : file.cameras) {
            const std::string stem = reportFileStem(c.name);
            const fs::path path =
                dir / (*format == CalibrationFormat::kOpenCV  ? stem + ".opencv.yml"
                       : *format == CalibrationFormat::kMrcal ? stem + ".cameramodel"
                                                              : stem + ".camera_info.yaml");
            MIXRAY_RETURN_IF_ERROR(exportCalibration(path, file, *format, c.name));
        }
    }
    return Status::ok();
}

int runCalibrate(const CalibrateCommandOptions& o);

int runLive(const CalibrateCommandOptions& o) {
    const std::string ext = o.inputs.empty() ? "" : fs::path(o.inputs[0]).extension().string();
    if (o.inputs.size() != 1 || !(ext == ".yaml" || ext == ".yml"))
        return fail("calibrate", {ErrorCode::kInvalidArgument,
                                  "--live takes one rig file (RIG.yaml) as its input"});
    LiveCalibrateOptions live = o.live_options;
    live.rig = o.inputs[0];
    live.target = o.target;
    live.output = o.output;
    if (!o.solve_live)
        return runCalibrateLive(live, {});
    return runCalibrateLive(live, [&o](const std::string& recording) {
        CalibrateCommandOptions offline = o;
        offline.live = false;
        offline.inputs = {recording};
        std::printf("solving %s\n", recording.c_str());
        return runCalibrate(offline);
    });
}

int runCalibrate(const CalibrateCommandOptions& o) {
    const auto start = std::chrono::steady_clock::now();
    auto target = parseTarget(o.target);
    if (!target)
        return fail("calibrate", target.status().withContext("--target"));
    const auto solver = solverFromString(o.solver);
    if (!solver)
        return fail("calibrate", {ErrorCode::kInvalidArgument,
                                  "--solver " + o.solver + ": expected auto, ceres or mrcal"});
    std::optional<WorldMarker> marker;
    if (!o.marker.empty()) {
        auto parsed = parseMarker(o.marker);
        if (!parsed)
            return fail("calibrate", parsed.status());
        marker = *parsed;
    }
    for (const std::string& name : o.exports) {
        const auto format = calibrationFormatFromString(name);
        if (!format || *format == CalibrationFormat::kMixray)
            return fail("calibrate",
                        {ErrorCode::kInvalidArgument,
                         "--export " + name + ": expected opencv, mrcal, kalibr or ros"});
    }
    std::optional<ImageSize> image_size;
    if (!o.image_size.empty()) {
        auto size = parseSize("--image-size", o.image_size);
        if (!size)
            return fail("calibrate", size.status());
        image_size = ImageSize{size->first, size->second};
    }
    const fs::path dir(o.output);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec)
        return fail("calibrate",
                    {ErrorCode::kIoError, "cannot create " + dir.string() + ": " + ec.message()});

    StatusLine status;
    auto inputs = collectInputs(o, *target, image_size, marker, status);
    if (!inputs) {
        status.finish();
        return fail("calibrate", inputs.status());
    }
    if (inputs->cameras.empty()) {
        status.finish();
        return fail("calibrate", {ErrorCode::kInvalidArgument, "no camera to calibrate"});
    }
    // The corners first: a solve that fails can be rerun from them without the images.
    if (Status s = writeCornersCache(dir / "corners.vnl", inputs->cameras); !s) {
        status.finish();
        return fail("calibrate", s);
    }
    for (const CameraViews& c : inputs->cameras) {
        const auto usable = c.usable().size();
        std::printf("%s: target in %zu of %zu views\n", c.camera.c_str(), usable, c.views.size());
    }
    auto models = cameraModels(o, inputs->cameras);
    if (!models) {
        status.finish();
        return fail("calibrate", models.status());
    }
    CalibrationFile given;
    if (!o.intrinsics.empty()) {
        auto read = importCalibration(o.intrinsics);
        if (!read) {
            status.finish();
            return fail("calibrate", read.status().withContext("--intrinsics"));
        }
        given = std::move(read).value();
    }
    Outcome outcome = solve(o, *inputs, *models, given, *solver, marker, status);
    if (outcome.models.empty()) {
        status.finish();
        std::fprintf(stderr, "mixray calibrate: no camera calibrated (corners kept in %s):\n",
                     (dir / "corners.vnl").string().c_str());
        for (const std::string& f : outcome.failures)
            std::fprintf(stderr, "  %s\n", f.c_str());
        return kExitBadInput;
    }
    if (Status s = writeCalibrationFile(dir / "calibration.yaml", outcome.file); !s) {
        status.finish();
        return fail("calibrate", s);
    }
    if (o.report) {
        if (Status s = writeReport(dir, *inputs, outcome, status); !s) {
            status.finish();
            return fail("calibrate", s);
        }
    }
    if (Status s = writeExports(dir, outcome.file, o.exports); !s) {
        status.finish();
        return fail("calibrate", s);
    }
    status.finish();

    for (const auto& [name, c] : outcome.cameras) {
        std::printf("%s: %s, %zu views, RMS %.3f px, %d outliers; %s\n", name.c_str(),
                    std::string(toString(c.model.lens)).c_str(), c.views.size(), c.rms_px,
                    c.outliers, intrinsicsLine(c).c_str());
        if (!c.observability.summary.empty())
            std::printf("%s: weakly determined, kept (--accept-weak): %s\n", name.c_str(),
                        c.observability.summary.c_str());
    }
    for (const std::string& n : outcome.notes)
        std::printf("%s\n", n.c_str());
    for (const std::string& f : outcome.failures)
        std::fprintf(stderr, "not calibrated: %s\n", f.c_str());
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("wrote %s%s in %.1f s\n", (dir / "calibration.yaml").string().c_str(),
                o.report ? " and report.md" : "", seconds);
    return outcome.failures.empty() ? kExitOk : kExitBadInput;
}

}  // namespace

void registerCalibrateCommand(CLI::App& app, Commands& commands) {
    auto o = std::make_shared<CalibrateCommandOptions>();
    CLI::App* sub = app.add_subcommand(
        "calibrate",
        "Calibrate cameras from views of a target: intrinsics with uncertainty, rigs by bundle "
        "adjustment, Kinect depth↔colour and the fish-eye environment camera's pose to the "
        "marker; writes calibration.yaml, corners.vnl and a report with pictures");
    sub->add_option("inputs", o->inputs,
                    "Image folders (one camera each, named after the folder), mixray recordings "
                    "(.mkv: every image stream) or corners caches (.vnl); with --live, a rig "
                    "file (RIG.yaml)")
        ->required();
    sub->add_option("--target", o->target,
                    "The target: chessboard:COLSxROWS:SQUARE_M, "
                    "charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT or aprilgrid:COLSxROWS:TAG_M:SPACING")
        ->required();
    sub->add_option("--model", o->models,
                    "Lens model for every camera (opencv4, opencv5, opencv8, fisheye, or a mrcal "
                    "LENSMODEL_...), or CAMERA=MODEL for one; default opencv5");
    sub->add_option("--solver", o->solver, "auto (mrcal where it has the model), ceres or mrcal")
        ->capture_default_str();
    sub->add_flag("--fix-aspect-ratio", o->fix_aspect_ratio, "fx = fy (Ceres)");
    sub->add_option("--outlier-sigma", o->outlier_sigma,
                    "Drop corners beyond this many standard deviations and solve again; 0: keep "
                    "every corner. The mrcal solver uses mrcal's own rejection (its fixed 4/5 "
                    "sigma thresholds, as mrcal-calibrate-cameras) whenever this is not 0")
        ->check(CLI::Range(0.0, 100.0))
        ->capture_default_str();
    sub->add_option("--image-size", o->image_size,
                    "WIDTHxHEIGHT of the images of mrcal's corners caches (.vnl), which do not "
                    "say; default: read from the first image the cache names");
    sub->add_option("--min-views", o->min_views, "Fewer usable views is an error")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    sub->add_flag("--accept-weak", o->accept_weak,
                  "Keep a solve whose fx, fy, cx or cy is weakly determined (1σ above 2 % of "
                  "the focal length: views tilted alike) instead of failing; the weakness and "
                  "the uncertainty go into calibration.yaml (weak:, intrinsics_stddev:) and the "
                  "report");
    sub->add_option("--max-rms", o->max_rms_px,
                    "A camera whose RMS reprojection error (px) is above this is not calibrated: "
                    "its corners do not fit one camera and board (0: no limit)")
        ->check(CLI::Range(0.0, 1000.0))
        ->capture_default_str();
    sub->add_option("--camera", o->cameras, "Calibrate only these cameras (repeatable)");
    sub->add_option("--pattern", o->pattern, "Image file names in folders (wildcards * and ?)")
        ->capture_default_str();
    sub->add_option("--rig", o->rigs,
                    "Cameras mounted rigidly together, A,B[,C...]: joint bundle adjustment of "
                    "their poses in A's frame (repeatable; a Kinect's colour and IR cameras are "
                    "found by themselves)");
    sub->add_option("--marker", o->marker,
                    "The world marker, DICTIONARY:ID:SIZE_M: wide-angle cameras on other devices "
                    "are aligned to it through the camera that sees it");
    sub->add_option("--main", o->main_camera,
                    "The camera that sees the world marker (default: the first that does)");
    sub->add_flag("--depth-per-pixel", o->depth_per_pixel,
                  "Fit Herrera's per-pixel depth distortion besides scale and offset");
    sub->add_option("--intrinsics", o->intrinsics,
                    "A calibration file (any format --export writes, or mixray's) whose cameras "
                    "keep their intrinsics instead of being solved (an environment camera "
                    "calibrated from close-up views)");
    sub->add_option("--export", o->exports,
                    "Also write opencv, mrcal, kalibr or ros files (repeatable)");
    sub->add_option("-o,--output", o->output, "Output folder")->capture_default_str();
    sub->add_flag("!--no-report", o->report, "Skip the report's pictures and tables");
    sub->add_flag("--live", o->live,
                  "A live session on the rig's devices (the input is RIG.yaml): judges each "
                  "camera's newest view of the target (kept, or the rule that rejected it), "
                  "shows coverage, tilts and views seen by camera pairs, and records the kept "
                  "views; ends with the devices, --duration or Ctrl-C (exit 0)");
    sub->add_option("--view", o->live_options.view,
                    "--live: serve the live view at [ADDR:]PORT (loopback unless ADDR is given; "
                    "docs/live-view.md)");
    addViewTokenOption(*sub, o->live_options.view_token);
    sub->add_option("--record", o->live_options.record,
                    "--live: the recording of the kept views (default OUTPUT/live_session.mkv)");
    sub->add_option("--duration", o->live_options.duration_s,
                    "--live: end the session after this many seconds (0: with the devices)")
        ->check(CLI::Range(0.0, 1e9));
    sub->add_option("--min-shift", o->live_options.min_shift_px,
                    "--live: a view whose corners moved less than this many pixels from a kept "
                    "view's is rejected as too similar (0: 2 % of the image diagonal)")
        ->check(CLI::Range(0.0, 10000.0));
    sub->add_option("--views-wanted", o->live_options.views_wanted,
                    "--live: kept views per camera before it stops being listed as missing")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    sub->add_option("--pair-views", o->live_options.pair_views_wanted,
                    "--live: views seen by both cameras of each pair wanted (and kept even when "
                    "too similar until reached)")
        ->check(CLI::Range(0, 100000))
        ->capture_default_str();
    sub->add_flag("--solve", o->solve_live,
                  "--live: after the session, calibrate its recording with the options above");
    commands.push_back({sub, [o] { return o->live ? runLive(*o) : runCalibrate(*o); }});
}

}  // namespace mixray::cli
