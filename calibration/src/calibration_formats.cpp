// Import and export of other tools' calibration formats (docs/calibration.md#other-formats):
// OpenCV FileStorage, Kalibr camchain.yaml, ROS camera_info YAML, mrcal .cameramodel; and
// recognising them from their content.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/core.hpp>
#include <sstream>
#include <utility>

#include "calibration_file_internal.h"
#include "file_storage_guard.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/calibration/ros_camera_info.h"
#include "mixray/graph/yaml_reader.h"
#include "mixray/graph/yaml_writer.h"
#include "mrcal_format.h"

namespace mixray::calibration {
namespace {

using yaml::find;
using yaml::Item;

constexpr std::array<std::string_view, 5> kFormatNames = {"mixray", "opencv", "mrcal", "kalibr",
                                                          "ros"};
constexpr std::array<std::string_view, 8> kRosKeys = {
    "image_width",          "image_height",     "camera_name",
    "camera_matrix",        "distortion_model", "distortion_coefficients",
    "rectification_matrix", "projection_matrix"};
constexpr std::array<std::string_view, 3> kRosMatrixKeys = {"rows", "cols", "data"};

Status invalid(std::string what) {
    return Status(ErrorCode::kInvalidArgument, std::move(what));
}

Status corruptFile(const std::filesystem::path& path, std::string_view what) {
    return Status(ErrorCode::kCorruptData, path.string() + ": " + std::string(what));
}

// The camera name a one-camera file gets when it names none: its file name without the
// extension, characters a frame name cannot hold replaced by '_'.
std::string nameFromPath(const std::filesystem::path& path) {
    std::string name = path.stem().string();
    for (char& c : name) {
        if (!detail::isFrameName(std::string_view(&c, 1)))
            c = '_';
    }
    if (name.size() > 128)
        name.resize(128);
    return name.empty() ? "camera" : name;
}

// A model whose size a file did not give (OpenCV's files may lack it) checked for everything
// else.
Status validateIgnoringSize(CameraModel model) {
    model.width = std::max(model.width, 1);
    model.height = std::max(model.height, 1);
    return model.validate();
}

// The distortion coefficients a pinhole model needs, dropping trailing zero terms that the
// target format's fixed length adds (OpenCV 12/14 with zero thin-prism and tilt terms).
std::optional<std::vector<double>> pinholeCoefficients(std::vector<double> d) {
    if (d.size() == 12 || d.size() == 14) {
        if (std::any_of(d.begin() + 8, d.end(), [](double v) { return v != 0; }))
            return std::nullopt;
        d.resize(8);
    }
    if (d.size() == 0 || d.size() == 4 || d.size() == 5 || d.size() == 8)
        return d;
    return std::nullopt;
}

// ---- content sniffing ----

std::string_view trimmedStart(std::string_view text) {
    while (true) {
        const size_t start = text.find_first_not_of(" \t\r\n");
        if (start == std::string_view::npos)
            return {};
        text.remove_prefix(start);
        if (text.front() != '#')
            return text;
        const size_t eol = text.find('\n');
        if (eol == std::string_view::npos)
            return {};
        text.remove_prefix(eol);
    }
}

Result<CalibrationFormat> sniff(const std::filesystem::path& path, std::string_view text) {
    const std::string_view start = trimmedStart(text);
    if (start.starts_with("%YAML:") || start.starts_with("<?xml") ||
        start.starts_with("<opencv_storage>")) {
        return CalibrationFormat::kOpenCV;
    }
    if (start.starts_with("{")) {
        if (text.find("lensmodel") != std::string_view::npos)
            return CalibrationFormat::kMrcal;
        if (text.find("\"camera_matrix\"") != std::string_view::npos)
            return CalibrationFormat::kOpenCV;
    }
    const std::string what =
        "cannot tell its calibration format (mixray, OpenCV FileStorage, mrcal .cameramodel, "
        "Kalibr camchain.yaml or ROS camera_info YAML); name it";
    YAML::Node root;
    try {
        root = YAML::Load(std::string(text));
    } catch (const YAML::Exception&) {
        return corruptFile(path, what);
    }
    if (!root.IsMap())
        return corruptFile(path, what);
    if (root["cameras"] && root["version"])
        return CalibrationFormat::kMixray;
    if (root["cam0"])
        return CalibrationFormat::kKalibr;
    if (root["camera_matrix"] && root["camera_matrix"].IsMap())
        return CalibrationFormat::kRos;
    return corruptFile(path, what);
}

// ---- OpenCV FileStorage ----

Result<CalibrationFile> readOpenCV(const std::filesystem::path& path) {
    cv::FileStorage fs;
    try {
        if (!fs.open(path.string(), cv::FileStorage::READ))
            return corruptFile(path, "OpenCV's FileStorage cannot open it");
    } catch (const cv::Exception& e) {
        return corruptFile(path, "OpenCV's FileStorage: " + e.msg);
    }
    try {
        CalibratedCamera camera;
        CameraModel& m = camera.model;
        const cv::FileNode k_node = fs["camera_matrix"];
        if (k_node.empty())
            return corruptFile(path, "camera_matrix: missing (a 3x3 opencv-matrix)");
        cv::Mat K;
        k_node >> K;
        if (K.rows != 3 || K.cols != 3 || K.channels() != 1)
            return corruptFile(path, "camera_matrix: expected a 3x3 matrix");
        K.convertTo(K, CV_64F);
        if (K.at<double>(0, 1) != 0 || K.at<double>(1, 0) != 0 || K.at<double>(2, 0) != 0 ||
            K.at<double>(2, 1) != 0 || K.at<double>(2, 2) != 1) {
            return corruptFile(path,
                               "camera_matrix: expected [fx 0 cx; 0 fy cy; 0 0 1] (mixray's "
                               "models have no skew)");
        }
        m.fx = K.at<double>(0, 0);
        m.fy = K.at<double>(1, 1);
        m.cx = K.at<double>(0, 2);
        m.cy = K.at<double>(1, 2);
        std::vector<double> d;
        if (const cv::FileNode d_node = fs["distortion_coefficients"]; !d_node.empty()) {
            cv::Mat D;
            d_node >> D;
            if (!D.empty()) {
                if ((D.rows != 1 && D.cols != 1) || D.channels() != 1)
                    return corruptFile(path,
                                       "distortion_coefficients: expected a 1xN or Nx1 matrix");
                D.convertTo(D, CV_64F);
                d.assign(D.begin<double>(), D.end<double>());
            }
        }
        const cv::FileNode fisheye = fs["fisheye_model"];
        if (!fisheye.empty() && fisheye.isInt() && static_cast<int>(fisheye) != 0) {
            m.lens = LensModel::kFisheye;
            if (d.size() != 4) {
                return corruptFile(path,
                                   "distortion_coefficients: a fisheye_model (cv::fisheye) "
                                   "has 4 coefficients, this has " +
                                       std::to_string(d.size()));
            }
            m.distortion = d;
        } else {
            auto kept = pinholeCoefficients(d);
            if (!kept) {
                return corruptFile(path, "distortion_coefficients: " + std::to_string(d.size()) +
                                             " coefficients; mixray's pinhole model takes 0, 4, "
                                             "5 or 8 (12 or 14 only with zero thin-prism and "
                                             "tilt terms)");
            }
            m.distortion = *kept;
        }
        for (auto [key, out] :
             {std::pair{"image_width", &m.width}, std::pair{"image_height", &m.height}}) {
            const cv::FileNode n = fs[key];
            if (!n.empty()) {
                if (!n.isInt() || static_cast<int>(n) <= 0)
                    return corruptFile(path, std::string(key) + ": expected a positive integer");
                *out = static_cast<int>(n);
            }
        }
        if ((m.width == 0) != (m.height == 0))
            return corruptFile(path, "image_width and image_height: give both or neither");
        if (Status s = validateIgnoringSize(m); !s)
            return corruptFile(path, s.message());
        if (const cv::FileNode n = fs["avg_reprojection_error"]; !n.empty() && n.isReal())
            camera.rms_px = std::max(0.0, static_cast<double>(n));
        for (const char* key : {"nframes", "nr_of_frames"}) {
            if (const cv::FileNode n = fs[key]; !n.empty() && n.isInt())
                camera.views = std::max(0, static_cast<int>(n));
        }
        camera.name = nameFromPath(path);
        if (const cv::FileNode n = fs["camera_name"]; !n.empty() && n.isString()) {
            const std::string name = static_cast<std::string>(n);
            if (detail::isFrameName(name))
                camera.name = name;
        }
        CalibrationFile file;
        if (const cv::FileNode n = fs["calibration_time"]; !n.empty() && n.isString())
            file.created = static_cast<std::string>(n);
        file.cameras.push_back(std::move(camera));
        return file;
    } catch (const cv::Exception& e) {
        return corruptFile(path, "OpenCV's FileStorage: " + e.msg);
    }
}

Status writeOpenCV(const std::filesystem::path& path, const CalibratedCamera& camera,
                   const CalibrationFile& file) {
    const CameraModel& m = camera.model;
    const std::string ext = path.extension().string();
    const int format = ext == ".xml"    ? cv::FileStorage::FORMAT_XML
                       : ext == ".json" ? cv::FileStorage::FORMAT_JSON
                                        : cv::FileStorage::FORMAT_YAML;
    const std::filesystem::path tmp = path.string() + ".tmp";
    try {
        cv::FileStorage fs(tmp.string(), cv::FileStorage::WRITE | format);
        if (!fs.isOpened())
            return Status(ErrorCode::kIoError, "cannot write " + path.string());
        if (!file.created.empty())
            fs << "calibration_time" << file.created;
        fs << "camera_name" << camera.name;
        fs << "image_width" << m.width << "image_height" << m.height;
        fs << "fisheye_model" << (m.lens == LensModel::kFisheye ? 1 : 0);
        const cv::Matx33d K(m.fx, 0, m.cx, 0, m.fy, m.cy, 0, 0, 1);
        fs << "camera_matrix" << cv::Mat(K);
        cv::Mat D(static_cast<int>(m.distortion.size()), 1, CV_64F);
        for (size_t i = 0; i < m.distortion.size(); ++i)
            D.at<double>(static_cast<int>(i)) = m.distortion[i];
        fs << "distortion_coefficients" << D;
        if (camera.rms_px > 0)
            fs << "avg_reprojection_error" << camera.rms_px;
        if (camera.views > 0)
            fs << "nframes" << camera.views;
        fs.release();
    } catch (const cv::Exception& e) {
        std::error_code ignored;
        std::filesystem::remove(tmp, ignored);
        return Status(ErrorCode::kIoError, "cannot write " + path.string() + ": " + e.msg);
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) {
        std::filesystem::remove(tmp, ec);
        return Status(ErrorCode::kIoError, "cannot write " + path.string() + ": " + ec.message());
    }
    return Status::ok();
}

// ---- YAML formats read with the strict reader (Kalibr, ROS) ----

class YamlImporter {
public:
    explicit YamlImporter(const std::filesystem::path& path) : path_(path), r_(path.string()) {}

    Result<CalibrationFile> kalibr(std::string_view text) {
        auto root = r_.load(text, detail::kMaxCalibrationFileBytes, detail::kMaxCalibrationNesting,
                            "a Kalibr camchain file");
        if (!root)
            return root.status();
        auto fields = r_.readMap(*root, {}, "a Kalibr camchain mapping with cam0, cam1, ...");
        if (!fields)
            return fields.status();
        CalibrationFile file;
        for (size_t i = 0; i < fields->size(); ++i) {
            const yaml::Field& f = (*fields)[i];
            if (f.key != "cam" + std::to_string(i)) {
                return corrupt(f.key_where, f.item.path,
                               "expected cam" + std::to_string(i) +
                                   " (a camchain lists cam0, cam1, ... in order)");
            }
            auto camera = kalibrCamera(f.item, i, file);
            if (!camera)
                return camera.status();
            file.cameras.push_back(std::move(*camera));
        }
        if (file.cameras.empty())
            return r_.fail(*root, "no cameras (expected cam0, cam1, ...)");
        return file;
    }

    Result<CalibrationFile> ros(std::string_view text) {
        auto root = r_.load(text, detail::kMaxCalibrationFileBytes, detail::kMaxCalibrationNesting,
                            "a ROS camera_info file");
        if (!root)
            return root.status();
        auto fields = r_.readMap(*root, kRosKeys,
                                 "a ROS camera_info mapping with image_width:, image_height:, "
                                 "camera_matrix:, distortion_model: and distortion_coefficients:");
        if (!fields)
            return fields.status();
        for (std::string_view key : {"image_width", "image_height", "camera_matrix"})
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, *root, key));
        CalibratedCamera camera;
        CameraModel& m = camera.model;
        for (auto [key, out] :
             {std::pair{"image_width", &m.width}, std::pair{"image_height", &m.height}}) {
            auto v = r_.integer(*find(*fields, key), 1, 65535);
            if (!v)
                return v.status();
            *out = static_cast<int>(*v);
        }
        const Item& k_item = *find(*fields, "camera_matrix");
        auto K = rosMatrix(k_item, 3, 3);
        if (!K)
            return K.status();
        const std::vector<double>& k = *K;
        if (k[1] != 0 || k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1)
            return r_.fail(k_item,
                           "expected [fx 0 cx 0 fy cy 0 0 1] (mixray's models have no skew)");
        m.fx = k[0];
        m.fy = k[4];
        m.cx = k[2];
        m.cy = k[5];
        std::string model = "plumb_bob";
        const Item* model_item = find(*fields, "distortion_model");
        if (model_item) {
            auto v = r_.text(*model_item);
            if (!v)
                return v.status();
            model = *v;
        }
        std::vector<double> d;
        if (const Item* d_item = find(*fields, "distortion_coefficients")) {
            auto values = rosMatrix(*d_item, 1, -1);
            if (!values)
                return values.status();
            d = *values;
        }
        const Item& where = model_item ? *model_item : *root;
        if (model == "plumb_bob") {
            if (d.size() != 0 && d.size() != 4 && d.size() != 5) {
                return r_.fail(where,
                               "plumb_bob has 5 coefficients k1 k2 t1 t2 k3; "
                               "distortion_coefficients has " +
                                   std::to_string(d.size()));
            }
        } else if (model == "rational_polynomial") {
            auto kept = pinholeCoefficients(d);
            if (!kept || kept->size() != 8) {
                return r_.fail(where,
                               "rational_polynomial has 8 coefficients k1 k2 t1 t2 k3 k4 k5 "
                               "k6 (12 or 14 only with zero thin-prism and tilt terms); "
                               "distortion_coefficients has " +
                                   std::to_string(d.size()));
            }
            d = *kept;
        } else if (model == "equidistant") {
            if (d.size() != 4) {
                return r_.fail(where,
                               "equidistant has 4 coefficients k1 k2 k3 k4; "
                               "distortion_coefficients has " +
                                   std::to_string(d.size()));
            }
            m.lens = LensModel::kFisheye;
        } else {
            return r_.fail(where, "distortion model " + yaml::quote(model) +
                                      " has no mixray lens model; expected plumb_bob, "
                                      "rational_polynomial or equidistant");
        }
        m.distortion = d;
        if (const Item* r = find(*fields, "rectification_matrix")) {
            auto v = rosMatrix(*r, 3, 3);
            if (!v)
                return v.status();
        }
        if (const Item* p = find(*fields, "projection_matrix")) {
            auto v = rosMatrix(*p, 3, 4);
            if (!v)
                return v.status();
        }
        if (Status s = m.validate(); !s)
            return r_.fail(k_item, s.message());
        camera.name = nameFromPath(path_);
        if (const Item* name = find(*fields, "camera_name")) {
            if (name->node.IsScalar() && detail::isFrameName(name->node.Scalar()))
                camera.name = name->node.Scalar();
        }
        CalibrationFile file;
        file.cameras.push_back(std::move(camera));
        return file;
    }

private:
    Result<std::vector<double>> numbers(const Item& item, size_t min, size_t max,
                                        std::string_view expectation) const {
        return detail::readNumbers(r_, item, min, max, -1e9, 1e9, expectation);
    }

    // {rows, cols, data}; cols < 0: any.
    Result<std::vector<double>> rosMatrix(const Item& item, int rows, int cols) const {
        auto fields =
            r_.readMap(item, kRosMatrixKeys, "a matrix mapping with rows:, cols: and data:");
        if (!fields)
            return fields.status();
        for (std::string_view key : kRosMatrixKeys)
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, key));
        auto r = r_.integer(*find(*fields, "rows"), 0, 64);
        if (!r)
            return r.status();
        auto c = r_.integer(*find(*fields, "cols"), 0, 64);
        if (!c)
            return c.status();
        const bool vector = cols < 0;
        // A coefficient vector may be written as a row or a column.
        const bool shape_ok =
            vector ? (*r == 1 || *c == 1 || *r * *c == 0) : (*r == rows && *c == cols);
        if (!shape_ok) {
            return r_.fail(item, "expected " +
                                     (vector ? std::string("a 1xN vector")
                                             : std::to_string(rows) + "x" + std::to_string(cols)) +
                                     ", got " + std::to_string(*r) + "x" + std::to_string(*c));
        }
        const size_t count = static_cast<size_t>(*r * *c);
        return numbers(*find(*fields, "data"), count, count,
                       "a list of " + std::to_string(count) + " numbers (rows x cols)");
    }

    Result<CalibratedCamera> kalibrCamera(const Item& item, size_t index,
                                          const CalibrationFile& file) const {
        auto fields = r_.readMap(item, {},
                                 "a camera mapping with camera_model:, intrinsics:, "
                                 "distortion_model:, distortion_coeffs: and resolution:");
        if (!fields)
            return fields.status();
        for (std::string_view key : {"camera_model", "intrinsics", "resolution"})
            MIXRAY_RETURN_IF_ERROR(r_.require(*fields, item, key));
        CalibratedCamera camera;
        CameraModel& m = camera.model;
        const Item& model_item = *find(*fields, "camera_model");
        auto model = r_.text(model_item);
        if (!model)
            return model.status();
        if (*model != "pinhole") {
            return r_.fail(model_item, "camera_model " + yaml::quote(*model) +
                                           " has no mixray lens model; mixray reads pinhole "
                                           "(with radtan, equidistant or none)");
        }
        auto intrinsics = numbers(*find(*fields, "intrinsics"), 4, 4, "[fu, fv, pu, pv]");
        if (!intrinsics)
            return intrinsics.status();
        m.fx = (*intrinsics)[0];
        m.fy = (*intrinsics)[1];
        m.cx = (*intrinsics)[2];
        m.cy = (*intrinsics)[3];
        auto resolution = r_.readList(*find(*fields, "resolution"), 2, 2, "[width, height]");
        if (!resolution)
            return resolution.status();
        for (auto [i, out] : {std::pair{0, &m.width}, std::pair{1, &m.height}}) {
            auto v = r_.integer((*resolution)[i], 1, 65535);
            if (!v)
                return v.status();
            *out = static_cast<int>(*v);
        }
        std::string distortion = "none";
        const Item* dm = find(*fields, "distortion_model");
        if (dm) {
            auto v = r_.text(*dm);
            if (!v)
                return v.status();
            distortion = *v;
        }
        std::vector<double> d;
        if (const Item* coeffs = find(*fields, "distortion_coeffs")) {
            auto v = numbers(*coeffs, 0, 16, "a list of distortion coefficients");
            if (!v)
                return v.status();
            d = *v;
        }
        const Item& where = dm ? *dm : item;
        if (distortion == "radtan" || distortion == "equidistant") {
            if (d.size() != 4) {
                return r_.fail(where, distortion + " has 4 coefficients; distortion_coeffs has " +
                                          std::to_string(d.size()));
            }
            if (distortion == "equidistant")
                m.lens = LensModel::kFisheye;
            m.distortion = d;
        } else if (distortion == "none") {
            if (std::any_of(d.begin(), d.end(), [](double v) { return v != 0; }))
                return r_.fail(where, "distortion_model none with non-zero distortion_coeffs");
        } else {
            return r_.fail(where, "distortion_model " + yaml::quote(distortion) +
                                      " has no mixray lens model; mixray reads radtan, "
                                      "equidistant and none");
        }
        if (Status s = m.validate(); !s)
            return r_.fail(item, s.message());
        camera.name = "cam" + std::to_string(index);
        if (const Item* topic = find(*fields, "rostopic"); topic && topic->node.IsScalar()) {
            std::string name = topic->node.Scalar();
            if (name.starts_with("/"))
                name.erase(0, 1);
            if (detail::isFrameName(name) && !file.find(name))
                camera.name = name;
        }
        if (const Item* t = find(*fields, "T_cn_cnm1")) {
            if (index == 0)
                return r_.fail(*t, "cam0 has no previous camera");
            auto T = transform(*t);
            if (!T)
                return T.status();
            camera.parent = file.cameras.back().name;
            camera.T_parent_camera = T->inverse();
        }
        return camera;
    }

    // A 4x4 rigid transform as a list of 4 rows.
    Result<Eigen::Isometry3d> transform(const Item& item) const {
        constexpr std::string_view kExpect = "a 4x4 transform: 4 rows of 4 numbers";
        auto rows = r_.readList(item, 4, 4, kExpect);
        if (!rows)
            return rows.status();
        Eigen::Matrix4d M;
        for (int i = 0; i < 4; ++i) {
            auto row = numbers((*rows)[i], 4, 4, kExpect);
            if (!row)
                return row.status();
            for (int j = 0; j < 4; ++j)
                M(i, j) = (*row)[j];
        }
        const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
        // Kalibr prints its transforms with numpy's default precision; allow for the rounding.
        if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-5 ||
            R.determinant() < 0 || M.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
            return r_.fail(item,
                           "not a rigid transform (rotation not orthonormal or last row not "
                           "[0, 0, 0, 1])");
        }
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
        T.translation() = M.topRightCorner<3, 1>();
        return T;
    }

    std::filesystem::path path_;
    yaml::Reader r_;
};

// OpenCV's, Kalibr's and ROS's files hold OpenCV's two lens families only.
Status holdsLens(CalibrationFormat format, const CalibratedCamera& c) {
    if (c.model.lens == LensModel::kPinhole || c.model.lens == LensModel::kFisheye)
        return Status::ok();
    return invalid("the " + std::string(toString(format)) + " format cannot hold camera " + c.name +
                   "'s model: " + std::string(toString(c.model.lens)) +
                   " (it holds pinhole models with OpenCV's distortion and cv::fisheye's)");
}

// Kalibr's distortion model for a mixray model; kInvalidArgument when it has none.
Result<std::pair<std::string, std::vector<double>>> kalibrDistortion(const CalibratedCamera& c) {
    const CameraModel& m = c.model;
    if (m.lens == LensModel::kFisheye)
        return std::pair{std::string("equidistant"), m.distortion};
    if (m.distortion.empty())
        return std::pair{std::string("none"), std::vector<double>{}};
    // Higher terms that are zero project exactly as radtan's four.
    if (std::all_of(m.distortion.begin() + 4, m.distortion.end(),
                    [](double v) { return v == 0; })) {
        return std::pair{std::string("radtan"),
                         std::vector<double>(m.distortion.begin(), m.distortion.begin() + 4)};
    }
    return invalid("Kalibr's camchain cannot hold camera " + c.name + "'s model: pinhole with " +
                   std::to_string(m.distortion.size()) +
                   " OpenCV coefficients (k3 and above non-zero); Kalibr's radtan has k1 k2 p1 "
                   "p2 only");
}

std::string matrixRow(const Eigen::Matrix4d& M, int row) {
    return detail::yamlList({M(row, 0), M(row, 1), M(row, 2), M(row, 3)});
}

Status writeKalibr(const std::filesystem::path& path, const CalibrationFile& file) {
    if (file.cameras.empty())
        return invalid("a Kalibr camchain needs at least one camera");
    std::ostringstream o;
    for (size_t i = 0; i < file.cameras.size(); ++i) {
        const CalibratedCamera& c = file.cameras[i];
        MIXRAY_RETURN_IF_ERROR(holdsLens(CalibrationFormat::kKalibr, c));
        auto distortion = kalibrDistortion(c);
        if (!distortion)
            return distortion.status();
        o << "cam" << i << ":\n";
        // A camera linked to no other (a camchain of independent cameras, as Kalibr reads one
        // without T_cn_cnm1) is written so; one linked elsewhere must reach the previous one.
        bool unlinked = false;
        if (i > 0) {
            auto T_previous_camera = file.pose(file.cameras[i - 1].name, c.name);
            unlinked = !T_previous_camera && c.parent.empty();
            if (!T_previous_camera && !unlinked) {
                return invalid(
                    "Kalibr's camchain gives each camera's pose in the previous one's frame: " +
                    T_previous_camera.status().message());
            }
            if (T_previous_camera) {
                const Eigen::Matrix4d M = T_previous_camera->inverse().matrix();
                o << "  T_cn_cnm1:\n";
                for (int r = 0; r < 4; ++r)
                    o << "  - " << matrixRow(M, r) << "\n";
            }
        }
        const CameraModel& m = c.model;
        o << "  camera_model: pinhole\n";
        o << "  intrinsics: " << detail::yamlList({m.fx, m.fy, m.cx, m.cy}) << "\n";
        o << "  distortion_model: " << distortion->first << "\n";
        o << "  distortion_coeffs: " << detail::yamlList(distortion->second) << "\n";
        o << "  resolution: [" << m.width << ", " << m.height << "]\n";
        o << "  rostopic: " << yaml::doubleQuoted("/" + c.name) << "\n";
        if (i > 0 && !unlinked)
            o << "  cam_overlaps: [" << i - 1 << "]\n";
    }
    return detail::writeTextFile(path, o.str());
}

std::string rosMatrixYaml(std::string_view key, int rows, int cols,
                          const std::vector<double>& data) {
    return std::string(key) + ":\n  rows: " + std::to_string(rows) +
           "\n  cols: " + std::to_string(cols) + "\n  data: " + detail::yamlList(data) + "\n";
}

Status writeRos(const std::filesystem::path& path, const CalibratedCamera& c) {
    auto info = toRosCameraInfo(c);
    if (!info)
        return info.status();
    const auto matrix = [](std::string_view key, int rows, int cols, const auto& data) {
        return rosMatrixYaml(key, rows, cols, std::vector<double>(data.begin(), data.end()));
    };
    std::ostringstream o;
    o << "image_width: " << info->width << "\nimage_height: " << info->height << "\n";
    o << "camera_name: " << yaml::doubleQuoted(c.name) << "\n";
    o << matrix("camera_matrix", 3, 3, info->k);
    o << "distortion_model: " << info->distortion_model << "\n";
    o << matrix("distortion_coefficients", 1, static_cast<int>(info->d.size()), info->d);
    o << matrix("rectification_matrix", 3, 3, info->r);
    o << matrix("projection_matrix", 3, 4, info->p);
    return detail::writeTextFile(path, o.str());
}

Result<CalibrationFile> readMrcal(const std::filesystem::path& path) {
    auto camera = detail::readMrcalCameramodel(path);
    if (!camera)
        return camera.status();
    if (camera->name.empty())
        camera->name = nameFromPath(path);
    CalibrationFile file;
    file.cameras.push_back(std::move(*camera));
    return file;
}

Result<const CalibratedCamera*> selectCamera(const CalibrationFile& file, CalibrationFormat format,
                                             std::string_view camera) {
    if (!camera.empty()) {
        if (const CalibratedCamera* c = file.find(camera))
            return c;
        std::string names;
        for (const auto& c : file.cameras)
            names += (names.empty() ? "" : ", ") + c.name;
        return Status(ErrorCode::kNotFound,
                      "no camera named \"" + std::string(camera) + "\" (cameras: " + names + ")");
    }
    if (file.cameras.size() == 1)
        return &file.cameras.front();
    std::string names;
    for (const auto& c : file.cameras)
        names += (names.empty() ? "" : ", ") + c.name;
    return invalid("the " + std::string(toString(format)) + " format holds one camera and the " +
                   "calibration has " + std::to_string(file.cameras.size()) + " (" + names +
                   "); name the one to write");
}

}  // namespace

std::string_view toString(CalibrationFormat format) {
    return kFormatNames[static_cast<size_t>(format)];
}

std::optional<CalibrationFormat> calibrationFormatFromString(std::string_view name) {
    for (size_t i = 0; i < kFormatNames.size(); ++i) {
        if (kFormatNames[i] == name)
            return static_cast<CalibrationFormat>(i);
    }
    return std::nullopt;
}

Result<CalibrationFile> importCalibration(const std::filesystem::path& path,
                                          std::optional<CalibrationFormat> format) {
    auto text = detail::readTextFile(path, detail::kMaxCalibrationFileBytes);
    if (!text)
        return text.status();
    if (!format) {
        auto sniffed = sniff(path, *text);
        if (!sniffed)
            return sniffed.status();
        format = *sniffed;
    }
    Result<CalibrationFile> file = Status(ErrorCode::kInternal, "unreachable");
    try {
        switch (*format) {
            case CalibrationFormat::kMixray:
                return readCalibrationFile(path);
            case CalibrationFormat::kOpenCV:
                if (const char* why = detail::crashesFileStorage(*text))
                    return corruptFile(path, why);
                if (const char* why = detail::hangsFileStorageYaml(*text))
                    return corruptFile(path, std::string(why) +
                                                 ", which OpenCV's reader "
                                                 "may never return from");
                file = readOpenCV(path);
                break;
            case CalibrationFormat::kMrcal:
                file = readMrcal(path);
                break;
            case CalibrationFormat::kKalibr:
                file = YamlImporter(path).kalibr(*text);
                break;
            case CalibrationFormat::kRos:
                file = YamlImporter(path).ros(*text);
                break;
        }
    } catch (const YAML::Exception& e) {
        return corruptFile(path, e.what());
    }
    if (!file)
        return file;
    // An OpenCV file may leave the image size unknown; readOpenCV() checked the rest.
    if (*format == CalibrationFormat::kOpenCV)
        return file;
    if (Status s = detail::validateCalibrationFile(*file); !s)
        return corruptFile(path, s.message());
    return file;
}

Status exportCalibration(const std::filesystem::path& path, const CalibrationFile& file,
                         CalibrationFormat format, std::string_view camera) {
    Status status;
    switch (format) {
        case CalibrationFormat::kMixray:
        case CalibrationFormat::kKalibr: {
            if (!camera.empty()) {
                return invalid("the " + std::string(toString(format)) +
                               " format holds every camera; name none");
            }
            if (Status s = detail::validateCalibrationFile(file); !s)
                return s.withContext("writing " + path.string());
            status = format == CalibrationFormat::kMixray ? writeCalibrationFile(path, file)
                                                          : writeKalibr(path, file);
            break;
        }
        case CalibrationFormat::kOpenCV:
        case CalibrationFormat::kMrcal:
        case CalibrationFormat::kRos: {
            auto selected = selectCamera(file, format, camera);
            if (!selected)
                return selected.status();
            const CalibratedCamera& c = **selected;
            if (Status s = c.model.validate(); !s)
                return invalid("writing " + path.string() + ": camera " + c.name + ": " +
                               s.message());
            if (format != CalibrationFormat::kMrcal)
                MIXRAY_RETURN_IF_ERROR(holdsLens(format, c));
            if (format == CalibrationFormat::kOpenCV)
                status = writeOpenCV(path, c, file);
            else if (format == CalibrationFormat::kRos)
                status = writeRos(path, c);
            else
                status = detail::writeMrcalCameramodel(path, c);
            break;
        }
    }
    return status;
}

}  // namespace mixray::calibration
