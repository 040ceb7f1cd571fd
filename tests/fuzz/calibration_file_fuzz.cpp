// libFuzzer target for the calibration files mixray reads (calibration_file.h): its own file,
// OpenCV FileStorage, mrcal .cameramodel, Kalibr camchain.yaml and ROS camera_info, each named
// or recognised from the content, and the Azure Kinect factory calibration.json
// (parseAzureKinectCalibration). The first byte picks the reader (modulo 8: 0 mixray, 1 OpenCV,
// 2 mrcal, 3 Kalibr, 4 ROS, 5 recognised, 6 and 7 Azure Kinect with a depth mode and colour
// resolution from the byte's upper bits); the rest is the file. A rejection is kCorruptData naming
// the file (kUnsupported for an mrcal lens or Azure model mixray has none for), never a throw or a
// crash; an accepted file writes out in its own format and in mixray's and reads back to the same
// cameras; an accepted Azure calibration is a valid registration.
#include <unistd.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <string_view>

#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/depth_registration.h"

namespace {

namespace fs = std::filesystem;
using namespace mixray;
using namespace mixray::calibration;

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "calibration_file_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

// in/ holds the input, out/ what is written: same file names, so one-camera formats name the
// camera after the file the same way both times.
const fs::path& scratch() {
    static const fs::path dir = [] {
        fs::path d =
            fs::temp_directory_path() / ("calibration_file_fuzz." + std::to_string(getpid()));
        fs::create_directories(d / "in");
        fs::create_directories(d / "out");
        return d;
    }();
    return dir;
}

struct Reader {
    const char* file;  // named so that the format writes what it reads (OpenCV: YAML)
    std::optional<CalibrationFormat> format;
};

constexpr std::array<Reader, 6> kReaders = {{
    {"rig.yaml", CalibrationFormat::kMixray},
    {"camera.yml", CalibrationFormat::kOpenCV},
    {"camera.cameramodel", CalibrationFormat::kMrcal},
    {"camchain.yaml", CalibrationFormat::kKalibr},
    {"ost.yaml", CalibrationFormat::kRos},
    {"calibration.yaml", std::nullopt},
}};

// Distortion without the zero terms a format's fixed length adds (ROS's plumb_bob writes k3,
// Kalibr's radtan drops it): the same projection.
std::vector<double> trimmed(const CameraModel& m) {
    std::vector<double> d = m.distortion;
    if (m.lens == LensModel::kPinhole) {
        while (!d.empty() && d.back() == 0)
            d.pop_back();
    }
    return d;
}

bool sameModel(const CameraModel& a, const CameraModel& b, bool exact) {
    return a.lens == b.lens && a.width == b.width && a.height == b.height && a.fx == b.fx &&
           a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.spline == b.spline &&
           (exact ? a.distortion == b.distortion : trimmed(a) == trimmed(b));
}

// The cameras' names, models and poses; with `exact` (mixray's own format) every other field.
void expectSame(const CalibrationFile& a, const CalibrationFile& b, bool exact, const char* how) {
    if (a.cameras.size() != b.cameras.size())
        broken(how, "another number of cameras");
    for (size_t i = 0; i < a.cameras.size(); ++i) {
        const CalibratedCamera& x = a.cameras[i];
        const CalibratedCamera& y = b.cameras[i];
        if (x.name != y.name)
            broken(how, "camera " + x.name + " comes back as " + y.name);
        if (!sameModel(x.model, y.model, exact))
            broken(how, "camera " + x.name + "'s model changed");
        if (x.parent != y.parent)
            broken(how, "camera " + x.name + "'s parent changed");
        if (!x.parent.empty() && !x.T_parent_camera.isApprox(y.T_parent_camera, 1e-9))
            broken(how, "camera " + x.name + "'s pose changed");
        if (!exact)
            continue;
        if (x.pose_covariance.has_value() != y.pose_covariance.has_value() ||
            (x.pose_covariance && *x.pose_covariance != *y.pose_covariance) ||
            x.intrinsics_stddev != y.intrinsics_stddev || x.rms_px != y.rms_px ||
            x.views != y.views || x.weak != y.weak || x.lens.has_value() != y.lens.has_value() ||
            (x.lens && (x.lens->f_number != y.lens->f_number ||
                        x.lens->focal_length_mm != y.lens->focal_length_mm ||
                        x.lens->focus_distance_m != y.lens->focus_distance_m)))
            broken(how, "camera " + x.name + "'s uncertainty, statistics or lens changed");
    }
    if (!exact)
        return;
    if (a.target != b.target || a.created != b.created)
        broken(how, "target or created changed");
    if (a.depth.size() != b.depth.size())
        broken(how, "another number of depth registrations");
    for (size_t i = 0; i < a.depth.size(); ++i) {
        const CalibratedDepth& x = a.depth[i];
        const CalibratedDepth& y = b.depth[i];
        const DepthCorrection& k = x.correction;
        const DepthCorrection& l = y.correction;
        if (x.stream != y.stream || x.depth_camera != y.depth_camera ||
            x.color_camera != y.color_camera || k.scale != l.scale || k.offset_m != l.offset_m ||
            k.alpha0 != l.alpha0 || k.alpha1 != l.alpha1 || k.distortion != l.distortion)
            broken(how, "depth registration " + x.stream + " changed");
    }
}

void expectRejection(const Status& status, const fs::path& path, bool unsupported_too) {
    const ErrorCode code = status.code();
    if (code != ErrorCode::kCorruptData && !(unsupported_too && code == ErrorCode::kUnsupported))
        broken("unexpected code", status.toString());
    if (status.message().rfind(path.string() + ":", 0) != 0)
        broken("message without the file", status.message());
}

// Written in `format` to out/, read back as `format`: the same cameras.
void expectRoundTrip(const CalibrationFile& file, const fs::path& name, CalibrationFormat format) {
    const fs::path out = scratch() / "out" / name;
    const std::string how = "round trip through " + std::string(toString(format));
    if (Status s = exportCalibration(out, file, format); !s)
        broken((how + ": accepted file cannot be written").c_str(), s.toString());
    auto again = importCalibration(out, format);
    if (!again)
        broken((how + ": written file does not read").c_str(), again.status().toString());
    expectSame(file, *again, format == CalibrationFormat::kMixray, how.c_str());
}

void fuzzFile(const Reader& reader, const uint8_t* data, size_t size) {
    const fs::path path = scratch() / "in" / reader.file;
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    }
    auto file = importCalibration(path, reader.format);
    if (!file) {
        // mrcal reads lens models mixray has none for (kUnsupported, naming the lens).
        expectRejection(file.status(), path,
                        !reader.format || *reader.format == CalibrationFormat::kMrcal);
        return;
    }
    if (file->cameras.empty())
        broken("accepted file without cameras", path.string());
    for (const CalibratedCamera& c : file->cameras) {
        // Only OpenCV's files may leave the image size unknown (documented): set it, as a
        // user must before writing the camera anywhere.
        if (c.model.width == 0 && c.model.height == 0 &&
            reader.format == CalibrationFormat::kOpenCV)
            continue;
        if (Status s = c.model.validate(); !s)
            broken("accepted camera does not validate", s.toString());
        if (!c.parent.empty() && !file->pose(c.parent, c.name))
            broken("accepted camera has no pose in its parent", c.name);
    }
    for (const CalibratedDepth& d : file->depth) {
        if (auto r = file->depthRegistration(d.stream); !r || !r->validate())
            broken("accepted depth registration does not validate", d.stream);
    }
    CalibrationFile sized = *file;
    for (CalibratedCamera& c : sized.cameras) {
        if (c.model.width == 0 && c.model.height == 0) {
            c.model.width = 640;
            c.model.height = 480;
        }
    }
    expectRoundTrip(sized, reader.file, CalibrationFormat::kMixray);
    if (reader.format)
        expectRoundTrip(sized, reader.file, *reader.format);
}

constexpr std::array<const char*, 5> kDepthModes = {
    "NFOV_UNBINNED", "NFOV_2X2BINNED", "WFOV_UNBINNED", "WFOV_2X2BINNED", "PASSIVE_IR"};
constexpr std::array<const char*, 6> kColorResolutions = {"720P",  "1080P", "1440P",
                                                          "1536P", "2160P", "MJPG_3072P"};

void fuzzAzure(uint8_t selector, const uint8_t* data, size_t size) {
    const unsigned mode = selector >> 3;  // 0..31
    const char* depth_mode = kDepthModes[mode % kDepthModes.size()];
    const char* color = kColorResolutions[mode / kDepthModes.size() % kColorResolutions.size()];
    auto cal = parseAzureKinectCalibration(
        std::string_view(reinterpret_cast<const char*>(data), size), depth_mode, color);
    if (!cal) {
        const ErrorCode code = cal.status().code();
        if (code != ErrorCode::kCorruptData && code != ErrorCode::kUnsupported)
            broken("unexpected Azure code", cal.status().toString());
        if (cal.status().message().rfind("Azure Kinect calibration: ", 0) != 0)
            broken("Azure message without its source", cal.status().message());
        return;
    }
    if (Status s = cal->registration.validate(); !s)
        broken("accepted Azure calibration does not validate", s.toString());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size == 0)
        return 0;
    const uint8_t selector = data[0];
    if (selector % 8 >= kReaders.size())
        fuzzAzure(selector, data + 1, size - 1);
    else
        fuzzFile(kReaders[selector % 8], data + 1, size - 1);
    return 0;
}
