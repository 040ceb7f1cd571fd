// Target detection and view rejection (detect.h): chessboards through OpenCV, ChArUco and
// AprilGrid through marker_detection.h; image folders and recordings.
#include "mixray/calibration/detect.h"

#include <fnmatch.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <string_view>
#include <system_error>
#include <utility>

#include "detect_internal.h"
#include "image_file.h"
#include "mixray/graph/mkv.h"

namespace mixray::calibration {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

std::string fmt(int decimals, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
    return buf;
}

ImageView viewOf(const cv::Mat& grey) {
    ImageView v;
    v.desc = ImageDesc{PixelFormat::kMono8, grey.cols, grey.rows, static_cast<int>(grey.step[0])};
    v.data = grey.data;
    v.size_bytes = grey.step[0] * static_cast<size_t>(grey.rows);
    return v;
}

Result<cv::Mat> greyOf(const ImageView& image) {
    const ImageDesc& d = image.desc;
    const PixelFormatInfo& info = pixelFormatInfo(d.format);
    const bool supported = d.format == PixelFormat::kMono8 || d.format == PixelFormat::kRGB8 ||
                           d.format == PixelFormat::kBGR8 || d.format == PixelFormat::kMono16 ||
                           d.format == PixelFormat::kIR16;
    if (!supported)
        return Status(ErrorCode::kInvalidArgument,
                      "targets are found in mono8, rgb8, bgr8, mono16 or ir16 images, not " +
                          std::string(toString(d.format)));
    const int bytes = static_cast<int>(info.bits_per_pixel / 8);
    if (d.width <= 0 || d.height <= 0 || !image.data || d.stride_bytes < d.width * bytes ||
        image.size_bytes < static_cast<size_t>(d.stride_bytes) * static_cast<size_t>(d.height - 1) +
                               static_cast<size_t>(d.width * bytes))
        return Status(ErrorCode::kInvalidArgument, "image buffer smaller than its " +
                                                       std::to_string(d.width) + "x" +
                                                       std::to_string(d.height) + " description");
    auto* data = const_cast<uint8_t*>(image.data);
    const auto step = static_cast<size_t>(d.stride_bytes);
    cv::Mat grey;
    switch (d.format) {
        case PixelFormat::kMono8:
            grey = cv::Mat(d.height, d.width, CV_8UC1, data, step).clone();
            break;
        case PixelFormat::kRGB8:
            cv::cvtColor(cv::Mat(d.height, d.width, CV_8UC3, data, step), grey, cv::COLOR_RGB2GRAY);
            break;
        case PixelFormat::kBGR8:
            cv::cvtColor(cv::Mat(d.height, d.width, CV_8UC3, data, step), grey, cv::COLOR_BGR2GRAY);
            break;
        default:
            grey = detail::stretch16(cv::Mat(d.height, d.width, CV_16UC1, data, step));
            break;
    }
    return grey;
}

// The median distance from each corner to its nearest neighbour, in pixels.
double cornerSpacing(const std::vector<Corner>& corners) {
    std::vector<double> nearest;
    for (size_t i = 0; i < corners.size(); ++i) {
        double best = 1e30;
        for (size_t j = 0; j < corners.size(); ++j)
            if (j != i)
                best = std::min(best, (corners[i].pixel - corners[j].pixel).norm());
        nearest.push_back(best);
    }
    if (nearest.empty())
        return 0;
    std::nth_element(nearest.begin(), nearest.begin() + static_cast<long>(nearest.size() / 2),
                     nearest.end());
    return nearest[nearest.size() / 2];
}

// Edge blur (detect.h, DetectionOptions::max_edge_blur_px): around each corner, the local
// contrast over the steepest Sobel gradient; the median over the corners.
double edgeBlurPx(const cv::Mat& grey, const std::vector<Corner>& corners) {
    if (corners.empty())
        return 0;
    const double spacing = cornerSpacing(corners);
    const int r = std::clamp(static_cast<int>(std::lround(0.35 * spacing)), 3, 10);
    cv::Mat gx, gy;
    cv::Sobel(grey, gx, CV_32F, 1, 0, 3, 1.0 / 8);
    cv::Sobel(grey, gy, CV_32F, 0, 1, 3, 1.0 / 8);
    std::vector<double> widths;
    for (const Corner& c : corners) {
        const int cx = static_cast<int>(std::lround(c.pixel.x()));
        const int cy = static_cast<int>(std::lround(c.pixel.y()));
        if (cx - r < 1 || cy - r < 1 || cx + r >= grey.cols - 1 || cy + r >= grey.rows - 1)
            continue;
        double lo = 255, hi = 0, steepest = 0;
        for (int y = cy - r; y <= cy + r; ++y)
            for (int x = cx - r; x <= cx + r; ++x) {
                const double v = grey.at<uint8_t>(y, x);
                lo = std::min(lo, v);
                hi = std::max(hi, v);
                steepest = std::max(steepest, std::hypot(static_cast<double>(gx.at<float>(y, x)),
                                                         static_cast<double>(gy.at<float>(y, x))));
            }
        if (hi - lo >= 10 && steepest > 0)
            widths.push_back((hi - lo) / steepest);
    }
    if (widths.empty())
        return 0;
    std::nth_element(widths.begin(), widths.begin() + static_cast<long>(widths.size() / 2),
                     widths.end());
    return widths[widths.size() / 2];
}

// The angle between the board's normal and the ray to the observed corners' centre, from IPPE
// on normalised image points; nullopt when no pose can be had.
std::optional<double> tiltDeg(const CalibrationTarget& target, const std::vector<Corner>& corners,
                              const CameraModel& camera) {
    if (corners.size() < 4)
        return std::nullopt;
    const std::vector<Vector3d> points = target.points();
    std::vector<cv::Point3d> obj;
    std::vector<cv::Point2d> img;
    Vector3d centre = Vector3d::Zero();
    for (const Corner& c : corners) {
        const auto d = camera.unproject(c.pixel);
        if (!d || d->z() <= 1e-9 || c.id < 0 || static_cast<size_t>(c.id) >= points.size())
            continue;
        const Vector3d& p = points[static_cast<size_t>(c.id)];
        obj.emplace_back(p.x(), p.y(), p.z());
        img.emplace_back(d->x() / d->z(), d->y() / d->z());
        centre += p;
    }
    if (obj.size() < 4)
        return std::nullopt;
    centre /= static_cast<double>(obj.size());
    cv::Mat rvec, tvec;
    try {
        if (!cv::solvePnP(obj, img, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvec, tvec, false,
                          cv::SOLVEPNP_IPPE))
            return std::nullopt;
    } catch (const cv::Exception&) {
        return std::nullopt;
    }
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    const Vector3d n(R.at<double>(0, 2), R.at<double>(1, 2), R.at<double>(2, 2));
    const Vector3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    Eigen::Matrix3d Re;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            Re(i, j) = R.at<double>(i, j);
    const Vector3d ray = Re * centre + t;
    if (ray.norm() <= 0)
        return std::nullopt;
    const double c = std::min(1.0, std::abs(n.dot(ray.normalized())));
    return std::acos(c) * 180 / M_PI;
}

// Saddle-point refinement of chessboard corners (X-junctions). Blurring an X-junction, and
// the camera's tone curve, keep it symmetric under a half turn about the junction, so the
// junction is a critical point of the blurred image: a quadratic fitted over a window centred
// on the estimate has its saddle there, exactly for a straight-edged junction. Iterated until
// the window is centred. Corners whose fit is no saddle or wanders off keep their position.
void refineSaddles(const cv::Mat& grey, std::vector<Corner>& corners, int radius) {
    cv::Mat f;
    grey.convertTo(f, CV_32F);
    cv::GaussianBlur(f, f, cv::Size(0, 0), 1.0);
    const auto sample = [&](double x, double y) {
        const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
        const double ax = x - x0, ay = y - y0;
        const float* r0 = f.ptr<float>(y0);
        const float* r1 = f.ptr<float>(y0 + 1);
        return (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) +
               ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]);
    };
    for (Corner& c : corners) {
        Vector2d p = c.pixel;
        bool ok = true;
        for (int iter = 0; iter < 8 && ok; ++iter) {
            if (p.x() - radius < 0 || p.y() - radius < 0 || p.x() + radius + 1 >= f.cols ||
                p.y() + radius + 1 >= f.rows) {
                ok = false;
                break;
            }
            // Least squares of v = a x² + b xy + c y² + d x + e y + g, Gaussian-weighted.
            Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
            Eigen::Matrix<double, 6, 1> rhs = Eigen::Matrix<double, 6, 1>::Zero();
            const double s2 = 2.0 * (0.5 * radius + 0.5) * (0.5 * radius + 0.5);
            for (int j = -radius; j <= radius; ++j)
                for (int i = -radius; i <= radius; ++i) {
                    const double w = std::exp(-(i * i + j * j) / s2);
                    Eigen::Matrix<double, 6, 1> m;
                    m << i * i, i * j, j * j, i, j, 1;
                    A += w * m * m.transpose();
                    rhs += w * m * sample(p.x() + i, p.y() + j);
                }
            const Eigen::Matrix<double, 6, 1> q = A.ldlt().solve(rhs);
            Eigen::Matrix2d H;
            H << 2 * q[0], q[1], q[1], 2 * q[2];
            if (H.determinant() >= 0) {  // no saddle
                ok = false;
                break;
            }
            const Vector2d step = -H.inverse() * Vector2d(q[3], q[4]);
            if (!step.allFinite() || step.norm() > radius) {
                ok = false;
                break;
            }
            p += step;
            if (step.norm() < 1e-3)
                break;
        }
        if (ok && (p - c.pixel).norm() <= radius)
            c.pixel = p;
    }
}

// The window of refineSaddles(): a radius of 12 % of the corner spacing, which stays clear of
// ChArUco's markers (13 % of a square from the corners on common boards), 2 to 4 px.
int saddleRadius(const std::vector<Corner>& corners) {
    return std::clamp(static_cast<int>(0.12 * cornerSpacing(corners)), 2, 4);
}

// Whether a chessboard's grid of X-junctions goes on beyond the corners found: a board declared
// smaller than printed is found as a sub-board, at a different place in each view, whose
// corner ids are not the board's. One square beyond a board's outermost corners there is
// its white margin (T-junctions, edges); on a larger board there are X-junctions again.
class GridExtension {
public:
    // `corners`: the found cols × rows grid, row-major (findChessboard()).
    GridExtension(const cv::Mat& grey, const std::vector<Corner>& corners, int cols, int rows) {
        grey.convertTo(blurred_, CV_32F);
        cv::GaussianBlur(blurred_, blurred_, cv::Size(0, 0), 1.0);
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < cols; ++c)
                grid_[{c, r}] = corners[static_cast<size_t>(r * cols + c)].pixel;
        // The contrast of a true X-junction here, and which of its diagonals is bright at the
        // first corner: the yardstick for the junctions looked for beyond the grid.
        std::vector<double> contrast;
        double sign_sum = 0;
        for (const auto& [cell, pixel] : grid_) {
            const auto H = localHomography(cell.first, cell.second);
            const auto q = H ? quadrants(*H, cell.first, cell.second) : std::nullopt;
            if (!q)
                continue;
            const double parity = (cell.first + cell.second) % 2 == 0 ? 1 : -1;
            const double d = 0.5 * ((*q)[0] + (*q)[3] - (*q)[1] - (*q)[2]);
            sign_sum += parity * d;
            contrast.push_back(std::abs(d));
        }
        if (contrast.size() < 4)
            return;
        std::nth_element(contrast.begin(),
                         contrast.begin() + static_cast<long>(contrast.size() / 2), contrast.end());
        contrast_ = contrast[contrast.size() / 2];
        sign_ = sign_sum >= 0 ? 1 : -1;
    }

    // Extends the grid outwards, one line at a time on each side, while a line of X-junctions
    // continues it; the lines added per side (left, right, top, bottom).
    std::array<int, 4> extend() {
        std::array<int, 4> added{0, 0, 0, 0};
        if (!(contrast_ > kMinContrast))
            return added;
        for (bool grew = true; grew;) {
            grew = false;
            for (int side = 0; side < 4; ++side) {
                if (added[0] + added[1] + added[2] + added[3] >= kMaxLines)
                    return added;
                if (extendSide(side)) {
                    ++added[static_cast<size_t>(side)];
                    grew = true;
                }
            }
        }
        return added;
    }

private:
    // Grey levels of a junction's diagonals must differ by this much to judge it at all.
    static constexpr double kMinContrast = 20;
    // A candidate is an X-junction when its weakest quadrant pair keeps this fraction of the
    // found junctions' contrast: 1 for a junction like the found ones, 0 or less for the
    // T-junctions and edges of a board's margin (whose two margin quadrants are alike).
    static constexpr double kMinJunction = 0.5;
    // This share of a line's candidates inside the image must be X-junctions, and at least
    // half of the line (and 3 candidates) must be inside the image to judge it.
    static constexpr double kMinLineShare = 0.8;
    // Never more lines than this in all (a board of X-junctions filling the image).
    static constexpr int kMaxLines = 40;

    using Cell = std::pair<int, int>;  // (column, row) in the found grid's numbering

    // The homography from grid coordinates to pixels fitted to the found corners within two
    // lines of (c, r) (a local fit: the lens's distortion bends the grid).
    std::optional<cv::Mat> localHomography(int c, int r) const {
        std::vector<cv::Point2f> from, to;
        for (const auto& [cell, pixel] : grid_) {
            if (std::abs(cell.first - c) <= 2 && std::abs(cell.second - r) <= 2) {
                from.emplace_back(static_cast<float>(cell.first), static_cast<float>(cell.second));
                to.emplace_back(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()));
            }
        }
        if (from.size() < 6)
            return std::nullopt;
        try {
            cv::Mat H = cv::findHomography(from, to, 0);
            if (H.empty())
                return std::nullopt;
            return H;
        } catch (const cv::Exception&) {
            return std::nullopt;
        }
    }

    static std::optional<Vector2d> apply(const cv::Mat& H, double u, double v) {
        const double x = H.at<double>(0, 0) * u + H.at<double>(0, 1) * v + H.at<double>(0, 2);
        const double y = H.at<double>(1, 0) * u + H.at<double>(1, 1) * v + H.at<double>(1, 2);
        const double w = H.at<double>(2, 0) * u + H.at<double>(2, 1) * v + H.at<double>(2, 2);
        if (!(std::abs(w) > 1e-12))
            return std::nullopt;
        return Vector2d(x / w, y / w);
    }

    // The mean grey level in each quadrant around grid point (c, r), sampled through H between
    // 0.15 and 0.35 of a square from the junction's lines: (+u +v), (+u −v), (−u +v), (−u −v).
    // nullopt when a sample falls outside the image.
    std::optional<std::array<double, 4>> quadrants(const cv::Mat& H, double c, double r) const {
        std::array<double, 4> mean{0, 0, 0, 0};
        constexpr std::array<double, 3> kOffsets = {0.15, 0.25, 0.35};
        for (int q = 0; q < 4; ++q) {
            const double su = q < 2 ? 1 : -1, sv = q % 2 == 0 ? 1 : -1;
            for (double a : kOffsets)
                for (double b : kOffsets) {
                    const auto p = apply(H, c + su * a, r + sv * b);
                    if (!p || p->x() < 0 || p->y() < 0 || p->x() > blurred_.cols - 2 ||
                        p->y() > blurred_.rows - 2)
                        return std::nullopt;
                    const int x0 = static_cast<int>(p->x()), y0 = static_cast<int>(p->y());
                    const double ax = p->x() - x0, ay = p->y() - y0;
                    const float* r0 = blurred_.ptr<float>(y0);
                    const float* r1 = blurred_.ptr<float>(y0 + 1);
                    mean[static_cast<size_t>(q)] +=
                        (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) +
                        ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]);
                }
            mean[static_cast<size_t>(q)] /= static_cast<double>(kOffsets.size() * kOffsets.size());
        }
        return mean;
    }

    // How much (c, r) looks like the grid's X-junction there would be: the darker of the
    // diagonal that should be bright less the brighter of the other, over the found contrast.
    std::optional<double> junction(const cv::Mat& H, int c, int r) const {
        const auto q = quadrants(H, c, r);
        if (!q)
            return std::nullopt;
        const double parity = (c + r) % 2 == 0 ? 1 : -1;
        const bool main_bright = sign_ * parity > 0;  // quadrants (+ +) and (− −)
        const double bright = main_bright ? std::min((*q)[0], (*q)[3]) : std::min((*q)[1], (*q)[2]);
        const double dark = main_bright ? std::max((*q)[1], (*q)[2]) : std::max((*q)[0], (*q)[3]);
        return (bright - dark) / contrast_;
    }

    // Adds the line beyond side 0 left, 1 right, 2 top, 3 bottom when it is one of X-junctions.
    bool extendSide(int side) {
        int c0 = 0, c1 = 0, r0 = 0, r1 = 0;
        for (const auto& [cell, pixel] : grid_) {
            c0 = std::min(c0, cell.first);
            c1 = std::max(c1, cell.first);
            r0 = std::min(r0, cell.second);
            r1 = std::max(r1, cell.second);
        }
        const bool vertical = side < 2;  // a new column
        const int fixed = side == 0 ? c0 - 1 : side == 1 ? c1 + 1 : side == 2 ? r0 - 1 : r1 + 1;
        const int from = vertical ? r0 : c0, to = vertical ? r1 : c1;
        std::vector<std::pair<Cell, Vector2d>> found;
        int inside = 0;
        for (int k = from; k <= to; ++k) {
            const Cell cell = vertical ? Cell{fixed, k} : Cell{k, fixed};
            const Cell inner = vertical ? Cell{fixed + (side == 0 ? 1 : -1), k}
                                        : Cell{k, fixed + (side == 2 ? 1 : -1)};
            const auto H = localHomography(inner.first, inner.second);
            if (!H)
                continue;
            const auto score = junction(*H, cell.first, cell.second);
            if (!score)
                continue;
            ++inside;
            if (*score > kMinJunction)
                found.push_back({cell, *apply(*H, cell.first, cell.second)});
        }
        const int length = to - from + 1;
        if (inside < 3 || 2 * inside < length ||
            static_cast<double>(found.size()) < kMinLineShare * inside)
            return false;
        for (const auto& [cell, pixel] : found)
            grid_[cell] = pixel;
        return true;
    }

    cv::Mat blurred_;
    std::map<Cell, Vector2d> grid_;
    double contrast_ = 0;
    double sign_ = 1;
};

// A view of a chessboard larger than `target` (detect.h, ViewRejection::kLargerBoard).
void markLargerBoard(TargetView& view, const CalibrationTarget& target, int seen_cols,
                     int seen_rows, const std::string& how) {
    view.rejection = ViewRejection::kLargerBoard;
    view.seen_cols = seen_cols;
    view.seen_rows = seen_rows;
    view.why = how + ": the board looks " + std::to_string(seen_cols) + "x" +
               std::to_string(seen_rows) + ", not " + std::to_string(target.cols) + "x" +
               std::to_string(target.rows);
}

// OpenCV's sector-based detector, or where it finds nothing (one of the 13 left*.jpg) the
// classic one, then the saddle fit: on synthetic boards findChessboardCornersSB is off by up to
// 0.47 px at 50° tilt, findChessboardCorners + cornerSubPix by up to 0.25 px at 20–35°, the saddle
// fit by less than 0.11 px (tests/calibration/detect_test.cpp). The sector-based detector is
// allowed a board larger than the target (CALIB_CB_LARGER): a board declared smaller than
// printed is then found whole and the view is kLargerBoard with the size found, instead of no
// target. A board found at the target's size is looked beyond (GridExtension) when
// `check_larger` is set.
std::vector<Corner> findChessboard(const cv::Mat& grey, const CalibrationTarget& target,
                                   TargetView& view, bool check_larger) {
    std::vector<cv::Point2f> found;
    std::vector<Corner> out;
    const cv::Size size(target.cols, target.rows);
    const size_t count = static_cast<size_t>(target.cols) * static_cast<size_t>(target.rows);
    constexpr int kSectorFlags = cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY;
    try {
        cv::Mat meta;
        bool sector = cv::findChessboardCornersSB(
            grey, size, found, kSectorFlags | (check_larger ? cv::CALIB_CB_LARGER : 0), meta);
        // A larger board by the permissive search is believed only when the target's size is
        // not found: on a board as declared it can take the print's edge for one more line
        // (left12.jpg of the OpenCV sample), and the stricter look beyond decides then.
        if (sector && found.size() > count) {
            std::vector<cv::Point2f> exact;
            if (cv::findChessboardCornersSB(grey, size, exact, kSectorFlags)) {
                found = exact;
                meta = cv::Mat();
            }
        }
        if (sector && found.size() > count && meta.rows > 0 && meta.cols > 0) {
            // OpenCV may give the larger board transposed; the size is told in the target's
            // orientation.
            int seen_cols = meta.cols, seen_rows = meta.rows;
            if ((target.cols >= target.rows) != (seen_cols >= seen_rows))
                std::swap(seen_cols, seen_rows);
            markLargerBoard(view, target, seen_cols, seen_rows,
                            "a " + std::to_string(seen_cols) + "x" + std::to_string(seen_rows) +
                                " chessboard found where " + std::to_string(target.cols) + "x" +
                                std::to_string(target.rows) + " was declared");
            return out;  // its corners are not the target's points
        }
        if (sector && check_larger && !meta.empty() && meta.cols != target.cols) {
            // The target's size, transposed: the plain search orders it as the target.
            sector = cv::findChessboardCornersSB(grey, size, found, kSectorFlags);
        }
        if (!sector &&
            !cv::findChessboardCorners(grey, size, found,
                                       cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE))
            return out;
    } catch (const cv::Exception&) {
        return out;
    }
    if (found.size() != count)
        return out;
    for (size_t i = 0; i < found.size(); ++i)
        out.push_back({static_cast<int>(i), Vector2d(found[i].x, found[i].y), 1.0});
    refineSaddles(grey, out, saddleRadius(out));
    if (!check_larger)
        return out;
    const std::array<int, 4> added = detail::chessboardBeyond(grey, out, target.cols, target.rows);
    if (added[0] + added[1] + added[2] + added[3] == 0)
        return out;
    static constexpr std::array<const char*, 4> kSide = {"left", "right", "above", "below"};
    std::string where;
    for (size_t side = 0; side < 4; ++side) {
        if (added[side] == 0)
            continue;
        where += (where.empty() ? "" : ", ") + std::to_string(added[side]) +
                 (side < 2 ? " column" : " row") + (added[side] > 1 ? "s " : " ") + kSide[side];
    }
    markLargerBoard(view, target, target.cols + added[0] + added[1],
                    target.rows + added[2] + added[3],
                    "X-junctions go on beyond the " + std::to_string(target.cols) + "x" +
                        std::to_string(target.rows) + " corners found (" + where + ")");
    return out;
}

// Markers of `dictionary`; when `expected` is not reached and `upsample` is set, a second pass
// on the image upsampled 2× (cubic) finds markers too small for the first, and the pass with
// more markers is kept (corners mapped back about pixel centres). The corners are refined on
// the original image afterwards.
Result<std::vector<MarkerDetection>> findMarkers(const cv::Mat& grey, std::string_view dictionary,
                                                 const DetectorOptions& options, size_t expected,
                                                 bool upsample) {
    auto found = detectMarkers(viewOf(grey), dictionary, options);
    if (!found || !upsample || found->size() >= expected)
        return found;
    cv::Mat big;
    cv::resize(grey, big, cv::Size(), 2, 2, cv::INTER_CUBIC);
    auto more = detectMarkers(viewOf(big), dictionary, options);
    if (!more || more->size() <= found->size())
        return found;
    const Vector2d half(0.5, 0.5);
    for (MarkerDetection& m : *more)
        for (Vector2d& c : m.corners)
            c = (c + half) / 2 - half;
    return more;
}

Result<std::vector<Corner>> findCharuco(const cv::Mat& grey, const CalibrationTarget& target,
                                        const DetectionOptions& options, size_t& marker_count) {
    auto found = findMarkers(grey, target.dictionary, options.markers,
                             static_cast<size_t>(target.cols * target.rows / 2),
                             options.upsample_small_markers);
    if (!found)
        return found.status();
    marker_count = found->size();
    const CharucoBoardSpec spec{target.cols,     target.rows,       target.square_m,
                                target.marker_m, target.dictionary, 0};
    auto corners = charucoCorners(viewOf(grey), spec, *found);
    if (!corners)
        return corners.status();
    // interpolateCornersCharuco's cornerSubPix is off by up to 0.35 px on synthetic boards; the
    // saddle fit by up to 0.11 px.
    if (corners->size() >= 2)
        refineSaddles(grey, *corners, saddleRadius(*corners));
    return corners;
}

// Kalibr's AprilGrid point ids for each tag found (target.h).
Result<std::vector<Corner>> findAprilGrid(const cv::Mat& grey, const CalibrationTarget& target,
                                          const DetectionOptions& options, size_t& marker_count) {
    // Kalibr prints the grid's tag36h11 tags with a two-cell border.
    auto found =
        findMarkers(grey, "apriltag:tag36h11b2", options.markers,
                    static_cast<size_t>(target.cols * target.rows), options.upsample_small_markers);
    if (!found)
        return found.status();
    marker_count = found->size();
    const int tags = target.cols * target.rows;
    std::map<int, int> seen;  // a tag id twice: a stray tag beside the grid, both left out
    for (const MarkerDetection& m : *found)
        ++seen[m.id];
    std::vector<Corner> out;
    const int row = 2 * target.cols;
    for (const MarkerDetection& m : *found) {
        if (m.id < 0 || m.id >= tags || seen[m.id] != 1)
            continue;
        const int base = (m.id / target.cols) * 2 * row + (m.id % target.cols) * 2;
        // libapriltag's p[0..3] (lower-left, lower-right, upper-right, upper-left as printed)
        // are MarkerDetection's corners[1], [0], [3], [2].
        const std::array<std::pair<int, size_t>, 4> ids = {
            {{base, 1}, {base + 1, 0}, {base + row + 1, 3}, {base + row, 2}}};
        for (const auto& [id, k] : ids)
            out.push_back({id, m.corners[k], 1.0});
    }
    std::sort(out.begin(), out.end(), [](const Corner& a, const Corner& b) { return a.id < b.id; });
    // Kalibr's squares in the gaps make every tag corner an X-junction (its reason for them).
    if (out.size() >= 2)
        refineSaddles(grey, out, saddleRadius(out));
    return out;
}

// Numbers the capture instants of a recording's frames in reading order: a frame starts a new
// key when its host stamp is more than the skew after the key's first frame, or its stream
// already has a frame in the key.
class KeyClock {
public:
    explicit KeyClock(int64_t max_skew_ns) : max_skew_ns_(max_skew_ns) {}
    int64_t keyOf(const FrameMetadata& meta) {
        if (key_ < 0 || meta.host_stamp_ns - start_ns_ > max_skew_ns_ ||
            in_key_.count(meta.stream)) {
            ++key_;
            start_ns_ = meta.host_stamp_ns;
            in_key_.clear();
        }
        in_key_.insert(meta.stream);
        return key_;
    }

private:
    int64_t max_skew_ns_;
    int64_t key_ = -1, start_ns_ = 0;
    std::set<StreamId> in_key_;
};

// Reads `recording` from the start and hands every frame to `visit` in order, after its stream
// list (`streams`); stops at the first error `visit` returns, or the reader's (but its end).
// Every frame is released before the next is read, so a stream never runs out of buffers;
// kUnavailable twice in a row is the reader's fault, not a wait.
Status forEachFrame(const std::filesystem::path& recording,
                    const std::function<void(const std::vector<StreamInfo>&)>& streams,
                    const std::function<Status(const FrameRef&)>& visit) {
    auto reader = openMkv(recording);
    if (!reader)
        return reader.status();
    streams((*reader)->streams());
    while (true) {
        auto frame = (*reader)->next();
        if (!frame && frame.status().code() == ErrorCode::kUnavailable)
            frame = (*reader)->next();
        if (!frame) {
            if (frame.status().code() == ErrorCode::kEndOfStream)
                return Status::ok();
            return frame.status().withContext(recording.string());
        }
        MIXRAY_RETURN_IF_ERROR(visit(*frame));
    }
}

// detectTarget() for a collector's view: `view` keeps its source and key. The tilt check's
// model only applies to images of its size.
Status detectInto(const ImageView& image, const CalibrationTarget& target,
                  const DetectionOptions& options, TargetView& view) {
    DetectionOptions o = options;
    if (o.camera && (o.camera->width != image.desc.width || o.camera->height != image.desc.height))
        o.camera.reset();
    auto found = detectTarget(image, target, o);
    if (!found)
        return found.status().withContext(view.source);
    found->source = std::move(view.source);
    found->key = view.key;
    view = std::move(found).value();
    return Status::ok();
}

CameraModel roughCamera(int width, int height) {
    CameraModel m;
    m.width = width;
    m.height = height;
    m.fx = m.fy = std::max(width, height);
    m.cx = 0.5 * (width - 1);
    m.cy = 0.5 * (height - 1);
    return m;
}

}  // namespace

Status DetectionOptions::validate() const {
    if (!(min_point_fraction >= 0 && min_point_fraction <= 1))
        return {
            ErrorCode::kInvalidArgument,
            "detection.min_point_fraction must be in [0, 1], got " + fmt(3, min_point_fraction)};
    if (!(max_edge_blur_px >= 0) || !std::isfinite(max_edge_blur_px))
        return {ErrorCode::kInvalidArgument, "detection.max_edge_blur_px must be >= 0"};
    if (!(max_tilt_deg >= 0 && max_tilt_deg <= 90))
        return {ErrorCode::kInvalidArgument,
                "detection.max_tilt_deg must be in [0, 90], got " + fmt(3, max_tilt_deg)};
    if (max_skew_ns < 0)
        return {ErrorCode::kInvalidArgument, "detection.max_skew_ns must be >= 0"};
    if (camera)
        MIXRAY_RETURN_IF_ERROR(camera->validate());
    if (!marker_dictionary.empty() && !isKnownDictionary(marker_dictionary))
        return {ErrorCode::kInvalidArgument,
                "detection.marker_dictionary: unknown dictionary " + marker_dictionary};
    return markers.validate();
}

Result<TargetView> detectTarget(const ImageView& image, const CalibrationTarget& target,
                                const DetectionOptions& options) {
    MIXRAY_RETURN_IF_ERROR(target.validate());
    MIXRAY_RETURN_IF_ERROR(options.validate());
    if (options.camera &&
        (options.camera->width != image.desc.width || options.camera->height != image.desc.height))
        return Status(ErrorCode::kInvalidArgument,
                      "detection.camera is " + std::to_string(options.camera->width) + "x" +
                          std::to_string(options.camera->height) + ", the image " +
                          std::to_string(image.desc.width) + "x" +
                          std::to_string(image.desc.height));
    auto grey = greyOf(image);
    if (!grey)
        return grey.status();
    TargetView view;
    if (!options.marker_dictionary.empty()) {
        auto seen = findMarkers(*grey, options.marker_dictionary, options.markers, 0, false);
        if (!seen)
            return seen.status();
        for (const MarkerDetection& m : *seen)
            view.markers.push_back({m.id, m.corners});
    }
    size_t markers = 0;
    switch (target.kind) {
        case TargetKind::kChessboard:
            view.corners = findChessboard(*grey, target, view, options.check_larger_board);
            break;
        case TargetKind::kCharuco: {
            auto found = findCharuco(*grey, target, options, markers);
            if (!found)
                return found.status();
            view.corners = std::move(found).value();
            break;
        }
        case TargetKind::kAprilGrid: {
            auto found = findAprilGrid(*grey, target, options, markers);
            if (!found)
                return found.status();
            view.corners = std::move(found).value();
            break;
        }
    }
    if (view.rejection != ViewRejection::kNone)
        return view;  // kLargerBoard
    const int total = target.pointCount();
    if (view.corners.empty()) {
        view.rejection = ViewRejection::kNoTarget;
        view.why = target.kind == TargetKind::kChessboard
                       ? "no " + std::to_string(target.cols) + "x" + std::to_string(target.rows) +
                             " chessboard found"
                       : "no corners found (" + std::to_string(markers) + " markers of " +
                             target.dictionary + " seen)";
        return view;
    }
    const double fraction = static_cast<double>(view.corners.size()) / total;
    if (fraction < options.min_point_fraction) {
        view.rejection = ViewRejection::kPartialTarget;
        view.why = std::to_string(view.corners.size()) + " of " + std::to_string(total) +
                   " points (" + fmt(0, 100 * fraction) + " %) < " +
                   fmt(0, 100 * options.min_point_fraction) + " %";
        return view;
    }
    if (options.max_edge_blur_px > 0) {
        const double blur = edgeBlurPx(*grey, view.corners);
        if (blur > options.max_edge_blur_px) {
            view.rejection = ViewRejection::kBlurred;
            view.why =
                "edge blur " + fmt(1, blur) + " px > " + fmt(1, options.max_edge_blur_px) + " px";
            return view;
        }
    }
    if (options.max_tilt_deg > 0) {
        const CameraModel camera =
            options.camera ? *options.camera : roughCamera(image.desc.width, image.desc.height);
        const auto tilt = tiltDeg(target, view.corners, camera);
        if (tilt && *tilt > options.max_tilt_deg) {
            view.rejection = ViewRejection::kTooOblique;
            view.why = "board tilted " + fmt(0, *tilt) + "° from the view, > " +
                       fmt(0, options.max_tilt_deg) + "°";
            return view;
        }
    }
    return view;
}

Result<CameraViews> detectInFolder(const std::filesystem::path& folder,
                                   const CalibrationTarget& target, const std::string& pattern,
                                   const DetectionOptions& options,
                                   const ProgressCallback& progress) {
    MIXRAY_RETURN_IF_ERROR(target.validate());
    MIXRAY_RETURN_IF_ERROR(options.validate());
    std::error_code ec;
    if (!std::filesystem::is_directory(folder, ec))
        return Status(ErrorCode::kNotFound, folder.string() + ": no such folder");
    std::vector<std::filesystem::path> files;
    for (const auto& entry : std::filesystem::directory_iterator(folder, ec)) {
        const std::string name = entry.path().filename().string();
        if (entry.is_regular_file(ec) && fnmatch(pattern.c_str(), name.c_str(), 0) == 0)
            files.push_back(entry.path());
    }
    if (ec)
        return Status(ErrorCode::kNotFound, folder.string() + ": " + ec.message());
    if (files.empty())
        return Status(ErrorCode::kNotFound,
                      folder.string() + ": no file matches '" + pattern + "'");
    std::sort(files.begin(), files.end());
    CameraViews out;
    out.camera = folder.filename().empty() ? folder.parent_path().filename().string()
                                           : folder.filename().string();
    out.target = target;
    for (size_t i = 0; i < files.size(); ++i) {
        TargetView view;
        view.source = files[i].string();
        view.key = static_cast<int64_t>(i);
        const detail::ImageFile file = detail::readImageFile(files[i]);
        const cv::Mat& img = file.mat;
        if (file.format == PixelFormat::kUnknown) {
            view.rejection = ViewRejection::kUnreadable;
            view.why = file.why;
        } else if (out.width != 0 && (img.cols != out.width || img.rows != out.height)) {
            view.rejection = ViewRejection::kWrongSize;
            view.why = std::to_string(img.cols) + "x" + std::to_string(img.rows) +
                       ", the camera's other images are " + std::to_string(out.width) + "x" +
                       std::to_string(out.height);
        } else {
            out.width = img.cols;
            out.height = img.rows;
            MIXRAY_RETURN_IF_ERROR(detectInto(file.view(), target, options, view));
        }
        out.views.push_back(std::move(view));
        if (progress)
            progress(static_cast<double>(i + 1) / static_cast<double>(files.size()),
                     files[i].filename().string());
    }
    return out;
}

Result<RecordingDetection> detectInRecording(const std::filesystem::path& recording,
                                             const CalibrationTarget& target,
                                             const DetectionOptions& options,
                                             const ProgressCallback& progress) {
    MIXRAY_RETURN_IF_ERROR(target.validate());
    MIXRAY_RETURN_IF_ERROR(options.validate());
    const auto usable = [](PixelFormat f) {
        switch (f) {
            case PixelFormat::kMono8:
            case PixelFormat::kRGB8:
            case PixelFormat::kBGR8:
            case PixelFormat::kMono16:
            case PixelFormat::kIR16:
            case PixelFormat::kMJPEG:
            case PixelFormat::kNV12:
            case PixelFormat::kYUYV:
                return true;
            default:
                return false;
        }
    };
    // A first pass counts the image frames, so that progress is a fraction.
    size_t total = 0;
    std::vector<StreamInfo> streams;
    MIXRAY_RETURN_IF_ERROR(forEachFrame(
        recording, [&](const std::vector<StreamInfo>& s) { streams = s; },
        [&](const FrameRef& frame) {
            const StreamId s = frame.meta().stream;
            if (s < streams.size() && usable(streams[s].format.format))
                ++total;
            return Status::ok();
        }));

    RecordingDetection detection;
    std::vector<CameraViews>& out = detection.cameras;
    std::map<StreamId, size_t> index;
    std::map<StreamId, size_t> depth_index;
    for (StreamId s = 0; s < streams.size(); ++s) {
        if (streams[s].format.format == PixelFormat::kDepth16) {
            depth_index[s] = detection.depth.size();
            RecordedDepth depth;
            depth.stream = streams[s].name;
            if (auto tag = streams[s].tags.find("aligned_with"); tag != streams[s].tags.end())
                depth.aligned_with = tag->second;
            if (auto tag = streams[s].tags.find("registered_to"); tag != streams[s].tags.end())
                depth.registered_to = tag->second;
            detection.depth.push_back(std::move(depth));
        }
        if (!usable(streams[s].format.format))
            continue;
        index[s] = out.size();
        CameraViews cv;
        cv.camera = streams[s].name;
        cv.width = streams[s].format.width;
        cv.height = streams[s].format.height;
        cv.target = target;
        out.push_back(std::move(cv));
    }
    if (out.empty())
        return Status(ErrorCode::kNotFound, recording.string() + ": no image stream");
    const std::string name = recording.filename().string();
    KeyClock keys(options.max_skew_ns);
    size_t done = 0;
    const auto ignore = [](const std::vector<StreamInfo>&) {};
    const Status scanned = forEachFrame(recording, ignore, [&](const FrameRef& frame) -> Status {
        const FrameMetadata meta = frame.meta();
        const auto it = index.find(meta.stream);
        if (it == index.end()) {
            if (depth_index.count(meta.stream))
                keys.keyOf(meta);
            return Status::ok();
        }
        const int64_t key = keys.keyOf(meta);
        CameraViews& cam = out[it->second];
        TargetView view;
        view.source = name + "#" + cam.camera + "@" + std::to_string(meta.sequence);
        view.key = key;
        const ImageView img = frame.image();
        cv::Mat decoded;
        ImageView use = img;
        try {
            if (img.desc.format == PixelFormat::kMJPEG) {
                decoded = cv::imdecode(cv::Mat(1, static_cast<int>(img.size_bytes), CV_8U,
                                               const_cast<uint8_t*>(img.data)),
                                       cv::IMREAD_GRAYSCALE);
                use = decoded.empty() ? ImageView{} : viewOf(decoded);
            } else if (img.desc.format == PixelFormat::kNV12 ||
                       img.desc.format == PixelFormat::kYUYV) {
                // Luma only: the Y plane of NV12, every other byte of YUYV.
                const bool nv12 = img.desc.format == PixelFormat::kNV12;
                const size_t need = static_cast<size_t>(img.desc.stride_bytes) *
                                    static_cast<size_t>(img.desc.height);
                if (img.data && img.size_bytes >= need && img.desc.width > 0) {
                    decoded = cv::Mat(img.desc.height, img.desc.width, CV_8U);
                    for (int y = 0; y < img.desc.height; ++y) {
                        const uint8_t* src = img.row<uint8_t>(y);
                        uint8_t* dst = decoded.ptr<uint8_t>(y);
                        for (int x = 0; x < img.desc.width; ++x)
                            dst[x] = nv12 ? src[x] : src[2 * x];
                    }
                    use = viewOf(decoded);
                } else {
                    use = ImageView{};
                }
            }
        } catch (const cv::Exception&) {
            use = ImageView{};
        }
        if (meta.status == FrameStatus::kCorrupt || !use.data) {
            view.rejection = ViewRejection::kUnreadable;
            view.why = meta.status == FrameStatus::kCorrupt ? "frame marked corrupt"
                                                            : "frame could not be decoded";
        } else if (use.desc.width != cam.width || use.desc.height != cam.height) {
            view.rejection = ViewRejection::kWrongSize;
            view.why = std::to_string(use.desc.width) + "x" + std::to_string(use.desc.height) +
                       ", the stream's " + std::to_string(cam.width) + "x" +
                       std::to_string(cam.height);
        } else {
            MIXRAY_RETURN_IF_ERROR(detectInto(use, target, options, view));
        }
        cam.views.push_back(std::move(view));
        ++done;
        if (progress)
            progress(total ? std::min(1.0, static_cast<double>(done) / total) : 1.0,
                     cam.views.back().source);
        return Status::ok();
    });
    if (!scanned)
        return scanned;
    if (detection.depth.empty())
        return detection;

    // The depth frames at keys some camera saw the target at, in a pass of their own: until
    // every camera's frame of a key has been seen it is not known whether the key is wanted.
    std::set<int64_t> wanted;
    for (const CameraViews& c : out)
        for (const TargetView& v : c.views)
            if (v.rejection == ViewRejection::kNone)
                wanted.insert(v.key);
    KeyClock depth_keys(options.max_skew_ns);
    const Status read = forEachFrame(recording, ignore, [&](const FrameRef& frame) -> Status {
        const FrameMetadata meta = frame.meta();
        if (!index.count(meta.stream) && !depth_index.count(meta.stream))
            return Status::ok();
        const int64_t key = depth_keys.keyOf(meta);
        const auto it = depth_index.find(meta.stream);
        if (it == depth_index.end() || !wanted.count(key) || meta.status == FrameStatus::kCorrupt)
            return Status::ok();
        const ImageView image = frame.image();
        Image copy(ImageDesc::packed(PixelFormat::kDepth16, image.desc.width, image.desc.height));
        const MutableImageView dst = copy.mutableView();
        for (int y = 0; y < image.desc.height; ++y)
            std::copy_n(image.row<uint16_t>(y), image.desc.width, dst.row<uint16_t>(y));
        detection.depth[it->second].frames.push_back({key, std::move(copy)});
        return Status::ok();
    });
    if (!read)
        return read;
    return detection;
}

namespace detail {

std::array<int, 4> chessboardBeyond(const cv::Mat& grey, const std::vector<Corner>& corners,
                                    int cols, int rows) {
    if (corners.size() != static_cast<size_t>(cols) * static_cast<size_t>(rows))
        return {0, 0, 0, 0};
    return GridExtension(grey, corners, cols, rows).extend();
}

}  // namespace detail

}  // namespace mixray::calibration
