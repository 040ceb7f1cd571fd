// The depth-correction fit: depth readings inside each board's outline against the board plane
// the IR camera saw (depth_registration.h, fitDepthCorrection).
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "mixray/calibration/depth_registration.h"

namespace mixray::calibration {

namespace {

struct Sample {
    int pixel = 0;      // y · width + x
    float z_raw = 0;    // the reading, metres
    float z_plane = 0;  // the board plane's depth along the pixel's ray, metres
};

// z_plane ≈ scale · z_raw + offset by least squares over the samples `use` marks.
bool fitLine(const std::vector<Sample>& samples, const std::vector<uint8_t>& use, double& scale,
             double& offset) {
    double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (size_t i = 0; i < samples.size(); ++i) {
        if (!use[i])
            continue;
        const double x = samples[i].z_raw, y = samples[i].z_plane;
        n += 1;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
    }
    const double det = n * sxx - sx * sx;
    if (n < 2 || !(std::abs(det) > 1e-12 * n * n))
        return false;
    scale = (n * sxy - sx * sy) / det;
    offset = (sy - scale * sx) / n;
    return true;
}

// D on a grid of nodes `step` pixels apart, bilinear between them.
struct Grid {
    int nx = 0, ny = 0, step = 16;
    int nodes() const { return nx * ny; }
    // The four nodes around pixel (x, y) and their bilinear weights.
    void weights(int x, int y, std::array<int, 4>& node, std::array<double, 4>& w) const {
        const double gx = static_cast<double>(x) / step, gy = static_cast<double>(y) / step;
        const int i = std::min(static_cast<int>(gx), nx - 2);
        const int j = std::min(static_cast<int>(gy), ny - 2);
        const double fx = gx - i, fy = gy - j;
        node = {j * nx + i, j * nx + i + 1, (j + 1) * nx + i, (j + 1) * nx + i + 1};
        w = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    }
};

struct PerPixelFit {
    double scale = 1, offset = 0, alpha0 = 0, alpha1 = 0;
    Eigen::VectorXd nodes;
    double rms = 0;

    // Herrera's model at a reading: zc = scale·z_raw + offset, and the decay e^(α0 − α1·zc)
    // that scales the spatial term there.
    double linear(double z_raw) const { return scale * z_raw + offset; }
    double decay(double zc) const { return std::exp(alpha0 - alpha1 * zc); }
};

// For a given α1, the linear least squares in (scale, offset, D nodes) with the membrane and
// ridge terms; the exponent's z' uses the previous round's scale and offset (three rounds).
PerPixelFit fitPerPixel(const std::vector<Sample>& samples, const std::vector<uint8_t>& use,
                        const Grid& grid, int width, double alpha1, double z_median, double scale0,
                        double offset0, const DepthCorrectionOptions& options) {
    PerPixelFit fit;
    fit.scale = scale0;
    fit.offset = offset0;
    fit.alpha1 = alpha1;
    fit.alpha0 = alpha1 * z_median;
    const int N = grid.nodes();
    const int n_unknowns = N + 2;  // nodes, then scale, offset
    size_t used = 0;
    for (uint8_t u : use)
        used += u;
    // Regularisation weights relative to the readings per node, so they do not depend on
    // how many views there are.
    const double per_node = static_cast<double>(used) / N;
    const double membrane = options.smoothness * per_node;
    const double ridge = options.ridge * per_node;
    for (int round = 0; round < 3; ++round) {
        // Normal equations: node-node couplings within a 3x3 stencil, node-(scale, offset)
        // dense columns, and the 2x2 (scale, offset) block.
        std::vector<std::array<double, 9>> nn(N, std::array<double, 9>{});
        Eigen::MatrixXd ns = Eigen::MatrixXd::Zero(N, 2);
        Eigen::Matrix2d ss = Eigen::Matrix2d::Zero();
        Eigen::VectorXd b = Eigen::VectorXd::Zero(n_unknowns);
        std::array<int, 4> node;
        std::array<double, 4> bw;
        for (size_t s = 0; s < samples.size(); ++s) {
            if (!use[s])
                continue;
            const Sample& sm = samples[s];
            const int x = sm.pixel % width, y = sm.pixel / width;
            grid.weights(x, y, node, bw);
            const double w = fit.decay(fit.linear(sm.z_raw));
            const double target = sm.z_plane;
            for (int a = 0; a < 4; ++a) {
                const double fa = w * bw[a];
                for (int c = 0; c < 4; ++c) {
                    const int dxn = node[c] % grid.nx - node[a] % grid.nx;
                    const int dyn = node[c] / grid.nx - node[a] / grid.nx;
                    nn[node[a]][(dyn + 1) * 3 + (dxn + 1)] += fa * w * bw[c];
                }
                ns(node[a], 0) += fa * sm.z_raw;
                ns(node[a], 1) += fa;
                b[node[a]] += fa * target;
            }
            ss(0, 0) += double(sm.z_raw) * sm.z_raw;
            ss(0, 1) += sm.z_raw;
            ss(1, 1) += 1;
            b[N] += sm.z_raw * target;
            b[N + 1] += target;
        }
        ss(1, 0) = ss(0, 1);
        // Membrane: membrane · (D_a − D_b)² for grid neighbours; ridge · D_a².
        for (int j = 0; j < grid.ny; ++j) {
            for (int i = 0; i < grid.nx; ++i) {
                const int a = j * grid.nx + i;
                nn[a][4] += ridge;
                for (const auto& [di, dj] : {std::pair{1, 0}, std::pair{0, 1}}) {
                    if (i + di >= grid.nx || j + dj >= grid.ny)
                        continue;
                    const int c = (j + dj) * grid.nx + (i + di);
                    nn[a][4] += membrane;
                    nn[c][4] += membrane;
                    nn[a][(dj + 1) * 3 + (di + 1)] -= membrane;
                    nn[c][(-dj + 1) * 3 + (-di + 1)] -= membrane;
                }
            }
        }
        std::vector<Eigen::Triplet<double>> triplets;
        triplets.reserve(static_cast<size_t>(N) * 13 + 4);
        for (int a = 0; a < N; ++a) {
            for (int k = 0; k < 9; ++k) {
                if (nn[a][k] == 0)
                    continue;
                const int c = a + (k / 3 - 1) * grid.nx + (k % 3 - 1);
                triplets.emplace_back(a, c, nn[a][k]);
            }
            for (int k = 0; k < 2; ++k) {
                if (ns(a, k) != 0) {
                    triplets.emplace_back(a, N + k, ns(a, k));
                    triplets.emplace_back(N + k, a, ns(a, k));
                }
            }
        }
        for (int r = 0; r < 2; ++r)
            for (int c = 0; c < 2; ++c)
                triplets.emplace_back(N + r, N + c, ss(r, c));
        Eigen::SparseMatrix<double> A(n_unknowns, n_unknowns);
        A.setFromTriplets(triplets.begin(), triplets.end());
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
        if (solver.info() != Eigen::Success) {
            fit.rms = std::numeric_limits<double>::infinity();
            return fit;
        }
        const Eigen::VectorXd x = solver.solve(b);
        fit.nodes = x.head(N);
        fit.scale = x[N];
        fit.offset = x[N + 1];
    }
    double sum = 0;
    std::array<int, 4> node;
    std::array<double, 4> bw;
    for (size_t s = 0; s < samples.size(); ++s) {
        if (!use[s])
            continue;
        const Sample& sm = samples[s];
        grid.weights(sm.pixel % width, sm.pixel / width, node, bw);
        double d = 0;
        for (int a = 0; a < 4; ++a)
            d += bw[a] * fit.nodes[node[a]];
        const double zc = fit.linear(sm.z_raw);
        const double r = zc + d * fit.decay(zc) - sm.z_plane;
        sum += r * r;
    }
    fit.rms = std::sqrt(sum / std::max<size_t>(used, 1));
    return fit;
}

double residual(const DepthCorrection& c, const Sample& s, int width) {
    return correctedDepth(c, s.z_raw, s.pixel % width, s.pixel / width, width) - s.z_plane;
}

}  // namespace

Result<DepthCorrectionFit> fitDepthCorrection(const CameraModel& ir,
                                              const std::vector<Eigen::Vector3d>& board_points,
                                              const std::vector<DepthPlaneView>& views,
                                              const DepthCorrectionOptions& options) {
    MIXRAY_RETURN_IF_ERROR(ir.validate().withContext("IR camera"));
    if (board_points.size() < 3)
        return Status(ErrorCode::kInvalidArgument, "depth correction: the board has no outline");
    if (views.empty())
        return Status(ErrorCode::kInvalidArgument, "depth correction: no views");
    if (options.grid_step_px < 2 || !(options.smoothness >= 0) || !(options.ridge > 0) ||
        !(options.board_margin_m >= 0) || !(options.max_residual_m > 0) ||
        !(options.max_alpha1 >= 0))
        return Status(ErrorCode::kInvalidArgument,
                      "depth correction: grid_step_px >= 2, smoothness >= 0, ridge > 0, "
                      "board_margin_m >= 0, max_residual_m > 0, max_alpha1 >= 0");
    const int W = ir.width, H = ir.height;

    // The board's outline in its own frame, less the margin.
    Eigen::Vector2d lo = board_points[0].head<2>(), hi = lo;
    for (const auto& p : board_points) {
        lo = lo.cwiseMin(p.head<2>());
        hi = hi.cwiseMax(p.head<2>());
    }
    lo.array() += options.board_margin_m;
    hi.array() -= options.board_margin_m;

    std::vector<Eigen::Vector2d> rays(static_cast<size_t>(W) * H,
                                      Eigen::Vector2d::Constant(std::nan("")));
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if (const auto dir = ir.unproject({double(x), double(y)}); dir && dir->z() > 1e-6)
                rays[static_cast<size_t>(y) * W + x] = dir->head<2>() / dir->z();

    std::vector<Sample> samples;
    for (size_t v = 0; v < views.size(); ++v) {
        const ImageView& depth = views[v].depth_mm;
        if (depth.desc.format != PixelFormat::kDepth16 || depth.desc.width != W ||
            depth.desc.height != H || depth.data == nullptr) {
            return Status(ErrorCode::kInvalidArgument,
                          "depth correction: view " + std::to_string(v) +
                              ": the depth image must be depth16 " + std::to_string(W) + "x" +
                              std::to_string(H) + " (the IR camera's size)");
        }
        const Eigen::Isometry3d& T = views[v].T_ir_board;
        const Eigen::Isometry3d T_board_ir = T.inverse();
        const Eigen::Vector3d n = T.linear().col(2);
        const double nd = n.dot(T.translation());
        for (int y = 0; y < H; ++y) {
            const uint16_t* row = depth.row<uint16_t>(y);
            for (int x = 0; x < W; ++x) {
                if (row[x] == 0)
                    continue;
                const Eigen::Vector2d& r = rays[static_cast<size_t>(y) * W + x];
                if (!std::isfinite(r.x()))
                    continue;
                const Eigen::Vector3d ray(r.x(), r.y(), 1);
                const double denom = n.dot(ray);
                if (std::abs(denom) < 1e-9)
                    continue;
                const double z = nd / denom;
                if (z <= 0)
                    continue;
                const Eigen::Vector3d q = T_board_ir * (ray * z);
                if (q.x() < lo.x() || q.y() < lo.y() || q.x() > hi.x() || q.y() > hi.y())
                    continue;
                samples.push_back(
                    {y * W + x, static_cast<float>(row[x] * 1e-3), static_cast<float>(z)});
            }
        }
    }
    if (samples.size() < 100) {
        return Status(ErrorCode::kInvalidArgument,
                      "depth correction: " + std::to_string(samples.size()) +
                          " depth readings inside the boards' outlines; at least 100 needed");
    }

    // Scale and offset, dropping readings off the plane (other objects, edges) and refitting.
    std::vector<uint8_t> use(samples.size(), 1);
    double scale = 1, offset = 0;
    for (int round = 0; round < 4; ++round) {
        if (!fitLine(samples, use, scale, offset))
            return Status(ErrorCode::kInvalidArgument,
                          "depth correction: all readings at one depth; the scale is not "
                          "observable (take views at several distances)");
        size_t changed = 0;
        for (size_t i = 0; i < samples.size(); ++i) {
            const bool keep = std::abs(scale * samples[i].z_raw + offset - samples[i].z_plane) <=
                              options.max_residual_m;
            changed += keep != static_cast<bool>(use[i]);
            use[i] = keep;
        }
        if (changed == 0)
            break;
    }
    std::vector<float> used_depths;
    for (size_t i = 0; i < samples.size(); ++i)
        if (use[i])
            used_depths.push_back(samples[i].z_raw);
    if (used_depths.size() < 100)
        return Status(ErrorCode::kInvalidArgument,
                      "depth correction: fewer than 100 readings lie near the board planes");
    std::nth_element(used_depths.begin(), used_depths.begin() + used_depths.size() / 2,
                     used_depths.end());
    const double z_median = used_depths[used_depths.size() / 2];
    {
        const auto [mn, mx] = std::minmax_element(used_depths.begin(), used_depths.end());
        if (*mx - *mn < 0.05)
            return Status(ErrorCode::kInvalidArgument,
                          "depth correction: the readings span less than 5 cm of depth; the "
                          "scale is not observable (take views at several distances)");
    }

    DepthCorrectionFit result;
    result.median_depth_m = z_median;
    result.samples = static_cast<int>(used_depths.size());
    result.correction.scale = scale;
    result.correction.offset_m = offset;

    if (options.per_pixel) {
        Grid grid;
        grid.step = options.grid_step_px;
        grid.nx = (W - 1 + grid.step - 1) / grid.step + 1;
        grid.ny = (H - 1 + grid.step - 1) / grid.step + 1;
        const auto evaluate = [&](double alpha1) {
            return fitPerPixel(samples, use, grid, W, alpha1, z_median, scale, offset, options);
        };
        // Golden-section search for α1: the residual is smooth and, over this interval,
        // single-minimum in practice (D absorbs the level, α1 only the depth dependence).
        const double g = (std::sqrt(5.0) - 1) / 2;
        double a = 0, b = options.max_alpha1;
        double c = b - g * (b - a), d = a + g * (b - a);
        PerPixelFit fc = evaluate(c), fd = evaluate(d);
        for (int it = 0; it < 20 && b - a > 1e-3; ++it) {
            if (fc.rms < fd.rms) {
                b = d;
                d = c;
                fd = fc;
                c = b - g * (b - a);
                fc = evaluate(c);
            } else {
                a = c;
                c = d;
                fc = fd;
                d = a + g * (b - a);
                fd = evaluate(d);
            }
        }
        const PerPixelFit& best = fc.rms < fd.rms ? fc : fd;
        if (!std::isfinite(best.rms))
            return Status(ErrorCode::kInternal, "depth correction: the per-pixel solve failed");
        DepthCorrection& c_out = result.correction;
        c_out.scale = best.scale;
        c_out.offset_m = best.offset;
        c_out.alpha0 = best.alpha0;
        c_out.alpha1 = best.alpha1;
        c_out.distortion.resize(static_cast<size_t>(W) * H);
        std::array<int, 4> node;
        std::array<double, 4> bw;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                grid.weights(x, y, node, bw);
                double v = 0;
                for (int k = 0; k < 4; ++k)
                    v += bw[k] * best.nodes[node[k]];
                c_out.distortion[static_cast<size_t>(y) * W + x] = static_cast<float>(v);
            }
    }

    double before = 0, after = 0;
    const DepthCorrection identity;
    for (size_t i = 0; i < samples.size(); ++i) {
        if (!use[i])
            continue;
        const double r0 = residual(identity, samples[i], W);
        const double r1 = residual(result.correction, samples[i], W);
        before += r0 * r0;
        after += r1 * r1;
    }
    result.rms_before_m = std::sqrt(before / result.samples);
    result.rms_after_m = std::sqrt(after / result.samples);
    return result;
}

}  // namespace mixray::calibration
