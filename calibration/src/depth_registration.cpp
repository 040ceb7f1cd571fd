// Depth correction and the registration of depth images into the colour camera: footprint
// quadrilaterals rasterised into a z-buffer (depth_registration.h says why).
#include "mixray/calibration/depth_registration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace mixray::calibration {

namespace {

constexpr uint8_t kUnused = 0;
constexpr uint8_t kShared = 1;
constexpr uint8_t kSplit = 2;

// A footprint that projects larger than this many colour pixels on a side is a lens model
// extrapolated past its image (a corner ray folding back), not a surface: it is skipped
// rather than smeared over the image.
constexpr float kMaxFootprintPx = 64.f;

bool finite(const Eigen::Isometry3d& T) {
    return T.matrix().allFinite();
}

bool rigid(const Eigen::Isometry3d& T) {
    const Eigen::Matrix3d R = T.linear();
    return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6 &&
           R.determinant() > 0;
}

bool sameModel(const CameraModel& a, const CameraModel& b) {
    return a.lens == b.lens && a.width == b.width && a.height == b.height && a.fx == b.fx &&
           a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

}  // namespace

double correctedDepth(const DepthCorrection& c, double z_m, int x, int y, int width) {
    const double z = c.scale * z_m + c.offset_m;
    if (c.distortion.empty())
        return z;
    const double d = c.distortion[static_cast<size_t>(y) * width + x];
    return z + d * std::exp(c.alpha0 - c.alpha1 * z);
}

Status DepthRegistration::validate() const {
    if (Status s = depth.validate(); !s)
        return s.withContext("depth camera");
    if (Status s = color.validate(); !s)
        return s.withContext("colour camera");
    if (!finite(T_color_depth) || !rigid(T_color_depth))
        return {ErrorCode::kInvalidArgument, "T_color_depth is not a finite rigid transform"};
    const DepthCorrection& c = correction;
    if (!std::isfinite(c.scale) || c.scale <= 0 || !std::isfinite(c.offset_m) ||
        !std::isfinite(c.alpha0) || !std::isfinite(c.alpha1)) {
        return {ErrorCode::kInvalidArgument,
                "depth correction: scale must be finite and > 0, offset and alphas finite"};
    }
    if (!c.distortion.empty()) {
        const size_t expected = static_cast<size_t>(depth.width) * depth.height;
        if (c.distortion.size() != expected) {
            return {ErrorCode::kInvalidArgument,
                    "depth correction: the distortion map has " +
                        std::to_string(c.distortion.size()) + " values, the depth camera " +
                        std::to_string(depth.width) + "x" + std::to_string(depth.height) +
                        " needs " + std::to_string(expected)};
        }
        if (!std::all_of(c.distortion.begin(), c.distortion.end(),
                         [](float v) { return std::isfinite(v); }))
            return {ErrorCode::kInvalidArgument, "depth correction: non-finite distortion"};
    }
    return Status::ok();
}

bool DepthRegistration::isIdentity() const {
    return sameModel(depth, color) && T_color_depth.isApprox(Eigen::Isometry3d::Identity(), 0) &&
           correction.isIdentity();
}

Registrar::Registrar(DepthRegistration registration, RegistrationOptions options)
    : registration_(std::move(registration)), options_(options) {
    const CameraModel& d = registration_.depth;
    const int W = d.width, H = d.height;
    corner_rays_.resize(static_cast<size_t>(W + 1) * (H + 1));
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int j = 0; j <= H; ++j) {
        for (int i = 0; i <= W; ++i) {
            Eigen::Vector2f& ray = corner_rays_[static_cast<size_t>(j) * (W + 1) + i];
            const auto dir = d.unproject({i - 0.5, j - 0.5});
            if (dir && dir->z() > 1e-6)
                ray = Eigen::Vector2f(static_cast<float>(dir->x() / dir->z()),
                                      static_cast<float>(dir->y() / dir->z()));
            else
                ray = Eigen::Vector2f(nan, nan);
        }
    }
    centre_rays_.resize(static_cast<size_t>(W) * H);
    for (int j = 0; j < H; ++j) {
        for (int i = 0; i < W; ++i) {
            Eigen::Vector2f& ray = centre_rays_[static_cast<size_t>(j) * W + i];
            const auto dir = d.unproject({double(i), double(j)});
            if (dir && dir->z() > 1e-6)
                ray = Eigen::Vector2f(static_cast<float>(dir->x() / dir->z()),
                                      static_cast<float>(dir->y() / dir->z()));
            else
                ray = Eigen::Vector2f(nan, nan);
        }
    }
}

Result<Registrar> Registrar::create(DepthRegistration registration, RegistrationOptions options) {
    MIXRAY_RETURN_IF_ERROR(registration.validate());
    if (!(options.max_jump_rel > 0) || !std::isfinite(options.max_jump_rel))
        return Status(ErrorCode::kInvalidArgument, "max_jump_rel must be finite and > 0");
    return Registrar(std::move(registration), options);
}

// Lifts depth-image corner (cx, cy) at depth 1 / inv_z_depth into the colour image.
bool Registrar::lift(int cx, int cy, float inv_z_depth, Corner& out) const {
    const int W = registration_.depth.width;
    const Eigen::Vector2f& ray = corner_rays_[static_cast<size_t>(cy) * (W + 1) + cx];
    if (!std::isfinite(ray.x()) || !(inv_z_depth > 0))
        return false;
    const double z = 1.0 / inv_z_depth;
    return project(Eigen::Vector3d(ray.x() * z, ray.y() * z, z), out);
}

// Lifts depth pixel (x, y) itself at depth z.
bool Registrar::liftPoint(int x, int y, float z, Corner& out) const {
    const Eigen::Vector2f& ray =
        centre_rays_[static_cast<size_t>(y) * registration_.depth.width + x];
    if (!std::isfinite(ray.x()))
        return false;
    return project(Eigen::Vector3d(ray.x() * z, ray.y() * z, z), out);
}

bool Registrar::project(const Eigen::Vector3d& p_depth, Corner& out) const {
    const Eigen::Vector3d p_color = registration_.T_color_depth * p_depth;
    if (p_color.z() <= 1e-6)
        return false;
    const auto px = registration_.color.project(p_color);
    if (!px)
        return false;
    out.x = static_cast<float>(px->x());
    out.y = static_cast<float>(px->y());
    out.inv_z = static_cast<float>(1.0 / p_color.z());
    return true;
}

// Rasterises the footprint: the fan of four triangles from the sample's own point `centre`
// to its corners c[0..3] (in order around it), so the sample's pixel keeps its own depth and
// neighbouring footprints meet along their shared corners. Pixel centres on a shared edge are
// taken by both triangles (a tolerance instead of a fill rule): drawing one twice costs a
// z-test, missing it would leave a crack.
void Registrar::drawFootprint(const Corner& centre, const Corner* c[4]) {
    const int CW = registration_.color.width, CH = registration_.color.height;
    float min_x = c[0]->x, max_x = c[0]->x, min_y = c[0]->y, max_y = c[0]->y;
    for (int k = 1; k < 4; ++k) {
        min_x = std::min(min_x, c[k]->x);
        max_x = std::max(max_x, c[k]->x);
        min_y = std::min(min_y, c[k]->y);
        max_y = std::max(max_y, c[k]->y);
    }
    if (max_x - min_x > kMaxFootprintPx || max_y - min_y > kMaxFootprintPx)
        return;
    for (int k = 0; k < 4; ++k)
        drawTriangle(centre, *c[k], *c[(k + 1) % 4], CW, CH);
}

void Registrar::drawTriangle(const Corner& a, const Corner& b, const Corner& d, int CW, int CH) {
    const float min_x = std::min({a.x, b.x, d.x}), max_x = std::max({a.x, b.x, d.x});
    const float min_y = std::min({a.y, b.y, d.y}), max_y = std::max({a.y, b.y, d.y});
    const int x0 = std::max(0, static_cast<int>(std::ceil(min_x - 1e-4f)));
    const int x1 = std::min(CW - 1, static_cast<int>(std::floor(max_x + 1e-4f)));
    const int y0 = std::max(0, static_cast<int>(std::ceil(min_y - 1e-4f)));
    const int y1 = std::min(CH - 1, static_cast<int>(std::floor(max_y + 1e-4f)));
    if (x0 > x1 || y0 > y1)
        return;
    const double area =
        (double(b.x) - a.x) * (double(d.y) - a.y) - (double(b.y) - a.y) * (double(d.x) - a.x);
    if (std::abs(area) < 1e-12)
        return;
    const double inv_area = 1.0 / area;
    const double eps = -1e-6;
    for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
            // Barycentric weights of the pixel centre from the edge functions.
            const double wa =
                ((double(b.x) - x) * (double(d.y) - y) - (double(b.y) - y) * (double(d.x) - x)) *
                inv_area;
            const double wb =
                ((double(d.x) - x) * (double(a.y) - y) - (double(d.y) - y) * (double(a.x) - x)) *
                inv_area;
            const double wd = 1.0 - wa - wb;
            if (wa < eps || wb < eps || wd < eps)
                continue;
            const double inv_z = wa * a.inv_z + wb * b.inv_z + wd * d.inv_z;
            if (!(inv_z > 0))
                continue;
            const float z = static_cast<float>(1.0 / inv_z);
            float& best = color_z_[static_cast<size_t>(y) * CW + x];
            if (z < best)
                best = z;
        }
    }
}

Status Registrar::registerDepth(const ImageView& depth_mm, const MutableImageView& out_mm) {
    const CameraModel& dm = registration_.depth;
    const CameraModel& cm = registration_.color;
    const int W = dm.width, H = dm.height;
    if (depth_mm.desc.format != PixelFormat::kDepth16 || depth_mm.desc.width != W ||
        depth_mm.desc.height != H || depth_mm.data == nullptr) {
        return {ErrorCode::kInvalidArgument, "registerDepth: the depth image must be depth16 " +
                                                 std::to_string(W) + "x" + std::to_string(H) +
                                                 " (the depth camera's size)"};
    }
    if (out_mm.desc.format != PixelFormat::kDepth16 || out_mm.desc.width != cm.width ||
        out_mm.desc.height != cm.height || out_mm.data == nullptr) {
        return {ErrorCode::kInvalidArgument,
                "registerDepth: the output must be depth16 " + std::to_string(cm.width) + "x" +
                    std::to_string(cm.height) + " (the colour camera's size)"};
    }
    z_.resize(static_cast<size_t>(W) * H);
    corners_.resize(static_cast<size_t>(W + 1) * (H + 1));
    color_z_.resize(static_cast<size_t>(cm.width) * cm.height);
    const float inf = std::numeric_limits<float>::infinity();
    std::fill(color_z_.begin(), color_z_.end(), inf);

    const DepthCorrection& correction = registration_.correction;
    for (int y = 0; y < H; ++y) {
        const uint16_t* row = depth_mm.row<uint16_t>(y);
        for (int x = 0; x < W; ++x) {
            float z = 0;
            if (row[x] != 0) {
                z = static_cast<float>(correctedDepth(correction, row[x] * 1e-3, x, y, W));
                if (!(z > 0))
                    z = 0;
            }
            z_[static_cast<size_t>(y) * W + x] = z;
        }
    }
    const auto zAt = [&](int x, int y) -> float {
        if (x < 0 || y < 0 || x >= W || y >= H)
            return 0.f;
        return z_[static_cast<size_t>(y) * W + x];
    };
    const float jump = static_cast<float>(options_.max_jump_rel);

    // Shared corners: every sample around the corner on one surface.
    for (int j = 0; j <= H; ++j) {
        for (int i = 0; i <= W; ++i) {
            Corner& corner = corners_[static_cast<size_t>(j) * (W + 1) + i];
            corner.state = kUnused;
            float lo = inf, hi = 0, inv_sum = 0;
            int n = 0;
            for (const float z : {zAt(i - 1, j - 1), zAt(i, j - 1), zAt(i - 1, j), zAt(i, j)}) {
                if (z > 0) {
                    lo = std::min(lo, z);
                    hi = std::max(hi, z);
                    inv_sum += 1.f / z;
                    ++n;
                }
            }
            if (n == 0)
                continue;
            if (hi - lo > jump * lo) {
                corner.state = kSplit;
                continue;
            }
            if (lift(i, j, inv_sum / n, corner))
                corner.state = kShared;
        }
    }

    // Every sample's footprint; corners at a discontinuity are lifted from the samples on the
    // sample's own surface only.
    Corner own[4];
    const Corner* quad[4];
    const int corner_dx[4] = {0, 1, 1, 0};
    const int corner_dy[4] = {0, 0, 1, 1};
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            const float z = z_[static_cast<size_t>(y) * W + x];
            if (!(z > 0))
                continue;
            bool ok = true;
            for (int k = 0; k < 4 && ok; ++k) {
                const int i = x + corner_dx[k], j = y + corner_dy[k];
                const Corner& shared = corners_[static_cast<size_t>(j) * (W + 1) + i];
                if (shared.state == kShared) {
                    quad[k] = &shared;
                    continue;
                }
                if (shared.state != kSplit) {
                    ok = false;  // the shared corner did not project
                    continue;
                }
                float inv_sum = 0;
                int n = 0;
                for (const float q : {zAt(i - 1, j - 1), zAt(i, j - 1), zAt(i - 1, j), zAt(i, j)}) {
                    if (q > 0 && std::abs(q - z) <= jump * std::min(q, z)) {
                        inv_sum += 1.f / q;
                        ++n;
                    }
                }
                ok = n > 0 && lift(i, j, inv_sum / n, own[k]);
                quad[k] = &own[k];
            }
            Corner centre;
            if (ok && liftPoint(x, y, z, centre))
                drawFootprint(centre, quad);
        }
    }

    for (int y = 0; y < cm.height; ++y) {
        uint16_t* row = out_mm.row<uint16_t>(y);
        float* zrow = color_z_.data() + static_cast<size_t>(y) * cm.width;
        for (int x = 0; x < cm.width; ++x) {
            if (zrow[x] == inf) {
                zrow[x] = 0;
                row[x] = 0;
            } else {
                row[x] = static_cast<uint16_t>(std::clamp(std::lround(zrow[x] * 1e3f), 1L, 65535L));
            }
        }
    }
    return Status::ok();
}

Result<Image> registerDepth(const DepthRegistration& registration, const ImageView& depth_mm,
                            const RegistrationOptions& options) {
    auto registrar = Registrar::create(registration, options);
    if (!registrar)
        return registrar.status();
    Image out(ImageDesc::packed(PixelFormat::kDepth16, registration.color.width,
                                registration.color.height));
    MIXRAY_RETURN_IF_ERROR(registrar->registerDepth(depth_mm, out.mutableView()));
    return out;
}

}  // namespace mixray::calibration
