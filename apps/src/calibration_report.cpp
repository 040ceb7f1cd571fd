// The pictures and tables of a calibration report, drawn with OpenCV and written as PNG.
#include "calibration_report.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace mixray::cli {
namespace {

using calibration::CameraCalibration;

constexpr int kLegendPx = 64;
constexpr double kMaxPlotSide = 1280;
const cv::Scalar kBackground(255, 255, 255);
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kOutlier(0, 0, 230);  // BGR red
// Thin arrows on white: the palette's pale yellow end would vanish, so arrows use its darker
// part.
constexpr double kArrowPaletteTop = 0.85;

Status invalid(std::string what) {
    return Status(ErrorCode::kInvalidArgument, std::move(what));
}

cv::Point at(const Eigen::Vector2d& p) {
    return {static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y()))};
}

// Viridis as 256 BGR colours: perceptually uniform and readable in grey.
const std::vector<cv::Vec3b>& palette() {
    static const std::vector<cv::Vec3b> colours = [] {
        cv::Mat ramp(1, 256, CV_8U);
        for (int i = 0; i < 256; ++i)
            ramp.at<uint8_t>(i) = static_cast<uint8_t>(i);
        cv::Mat coloured;
        cv::applyColorMap(ramp, coloured, cv::COLORMAP_VIRIDIS);
        std::vector<cv::Vec3b> out(256);
        for (int i = 0; i < 256; ++i)
            out[i] = coloured.at<cv::Vec3b>(0, i);
        return out;
    }();
    return colours;
}

cv::Vec3b colourAt(double fraction) {
    const int i = static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * 255));
    return palette()[static_cast<size_t>(i)];
}

cv::Scalar scalar(const cv::Vec3b& c) {
    return {static_cast<double>(c[0]), static_cast<double>(c[1]), static_cast<double>(c[2])};
}

std::string fixed(double v, int digits) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

// Few digits for a label: 0.05, 0.2, 1, 12.
std::string label(double v) {
    if (v == 0)
        return "0";
    const double a = std::abs(v);
    const int digits = a >= 10 ? 0 : a >= 1 ? 1 : a >= 0.1 ? 2 : 3;
    std::string s = fixed(v, digits);
    if (s.find('.') != std::string::npos) {
        while (s.back() == '0')
            s.pop_back();
        if (s.back() == '.')
            s.pop_back();
    }
    return s;
}

void text(cv::Mat& m, const std::string& s, cv::Point where, double size = 0.45,
          const cv::Scalar& colour = kInk) {
    cv::putText(m, s, where, cv::FONT_HERSHEY_SIMPLEX, size, colour, 1, cv::LINE_AA);
}

// Text with a light halo, readable over any colour.
void haloText(cv::Mat& m, const std::string& s, cv::Point where, double size = 0.45) {
    cv::putText(m, s, where, cv::FONT_HERSHEY_SIMPLEX, size, cv::Scalar(255, 255, 255), 3,
                cv::LINE_AA);
    cv::putText(m, s, where, cv::FONT_HERSHEY_SIMPLEX, size, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

// The legend's colour bar from `low` to `high` with labelled ticks, and a caption.
void colourBar(cv::Mat& m, const ImagePlotLayout& layout, double low, double high,
               const std::string& unit, const std::string& caption, double palette_top = 1) {
    const int x0 = 10, x1 = std::max(x0 + 100, std::min(layout.width - 10, x0 + 400));
    const int y0 = layout.height + 8, y1 = y0 + 14;
    for (int x = x0; x <= x1; ++x) {
        const double f = static_cast<double>(x - x0) / (x1 - x0);
        cv::line(m, {x, y0}, {x, y1}, scalar(colourAt(f * palette_top)));
    }
    cv::rectangle(m, {x0, y0}, {x1, y1}, kInk);
    for (int i = 0; i <= 4; ++i) {
        const int x = x0 + (x1 - x0) * i / 4;
        cv::line(m, {x, y1}, {x, y1 + 4}, kInk);
        const std::string s = label(low + (high - low) * i / 4.0) + (i == 4 ? " " + unit : "");
        text(m, s, {x - 8, y1 + 18}, 0.4);
    }
    text(m, caption, {x0, y1 + 38}, 0.45);
}

cv::Mat blankPlot(const ImagePlotLayout& layout) {
    cv::Mat m(layout.height + layout.legend_px, layout.width, CV_8UC3, kBackground);
    cv::rectangle(m, {0, 0}, {layout.width - 1, layout.height - 1}, kInk);
    return m;
}

Status writePng(const std::filesystem::path& png, const cv::Mat& image) {
    try {
        if (cv::imwrite(png.string(), image))
            return Status::ok();
    } catch (const cv::Exception& e) {
        return Status(ErrorCode::kIoError, "cannot write " + png.string() + ": " + e.msg);
    }
    return Status(ErrorCode::kIoError,
                  "cannot write " + png.string() + " (does its folder exist and is it writable?)");
}

Status checkModel(const CameraCalibration& c) {
    if (c.model.width <= 0 || c.model.height <= 0)
        return invalid("camera " + c.camera + ": the model has no image size");
    return Status::ok();
}

double percentile(std::vector<double> values, double p) {
    if (values.empty())
        return 0;
    const size_t k = std::min(values.size() - 1, static_cast<size_t>(p * values.size()));
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
    return values[k];
}

// 1, 2 or 5 × 10^k nearest below `v`.
double niceBelow(double v) {
    const double decade = std::pow(10.0, std::floor(std::log10(v)));
    for (double m : {5.0, 2.0, 1.0}) {
        if (m * decade <= v)
            return m * decade;
    }
    return decade;
}

std::string markdownCell(std::string s) {
    std::string out;
    for (char c : s) {
        if (c == '|')
            out += "\\|";
        else if (c == '\n')
            out += ' ';
        else
            out += c;
    }
    return out;
}

}  // namespace

ImagePlotLayout imagePlotLayout(int image_width, int image_height) {
    ImagePlotLayout l;
    l.scale = std::min(1.0, kMaxPlotSide / std::max(image_width, image_height));
    l.width = std::max(1, static_cast<int>(std::lround(image_width * l.scale)));
    l.height = std::max(1, static_cast<int>(std::lround(image_height * l.scale)));
    l.legend_px = kLegendPx;
    return l;
}

Status writeResidualPlot(const std::filesystem::path& png, const CameraCalibration& c,
                         double arrow_scale) {
    MIXRAY_RETURN_IF_ERROR(checkModel(c));
    if (c.residuals.empty())
        return invalid("camera " + c.camera + ": no residuals to draw");
    const ImagePlotLayout layout = imagePlotLayout(c.model.width, c.model.height);
    std::vector<double> lengths;
    for (const auto& r : c.residuals) {
        if (!r.outlier)
            lengths.push_back(r.residual.norm());
    }
    const double p95 = percentile(lengths, 0.95);
    if (arrow_scale <= 0)
        arrow_scale = p95 > 0 ? niceBelow(0.05 * c.model.width / p95) : 1;
    const double top = std::max(percentile(lengths, 1.0), 1e-6);
    cv::Mat m = blankPlot(layout);
    // Inliers first so that outliers stay visible on top.
    for (int pass = 0; pass < 2; ++pass) {
        for (const auto& r : c.residuals) {
            if (r.outlier != (pass == 1))
                continue;
            const Eigen::Vector2d from = layout.toPlot(r.observed);
            const Eigen::Vector2d to = layout.toPlot(r.observed + arrow_scale * r.residual);
            const cv::Scalar colour =
                r.outlier ? kOutlier : scalar(colourAt(kArrowPaletteTop * r.residual.norm() / top));
            if ((to - from).norm() < 1.5)
                cv::circle(m, at(from), 1, colour, cv::FILLED, cv::LINE_AA);
            else
                cv::arrowedLine(m, at(from), at(to), colour, 1, cv::LINE_AA, 0, 0.25);
            if (r.outlier)
                cv::drawMarker(m, at(from), kOutlier, cv::MARKER_TILTED_CROSS, 9, 2);
        }
    }
    std::string caption = "residuals x" + label(arrow_scale) + ", RMS " + fixed(c.rms_px, 3) +
                          " px, " + std::to_string(lengths.size()) + " points";
    if (c.outliers > 0 || std::any_of(c.residuals.begin(), c.residuals.end(),
                                      [](const auto& r) { return r.outlier; })) {
        const auto n = std::count_if(c.residuals.begin(), c.residuals.end(),
                                     [](const auto& r) { return r.outlier; });
        caption += ", " + std::to_string(n) + " outliers (red x)";
    }
    colourBar(m, layout, 0, top, "px", c.camera + ": " + caption, kArrowPaletteTop);
    return writePng(png, m);
}

Status writeCoverageMap(const std::filesystem::path& png, const CameraCalibration& c, int cell_px) {
    MIXRAY_RETURN_IF_ERROR(checkModel(c));
    if (cell_px < 1)
        return invalid("coverage cell size must be at least 1 pixel");
    if (c.residuals.empty())
        return invalid("camera " + c.camera + ": no observed corners to map");
    const ImagePlotLayout layout = imagePlotLayout(c.model.width, c.model.height);
    const int cols = (c.model.width + cell_px - 1) / cell_px;
    const int rows = (c.model.height + cell_px - 1) / cell_px;
    std::vector<int> counts(static_cast<size_t>(cols) * rows, 0);
    for (const auto& r : c.residuals) {
        const int col = static_cast<int>(std::floor((r.observed.x() + 0.5) / cell_px));
        const int row = static_cast<int>(std::floor((r.observed.y() + 0.5) / cell_px));
        if (col >= 0 && col < cols && row >= 0 && row < rows)
            ++counts[static_cast<size_t>(row) * cols + col];
    }
    const int top = std::max(1, *std::max_element(counts.begin(), counts.end()));
    cv::Mat m = blankPlot(layout);
    int covered = 0;
    for (int row = 0; row < rows; ++row) {
        for (int col = 0; col < cols; ++col) {
            const int n = counts[static_cast<size_t>(row) * cols + col];
            covered += n > 0;
            const cv::Scalar colour =
                n == 0 ? cv::Scalar(0, 0, 0) : scalar(colourAt(static_cast<double>(n) / top));
            const Eigen::Vector2d a = layout.toPlot({col * cell_px - 0.5, row * cell_px - 0.5});
            const Eigen::Vector2d b =
                layout.toPlot({std::min((col + 1) * cell_px, c.model.width) - 0.5,
                               std::min((row + 1) * cell_px, c.model.height) - 0.5});
            cv::rectangle(m, at(a), at(b) - cv::Point(1, 1), colour, cv::FILLED);
        }
    }
    for (const auto& r : c.residuals)
        cv::circle(m, at(layout.toPlot(r.observed)), 1, cv::Scalar(255, 255, 255), cv::FILLED);
    cv::rectangle(m, {0, 0}, {layout.width - 1, layout.height - 1}, kInk);
    const double share = 100.0 * covered / (cols * rows);
    colourBar(m, layout, 0, top, "corners",
              c.camera + ": corners per " + std::to_string(cell_px) + " px cell; " +
                  fixed(share, 0) + "% of cells observed (black: none)");
    return writePng(png, m);
}

std::vector<double> uncertaintyLevels(double low, double high, int max_levels) {
    std::vector<double> levels;
    if (!(high > 0) || !(high > low) || max_levels < 1)
        return levels;
    const double start = std::pow(10.0, std::floor(std::log10(std::max(low, high * 1e-4))));
    for (double decade = start; decade <= high; decade *= 10) {
        for (double m : {1.0, 2.0, 5.0}) {
            const double v = m * decade;
            if (v > low && v < high)
                levels.push_back(v);
        }
    }
    // Too many: keep the finest ones near the low end out, the upper ones are what users
    // look for (where the calibration stops being trustworthy).
    if (static_cast<int>(levels.size()) > max_levels)
        levels.erase(levels.begin(), levels.end() - max_levels);
    return levels;
}

Status writeUncertaintyMap(const std::filesystem::path& png, const calibration::UncertaintyMap& map,
                           int image_width, int image_height) {
    if (map.cols < 1 || map.rows < 1 || map.step_px <= 0 ||
        map.stddev_px.size() != static_cast<size_t>(map.cols) * map.rows) {
        return invalid("the uncertainty map is empty or its samples do not match cols x rows");
    }
    if (image_width <= 0 || image_height <= 0)
        return invalid("the uncertainty map needs the image size");
    const ImagePlotLayout layout = imagePlotLayout(image_width, image_height);
    // The value at every picture pixel of the image area.
    cv::Mat value(layout.height, layout.width, CV_32F);
    float max_value = 0;
    for (int y = 0; y < layout.height; ++y) {
        for (int x = 0; x < layout.width; ++x) {
            const double u = (x + 0.5) / layout.scale - 0.5;
            const double v = (y + 0.5) / layout.scale - 0.5;
            const double gx = std::clamp(u / map.step_px, 0.0, map.cols - 1.0);
            const double gy = std::clamp(v / map.step_px, 0.0, map.rows - 1.0);
            const int c0 = std::min(static_cast<int>(gx), map.cols - 1);
            const int r0 = std::min(static_cast<int>(gy), map.rows - 1);
            const int c1 = std::min(c0 + 1, map.cols - 1);
            const int r1 = std::min(r0 + 1, map.rows - 1);
            const double fx = gx - c0, fy = gy - r0;
            const double s = (1 - fy) * ((1 - fx) * map.at(c0, r0) + fx * map.at(c1, r0)) +
                             fy * ((1 - fx) * map.at(c0, r1) + fx * map.at(c1, r1));
            value.at<float>(y, x) = static_cast<float>(s);
            if (std::isfinite(s))
                max_value = std::max(max_value, static_cast<float>(s));
        }
    }
    float min_value = max_value;
    for (float s : map.stddev_px) {
        if (std::isfinite(s))
            min_value = std::min(min_value, s);
    }
    const std::vector<double> levels = uncertaintyLevels(min_value, max_value);
    const double top =
        std::max(levels.empty() ? static_cast<double>(max_value) : levels.back(), 1e-9);
    cv::Mat m = blankPlot(layout);
    for (int y = 0; y < layout.height; ++y) {
        for (int x = 0; x < layout.width; ++x) {
            const float s = value.at<float>(y, x);
            m.at<cv::Vec3b>(y, x) = std::isfinite(s) ? colourAt(s / top) : cv::Vec3b(0, 0, 0);
        }
    }
    for (double level : levels) {
        cv::Mat above = value >= static_cast<float>(level);
        std::vector<std::vector<cv::Point>> contours;
        cv::findContours(above, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
        cv::drawContours(m, contours, -1, cv::Scalar(255, 255, 255), 1, cv::LINE_8);
        // One label per contour long enough to carry it, at its point nearest the image's top
        // left so labels of nested contours do not pile up at one spot.
        for (const auto& contour : contours) {
            if (contour.size() < 40)
                continue;
            const cv::Point& p = contour[contour.size() / 2];
            haloText(m, label(level),
                     {std::clamp(p.x + 3, 0, layout.width - 30),
                      std::clamp(p.y - 3, 12, layout.height - 3)},
                     0.4);
        }
    }
    cv::rectangle(m, {0, 0}, {layout.width - 1, layout.height - 1}, kInk);
    std::string caption = "projection uncertainty (1 sigma, worst direction)";
    caption += map.distance_m > 0 ? " at " + label(map.distance_m) + " m" : " at infinity";
    caption += "; contours at";
    for (double level : levels)
        caption += " " + label(level);
    caption += " px";
    colourBar(m, layout, 0, top, "px", caption);
    return writePng(png, m);
}

RigDiagramLayout rigDiagramLayout(const calibration::RigCalibration& rig) {
    RigDiagramLayout l;
    Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
    for (const auto& T : rig.T_ref_camera) {
        lo = lo.cwiseMin(T.translation());
        hi = hi.cwiseMax(T.translation());
    }
    const double extent = (hi - lo).maxCoeff();
    l.frustum_depth_m = std::max(0.05, 0.25 * extent);
    // Room around the cameras for frusta pointing any way.
    const double margin = 1.6 * l.frustum_depth_m;
    lo.array() -= margin;
    hi.array() += margin;
    constexpr double kPanel = 560;  // the larger side of each view, pixels
    const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), hi.z() - lo.z()});
    l.px_per_m = kPanel / span;
    constexpr int kTitle = 30, kFooter = 40, kGap = 20;
    const int top_w = static_cast<int>(std::ceil((hi.x() - lo.x()) * l.px_per_m));
    const int top_h = static_cast<int>(std::ceil((hi.z() - lo.z()) * l.px_per_m));
    const int side_w = static_cast<int>(std::ceil((hi.z() - lo.z()) * l.px_per_m));
    const int side_h = static_cast<int>(std::ceil((hi.y() - lo.y()) * l.px_per_m));
    l.side_left = top_w + kGap;
    l.width = top_w + kGap + side_w;
    l.height = kTitle + std::max(top_h, side_h) + kFooter;
    // Top view: x to the right, z up the picture.
    l.top_origin = {-lo.x() * l.px_per_m, kTitle + hi.z() * l.px_per_m};
    // Side view: z to the right, y down.
    l.side_origin = {top_w + kGap - lo.z() * l.px_per_m, kTitle - lo.y() * l.px_per_m};
    return l;
}

Status writeRigDiagram(const std::filesystem::path& png, const calibration::RigCalibration& rig) {
    if (rig.cameras.empty() || rig.T_ref_camera.size() != rig.cameras.size())
        return invalid("the rig has no cameras, or not one pose per camera");
    const RigDiagramLayout l = rigDiagramLayout(rig);
    cv::Mat m(l.height, l.width, CV_8UC3, kBackground);
    text(m, "top: x right, z up (" + rig.reference + " frame)", {8, 20});
    text(m, "side: z right, y down", {l.side_left + 8, 20});
    const std::array<cv::Scalar, 3> axis_colours = {cv::Scalar(0, 0, 220), cv::Scalar(0, 170, 0),
                                                    cv::Scalar(220, 0, 0)};
    using Project = Eigen::Vector2d (RigDiagramLayout::*)(const Eigen::Vector3d&) const;
    for (Project project : {&RigDiagramLayout::top, &RigDiagramLayout::side}) {
        for (size_t i = 0; i < rig.cameras.size(); ++i) {
            const Eigen::Isometry3d& T = rig.T_ref_camera[i];
            const calibration::CameraModel& model = rig.cameras[i].model;
            const Eigen::Vector3d centre = T.translation();
            const cv::Point c = at((l.*project)(centre));
            // The frustum: rays through the image corners to the frustum depth.
            std::vector<cv::Point> far;
            const double w = model.width - 1.0, h = model.height - 1.0;
            for (const Eigen::Vector2d& corner : {Eigen::Vector2d(0, 0), Eigen::Vector2d(w, 0),
                                                  Eigen::Vector2d(w, h), Eigen::Vector2d(0, h)}) {
                auto ray = model.unproject(corner);
                if (!ray || ray->z() <= 1e-3)
                    continue;
                const Eigen::Vector3d p = T * (*ray / ray->z() * l.frustum_depth_m);
                far.push_back(at((l.*project)(p)));
            }
            for (const cv::Point& p : far)
                cv::line(m, c, p, kInk, 1, cv::LINE_AA);
            for (size_t k = 0; far.size() > 1 && k < far.size(); ++k)
                cv::line(m, far[k], far[(k + 1) % far.size()], kInk, 1, cv::LINE_AA);
            for (int a = 0; a < 3; ++a) {
                const Eigen::Vector3d tip =
                    T * (0.5 * l.frustum_depth_m * Eigen::Vector3d::Unit(a));
                cv::arrowedLine(m, c, at((l.*project)(tip)), axis_colours[a], 2, cv::LINE_AA, 0,
                                0.2);
            }
            cv::circle(m, c, 4, kInk, cv::FILLED, cv::LINE_AA);
            haloText(m, rig.cameras[i].camera, c + cv::Point(6, 16));
        }
    }
    // Scale bar: a round length near a fifth of the top view.
    const double bar_m = niceBelow(std::max(1e-3, 0.2 * l.side_left / l.px_per_m));
    const int bar_px = static_cast<int>(std::lround(bar_m * l.px_per_m));
    const int y = l.height - 16;
    cv::line(m, {10, y}, {10 + bar_px, y}, kInk, 2);
    cv::line(m, {10, y - 5}, {10, y + 5}, kInk, 2);
    cv::line(m, {10 + bar_px, y - 5}, {10 + bar_px, y + 5}, kInk, 2);
    text(m, label(bar_m) + " m", {16 + bar_px, y + 5});
    return writePng(png, m);
}

std::string viewTable(const CameraCalibration& c, const calibration::CameraViews* views) {
    std::vector<double> rms;
    for (const auto& v : c.views)
        rms.push_back(v.rms_px);
    const double median = percentile(rms, 0.5);
    std::ostringstream o;
    o << "## " << c.camera << "\n\n";
    o << "RMS " << fixed(c.rms_px, 3) << " px over " << c.views.size() << " views, " << c.outliers
      << " outliers.\n\n";
    const calibration::Observability& seen = c.observability;
    if (seen.noise_px > 0) {
        o << "Intrinsics' 1σ as a share of the focal length, at " << fixed(seen.noise_px, 2)
          << " px corner noise: fx " << fixed(100 * seen.relative_stddev[0], 2) << " %, fy "
          << fixed(100 * seen.relative_stddev[1], 2) << " %, cx "
          << fixed(100 * seen.relative_stddev[2], 2) << " %, cy "
          << fixed(100 * seen.relative_stddev[3], 2) << " %; condition " << fixed(seen.condition, 0)
          << "; board normals spread over " << fixed(seen.normal_spread_deg, 1) << "°.\n\n";
    }
    if (!seen.summary.empty())
        o << "**Weakly determined, kept (--accept-weak):** " << markdownCell(seen.summary)
          << "\n\n";
    o << "| view | source | key | corners | outliers | RMS (px) | note |\n";
    o << "|---:|---|---:|---:|---:|---:|---|\n";
    std::vector<bool> used(views ? views->views.size() : 0, false);
    for (const auto& v : c.views) {
        std::string source, key;
        if (views && v.view < views->views.size()) {
            source = markdownCell(views->views[v.view].source);
            key = std::to_string(views->views[v.view].key);
            used[v.view] = true;
        }
        const bool high = median > 0 && v.rms_px > 2 * median;
        o << "| " << v.view << " | " << source << " | " << key << " | " << v.corners << " | "
          << v.outliers << " | " << fixed(v.rms_px, 3) << " | "
          << (high ? "RMS over twice the median" : "") << " |\n";
    }
    if (views) {
        bool header = false;
        for (size_t i = 0; i < views->views.size(); ++i) {
            if (used[i])
                continue;
            const auto& v = views->views[i];
            if (!header) {
                o << "\nNot used:\n\n| view | source | key | why |\n|---:|---|---:|---|\n";
                header = true;
            }
            std::string why(calibration::toString(v.rejection));
            if (!v.why.empty())
                why += ": " + v.why;
            o << "| " << i << " | " << markdownCell(v.source) << " | " << v.key << " | "
              << markdownCell(why) << " |\n";
        }
    }
    return o.str();
}

Status writeViewTable(const std::filesystem::path& md, const CameraCalibration& c,
                      const calibration::CameraViews* views) {
    std::ofstream out(md, std::ios::binary | std::ios::trunc);
    if (!out)
        return Status(ErrorCode::kIoError, "cannot write " + md.string());
    out << viewTable(c, views);
    out.flush();
    if (!out)
        return Status(ErrorCode::kIoError, "writing " + md.string() + " failed");
    return Status::ok();
}

std::string reportFileStem(const std::string& camera) {
    std::string s = camera;
    for (char& ch : s) {
        const bool keep = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                          (ch >= '0' && ch <= '9') || ch == '-' || ch == '.';
        if (!keep)
            ch = '_';
    }
    return s.empty() ? "camera" : s;
}

}  // namespace mixray::cli
