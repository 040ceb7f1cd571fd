// The rig calibration file (docs/calibration.md#calibration-files): reading with file:line:field
// errors, writing that reads back to the same values, and poses composed through parents.
#include "mixray/calibration/calibration_file.h"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <utility>

#include "calibration_file_internal.h"
#include "mixray/calibration/camera_model_yaml.h"
#include "mixray/graph/yaml_reader.h"
#include "mixray/graph/yaml_writer.h"

namespace mixray::calibration {
namespace {

using yaml::find;
using yaml::Item;

constexpr std::array<std::string_view, 5> kTopKeys = {"version", "created", "target", "cameras",
                                                      "depth"};
constexpr std::array<std::string_view, 10> kCameraKeys = {
    "name",  "model", "parent", "T_parent_camera", "pose_covariance", "intrinsics_stddev", "rms_px",
    "views", "weak",  "lens"};
constexpr std::array<std::string_view, 3> kLensKeys = {"f_number", "focal_length_mm",
                                                       "focus_distance_m"};
constexpr std::array<std::string_view, 4> kDepthKeys = {"stream", "depth_camera", "color_camera",
                                                        "correction"};
constexpr std::array<std::string_view, 5> kCorrectionKeys = {"scale", "offset_m", "alpha0",
                                                             "alpha1", "distortion"};
constexpr std::array<std::string_view, 4> kMapKeys = {"width", "height", "encoding", "data"};
constexpr std::string_view kMapEncoding = "base64-float32le";
// Poses in a calibration file relate cameras of one rig or a rig to its marker; a kilometre
// is beyond any of them and catches unit mistakes (millimetres) early.
constexpr double kMaxTranslationM = 1000;

Status invalid(std::string what) {
    return Status(ErrorCode::kInvalidArgument, std::move(what));
}

std::string num(double v) {
    return yaml::shortest(v);
}

std::string poseYaml(const Eigen::Isometry3d& T) {
    const Eigen::Quaterniond q(T.linear());
    const Eigen::Vector3d t = T.translation();
    return "{translation: " + detail::yamlList({t.x(), t.y(), t.z()}) +
           ", quaternion: " + detail::yamlList({q.w(), q.x(), q.y(), q.z()}) + "}";
}

bool allFinite(const std::vector<double>& values) {
    return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

// The frames from `camera` up its parents: the cameras passed, and where the chain ends (a
// camera without a parent, or a frame that is no camera), with T_root_camera.
struct Chain {
    std::vector<std::string> path;  // camera first, root last
    Eigen::Isometry3d T_root_camera = Eigen::Isometry3d::Identity();
    const std::string& root() const { return path.back(); }
};

std::string joinPath(const std::vector<std::string>& path) {
    std::string out;
    for (const auto& p : path)
        out += (out.empty() ? "" : " -> ") + p;
    return out;
}

Result<Chain> chainOf(const CalibrationFile& file, std::string_view camera) {
    Chain chain;
    chain.path.emplace_back(camera);
    const CalibratedCamera* c = file.find(camera);
    while (c != nullptr && !c->parent.empty()) {
        chain.T_root_camera = c->T_parent_camera * chain.T_root_camera;
        if (std::find(chain.path.begin(), chain.path.end(), c->parent) != chain.path.end()) {
            chain.path.push_back(c->parent);
            return Status(ErrorCode::kCorruptData,
                          "the cameras' parents form a cycle: " + joinPath(chain.path));
        }
        chain.path.push_back(c->parent);
        c = file.find(c->parent);
    }
    return chain;
}

std::string cameraNames(const CalibrationFile& file) {
    std::string out;
    for (const auto& c : file.cameras)
        out += (out.empty() ? "" : ", ") + c.name;
    return out.empty() ? "none" : out;
}

// The checks of validateCalibrationFile() that the reader also makes once every entry is read,
// against the file's own cameras.
Status checkDepthEntry(const CalibrationFile& file, const CalibratedDepth& d) {
    for (const auto& [role, name] :
         {std::pair{"depth_camera", &d.depth_camera}, std::pair{"color_camera", &d.color_camera}}) {
        if (!file.find(*name)) {
            return invalid(std::string(role) + ": no camera \"" + *name +
                           "\" in the file (cameras: " + cameraNames(file) + ")");
        }
    }
    const DepthCorrection& k = d.correction;
    if (!std::isfinite(k.scale) || k.scale <= 0)
        return invalid("correction.scale: must be finite and above 0");
    if (!std::isfinite(k.offset_m) || !std::isfinite(k.alpha0) || !std::isfinite(k.alpha1))
        return invalid("correction: offset_m, alpha0 and alpha1 must be finite");
    if (!k.distortion.empty()) {
        const CameraModel& depth = file.find(d.depth_camera)->model;
        const size_t pixels = static_cast<size_t>(depth.width) * static_cast<size_t>(depth.height);
        if (k.distortion.size() != pixels) {
            return invalid("correction.distortion: " + std::to_string(k.distortion.size()) +
                           " values; the depth camera " + d.depth_camera + " is " +
                           std::to_string(depth.width) + "x" + std::to_string(depth.height) +
                           " pixels");
        }
        if (!std::all_of(k.distortion.begin(), k.distortion.end(),
                         [](float v) { return std::isfinite(v); })) {
            return invalid("correction.distortion: values must be finite");
        }
    }
    return Status::ok();
}

class Parser {
public:
    explicit Parser(std::string file) : r_(std::move(file)) {}

    Result<CalibrationFile> parse(std::string_view text) {
        auto root = r_.load(text, detail::kMaxCalibrationFileBytes, detail::kMaxCalibrationNesting,
                            "a calibration file");
        if (!root)
            return root.status();
        auto fields = r_.readMap(*root, kTopKeys,
                                 "a calibration file mapping with version: 1 "
                                 "and cameras:");
        if (!fields)
            return fields.status();
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, *root, "version"));
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, *root, "cameras"));
        auto version = r_.integer(*find(*fields, "version"), 1, 1);
        if (!version)
            return version.status();
        CalibrationFile file;
        for (auto [key, out] :
             {std::pair{"created", &file.created}, std::pair{"target", &file.target}}) {
            if (const Item* item = find(*fields, key)) {
                auto v = r_.text(*item);
                if (!v)
                    return v.status();
                // What writeCalibrationFile() refuses (validateCalibrationFile).
                if (std::any_of(v->begin(), v->end(),
                                [](char ch) { return static_cast<unsigned char>(ch) < 0x20; }))
                    return r_.fail(*item, "expected one line without control characters");
                *out = *v;
            }
        }
        auto cameras = r_.readList(*find(*fields, "cameras"), 1, 1024, "a list of cameras");
        if (!cameras)
            return cameras.status();
        std::vector<Item> camera_items = *cameras;
        for (const Item& item : camera_items) {
            auto camera = parseCamera(item);
            if (!camera)
                return camera.status();
            if (const CalibratedCamera* other = file.find(camera->name))
                return r_.fail(item, "a second camera named \"" + other->name + "\"");
            file.cameras.push_back(std::move(*camera));
        }
        // Parents are checked once all cameras are known: a parent may be listed after its child.
        for (size_t i = 0; i < file.cameras.size(); ++i) {
            auto chain = chainOf(file, file.cameras[i].name);
            if (!chain)
                return r_.fail(camera_items[i], chain.status().message());
        }
        if (const Item* depth = find(*fields, "depth")) {
            auto entries = r_.readList(*depth, 0, 1024, "a list of depth registrations");
            if (!entries)
                return entries.status();
            for (const Item& item : *entries) {
                auto d = parseDepth(file, item);
                if (!d)
                    return d.status();
                file.depth.push_back(std::move(*d));
            }
        }
        return file;
    }

private:
    Result<std::string> name(const Item& item) const {
        auto text = r_.text(item);
        if (!text)
            return text.status();
        if (!detail::isFrameName(*text)) {
            return r_.expected(item, "a name of 1 to 128 letters, digits, '_', '-', '.' or '/'");
        }
        return *text;
    }

    Result<CalibratedCamera> parseCamera(const Item& item) const {
        auto fields = r_.readMap(item, kCameraKeys, "a camera mapping with name: and model:");
        if (!fields)
            return fields.status();
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "name"));
        MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, "model"));
        CalibratedCamera c;
        auto n = name(*find(*fields, "name"));
        if (!n)
            return n.status();
        c.name = *n;
        const Item& model_item = *find(*fields, "model");
        auto model = readCameraModel(r_, model_item);
        if (!model)
            return model.status();
        if (Status s = model->validate(); !s)
            return r_.fail(model_item, s.message());
        c.model = *model;
        if (const Item* parent = find(*fields, "parent")) {
            auto p = name(*parent);
            if (!p)
                return p.status();
            if (*p == c.name)
                return r_.fail(*parent, "a camera cannot be its own parent");
            c.parent = *p;
        }
        if (const Item* pose = find(*fields, "T_parent_camera")) {
            if (c.parent.empty())
                return r_.fail(*pose, "a pose needs parent: (the frame it is given in)");
            auto T = r_.pose(*pose, kMaxTranslationM);
            if (!T)
                return T.status();
            c.T_parent_camera = *T;
        } else if (!c.parent.empty()) {
            return r_.require(*fields, item, "T_parent_camera");
        }
        if (const Item* cov = find(*fields, "pose_covariance")) {
            if (c.parent.empty())
                return r_.fail(*cov, "a pose covariance needs parent: and T_parent_camera:");
            auto covariance = parseCovariance(*cov);
            if (!covariance)
                return covariance.status();
            c.pose_covariance = *covariance;
        }
        if (const Item* stddev = find(*fields, "intrinsics_stddev")) {
            const size_t count = 4 + c.model.distortion.size();
            auto values = detail::readNumbers(r_, *stddev, count, count, 0, 1e9,
                                              "a list of " + std::to_string(count) +
                                                  " standard deviations (fx fy cx cy, then the " +
                                                  std::to_string(c.model.distortion.size()) +
                                                  " distortion coefficients)");
            if (!values)
                return values.status();
            c.intrinsics_stddev = *values;
        }
        if (const Item* rms = find(*fields, "rms_px")) {
            auto v = r_.number(*rms, 0, 1e6, false);
            if (!v)
                return v.status();
            c.rms_px = *v;
        }
        if (const Item* views = find(*fields, "views")) {
            auto v = r_.integer(*views, 0, 1000000);
            if (!v)
                return v.status();
            c.views = static_cast<int>(*v);
        }
        if (const Item* weak = find(*fields, "weak")) {
            auto v = r_.text(*weak);
            if (!v)
                return v.status();
            c.weak = *v;
        }
        if (const Item* lens = find(*fields, "lens")) {
            auto settings =
                r_.readMap(*lens, kLensKeys,
                           "a lens mapping with f_number:, focal_length_mm: and focus_distance_m:");
            if (!settings)
                return settings.status();
            LensSettings l;
            const std::array<std::pair<std::string_view, double*>, 3> values = {
                {{"f_number", &l.f_number},
                 {"focal_length_mm", &l.focal_length_mm},
                 {"focus_distance_m", &l.focus_distance_m}}};
            for (const auto& [key, out] : values) {
                MIXRAY_RETURN_IF_ERROR(r_.require(*settings, *lens, key));
                auto v = r_.number(*find(*settings, key), 0, 1e4, true);
                if (!v)
                    return v.status();
                *out = *v;
            }
            c.lens = l;
        }
        return c;
    }

    Result<Eigen::Matrix<double, 6, 6>> parseCovariance(const Item& item) const {
        constexpr std::string_view kExpect =
            "6 rows of 6 numbers: the covariance of [rotation vector (rad), translation (m)]";
        auto rows = r_.readList(item, 6, 6, kExpect);
        if (!rows)
            return rows.status();
        Eigen::Matrix<double, 6, 6> m;
        for (int i = 0; i < 6; ++i) {
            auto row = detail::readNumbers(r_, (*rows)[i], 6, 6, -1e6, 1e6, kExpect);
            if (!row)
                return row.status();
            for (int j = 0; j < 6; ++j)
                m(i, j) = (*row)[j];
        }
        for (int i = 0; i < 6; ++i) {
            if (m(i, i) < 0)
                return r_.fail((*rows)[i], "a variance (diagonal entry) is negative");
            for (int j = 0; j < i; ++j) {
                if (std::abs(m(i, j) - m(j, i)) > 1e-9 * std::max(std::abs(m(i, j)), 1e-300)) {
                    return r_.fail((*rows)[i], "not symmetric: entry (" + std::to_string(i) + ", " +
                                                   std::to_string(j) + ") differs from (" +
                                                   std::to_string(j) + ", " + std::to_string(i) +
                                                   ")");
                }
            }
        }
        return m;
    }

    Result<CalibratedDepth> parseDepth(const CalibrationFile& file, const Item& item) const {
        auto fields = r_.readMap(item, kDepthKeys,
                                 "a depth mapping with stream:, depth_camera:, color_camera: and "
                                 "correction:");
        if (!fields)
            return fields.status();
        for (std::string_view key : {"stream", "depth_camera", "color_camera"})
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, key));
        CalibratedDepth d;
        for (auto [key, out] :
             {std::pair{"stream", &d.stream}, std::pair{"depth_camera", &d.depth_camera},
              std::pair{"color_camera", &d.color_camera}}) {
            const Item& field = *find(*fields, key);
            auto n = name(field);
            if (!n)
                return n.status();
            if (std::string_view(key) != "stream" && !file.find(*n)) {
                return r_.fail(field, "no camera \"" + *n +
                                          "\" in the file (cameras: " + cameraNames(file) + ")");
            }
            *out = *n;
        }
        for (const auto& other : file.depth) {
            if (other.stream == d.stream)
                return r_.fail(*find(*fields, "stream"), "a second entry for this stream");
        }
        if (const Item* correction = find(*fields, "correction")) {
            auto c = parseCorrection(*correction, file.find(d.depth_camera)->model);
            if (!c)
                return c.status();
            d.correction = std::move(*c);
        }
        return d;
    }

    Result<DepthCorrection> parseCorrection(const Item& item, const CameraModel& depth) const {
        auto fields = r_.readMap(item, kCorrectionKeys,
                                 "a correction mapping with scale:, offset_m:, alpha0:, alpha1: "
                                 "and distortion:");
        if (!fields)
            return fields.status();
        DepthCorrection c;
        if (const Item* scale = find(*fields, "scale")) {
            auto v = r_.number(*scale, 0, 100, true);
            if (!v)
                return v.status();
            c.scale = *v;
        }
        for (auto [key, out] : {std::pair{"offset_m", &c.offset_m}, std::pair{"alpha0", &c.alpha0},
                                std::pair{"alpha1", &c.alpha1}}) {
            if (const Item* field = find(*fields, key)) {
                auto v = r_.number(*field, -1e6, 1e6, false);
                if (!v)
                    return v.status();
                *out = *v;
            }
        }
        if (const Item* map = find(*fields, "distortion")) {
            auto values = parseMap(*map, depth);
            if (!values)
                return values.status();
            c.distortion = std::move(*values);
        }
        return c;
    }

    Result<std::vector<float>> parseMap(const Item& item, const CameraModel& depth) const {
        auto fields = r_.readMap(item, kMapKeys,
                                 "a map with width:, height:, encoding: base64-float32le and "
                                 "data:");
        if (!fields)
            return fields.status();
        for (std::string_view key : kMapKeys)
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, key));
        auto width = r_.integer(*find(*fields, "width"), 1, 65535);
        if (!width)
            return width.status();
        auto height = r_.integer(*find(*fields, "height"), 1, 65535);
        if (!height)
            return height.status();
        if (*width != depth.width || *height != depth.height) {
            return r_.fail(item, "the map is " + std::to_string(*width) + "x" +
                                     std::to_string(*height) + "; the depth camera is " +
                                     std::to_string(depth.width) + "x" +
                                     std::to_string(depth.height));
        }
        const Item& encoding = *find(*fields, "encoding");
        if (!encoding.node.IsScalar() || encoding.node.Scalar() != kMapEncoding)
            return r_.expected(encoding, std::string(kMapEncoding));
        const Item& data = *find(*fields, "data");
        if (!data.node.IsScalar())
            return r_.expected(data, "base64 text");
        auto bytes = detail::base64Decode(data.node.Scalar());
        if (!bytes)
            return r_.fail(data, "not valid base64 text");
        const size_t count = static_cast<size_t>(*width) * static_cast<size_t>(*height);
        if (bytes->size() != count * 4) {
            return r_.fail(data, std::to_string(bytes->size()) + " bytes; a " +
                                     std::to_string(*width) + "x" + std::to_string(*height) +
                                     " float32 map is " + std::to_string(count * 4));
        }
        std::vector<float> values(count);
        for (size_t i = 0; i < count; ++i) {
            const uint32_t bits = static_cast<uint32_t>((*bytes)[4 * i]) |
                                  static_cast<uint32_t>((*bytes)[4 * i + 1]) << 8 |
                                  static_cast<uint32_t>((*bytes)[4 * i + 2]) << 16 |
                                  static_cast<uint32_t>((*bytes)[4 * i + 3]) << 24;
            std::memcpy(&values[i], &bits, sizeof bits);
            if (!std::isfinite(values[i])) {
                const auto w = static_cast<size_t>(*width);
                return r_.fail(data, "the value at column " + std::to_string(i % w) + ", row " +
                                         std::to_string(i / w) + " is not finite");
            }
        }
        return values;
    }

    yaml::Reader r_;
};

std::string mapYaml(const std::vector<float>& values, int width, int height) {
    std::vector<uint8_t> bytes(values.size() * 4);
    for (size_t i = 0; i < values.size(); ++i) {
        uint32_t bits = 0;
        std::memcpy(&bits, &values[i], sizeof bits);
        for (int b = 0; b < 4; ++b)
            bytes[4 * i + b] = static_cast<uint8_t>(bits >> (8 * b));
    }
    const std::string text = detail::base64Encode(bytes);
    std::string out = "      distortion:\n        width: " + std::to_string(width) +
                      "\n        height: " + std::to_string(height) +
                      "\n        encoding: " + std::string(kMapEncoding) + "\n        data: |\n";
    constexpr size_t kLine = 76;
    for (size_t i = 0; i < text.size(); i += kLine)
        out += "          " + text.substr(i, kLine) + "\n";
    return out;
}

}  // namespace

namespace detail {

bool isFrameName(std::string_view name) {
    return !name.empty() && name.size() <= 128 && std::all_of(name.begin(), name.end(), [](char c) {
        return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
               c == '_' || c == '-' || c == '.' || c == '/';
    });
}

Status validateCalibrationFile(const CalibrationFile& file) {
    std::set<std::string> names;
    for (size_t i = 0; i < file.cameras.size(); ++i) {
        const CalibratedCamera& c = file.cameras[i];
        const std::string where = "cameras[" + std::to_string(i) + "] (" + c.name + "): ";
        if (!isFrameName(c.name))
            return invalid(where + "name: expected 1 to 128 letters, digits, '_', '-', '.' or '/'");
        if (!names.insert(c.name).second)
            return invalid(where + "a second camera with this name");
        if (Status s = c.model.validate(); !s)
            return invalid(where + "model: " + s.message());
        if (!c.parent.empty() && !isFrameName(c.parent))
            return invalid(where + "parent: not a frame name");
        if (c.parent == c.name)
            return invalid(where + "parent: a camera cannot be its own parent");
        const Eigen::Matrix3d R = c.T_parent_camera.linear();
        if (!c.T_parent_camera.matrix().allFinite() ||
            (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
            R.determinant() < 0) {
            return invalid(where + "T_parent_camera: not a finite rigid transform");
        }
        if (c.parent.empty() && !c.T_parent_camera.isApprox(Eigen::Isometry3d::Identity(), 0)) {
            return invalid(where +
                           "T_parent_camera is set but parent is empty (the frame it is "
                           "given in)");
        }
        if (c.T_parent_camera.translation().cwiseAbs().maxCoeff() > kMaxTranslationM)
            return invalid(where + "T_parent_camera: translation beyond 1000 m");
        if (c.pose_covariance) {
            if (c.parent.empty())
                return invalid(where + "pose_covariance without a parent");
            if (!c.pose_covariance->allFinite() ||
                !c.pose_covariance->isApprox(c.pose_covariance->transpose(), 1e-9) ||
                (c.pose_covariance->diagonal().array() < 0).any()) {
                return invalid(where +
                               "pose_covariance: not a finite symmetric matrix with a "
                               "non-negative diagonal");
            }
        }
        if (!c.intrinsics_stddev.empty() &&
            (c.intrinsics_stddev.size() != 4 + c.model.distortion.size() ||
             !allFinite(c.intrinsics_stddev) ||
             *std::min_element(c.intrinsics_stddev.begin(), c.intrinsics_stddev.end()) < 0)) {
            return invalid(where + "intrinsics_stddev: expected " +
                           std::to_string(4 + c.model.distortion.size()) +
                           " finite non-negative values (fx fy cx cy, then distortion)");
        }
        if (!std::isfinite(c.rms_px) || c.rms_px < 0)
            return invalid(where + "rms_px: must be finite and non-negative");
        if (c.views < 0)
            return invalid(where + "views: must be non-negative");
        if (c.lens &&
            !(c.lens->f_number > 0 && c.lens->focal_length_mm > 0 && c.lens->focus_distance_m > 0 &&
              std::isfinite(c.lens->f_number) && std::isfinite(c.lens->focal_length_mm) &&
              std::isfinite(c.lens->focus_distance_m)))
            return invalid(where +
                           "lens: f_number, focal_length_mm and focus_distance_m must be "
                           "finite and above 0");
    }
    for (const CalibratedCamera& c : file.cameras) {
        auto chain = chainOf(file, c.name);
        if (!chain)
            return invalid(chain.status().message());
    }
    std::set<std::string> streams;
    for (size_t i = 0; i < file.depth.size(); ++i) {
        const CalibratedDepth& d = file.depth[i];
        const std::string where = "depth[" + std::to_string(i) + "] (" + d.stream + "): ";
        if (!isFrameName(d.stream))
            return invalid(where + "stream: not a stream name");
        if (!streams.insert(d.stream).second)
            return invalid(where + "a second entry for this stream");
        if (Status s = checkDepthEntry(file, d); !s)
            return invalid(where + s.message());
    }
    for (std::string_view text : {std::string_view(file.created), std::string_view(file.target)}) {
        if (std::any_of(text.begin(), text.end(),
                        [](char ch) { return static_cast<unsigned char>(ch) < 0x20; })) {
            return invalid("created and target must be one line without control characters");
        }
    }
    return Status::ok();
}

Result<std::string> readTextFile(const std::filesystem::path& path, size_t max_bytes) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec))
        return Status(ErrorCode::kNotFound, path.string() + ": no such file");
    if (std::filesystem::is_directory(path, ec))
        return Status(ErrorCode::kIoError, path.string() + ": is a directory, not a file");
    const auto size = std::filesystem::file_size(path, ec);
    if (!ec && size > max_bytes) {
        return Status(ErrorCode::kCorruptData, path.string() + ": " + std::to_string(size) +
                                                   " bytes; a calibration file " + "is at most " +
                                                   std::to_string(max_bytes));
    }
    std::ifstream in(path, std::ios::binary);
    if (!in)
        return Status(ErrorCode::kIoError,
                      path.string() + ": cannot open: " + std::strerror(errno));
    std::ostringstream text;
    text << in.rdbuf();
    if (in.bad())
        return Status(ErrorCode::kIoError, path.string() + ": read failed");
    return text.str();
}

Status writeTextFile(const std::filesystem::path& path, std::string_view text) {
    const std::filesystem::path tmp =
        path.string() + ".tmp" + std::to_string(static_cast<long>(::getpid()));
    {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) {
            return Status(ErrorCode::kIoError,
                          "cannot write " + path.string() + ": " + std::strerror(errno));
        }
        out.write(text.data(), static_cast<std::streamsize>(text.size()));
        out.flush();
        if (!out) {
            std::error_code ignored;
            std::filesystem::remove(tmp, ignored);
            return Status(ErrorCode::kIoError, "writing " + path.string() + " failed");
        }
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) {
        std::error_code ignored;
        std::filesystem::remove(tmp, ignored);
        return Status(ErrorCode::kIoError, "cannot write " + path.string() + ": " + ec.message());
    }
    return Status::ok();
}

std::string base64Encode(const std::vector<uint8_t>& bytes) {
    static constexpr char kAlphabet[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    out.reserve((bytes.size() + 2) / 3 * 4);
    for (size_t i = 0; i < bytes.size(); i += 3) {
        const uint32_t b0 = bytes[i];
        const uint32_t b1 = i + 1 < bytes.size() ? bytes[i + 1] : 0;
        const uint32_t b2 = i + 2 < bytes.size() ? bytes[i + 2] : 0;
        const uint32_t triple = b0 << 16 | b1 << 8 | b2;
        out += kAlphabet[(triple >> 18) & 63];
        out += kAlphabet[(triple >> 12) & 63];
        out += i + 1 < bytes.size() ? kAlphabet[(triple >> 6) & 63] : '=';
        out += i + 2 < bytes.size() ? kAlphabet[triple & 63] : '=';
    }
    return out;
}

std::optional<std::vector<uint8_t>> base64Decode(std::string_view text) {
    auto value = [](char c) -> int {
        if (c >= 'A' && c <= 'Z')
            return c - 'A';
        if (c >= 'a' && c <= 'z')
            return c - 'a' + 26;
        if (c >= '0' && c <= '9')
            return c - '0' + 52;
        if (c == '+')
            return 62;
        if (c == '/')
            return 63;
        return -1;
    };
    std::vector<uint8_t> out;
    uint32_t accumulator = 0;
    int bits = 0;
    size_t symbols = 0;
    size_t padding = 0;
    for (char c : text) {
        if (c == ' ' || c == '\n' || c == '\r')
            continue;
        if (c == '=') {
            ++padding;
            ++symbols;
            continue;
        }
        const int v = value(c);
        if (v < 0 || padding > 0)
            return std::nullopt;
        accumulator = (accumulator << 6) | static_cast<uint32_t>(v);
        bits += 6;
        ++symbols;
        if (bits >= 8) {
            bits -= 8;
            out.push_back(static_cast<uint8_t>(accumulator >> bits));
            accumulator &= (1u << bits) - 1;
        }
    }
    if (symbols % 4 != 0 || padding > 2)
        return std::nullopt;
    return out;
}

std::string yamlList(const std::vector<double>& values) {
    std::string out = "[";
    for (size_t i = 0; i < values.size(); ++i)
        out += (i ? ", " : "") + yaml::shortest(values[i]);
    return out + "]";
}

Result<std::vector<double>> readNumbers(const yaml::Reader& r, const yaml::Item& item,
                                        size_t min_count, size_t max_count, double min, double max,
                                        std::string_view expectation) {
    auto elements = r.readList(item, min_count, max_count, expectation);
    if (!elements)
        return elements.status();
    std::vector<double> out;
    for (const yaml::Item& e : *elements) {
        auto v = r.number(e, min, max, false);
        if (!v)
            return v.status();
        out.push_back(*v);
    }
    return out;
}

}  // namespace detail

const CalibratedCamera* CalibrationFile::find(std::string_view name) const {
    for (const auto& c : cameras) {
        if (c.name == name)
            return &c;
    }
    return nullptr;
}

Result<Eigen::Isometry3d> CalibrationFile::pose(std::string_view frame,
                                                std::string_view camera) const {
    if (!find(camera)) {
        return Status(ErrorCode::kNotFound, "no camera named \"" + std::string(camera) +
                                                "\" (cameras: " + cameraNames(*this) + ")");
    }
    auto camera_chain = chainOf(*this, camera);
    if (!camera_chain)
        return camera_chain.status();
    Chain frame_chain;
    if (find(frame)) {
        auto chain = chainOf(*this, frame);
        if (!chain)
            return chain.status();
        frame_chain = std::move(*chain);
    } else {
        const bool is_parent = std::any_of(cameras.begin(), cameras.end(),
                                           [&](const auto& c) { return c.parent == frame; });
        if (!is_parent) {
            return Status(ErrorCode::kNotFound,
                          "no frame named \"" + std::string(frame) +
                              "\": neither a camera nor any camera's parent (cameras: " +
                              cameraNames(*this) + ")");
        }
        frame_chain.path.emplace_back(frame);
    }
    if (camera_chain->root() != frame_chain.root()) {
        return Status(ErrorCode::kNotFound, "camera " + std::string(camera) + " and frame " +
                                                std::string(frame) +
                                                " are not linked: " + joinPath(camera_chain->path) +
                                                "; " + joinPath(frame_chain.path));
    }
    return Eigen::Isometry3d(frame_chain.T_root_camera.inverse() * camera_chain->T_root_camera);
}

Result<DepthRegistration> CalibrationFile::depthRegistration(std::string_view stream) const {
    const auto it = std::find_if(depth.begin(), depth.end(),
                                 [&](const CalibratedDepth& d) { return d.stream == stream; });
    if (it == depth.end()) {
        std::string streams;
        for (const auto& d : depth)
            streams += (streams.empty() ? "" : ", ") + d.stream;
        return Status(ErrorCode::kNotFound,
                      "no depth registration for stream \"" + std::string(stream) +
                          "\" (registered: " + (streams.empty() ? "none" : streams) + ")");
    }
    const CalibratedCamera* depth_camera = find(it->depth_camera);
    const CalibratedCamera* color_camera = find(it->color_camera);
    if (!depth_camera || !color_camera) {
        return Status(ErrorCode::kNotFound, "depth registration of " + it->stream +
                                                " names cameras the file lacks: " +
                                                it->depth_camera + ", " + it->color_camera);
    }
    auto T_color_depth = pose(it->color_camera, it->depth_camera);
    if (!T_color_depth) {
        return T_color_depth.status().withContext("depth registration of " + it->stream);
    }
    DepthRegistration registration;
    registration.depth = depth_camera->model;
    registration.color = color_camera->model;
    registration.T_color_depth = *T_color_depth;
    registration.correction = it->correction;
    return registration;
}

Result<CalibrationFile> readCalibrationFile(const std::filesystem::path& path) {
    auto text = detail::readTextFile(path, detail::kMaxCalibrationFileBytes);
    if (!text)
        return text.status();
    try {
        Parser parser(path.string());
        return parser.parse(*text);
    } catch (const YAML::Exception& e) {
        return Status(ErrorCode::kCorruptData, path.string() + ": " + e.what());
    }
}

Status writeCalibrationFile(const std::filesystem::path& path, const CalibrationFile& file) {
    if (Status s = detail::validateCalibrationFile(file); !s)
        return s.withContext("writing " + path.string());
    std::ostringstream o;
    o << "# mixray calibration (docs/calibration.md#calibration-files). T_parent_camera maps the\n"
         "# camera's frame into its parent's: {translation (m), quaternion [w, x, y, z]};\n"
         "# pose_covariance is over [rotation vector (rad), translation (m)].\n";
    o << "version: 1\n";
    if (!file.created.empty())
        o << "created: " << yaml::doubleQuoted(file.created) << "\n";
    if (!file.target.empty())
        o << "target: " << yaml::doubleQuoted(file.target) << "\n";
    o << "cameras:\n";
    for (const CalibratedCamera& c : file.cameras) {
        o << "  - name: " << yaml::doubleQuoted(c.name) << "\n";
        o << "    model: " << cameraModelYaml(c.model) << "\n";
        if (!c.parent.empty()) {
            o << "    parent: " << yaml::doubleQuoted(c.parent) << "\n";
            o << "    T_parent_camera: " << poseYaml(c.T_parent_camera) << "\n";
        }
        if (c.pose_covariance) {
            o << "    pose_covariance:\n";
            for (int i = 0; i < 6; ++i) {
                std::vector<double> row(6);
                for (int j = 0; j < 6; ++j)
                    row[j] = (*c.pose_covariance)(i, j);
                o << "      - " << detail::yamlList(row) << "\n";
            }
        }
        if (!c.intrinsics_stddev.empty())
            o << "    intrinsics_stddev: " << detail::yamlList(c.intrinsics_stddev) << "\n";
        if (c.rms_px > 0)
            o << "    rms_px: " << num(c.rms_px) << "\n";
        if (c.views > 0)
            o << "    views: " << c.views << "\n";
        if (!c.weak.empty())
            o << "    weak: " << yaml::doubleQuoted(c.weak) << "\n";
        if (c.lens)
            o << "    lens: {f_number: " << num(c.lens->f_number)
              << ", focal_length_mm: " << num(c.lens->focal_length_mm)
              << ", focus_distance_m: " << num(c.lens->focus_distance_m) << "}\n";
    }
    if (!file.depth.empty()) {
        o << "depth:\n";
        for (const CalibratedDepth& d : file.depth) {
            const DepthCorrection& k = d.correction;
            o << "  - stream: " << yaml::doubleQuoted(d.stream) << "\n";
            o << "    depth_camera: " << yaml::doubleQuoted(d.depth_camera) << "\n";
            o << "    color_camera: " << yaml::doubleQuoted(d.color_camera) << "\n";
            o << "    correction:\n      scale: " << num(k.scale)
              << "\n      offset_m: " << num(k.offset_m) << "\n      alpha0: " << num(k.alpha0)
              << "\n      alpha1: " << num(k.alpha1) << "\n";
            if (!k.distortion.empty()) {
                const CameraModel& depth = file.find(d.depth_camera)->model;
                o << mapYaml(k.distortion, depth.width, depth.height);
            }
        }
    }
    return detail::writeTextFile(path, o.str());
}

}  // namespace mixray::calibration
