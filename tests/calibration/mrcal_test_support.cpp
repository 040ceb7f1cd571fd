// Helpers of the mrcal tests: generated chessboard views and mrcal's own tools.
#include "mrcal_test_support.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <random>
#include <sstream>

#include "ceres_synthetic.h"
#include "test_data.h"

namespace mixray::calibration::test {
namespace {

using mixray::test::readText;

std::vector<Eigen::Vector3d> gridPoints(const CalibrationTarget& target) {
    std::vector<Eigen::Vector3d> points;
    for (int r = 0; r < target.rows; ++r) {
        for (int c = 0; c < target.cols; ++c)
            points.emplace_back(c * target.square_m, r * target.square_m, 0);
    }
    return points;
}

}  // namespace

CalibrationTarget mrcalChessboard() {
    return chessboard(10, 7, 0.04);
}

CameraModel opencv8Truth() {
    CameraModel m = CameraModel::pinhole(1280, 704, 563.578, 563.600, 628.876, 347.846);
    m.distortion = {-0.01266096516, 0.03590794372, -0.0002547045941, 0.0005275929652,
                    0.01968883397,  0.01482863541, -0.0562239888,    0.0500223357};
    return m;
}

SyntheticViews syntheticViews(const CameraModel& truth, const CalibrationTarget& target, int count,
                              double noise_px, unsigned seed) {
    SyntheticViews out;
    out.views.camera = "synthetic";
    out.views.width = truth.width;
    out.views.height = truth.height;
    out.views.target = target;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::normal_distribution<double> noise(0.0, noise_px);
    const std::vector<Eigen::Vector3d> points = gridPoints(target);
    const Eigen::Vector3d centre((target.cols - 1) * target.square_m / 2,
                                 (target.rows - 1) * target.square_m / 2, 0);
    const double board_m = std::max(target.cols, target.rows) * target.square_m;
    const double margin = 10;
    while (static_cast<int>(out.views.views.size()) < count) {
        // The board's centre on the ray through a random pixel, at a distance where it spans
        // a third to two thirds of the image width, tilted up to 35° about a random axis.
        const Eigen::Vector2d pixel(margin + unit(rng) * (truth.width - 2 * margin),
                                    margin + unit(rng) * (truth.height - 2 * margin));
        const std::optional<Eigen::Vector3d> ray = truth.unproject(pixel);
        if (!ray)
            continue;
        const double span = (1.0 / 3 + unit(rng) / 3) * truth.width;
        const double distance = truth.fx * board_m / span;
        const double tilt = 35.0 * std::numbers::pi / 180 * std::sqrt(unit(rng));
        const double axis_angle = 2 * std::numbers::pi * unit(rng);
        const double roll = (unit(rng) - 0.5) * 0.6;
        const Eigen::Matrix3d R =
            (Eigen::AngleAxisd(tilt,
                               Eigen::Vector3d(std::cos(axis_angle), std::sin(axis_angle), 0)) *
             Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()))
                .toRotationMatrix();
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = R;
        T.translation() = *ray / ray->z() * distance - R * centre;
        TargetView view;
        view.source = "view" + std::to_string(out.views.views.size());
        view.key = static_cast<int64_t>(out.views.views.size());
        bool inside = true;
        for (size_t id = 0; id < points.size() && inside; ++id) {
            const std::optional<Eigen::Vector2d> q = truth.project(T * points[id]);
            inside = q && q->x() > margin && q->y() > margin && q->x() < truth.width - margin &&
                     q->y() < truth.height - margin;
            if (inside) {
                view.corners.push_back(
                    {static_cast<int>(id), *q + Eigen::Vector2d(noise(rng), noise(rng)), 1.0});
            }
        }
        if (!inside)
            continue;
        out.views.views.push_back(view);
        out.T_camera_target.push_back(T);
    }
    return out;
}

detail::SolveInput seededInput(const CameraViews& views, const CameraModel& seed) {
    detail::SolveInput input;
    input.views = &views;
    input.seed = seed;
    const cv::Mat K = (cv::Mat_<double>(3, 3) << seed.fx, 0, seed.cx, 0, seed.fy, seed.cy, 0, 0, 1);
    std::vector<cv::Point3d> board;
    for (const Eigen::Vector3d& p : gridPoints(views.target))
        board.emplace_back(p.x(), p.y(), p.z());
    for (size_t v = 0; v < views.views.size(); ++v) {
        const TargetView& view = views.views[v];
        std::vector<cv::Point3d> object;
        std::vector<cv::Point2d> image;
        for (const Corner& c : view.corners) {
            object.push_back(board[static_cast<size_t>(c.id)]);
            image.emplace_back(c.pixel.x(), c.pixel.y());
        }
        cv::Vec3d rvec, tvec;
        cv::solvePnP(object, image, K, cv::noArray(), rvec, tvec);
        cv::Mat R;
        cv::Rodrigues(rvec, R);
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j)
                T.linear()(i, j) = R.at<double>(i, j);
            T.translation()[i] = tvec[i];
        }
        input.used.push_back(v);
        input.inlier.emplace_back(view.corners.size(), true);
        input.T_camera_target.push_back(T);
    }
    return input;
}

void writeCornersVnl(const std::filesystem::path& path, const CameraViews& views) {
    std::ofstream out(path);
    out << "# filename x y level\n";
    char line[256];
    for (size_t v = 0; v < views.views.size(); ++v) {
        std::snprintf(line, sizeof line, "view%03zu.png", v);
        const std::string name = line;
        std::vector<const Corner*> by_id(
            static_cast<size_t>(views.target.cols) * static_cast<size_t>(views.target.rows),
            nullptr);
        for (const Corner& c : views.views[v].corners)
            by_id[static_cast<size_t>(c.id)] = &c;
        for (const Corner* c : by_id) {
            if (c) {
                const long level = c->weight >= 1 ? 0 : std::lround(-std::log2(c->weight));
                std::snprintf(line, sizeof line, "%s %.12g %.12g %ld\n", name.c_str(), c->pixel.x(),
                              c->pixel.y(), level);
            } else {
                std::snprintf(line, sizeof line, "%s - - -\n", name.c_str());
            }
            out << line;
        }
    }
}

bool mrcalPythonAvailable() {
    return std::filesystem::exists("/usr/bin/mrcal-calibrate-cameras") &&
           std::system("/usr/bin/python3 -c 'import mrcal' > /dev/null 2>&1") == 0;
}

std::optional<CliResult> runMrcalCalibrateCameras(const std::filesystem::path& vnl,
                                                  const CameraViews& views,
                                                  const std::string& lensmodel, double focal_px,
                                                  const std::string& extra,
                                                  const std::filesystem::path& outdir,
                                                  std::string* log) {
    std::filesystem::create_directories(outdir);
    std::ostringstream command;
    command.precision(17);
    command << "cd '" << outdir.string() << "' && /usr/bin/python3 /usr/bin/mrcal-calibrate-cameras"
            << " --corners-cache '" << vnl.string() << "' --lensmodel " << lensmodel << " --focal "
            << focal_px << " --object-spacing " << views.target.square_m << " --object-width-n "
            << views.target.cols << " --object-height-n " << views.target.rows << " --imagersize "
            << views.width << " " << views.height << " --outdir '" << outdir.string() << "' "
            << extra << " 'view*.png' > cli.out 2> cli.err";
    const int status = std::system(command.str().c_str());
    const std::string err = readText(outdir / "cli.err");
    if (log)
        *log = command.str() + "\n" + readText(outdir / "cli.out") + err;
    if (status != 0)
        return std::nullopt;
    CliResult result;
    result.model = outdir / "camera-0.cameramodel";
    const std::string key = "## RMS error: ";
    const size_t at = err.rfind(key);
    if (at == std::string::npos || !std::filesystem::exists(result.model))
        return std::nullopt;
    result.rms_px = std::strtod(err.c_str() + at + key.size(), nullptr);
    return result;
}

std::optional<std::string> runPython(const std::string& program, const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir);
    {
        std::ofstream out(dir / "program.py");
        out << program;
    }
    const std::string command =
        "cd '" + dir.string() + "' && /usr/bin/python3 program.py > program.out 2> program.err";
    if (std::system(command.c_str()) != 0)
        return std::nullopt;
    return readText(dir / "program.out");
}

std::vector<double> projectionDifferencesPx(const CameraModel& a, const CameraModel& b,
                                            double step_px) {
    std::vector<double> out;
    for (double y = 0; y <= a.height - 1; y += step_px) {
        for (double x = 0; x <= a.width - 1; x += step_px) {
            const std::optional<Eigen::Vector3d> ray = a.unproject({x, y});
            const std::optional<Eigen::Vector2d> qa = ray ? a.project(*ray) : std::nullopt;
            const std::optional<Eigen::Vector2d> qb = ray ? b.project(*ray) : std::nullopt;
            out.push_back(qa && qb ? (*qa - *qb).norm() : INFINITY);
        }
    }
    return out;
}

double maxProjectionDifferencePx(const CameraModel& a, const CameraModel& b, double step_px) {
    const std::vector<double> d = projectionDifferencesPx(a, b, step_px);
    return d.empty() ? 0 : *std::max_element(d.begin(), d.end());
}

double medianProjectionDifferencePx(const CameraModel& a, const CameraModel& b, double step_px) {
    std::vector<double> d = projectionDifferencesPx(a, b, step_px);
    if (d.empty())
        return 0;
    const auto middle = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
    std::nth_element(d.begin(), middle, d.end());
    return *middle;
}

}  // namespace mixray::calibration::test
