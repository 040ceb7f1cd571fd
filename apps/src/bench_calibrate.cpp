// mixray bench calibrate: seconds to calibrate one camera from N generated chessboard views —
// mixray's mrcal back end (seeding included), OpenCV's cv::calibrateCamera and the
// mrcal-calibrate-cameras CLI (a subprocess: wall time, Python start-up included) — on the same
// corners in the same run, with the RMS each reaches and how far its lens is from the truth.
#include "bench_calibrate.h"

#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <random>
#include <sstream>

#include "mixray/calibration/calibrate.h"
#include "mixray/calibration/corners_cache.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;
using calibration::CameraModel;
using nlohmann::json;

struct BenchCalibrateOptions {
    std::string views = "10,20,40";
    std::string model = "opencv8";
    double noise_px = 0.3;
    int repeats = 3;
    bool json = false;
};

// The lens the corners are generated through: mrcal's cam0.opencv8 test lens scaled to
// 1280x704, a wide real-lens-like rational model.
CameraModel truthLens() {
    CameraModel m = CameraModel::pinhole(1280, 704, 563.578, 563.600, 628.876, 347.846);
    m.distortion = {-0.01266096516, 0.03590794372, -0.0002547045941, 0.0005275929652,
                    0.01968883397,  0.01482863541, -0.0562239888,    0.0500223357};
    return m;
}

calibration::CalibrationTarget board() {
    calibration::CalibrationTarget target;
    target.kind = calibration::TargetKind::kChessboard;
    target.cols = 10;
    target.rows = 7;
    target.square_m = 0.04;
    return target;
}

// `count` views from poses spread over the image, tilted up to 35°, every corner inside.
calibration::CameraViews generateViews(const CameraModel& truth, int count, double noise_px,
                                       unsigned seed) {
    calibration::CameraViews views;
    views.camera = "bench";
    views.width = truth.width;
    views.height = truth.height;
    views.target = board();
    const calibration::CalibrationTarget& target = views.target;
    const std::vector<Eigen::Vector3d> points = target.points();
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::normal_distribution<double> noise(0.0, noise_px);
    const Eigen::Vector3d centre((target.cols - 1) * target.square_m / 2,
                                 (target.rows - 1) * target.square_m / 2, 0);
    const double board_m = target.cols * target.square_m;
    const double margin = 10;
    while (static_cast<int>(views.views.size()) < count) {
        const Eigen::Vector2d pixel(margin + unit(rng) * (truth.width - 2 * margin),
                                    margin + unit(rng) * (truth.height - 2 * margin));
        const auto ray = truth.unproject(pixel);
        if (!ray)
            continue;
        const double distance = truth.fx * board_m / ((1.0 / 3 + unit(rng) / 3) * truth.width);
        const double tilt = 35.0 * std::numbers::pi / 180 * std::sqrt(unit(rng));
        const double axis = 2 * std::numbers::pi * unit(rng);
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = (Eigen::AngleAxisd(tilt, Eigen::Vector3d(std::cos(axis), std::sin(axis), 0)) *
                      Eigen::AngleAxisd((unit(rng) - 0.5) * 0.6, Eigen::Vector3d::UnitZ()))
                         .toRotationMatrix();
        T.translation() = *ray / ray->z() * distance - T.linear() * centre;
        calibration::TargetView view;
        char name[32];
        std::snprintf(name, sizeof name, "view%03zu.png", views.views.size());
        view.source = name;  // the CLI's image glob matches the corners cache's file names
        view.key = static_cast<int64_t>(views.views.size());
        bool inside = true;
        for (int id = 0; id < target.cols * target.rows && inside; ++id) {
            const auto q = truth.project(T * points[static_cast<size_t>(id)]);
            inside = q && q->x() > margin && q->y() > margin && q->x() < truth.width - margin &&
                     q->y() < truth.height - margin;
            if (inside)
                view.corners.push_back({id, *q + Eigen::Vector2d(noise(rng), noise(rng)), 1.0});
        }
        if (inside)
            views.views.push_back(std::move(view));
    }
    return views;
}

struct CornerLists {
    std::vector<std::vector<cv::Point3f>> object;
    std::vector<std::vector<cv::Point2f>> image;
};

CornerLists cornerLists(const calibration::CameraViews& views) {
    CornerLists lists;
    const std::vector<Eigen::Vector3d> points = views.target.points();
    for (const auto& view : views.views) {
        lists.object.emplace_back();
        lists.image.emplace_back();
        for (const auto& c : view.corners) {
            const Eigen::Vector3d& p = points[static_cast<size_t>(c.id)];
            lists.object.back().emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                             0.f);
            lists.image.back().emplace_back(static_cast<float>(c.pixel.x()),
                                            static_cast<float>(c.pixel.y()));
        }
    }
    return lists;
}

double bestSeconds(int repeats, const std::function<bool()>& body, bool* ok) {
    double best = std::numeric_limits<double>::infinity();
    *ok = true;
    for (int r = 0; r < repeats; ++r) {
        const auto start = std::chrono::steady_clock::now();
        *ok = body() && *ok;
        best = std::min(
            best, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    return best;
}

// The largest distance between two lenses' projections of the rays through a 16 px grid.
double maxDifferencePx(const CameraModel& a, const CameraModel& b) {
    double worst = 0;
    for (double y = 0; y < a.height; y += 16) {
        for (double x = 0; x < a.width; x += 16) {
            const auto ray = a.unproject({x, y});
            const auto qb = ray ? b.project(*ray) : std::nullopt;
            if (!qb)
                return std::numeric_limits<double>::infinity();
            worst = std::max(worst, (*qb - Eigen::Vector2d(x, y)).norm());
        }
    }
    return worst;
}

struct Row {
    int views = 0;
    double mixray_s = 0, ceres_s = 0, opencv_s = 0, cli_s = 0;  // cli_s < 0: not run
    double mixray_rms = 0, ceres_rms = 0, opencv_rms = 0, cli_rms = 0;
    // Against the true lens, whole image.
    double mixray_error_px = 0, ceres_error_px = 0, opencv_error_px = 0;
};

// mixray's calibrateCamera() through one back end, seeding and covariance included.
Result<calibration::CameraCalibration> timeMixray(const calibration::CameraViews& views,
                                                  const BenchCalibrateOptions& options,
                                                  calibration::Solver solver, double* seconds) {
    calibration::CalibrationOptions solve_options;
    solve_options.model = options.model;
    solve_options.solver = solver;
    // The other two keep every corner; so does mixray here, for the same problem.
    solve_options.outlier_sigma = 0;
    // And returns what it solved, as they do, however few the views or large the noise.
    solve_options.accept_weak = true;
    solve_options.max_rms_px = 0;
    Result<calibration::CameraCalibration> result =
        Status(ErrorCode::kInternal, "calibrateCamera not run");
    bool ok = false;
    *seconds = bestSeconds(
        options.repeats,
        [&] {
            result = calibration::calibrateCamera(views, solve_options);
            return result.isOk();
        },
        &ok);
    return result;
}

Result<Row> benchViews(int count, const BenchCalibrateOptions& options, bool cli_available,
                       const fs::path& dir) {
    const CameraModel truth = truthLens();
    const calibration::CameraViews views =
        generateViews(truth, count, options.noise_px, 1000u + static_cast<unsigned>(count));
    Row row;
    row.views = count;
    constexpr double kFocalGuess = 600;

    auto mixray = timeMixray(views, options, calibration::Solver::kMrcal, &row.mixray_s);
    if (!mixray)
        return mixray.status().withContext("mixray (mrcal)");
    row.mixray_rms = mixray->rms_px;
    row.mixray_error_px = maxDifferencePx(truth, mixray->model);
    auto ceres = timeMixray(views, options, calibration::Solver::kCeres, &row.ceres_s);
    if (!ceres)
        return ceres.status().withContext("mixray (Ceres)");
    row.ceres_rms = ceres->rms_px;
    row.ceres_error_px = maxDifferencePx(truth, ceres->model);
    bool ok = false;

    const CornerLists lists = cornerLists(views);
    const int flags = options.model == "opencv8"   ? cv::CALIB_RATIONAL_MODEL
                      : options.model == "opencv4" ? cv::CALIB_FIX_K3
                                                   : 0;
    cv::Mat K, distortion;
    row.opencv_s = bestSeconds(
        options.repeats,
        [&] {
            std::vector<cv::Mat> rvecs, tvecs;
            row.opencv_rms =
                cv::calibrateCamera(lists.object, lists.image, cv::Size(views.width, views.height),
                                    K, distortion, rvecs, tvecs, flags);
            return std::isfinite(row.opencv_rms);
        },
        &ok);
    CameraModel opencv =
        CameraModel::pinhole(views.width, views.height, K.at<double>(0, 0), K.at<double>(1, 1),
                             K.at<double>(0, 2), K.at<double>(1, 2));
    const size_t coefficients = options.model == "opencv8" ? 8 : options.model == "opencv4" ? 4 : 5;
    for (size_t k = 0; k < coefficients; ++k)
        opencv.distortion.push_back(distortion.at<double>(static_cast<int>(k)));
    row.opencv_error_px = maxDifferencePx(truth, opencv);

    row.cli_s = -1;
    if (cli_available) {
        const fs::path vnl = dir / ("corners" + std::to_string(count) + ".vnl");
        MIXRAY_RETURN_IF_ERROR(calibration::writeCornersCache(vnl, {views}));
        std::string lensmodel = "LENSMODEL_OPENCV" + options.model.substr(6);
        std::ostringstream command;
        command << "/usr/bin/python3 /usr/bin/mrcal-calibrate-cameras --corners-cache '"
                << vnl.string() << "' --lensmodel " << lensmodel << " --focal " << kFocalGuess
                << " --object-spacing " << views.target.square_m << " --object-width-n "
                << views.target.cols << " --object-height-n " << views.target.rows
                << " --imagersize " << views.width << " " << views.height << " --outdir '"
                << dir.string()
                << "' --skip-outlier-rejection --skip-calobject-warp-solve 'view*.png' > '"
                << (dir / "cli.out").string() << "' 2> '" << (dir / "cli.err").string() << "'";
        row.cli_s = bestSeconds(
            options.repeats, [&] { return std::system(command.str().c_str()) == 0; }, &ok);
        if (!ok) {
            return Status(ErrorCode::kInternal,
                          "mrcal-calibrate-cameras failed: see " + (dir / "cli.err").string());
        }
        std::ifstream err(dir / "cli.err");
        std::stringstream text;
        text << err.rdbuf();
        const std::string s = text.str();
        const size_t at = s.rfind("## RMS error: ");
        // mrcal's RMS is per coordinate (and counts its regularisation terms); × √2 puts it
        // per point as mixray's and OpenCV's.
        if (at != std::string::npos)
            row.cli_rms = std::strtod(s.c_str() + at + 14, nullptr) * std::sqrt(2.0);
    }
    return row;
}

Result<std::vector<int>> parseViews(const std::string& text) {
    std::vector<int> counts;
    std::stringstream list(text);
    std::string item;
    while (std::getline(list, item, ',')) {
        char* end = nullptr;
        const long n = std::strtol(item.c_str(), &end, 10);
        if (item.empty() || *end != '\0' || n < 5 || n > 500)
            return Status(ErrorCode::kInvalidArgument,
                          "--views: '" + item + "' is not a view count in [5, 500]");
        counts.push_back(static_cast<int>(n));
    }
    if (counts.empty())
        return Status(ErrorCode::kInvalidArgument, "--views: no view counts");
    return counts;
}

int runBenchCalibrate(const BenchCalibrateOptions& options) {
    if (options.model != "opencv4" && options.model != "opencv5" && options.model != "opencv8") {
        return fail("bench calibrate",
                    Status(ErrorCode::kInvalidArgument, "--model: '" + options.model +
                                                            "' is not opencv4, opencv5 or opencv8 "
                                                            "(the models all three solvers have)"));
    }
    auto counts = parseViews(options.views);
    if (!counts)
        return fail("bench calibrate", counts.status());
    const bool cli_available =
        fs::exists("/usr/bin/mrcal-calibrate-cameras") &&
        std::system("/usr/bin/python3 -c 'import mrcal' > /dev/null 2>&1") == 0;
    if (!cli_available) {
        std::fprintf(stderr,
                     "bench calibrate: mrcal-calibrate-cameras or Python's mrcal is "
                     "absent; its column stays empty\n");
    }
    const fs::path dir =
        fs::temp_directory_path() / ("mixray-bench-calibrate-" + std::to_string(getpid()));
    fs::create_directories(dir);
    std::vector<Row> rows;
    for (int count : *counts) {
        std::fprintf(stderr, "bench calibrate: %d views ...\n", count);
        auto row = benchViews(count, options, cli_available, dir);
        if (!row) {
            fs::remove_all(dir);
            return fail("bench calibrate", row.status());
        }
        rows.push_back(*row);
    }
    fs::remove_all(dir);

    if (options.json) {
        json out = json::array();
        for (const Row& r : rows) {
            json one = {{"views", r.views},
                        {"model", options.model},
                        {"noise_px", options.noise_px},
                        {"mixray_mrcal_s", r.mixray_s},
                        {"mixray_ceres_s", r.ceres_s},
                        {"mixray_ceres_rms_px", r.ceres_rms},
                        {"mixray_ceres_max_error_px", r.ceres_error_px},
                        {"opencv_s", r.opencv_s},
                        {"mixray_rms_px", r.mixray_rms},
                        {"opencv_rms_px", r.opencv_rms},
                        {"mixray_max_error_px", r.mixray_error_px},
                        {"opencv_max_error_px", r.opencv_error_px}};
            if (r.cli_s >= 0) {
                one["mrcal_cli_s"] = r.cli_s;
                one["mrcal_cli_rms_px"] = r.cli_rms;
            }
            out.push_back(one);
        }
        std::printf("%s\n", out.dump(2).c_str());
        return kExitOk;
    }
    std::printf(
        "Calibrating %s from N generated views of a 10x7 chessboard (1280x704, %.2f px noise), "
        "best of %d runs:\n",
        options.model.c_str(), options.noise_px, options.repeats);
    std::printf("  %5s %16s %18s %18s %20s %18s %18s\n", "views", "mixray (mrcal)",
                "mixray (Ceres)", "OpenCV (ratio)", "mrcal CLI (ratio)", "RMS m/c/O/C",
                "max err m/c/O");
    for (const Row& r : rows) {
        char cli[40] = "n/a";
        if (r.cli_s >= 0)
            std::snprintf(cli, sizeof cli, "%9.3f s (%5.1fx)", r.cli_s, r.cli_s / r.mixray_s);
        std::printf(
            "  %5d %14.3f s %7.3f s (%5.2fx) %7.3f s (%5.2fx) %20s %4.3f/%4.3f/%4.3f/%4.3f "
            "%5.3f/%5.3f/%5.3f px\n",
            r.views, r.mixray_s, r.ceres_s, r.ceres_s / r.mixray_s, r.opencv_s,
            r.opencv_s / r.mixray_s, cli, r.mixray_rms, r.ceres_rms, r.opencv_rms, r.cli_rms,
            r.mixray_error_px, r.ceres_error_px, r.opencv_error_px);
    }
    std::printf(
        "  ratio: the other's time / mixray (mrcal)'s. mixray is calibrateCamera(): seeding, "
        "solve and covariance; the CLI is a subprocess (Python start-up included). RMS per "
        "point; max err: worst projection difference to the true lens over the image.\n");
    return kExitOk;
}

}  // namespace

void registerBenchCalibrate(CLI::App& bench, Commands& commands) {
    auto* calibrate = bench.add_subcommand(
        "calibrate",
        "Time to calibrate one camera from N chessboard views: mixray's calibrateCamera (mrcal "
        "and Ceres back ends), OpenCV's calibrateCamera and mrcal-calibrate-cameras on the same "
        "corners");
    auto options = std::make_shared<BenchCalibrateOptions>();
    calibrate->add_option("--views", options->views, "View counts, N[,N...]")
        ->capture_default_str();
    calibrate->add_option("--model", options->model, "opencv4, opencv5 or opencv8")
        ->capture_default_str();
    calibrate->add_option("--noise", options->noise_px, "Corner noise, pixels (1σ per axis)")
        ->check(CLI::Range(0.0, 5.0))
        ->capture_default_str();
    calibrate->add_option("--repeats", options->repeats, "Timed runs; the best counts")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    calibrate->add_flag("--json", options->json, "Print the figures as JSON");
    commands.push_back({calibrate, [options] { return runBenchCalibrate(*options); }});
}

}  // namespace mixray::cli
