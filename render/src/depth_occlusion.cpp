// Depth maps as real geometry: per-pixel ray distances, RT²AR's screen-space traversal of
// secondary rays (Algorithm 2, corrected and made exact for any lens model) and a depth mesh.
//
// Differences from the paper's Algorithm 2 (Figure 6), and why:
//  - Its `return` sits inside the loop after the first pixel (the `end if` is misplaced), so
//    the loop never gets past one pixel. Here the walk stops only on a hit or at the end.
//  - It swaps p1/p2 so that x increases, which walks half of all rays backwards; with the
//    return fixed it would stop at the crossing farthest from the origin. Here the walk always
//    starts at the origin, so the first crossing found is the nearest.
//  - It steps along x only: steep projections skip rows, vertical ones divide by zero
//    (m = dy/dx), and z-factor divides by deltaY (zero for horizontal lines) while stepping in
//    x. Here each step moves about one pixel along the local major axis, whichever it is.
//  - It clips after projecting, but a point behind the camera projects to a mirrored pixel,
//    and its loop checks only x < width (not x >= 0, nor y). Here the 3D segment is clipped
//    first (near/far planes and the view frustum) and samples outside the image are unknown.
//  - It ends every ray at camera.far, ignoring the ray's own extent (a shadow ray ends at its
//    light). Here t_max bounds the walk.
//  - It interpolates 1/z linearly in screen space, exact only for an undistorted pinhole. Here
//    the ray's z is recomputed from t at every sample (exact for any lens), and projections go
//    through CameraModel, so the walk follows the curved image of a line under distortion.
//  - It samples only floor(y + 0.5) of the minor axis. Here the depth surface is sampled
//    between pixel centres (bilinear in 1/z over the 2x2 neighbours where they are
//    continuous), so a slanted surface cannot slip between two samples.
//  - Its per-pixel test (checkIntersectionWithDepthPixel) is not given. Here a hit needs the
//    ray to pass from in front of the surface to behind it by at most `thickness`, refined
//    between the two samples to a fraction of a pixel and of a millimetre.
#include "mixray/render/depth_occlusion.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace mixray::render {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kNearPlaneM = 1e-3;       // walks start at least 1 mm in front of the lens
constexpr double kMaxDepthM = 65.535;      // largest depth16 value
constexpr double kMinThicknessM = 1e-3;    // one depth16 step: the resolution of the data
constexpr double kMaxRangeM = 1e5;         // longest walk, for rays that never leave the view
constexpr double kTargetStepPx = 0.9;      // march step along the major image axis
constexpr double kMaxStepPx = 1.1;         // longest accepted step
constexpr double kRefinePx = 1.0 / 128;    // crossing refined to this in the image...
constexpr double kRefineZM = 2.5e-4;       // ...and to this in the ray's z
constexpr double kInterpolateJump = 0.05;  // relative depth step always interpolated over
constexpr double kSlopeTolerance = 0.3;    // larger steps: relative mismatch to a neighbour step
constexpr double kFrustumMargin = 0.02;    // relative widening of the clip frustum
constexpr double kWideAngleCosine = 0.1;   // border rays wider than this: no side clipping
constexpr int kBorderSamplesPerEdge = 32;  // unprojected points per image edge
constexpr int kMaxRejections = 64;         // shortened retries before a step is taken anyway
constexpr int kMaxRefineIterations = 64;

bool usable(const DepthView& depth) {
    const ImageDesc& d = depth.depth_mm.desc;
    return depth.depth_mm.data != nullptr && d.format == PixelFormat::kDepth16 && d.width > 0 &&
           d.height > 0 && d.stride_bytes >= d.width * 2 && d.width == depth.camera.width &&
           d.height == depth.camera.height && depth.camera.validate().isOk();
}

uint16_t rawAt(const ImageView& view, int x, int y) {
    return view.row<uint16_t>(y)[x];
}

// Inverse depth (1/m) of a pixel; 0 for no measurement or outside the image.
double inverseDepthAt(const ImageView& view, int x, int y) {
    if (x < 0 || y < 0 || x >= view.desc.width || y >= view.desc.height)
        return 0;
    const uint16_t z_mm = rawAt(view, x, y);
    return z_mm == 0 ? 0 : 1000.0 / z_mm;
}

// Whether the surface is continuous between neighbours `a` and `b` (inverse depths), given the
// samples `before` a and `after` b on the same line. Steps below kInterpolateJump always are.
// A larger step is continuous when it matches the slope on either side: a surface seen at a
// grazing angle changes depth steadily from pixel to pixel, while at a silhouette the step
// between a and b stands out from its neighbours' (which lie on one surface each).
bool continuous(double before, double a, double b, double after) {
    const double step = b - a;
    if (std::abs(step) <= kInterpolateJump * std::min(a, b))
        return true;
    const auto sameSlope = [step](double other_step) {
        return std::abs(step - other_step) <= kSlopeTolerance * std::abs(step);
    };
    return (before > 0 && sameSlope(a - before)) || (after > 0 && sameSlope(after - b));
}

// The depth surface's z (metres) at a sub-pixel position. Inverse depth is interpolated
// bilinearly over the four pixel centres around the position when all four are valid and
// continuous with each other: 1/z is affine in pixel coordinates for a plane seen by a
// pinhole, so this is exact there and close (well under a millimetre at 1 px) for distorted
// and fish-eye lenses. Elsewhere the nearest sample is used, so silhouettes stay steps and are
// never bridged.
std::optional<double> surfaceZ(const DepthView& depth, const Vector2d& px) {
    const ImageView& view = depth.depth_mm;
    const int w = view.desc.width;
    const int h = view.desc.height;
    if (!(px.x() >= -0.5 && px.x() < w - 0.5 && px.y() >= -0.5 && px.y() < h - 0.5)) {
        return std::nullopt;
    }
    // The 2x2 block of pixel centres around the position; in the half pixel along the image
    // border the block is the outermost one and the weights extrapolate (by at most half a
    // pixel), so a slanted surface keeps its slope up to the edge.
    const int xa = std::clamp(static_cast<int>(std::floor(px.x())), 0, std::max(0, w - 2));
    const int ya = std::clamp(static_cast<int>(std::floor(px.y())), 0, std::max(0, h - 2));
    const int xb = std::min(xa + 1, w - 1);
    const int yb = std::min(ya + 1, h - 1);
    const double ax = xb > xa ? px.x() - xa : 0;
    const double ay = yb > ya ? px.y() - ya : 0;
    const uint16_t z00 = rawAt(view, xa, ya), z10 = rawAt(view, xb, ya);
    const uint16_t z01 = rawAt(view, xa, yb), z11 = rawAt(view, xb, yb);
    const auto [lo, hi] = std::minmax({z00, z10, z01, z11});
    if (lo > 0) {
        bool smooth = hi - lo <= kInterpolateJump * lo;
        if (!smooth) {
            // Larger steps: look one pixel further out along each row and column.
            const auto at = [&view](int x, int y) { return inverseDepthAt(view, x, y); };
            const double w00 = 1000.0 / z00, w10 = 1000.0 / z10;
            const double w01 = 1000.0 / z01, w11 = 1000.0 / z11;
            smooth = continuous(at(xa - 1, ya), w00, w10, at(xb + 1, ya)) &&
                     continuous(at(xa - 1, yb), w01, w11, at(xb + 1, yb)) &&
                     continuous(at(xa, ya - 1), w00, w01, at(xa, yb + 1)) &&
                     continuous(at(xb, ya - 1), w10, w11, at(xb, yb + 1));
        }
        const double top = (1 - ax) * 1000.0 / z00 + ax * 1000.0 / z10;
        const double bottom = (1 - ax) * 1000.0 / z01 + ax * 1000.0 / z11;
        const double inverse = (1 - ay) * top + ay * bottom;
        if (smooth && inverse > 0)
            return 1 / inverse;
    }
    const uint16_t nearest = rawAt(view, ax < 0.5 ? xa : xb, ay < 0.5 ? ya : yb);
    if (nearest == 0)
        return std::nullopt;
    return nearest * 1e-3;
}

// A box in normalised image coordinates (x/z, y/z) that holds every pixel's ray, widened by a
// margin: the view frustum the walk is clipped to. Unbounded for fish-eyes that see (nearly)
// 90° or more off axis, and where no border pixel unprojects.
struct ViewBounds {
    bool bounded = false;
    double x_min = 0, x_max = 0, y_min = 0, y_max = 0;
};

bool sameCamera(const calibration::CameraModel& a, const calibration::CameraModel& b) {
    return a.lens == b.lens && a.width == b.width && a.height == b.height && a.fx == b.fx &&
           a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

ViewBounds computeViewBounds(const calibration::CameraModel& camera) {
    ViewBounds bounds;
    const double right = camera.width - 0.5;
    const double bottom = camera.height - 0.5;
    const bool undistorted = camera.lens == calibration::LensModel::kPinhole &&
                             std::all_of(camera.distortion.begin(), camera.distortion.end(),
                                         [](double k) { return k == 0; });
    if (undistorted) {
        bounds.x_min = (-0.5 - camera.cx) / camera.fx;
        bounds.x_max = (right - camera.cx) / camera.fx;
        bounds.y_min = (-0.5 - camera.cy) / camera.fy;
        bounds.y_max = (bottom - camera.cy) / camera.fy;
    } else {
        bounds.x_min = bounds.y_min = std::numeric_limits<double>::infinity();
        bounds.x_max = bounds.y_max = -std::numeric_limits<double>::infinity();
        // Walk the image border: distortion can push the extremes of the view to the corners
        // (barrel) or to the middle of the edges (pincushion, moustache).
        for (int edge = 0; edge < 4; ++edge) {
            for (int i = 0; i <= kBorderSamplesPerEdge; ++i) {
                const double s = static_cast<double>(i) / kBorderSamplesPerEdge;
                const Vector2d px = edge == 0   ? Vector2d(-0.5 + s * camera.width, -0.5)
                                    : edge == 1 ? Vector2d(-0.5 + s * camera.width, bottom)
                                    : edge == 2 ? Vector2d(-0.5, -0.5 + s * camera.height)
                                                : Vector2d(right, -0.5 + s * camera.height);
                const std::optional<Vector3d> ray = camera.unproject(px);
                const bool wide = !ray || !(ray->z() > kWideAngleCosine);
                // A fish-eye seeing this wide gets no side planes; a pinhole model that does
                // not invert at its border is not used there (no ray is traced through it).
                if (wide && camera.lens == calibration::LensModel::kFisheye)
                    return ViewBounds{};
                if (wide)
                    continue;
                bounds.x_min = std::min(bounds.x_min, ray->x() / ray->z());
                bounds.x_max = std::max(bounds.x_max, ray->x() / ray->z());
                bounds.y_min = std::min(bounds.y_min, ray->y() / ray->z());
                bounds.y_max = std::max(bounds.y_max, ray->y() / ray->z());
            }
        }
    }
    if (!(bounds.x_min < bounds.x_max && bounds.y_min < bounds.y_max))
        return ViewBounds{};
    const double mx = kFrustumMargin * (bounds.x_max - bounds.x_min) + 2 / camera.fx;
    const double my = kFrustumMargin * (bounds.y_max - bounds.y_min) + 2 / camera.fy;
    bounds.x_min -= mx;
    bounds.x_max += mx;
    bounds.y_min -= my;
    bounds.y_max += my;
    bounds.bounded = true;
    return bounds;
}

// The bounds of the last camera this thread traced with: a renderer traces millions of rays
// through one camera, and the border walk costs ~130 unprojections.
const ViewBounds& viewBounds(const calibration::CameraModel& camera) {
    struct Cache {
        bool valid = false;
        calibration::CameraModel camera;
        ViewBounds bounds;
    };
    thread_local Cache cache;
    if (!cache.valid || !sameCamera(cache.camera, camera)) {
        cache.bounds = computeViewBounds(camera);
        cache.camera = camera;
        cache.valid = true;
    }
    return cache.bounds;
}

// Liang–Barsky: narrows [t0, t1] to where a + b·t >= 0. False when nothing is left.
bool clipHalfSpace(double a, double b, double& t0, double& t1) {
    if (b == 0)
        return a >= 0;
    const double t = -a / b;
    if (b > 0) {
        t0 = std::max(t0, t);
    } else {
        t1 = std::min(t1, t);
    }
    return t0 <= t1;
}

// One point of the walk: where the ray is at t, where that lands in the image and how far the
// ray is behind the depth surface there (f = z_ray - z_surface; negative in front).
struct Sample {
    double t = 0;
    double z = 0;
    bool projected = false;
    Vector2d px = Vector2d::Zero();
    std::optional<double> f;
};

class Walker {
public:
    Walker(const DepthView& depth, const Vector3d& origin, const Vector3d& direction)
        : depth_(depth), origin_(origin), direction_(direction) {}

    Sample at(double t) const {
        Sample s;
        s.t = t;
        const Vector3d p = origin_ + t * direction_;
        s.z = p.z();
        const std::optional<Vector2d> px = depth_.camera.project(p);
        if (!px || !px->allFinite())
            return s;
        s.projected = true;
        s.px = *px;
        if (const std::optional<double> surface = surfaceZ(depth_, s.px)) {
            s.f = s.z - *surface;
        }
        return s;
    }

    // Pixels outside the image, along the farther axis; 0 inside.
    double outside(const Sample& s) const {
        if (!s.projected)
            return 0;
        const double w = depth_.depth_mm.desc.width - 0.5;
        const double h = depth_.depth_mm.desc.height - 0.5;
        const double dx = std::max({0.0, -0.5 - s.px.x(), s.px.x() - w});
        const double dy = std::max({0.0, -0.5 - s.px.y(), s.px.y() - h});
        return std::max(dx, dy);
    }

    // Bisects between `front` (in front of the surface, or unmeasured) and `behind` (a measured
    // sample with f >= 0) down to a fraction of a pixel and of a millimetre; the crossing t if
    // the ray is then behind the surface by at most `thickness`. A larger value means the
    // surface steps towards the camera there (a silhouette) and the ray passes behind it.
    std::optional<double> refine(Sample front, Sample behind, double thickness) const {
        for (int i = 0; i < kMaxRefineIterations; ++i) {
            const bool close_in_image =
                front.projected && behind.projected &&
                (behind.px - front.px).lpNorm<Eigen::Infinity>() <= kRefinePx;
            if (close_in_image && std::abs(behind.z - front.z) <= kRefineZM)
                break;
            const Sample mid = at(0.5 * (front.t + behind.t));
            if (mid.f && *mid.f >= 0) {
                behind = mid;
            } else {
                front = mid;
            }
        }
        if (*behind.f > thickness)
            return std::nullopt;
        if (!front.f)
            return behind.t;
        const double span = *behind.f - *front.f;
        return span > 0 ? front.t + (behind.t - front.t) * (-*front.f / span) : behind.t;
    }

private:
    const DepthView& depth_;
    Vector3d origin_;
    Vector3d direction_;
};

Vector3d pointOnPixelRay(const Vector3d& ray, double z) {
    return ray * (z / ray.z());
}

}  // namespace

std::optional<float> DepthView::zAt(int x, int y) const {
    const ImageDesc& d = depth_mm.desc;
    if (depth_mm.data == nullptr || d.format != PixelFormat::kDepth16 || x < 0 || y < 0 ||
        x >= d.width || y >= d.height) {
        return std::nullopt;
    }
    const uint16_t z_mm = rawAt(depth_mm, x, y);
    if (z_mm == 0)
        return std::nullopt;
    return static_cast<float>(z_mm * 1e-3);
}

std::optional<float> rayDistanceAt(const DepthView& depth, int x, int y) {
    const std::optional<float> z = depth.zAt(x, y);
    if (!z)
        return std::nullopt;
    const std::optional<Vector3d> ray = depth.camera.unproject(Vector2d(x, y));
    if (!ray || !(ray->z() > 0))
        return std::nullopt;
    // `ray` is unit length, so its z is the cosine of the angle to the optical axis.
    return static_cast<float>(*z / ray->z());
}

std::optional<float> traceDepthMap(const DepthView& depth, const Eigen::Vector3f& origin_cam,
                                   const Eigen::Vector3f& direction_cam, float t_max,
                                   float thickness) {
    if (!usable(depth) || !origin_cam.allFinite() || !direction_cam.allFinite() ||
        direction_cam.squaredNorm() == 0 || !(t_max > 0)) {
        return std::nullopt;
    }
    const Vector3d o = origin_cam.cast<double>();
    const Vector3d d = direction_cam.cast<double>();
    const double shell = std::max(kMinThicknessM, std::isfinite(thickness) ? thickness : 0.0);

    // Clip the 3D segment before projecting anything: to z in (near, deepest depth16 value +
    // shell] (nothing farther can be behind a surface by at most the shell) and to the view.
    double t0 = 0;
    double t1 = std::min(static_cast<double>(t_max), kMaxRangeM / d.norm());
    if (!clipHalfSpace(o.z() - kNearPlaneM, d.z(), t0, t1) ||
        !clipHalfSpace(kMaxDepthM + shell - o.z(), -d.z(), t0, t1)) {
        return std::nullopt;
    }
    const ViewBounds& view = viewBounds(depth.camera);
    if (view.bounded &&
        (!clipHalfSpace(o.x() - view.x_min * o.z(), d.x() - view.x_min * d.z(), t0, t1) ||
         !clipHalfSpace(view.x_max * o.z() - o.x(), view.x_max * d.z() - d.x(), t0, t1) ||
         !clipHalfSpace(o.y() - view.y_min * o.z(), d.y() - view.y_min * d.z(), t0, t1) ||
         !clipHalfSpace(view.y_max * o.z() - o.y(), view.y_max * d.z() - d.y(), t0, t1))) {
        return std::nullopt;
    }

    // March in t, one pixel along the local major image axis per step: the step is rescaled
    // from the previous step's pixels-per-t and rejected (shortened) when it moved too far.
    // This follows the curved image of the line under any lens without subdividing it, needs
    // one projection per step, and where the projection barely moves (rays along a pixel ray,
    // approaching the vanishing point) the step grows geometrically, so t_max costs nothing.
    // Outside the image the step grows with the distance to it (sphere tracing in the image).
    const Walker walker(depth, o, d);
    const double t_floor = 1e-12 * std::max(1.0, t1);
    const int max_steps = 64 * (depth.depth_mm.desc.width + depth.depth_mm.desc.height) + 1024;
    Sample current = walker.at(t0);
    std::optional<Sample> front;  // the last measured sample in front of the surface
    double dt = t1 - t0;
    for (int step = 0; step < max_steps; ++step) {
        if (current.f) {
            if (*current.f < 0) {
                front = current;
            } else if (front) {
                if (const std::optional<double> t = walker.refine(*front, current, shell)) {
                    return static_cast<float>(*t);
                }
                front.reset();
            }
        }
        if (current.t >= t1)
            break;

        const double target = std::max(kTargetStepPx, 0.5 * walker.outside(current));
        Sample next;
        double moved = 0;
        for (int tries = 0;; ++tries) {
            next = walker.at(std::min(current.t + dt, t1));
            const bool comparable = current.projected && next.projected;
            moved = comparable ? (next.px - current.px).lpNorm<Eigen::Infinity>()
                               : std::numeric_limits<double>::infinity();
            if (!current.projected && !next.projected)
                moved = 0;  // beyond the lens's view
            if (moved <= target * (kMaxStepPx / kTargetStepPx) || dt <= t_floor ||
                tries >= kMaxRejections) {
                break;
            }
            dt *= std::isfinite(moved) ? std::max(0.1, target / moved) : 0.5;
        }
        const double taken = next.t - current.t;
        current = next;
        // Next step: the same pixels per t, growing at most 4x when the image barely moved.
        const double next_target = std::max(kTargetStepPx, 0.5 * walker.outside(current));
        dt = moved > 0 ? std::min(taken * next_target / moved, 4 * std::max(taken, t_floor))
                       : 4 * std::max(taken, t_floor);
        dt = std::max(dt, t_floor);
    }
    return std::nullopt;
}

TriangleMesh depthToMesh(const DepthView& depth, const DepthMeshOptions& options) {
    TriangleMesh mesh;
    DepthMesher().build(depth, options, mesh);
    return mesh;
}

void DepthMesher::build(const DepthView& depth, const DepthMeshOptions& options,
                        TriangleMesh& mesh) {
    mesh.positions.clear();
    mesh.normals.clear();
    mesh.uvs.clear();
    mesh.triangles.clear();
    if (!usable(depth))
        return;
    const int w = depth.depth_mm.desc.width;
    const int h = depth.depth_mm.desc.height;
    const int step = std::max(1, options.step);
    const int gw = (w - 1) / step + 1;
    const int gh = (h - 1) / step + 1;
    const auto grid = [gw](int i, int j) { return static_cast<size_t>(j) * gw + i; };
    const size_t vertices = static_cast<size_t>(gw) * gh;
    // The largest mesh this grid can give, so that later frames of this size fit.
    mesh.positions.reserve(vertices);
    mesh.normals.reserve(vertices);
    mesh.uvs.reserve(vertices);
    mesh.triangles.reserve(2 * static_cast<size_t>(gw - 1) * static_cast<size_t>(gh - 1));

    // Grid vertices on their pixel rays; z = 0 marks a vertex without a point.
    std::vector<Vector3d>& points = points_;
    std::vector<double>& zs = zs_;
    points.assign(vertices, Vector3d::Zero());
    zs.assign(vertices, 0.0);
    for (int j = 0; j < gh; ++j) {
        for (int i = 0; i < gw; ++i) {
            const std::optional<float> z = depth.zAt(i * step, j * step);
            if (!z)
                continue;
            const std::optional<Vector3d> ray =
                depth.camera.unproject(Vector2d(i * step, j * step));
            if (!ray || !(ray->z() > 0))
                continue;
            points[grid(i, j)] = pointOnPixelRay(*ray, *z);
            zs[grid(i, j)] = *z;
        }
    }

    const double jump = std::max(0.0, static_cast<double>(options.max_edge_jump_m));
    const auto connected = [&](size_t a, size_t b) {
        return std::abs(zs[a] - zs[b]) <= jump * std::min(zs[a], zs[b]);
    };
    const auto usableTriangle = [&](const std::array<size_t, 3>& t) {
        return zs[t[0]] > 0 && zs[t[1]] > 0 && zs[t[2]] > 0 && connected(t[0], t[1]) &&
               connected(t[1], t[2]) && connected(t[2], t[0]);
    };

    std::vector<int64_t>& index = index_;
    index.assign(vertices, -1);
    const auto vertex = [&](size_t g) {
        if (index[g] < 0) {
            index[g] = static_cast<int64_t>(mesh.positions.size());
            mesh.positions.push_back(points[g].cast<float>());
            const int i = static_cast<int>(g % gw);
            const int j = static_cast<int>(g / gw);
            mesh.uvs.emplace_back(static_cast<float>((i * step + 0.5) / w),
                                  static_cast<float>((j * step + 0.5) / h));
        }
        return static_cast<uint32_t>(index[g]);
    };
    const auto emit = [&](const std::array<size_t, 3>& t) {
        mesh.triangles.push_back({vertex(t[0]), vertex(t[1]), vertex(t[2])});
    };

    // Each grid cell a (top left), b (right), c (below), d (diagonal) becomes two triangles,
    // counter-clockwise seen from the camera (their normals face it). Of the two diagonals,
    // take the one that keeps more triangles, then the shorter one in 3D.
    for (int j = 0; j + 1 < gh; ++j) {
        for (int i = 0; i + 1 < gw; ++i) {
            const size_t a = grid(i, j), b = grid(i + 1, j), c = grid(i, j + 1),
                         d = grid(i + 1, j + 1);
            const std::array<std::array<size_t, 3>, 2> split_bc = {{{a, c, b}, {b, c, d}}};
            const std::array<std::array<size_t, 3>, 2> split_ad = {{{a, c, d}, {a, d, b}}};
            const int keep_bc = usableTriangle(split_bc[0]) + usableTriangle(split_bc[1]);
            const int keep_ad = usableTriangle(split_ad[0]) + usableTriangle(split_ad[1]);
            bool use_bc = keep_bc > keep_ad;
            if (keep_bc == keep_ad) {
                use_bc =
                    (points[b] - points[c]).squaredNorm() <= (points[a] - points[d]).squaredNorm();
            }
            for (const auto& t : use_bc ? split_bc : split_ad) {
                if (usableTriangle(t))
                    emit(t);
            }
        }
    }

    // Smooth normals: area-weighted sums of the faces around each vertex.
    std::vector<Vector3d>& sums = sums_;
    sums.reserve(vertices);
    sums.assign(mesh.positions.size(), Vector3d::Zero());
    for (const auto& t : mesh.triangles) {
        const Vector3d p0 = mesh.positions[t[0]].cast<double>();
        const Vector3d n = (mesh.positions[t[1]].cast<double>() - p0)
                               .cross(mesh.positions[t[2]].cast<double>() - p0);
        for (const uint32_t v : t)
            sums[v] += n;
    }
    for (size_t v = 0; v < sums.size(); ++v) {
        const double norm = sums[v].norm();
        // A vertex whose faces cancel (degenerate slivers) faces the camera.
        mesh.normals.push_back(norm > 0 ? Vector3f((sums[v] / norm).cast<float>())
                                        : Vector3f(-mesh.positions[v].normalized()));
    }
}

}  // namespace mixray::render
