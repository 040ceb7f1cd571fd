// Lights from a light-probe sphere in the camera image (de Castro, de Figueiredo, Velho 2012,
// "Realistic Shadows for Mobile AR", §3): the probe's samples in the image or on a (u,v) grid
// over the sphere, 4-connected components of maximum luminance ranked by size; a mirror ball's
// highlight reflects the camera ray, a diffuse ball's shading is fitted with a Lambertian model.
#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "lights_internal.h"

namespace mixray::tracking {

namespace {

using Eigen::Isometry3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

// One place on the probe's visible surface and what the camera sees there.
struct Sample {
    Vector3d normal_world;  // unit outward normal
    Vector3d view_world;    // unit, from the camera towards the surface point
    double luma = 0;        // gamma-encoded luminance, fraction of full scale (the paper's l)
    Vector3d linear_rgb;    // sRGB-decoded
    bool clipped = false;   // a channel at the top of the 8-bit range
};

// Samples on a grid (image pixels in the outline's box, or the sphere's (u,v) grid) so that
// 4-neighbours are grid neighbours; cell -1 holds no sample.
struct SampleGrid {
    int cols = 0;
    int rows = 0;
    std::vector<int> cell;
    std::vector<Sample> samples;
};

struct Pixel {
    double luma = 0;
    Vector3d linear_rgb = Vector3d::Zero();
    bool clipped = false;
};

Pixel pixelAt(const ImageView& image, int x, int y) {
    const auto& table = srgbToLinearTable();
    const auto codes = detail::codesAt(image, x, y);
    Pixel p;
    Vector3d encoded;
    for (size_t c = 0; c < 3; ++c) {
        encoded[static_cast<Eigen::Index>(c)] = codes[c] / 255.0;
        p.linear_rgb[static_cast<Eigen::Index>(c)] = table[codes[c]];
        p.clipped = p.clipped || codes[c] >= 250;
    }
    p.luma = detail::luminance(encoded);
    return p;
}

// The pixel a projected point falls in (the paper reads the vertex's pixel); nullopt outside
// the image. Not interpolated: a highlight of a pixel or two at the limb would blend with the
// background and drop below the maximum.
std::optional<Pixel> pixelNearest(const ImageView& image, const Vector2d& px) {
    const long x = std::lround(px.x()), y = std::lround(px.y());
    if (!(x >= 0 && y >= 0 && x < image.desc.width && y < image.desc.height))
        return std::nullopt;
    return pixelAt(image, static_cast<int>(x), static_cast<int>(y));
}

// The mirror direction of the camera ray `view` (camera to surface) about the unit normal.
// The paper prints v_r = −2(c_i·n_s)n − c_i; reflecting about the tangent plane needs
// c_i − 2(c_i·n_s)n_s (a ray hitting the sphere head-on, c_i = −n_s, comes straight back:
// v_r = n_s; the printed form gives −3·... off the unit sphere, pointing into the probe).
Vector3d reflect(const Vector3d& view, const Vector3d& normal) {
    return view - 2 * view.dot(normal) * normal;
}

// The probe's silhouette in the image and how much of it lies inside.
struct Outline {
    ProbeOutline outline;
    double visible_fraction = 0;
    Eigen::AlignedBox2d box;
};

Outline outlineOf(const calibration::CameraModel& camera, const Vector3d& centre_cam,
                  double radius) {
    constexpr int kPoints = 64;
    const double d = centre_cam.norm();
    const Vector3d axis = centre_cam / d;
    const Vector3d e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
    const double sin_a = radius / d, cos_a = std::sqrt(1 - sin_a * sin_a);
    Outline out;
    std::vector<Vector2d> points;
    int inside = 0;
    for (int k = 0; k < kPoints; ++k) {
        const double t = 2 * std::numbers::pi * k / kPoints;
        const Vector3d ray = cos_a * axis + sin_a * (std::cos(t) * e1 + std::sin(t) * e2);
        const auto px = camera.project(ray);
        // Far outside the image a distortion polynomial can fold back into it: only a pixel
        // that leads back to the same ray counts.
        const auto back = px ? camera.unproject(*px) : std::nullopt;
        if (!back || back->dot(ray) < std::cos(1e-3))
            continue;
        points.push_back(*px);
        out.box.extend(*px);
        if (px->x() >= -0.5 && px->y() >= -0.5 && px->x() <= camera.width - 0.5 &&
            px->y() <= camera.height - 0.5)
            ++inside;
    }
    out.visible_fraction = static_cast<double>(inside) / kPoints;
    if (points.empty())
        return out;
    Vector2d mean = Vector2d::Zero();
    for (const Vector2d& p : points)
        mean += p;
    mean /= static_cast<double>(points.size());
    double r = 0;
    for (const Vector2d& p : points)
        r += (p - mean).norm();
    out.outline.centre_px = mean;
    out.outline.radius_px = r / static_cast<double>(points.size());
    return out;
}

// The paper's image domain: every pixel in the outline's box whose ray hits the sphere.
SampleGrid imageDomain(const ImageView& image, const calibration::CameraModel& camera,
                       const Isometry3d& T_world_camera, const Vector3d& centre_cam, double radius,
                       const Eigen::AlignedBox2d& box) {
    const int x0 = std::max(0, static_cast<int>(std::floor(box.min().x())));
    const int y0 = std::max(0, static_cast<int>(std::floor(box.min().y())));
    const int x1 = std::min(camera.width - 1, static_cast<int>(std::ceil(box.max().x())));
    const int y1 = std::min(camera.height - 1, static_cast<int>(std::ceil(box.max().y())));
    SampleGrid grid;
    grid.cols = std::max(0, x1 - x0 + 1);
    grid.rows = std::max(0, y1 - y0 + 1);
    grid.cell.assign(static_cast<size_t>(grid.cols) * grid.rows, -1);
    const Eigen::Matrix3d R = T_world_camera.linear();
    const double c2 = centre_cam.squaredNorm() - radius * radius;
    for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
            const auto ray = camera.unproject(Vector2d(x, y));
            if (!ray)
                continue;
            const double b = ray->dot(centre_cam);
            const double disc = b * b - c2;
            if (disc < 0)
                continue;
            const double t = b - std::sqrt(disc);
            if (t <= 0)
                continue;
            const Vector3d n_cam = (t * *ray - centre_cam) / radius;
            const Pixel p = pixelAt(image, x, y);
            grid.cell[static_cast<size_t>(y - y0) * grid.cols + (x - x0)] =
                static_cast<int>(grid.samples.size());
            grid.samples.push_back(
                {(R * n_cam).normalized(), R * *ray, p.luma, p.linear_rgb, p.clipped});
        }
    return grid;
}

// The paper's sphere domain: a fixed n×n grid over the visible cap, (u,v) in [−1,1]² mapped
// azimuthally-equidistant about the direction towards the camera, so the cost does not depend on
// the probe's size in the image.
SampleGrid sphereDomain(const ImageView& image, const calibration::CameraModel& camera,
                        const Isometry3d& T_world_camera, const Vector3d& centre_world,
                        double radius, int n) {
    const Vector3d eye = T_world_camera.translation();
    const Isometry3d T_camera_world = T_world_camera.inverse();
    const double d = (eye - centre_world).norm();
    const Vector3d w = (eye - centre_world) / d;
    const Vector3d e1 = w.unitOrthogonal(), e2 = w.cross(e1);
    // The horizon seen from the eye; samples stop just short of it.
    const double theta_max = std::acos(radius / d);
    SampleGrid grid;
    grid.cols = grid.rows = n;
    grid.cell.assign(static_cast<size_t>(n) * n, -1);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const double u = 2 * (i + 0.5) / n - 1, v = 2 * (j + 0.5) / n - 1;
            const double rho = std::hypot(u, v);
            if (rho > 1)
                continue;
            const double theta = theta_max * rho;
            const Vector3d tangent = rho > 0 ? Vector3d((u * e1 + v * e2) / rho) : e1;
            const Vector3d normal = std::cos(theta) * w + std::sin(theta) * tangent;
            const Vector3d point = centre_world + radius * normal;
            const auto px = camera.project(T_camera_world * point);
            if (!px)
                continue;
            const auto p = pixelNearest(image, *px);
            if (!p)
                continue;
            grid.cell[static_cast<size_t>(j) * n + i] = static_cast<int>(grid.samples.size());
            grid.samples.push_back(
                {normal, (point - eye).normalized(), p->luma, p->linear_rgb, p->clipped});
        }
    return grid;
}

// 4-connected components of samples at the maximum luminance (within `tolerance`), largest
// first, by flood fill (the paper's procedure).
std::vector<std::vector<int>> maxLuminanceComponents(const SampleGrid& grid, double tolerance) {
    double l_max = 0;
    for (const Sample& s : grid.samples)
        l_max = std::max(l_max, s.luma);
    const double floor = l_max - tolerance;
    std::vector<char> seen(grid.cell.size(), 0);
    std::vector<std::vector<int>> components;
    std::vector<int> stack;
    auto bright = [&](int cell) {
        const int s = grid.cell[static_cast<size_t>(cell)];
        return s >= 0 && grid.samples[static_cast<size_t>(s)].luma >= floor;
    };
    for (int start = 0; start < static_cast<int>(grid.cell.size()); ++start) {
        if (seen[static_cast<size_t>(start)] || !bright(start))
            continue;
        std::vector<int> component;
        stack.assign(1, start);
        seen[static_cast<size_t>(start)] = 1;
        while (!stack.empty()) {
            const int c = stack.back();
            stack.pop_back();
            component.push_back(grid.cell[static_cast<size_t>(c)]);
            const int x = c % grid.cols, y = c / grid.cols;
            const int neighbours[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
            for (const auto& nb : neighbours) {
                if (nb[0] < 0 || nb[1] < 0 || nb[0] >= grid.cols || nb[1] >= grid.rows)
                    continue;
                const int k = nb[1] * grid.cols + nb[0];
                if (!seen[static_cast<size_t>(k)] && bright(k)) {
                    seen[static_cast<size_t>(k)] = 1;
                    stack.push_back(k);
                }
            }
        }
        components.push_back(std::move(component));
    }
    std::stable_sort(components.begin(), components.end(),
                     [](const auto& a, const auto& b) { return a.size() > b.size(); });
    return components;
}

// Intensity-weighted mean of unit vectors, and the RMS angle about it.
std::pair<Vector3d, double> weightedMeanDirection(const std::vector<Vector3d>& dirs,
                                                  const std::vector<double>& weights) {
    Vector3d sum = Vector3d::Zero();
    for (size_t k = 0; k < dirs.size(); ++k)
        sum += weights[k] * dirs[k];
    const Vector3d mean = sum.normalized();
    double sq = 0, total = 0;
    for (size_t k = 0; k < dirs.size(); ++k) {
        const double a = std::acos(std::clamp(dirs[k].dot(mean), -1.0, 1.0));
        sq += weights[k] * a * a;
        total += weights[k];
    }
    return {mean, total > 0 ? std::sqrt(sq / total) : 0.0};
}

std::vector<EstimatedLight> mirrorLights(const SampleGrid& grid,
                                         const std::vector<std::vector<int>>& components,
                                         int max_lights) {
    std::vector<EstimatedLight> lights;
    for (const auto& component : components) {
        if (static_cast<int>(lights.size()) == max_lights)
            break;
        std::vector<Vector3d> dirs;
        std::vector<double> weights;
        Vector3d rgb = Vector3d::Zero();
        for (int s : component) {
            const Sample& sample = grid.samples[static_cast<size_t>(s)];
            dirs.push_back(reflect(sample.view_world, sample.normal_world));
            weights.push_back(sample.luma);
            rgb += sample.linear_rgb;
        }
        const auto [dir, rms] = weightedMeanDirection(dirs, weights);
        EstimatedLight light;
        light.source = LightSource::kProbeMirror;
        light.to_light_world = dir;
        // A uniform disc of angular radius ρ has an RMS angle of ρ/√2 about its centre.
        light.angular_radius_rad = std::sqrt(2.0) * rms;
        light.weight = static_cast<double>(component.size());
        // Clipped highlights hide how bright each light is: the component's size stands in.
        light.intensity = rgb / static_cast<double>(component.size()) * light.weight;
        lights.push_back(light);
    }
    return lights;
}

// ---- the diffuse probe: linear luminance y(n) = a + Σ_i max(0, n·b_i) ----

struct LambertFit {
    double ambient = 0;
    std::vector<Vector3d> b;  // light i: direction b/|b|, strength |b| (albedo·irradiance/π)
    double cost = 0;
};

// One sample of the fit: the surface normal and the linear luminance seen there.
struct FitSample {
    Vector3d normal;
    double y = 0;
};

double lambertModel(const LambertFit& f, const Vector3d& n) {
    double y = f.ambient;
    for (const Vector3d& b : f.b)
        y += std::max(0.0, n.dot(b));
    return y;
}

double lambertCost(const LambertFit& f, const std::vector<FitSample>& samples) {
    double cost = 0;
    for (const FitSample& s : samples) {
        const double r = lambertModel(f, s.normal) - s.y;
        cost += r * r;
    }
    return cost;
}

// Levenberg–Marquardt on (a, b_1, ..., b_k), at most `iterations` steps.
LambertFit refineLambert(LambertFit f, const std::vector<FitSample>& samples, int iterations = 60) {
    const int k = static_cast<int>(f.b.size());
    const int m = 1 + 3 * k;
    auto pack = [&](const LambertFit& g) {
        Eigen::VectorXd p(m);
        p[0] = g.ambient;
        for (int i = 0; i < k; ++i)
            p.segment<3>(1 + 3 * i) = g.b[static_cast<size_t>(i)];
        return p;
    };
    auto unpack = [&](const Eigen::VectorXd& p) {
        LambertFit g;
        g.ambient = p[0];
        for (int i = 0; i < k; ++i)
            g.b.push_back(p.segment<3>(1 + 3 * i));
        return g;
    };
    f.cost = lambertCost(f, samples);
    double lambda = 1e-3;
    Eigen::MatrixXd JtJ(m, m);
    Eigen::VectorXd Jtr(m);
    std::vector<int> lit;  // the lights facing the sample
    lit.reserve(static_cast<size_t>(k));
    for (int iter = 0; iter < iterations; ++iter) {
        // The Jacobian row of a sample is (1, n·[n·b_1 > 0], ..., n·[n·b_k > 0]): its products
        // are blocks of n nᵀ between the lights it faces, accumulated directly (the lower
        // triangle) instead of through a general rank update of a dynamic row.
        JtJ.setZero();
        Jtr.setZero();
        for (const FitSample& s : samples) {
            const Vector3d& n = s.normal;
            lit.clear();
            double model = f.ambient;
            for (int i = 0; i < k; ++i) {
                const double c = n.dot(f.b[static_cast<size_t>(i)]);
                if (c > 0) {
                    lit.push_back(i);
                    model += c;
                }
            }
            const double r = model - s.y;
            JtJ(0, 0) += 1;
            Jtr[0] += r;
            if (lit.empty())
                continue;
            const Eigen::Matrix3d nn = n * n.transpose();
            for (size_t a = 0; a < lit.size(); ++a) {
                const int i = 1 + 3 * lit[a];
                JtJ.block<3, 1>(i, 0) += n;
                Jtr.segment<3>(i) += r * n;
                for (size_t c = 0; c <= a; ++c)
                    JtJ.block<3, 3>(i, 1 + 3 * lit[c]) += nn;
            }
        }
        JtJ = JtJ.selfadjointView<Eigen::Lower>();
        bool improved = false;
        for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
            Eigen::MatrixXd A = JtJ;
            A.diagonal() += lambda * (JtJ.diagonal().array() + 1e-9).matrix();
            const Eigen::VectorXd step = A.ldlt().solve(-Jtr);
            LambertFit trial = unpack(pack(f) + step);
            trial.cost = lambertCost(trial, samples);
            if (trial.cost < f.cost) {
                const double gain = f.cost - trial.cost;
                f = std::move(trial);
                lambda = std::max(lambda / 3, 1e-9);
                improved = true;
                if (gain < 1e-12 * std::max(f.cost, 1e-12))
                    return f;
            } else {
                lambda *= 4;
            }
        }
        if (!improved)
            break;
    }
    return f;
}

double angleBetween(const Vector3d& a, const Vector3d& b) {
    return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0));
}

// Lights one at a time: the first from the largest maximum-luminance component (the paper's
// estimate), each further one from where the current fit leaves the most light unexplained;
// every addition refits all of them and stays only if it explains a real part of the shading.
LambertFit fitLambert(const std::vector<FitSample>& samples, const Vector3d& first_normal,
                      const Vector3d& towards_camera, int max_lights) {
    double y_min = 1e300, y_max = 0;
    for (const FitSample& s : samples) {
        y_min = std::min(y_min, s.y);
        y_max = std::max(y_max, s.y);
    }
    LambertFit fit;
    fit.ambient = y_min;
    fit.b = {std::max(y_max - y_min, 1e-3) * first_normal};
    fit = refineLambert(fit, samples);
    const Vector3d e1 = towards_camera.unitOrthogonal(), e2 = towards_camera.cross(e1);
    while (static_cast<int>(fit.b.size()) < max_lights) {
        // Where the fit falls shortest, plus a ring of directions around the view axis: a
        // light mostly behind the probe lights only a rim the residual alone may not single out.
        std::vector<Vector3d> starts;
        Vector3d sum = Vector3d::Zero();
        double best = 0;
        for (const FitSample& s : samples)
            best = std::max(best, s.y - lambertModel(fit, s.normal));
        for (const FitSample& s : samples) {
            const double r = s.y - lambertModel(fit, s.normal);
            if (r > 0.5 * best)
                sum += r * s.normal;
        }
        if (sum.norm() > 0)
            starts.push_back(sum.normalized());
        for (int k = 0; k < 8; ++k) {
            const double t = 2 * std::numbers::pi * k / 8;
            for (double elevation : {0.2, 0.8})
                starts.push_back((elevation * towards_camera + std::cos(t) * e1 + std::sin(t) * e2)
                                     .normalized());
        }
        // A few steps from every start single out where the fit is going; only the most
        // promising starts are refined to the end (most of the 17 converge to the same light).
        constexpr int kScreeningSteps = 6;
        constexpr size_t kRefinedStarts = 3;
        std::vector<LambertFit> screened;
        for (const Vector3d& start : starts) {
            LambertFit trial = fit;
            trial.b.push_back(std::max(best, 1e-3) * start);
            screened.push_back(refineLambert(std::move(trial), samples, kScreeningSteps));
        }
        std::stable_sort(screened.begin(), screened.end(),
                         [](const LambertFit& a, const LambertFit& b) { return a.cost < b.cost; });
        screened.resize(std::min(screened.size(), kRefinedStarts));
        std::optional<LambertFit> best_fit;
        for (LambertFit& trial : screened) {
            trial = refineLambert(std::move(trial), samples);
            if (!best_fit || trial.cost < best_fit->cost)
                best_fit = std::move(trial);
        }
        if (!best_fit)
            break;
        double strongest = 0;
        for (const Vector3d& b : best_fit->b)
            strongest = std::max(strongest, b.norm());
        const Vector3d& added = best_fit->b.back();
        bool distinct = true;
        for (size_t i = 0; i + 1 < best_fit->b.size(); ++i)
            distinct =
                distinct && angleBetween(added, best_fit->b[i]) > 10 * std::numbers::pi / 180;
        // A light must lower the misfit clearly and carry a few percent of the strongest's
        // strength; otherwise it is fitting the 8-bit quantisation.
        if (!distinct || added.norm() < 0.03 * strongest || best_fit->cost > 0.7 * fit.cost)
            break;
        fit = std::move(*best_fit);
    }
    return fit;
}

std::vector<EstimatedLight> diffuseLights(const SampleGrid& grid, const std::vector<int>& brightest,
                                          const Vector3d& towards_camera, int max_lights,
                                          std::string& why_not) {
    std::vector<const Sample*> usable;
    for (const Sample& s : grid.samples) {
        // The limb mixes the sphere with the background, and clipped pixels hide how bright
        // the shading really is.
        if (!s.clipped && -s.view_world.dot(s.normal_world) > 0.2)
            usable.push_back(&s);
    }
    // A few thousand samples pin down a handful of parameters; more only cost time.
    constexpr size_t kMaxFitSamples = 3000;
    const size_t stride = (usable.size() + kMaxFitSamples - 1) / kMaxFitSamples;
    std::vector<const Sample*> samples;
    for (size_t j = 0; j < usable.size(); j += std::max<size_t>(stride, 1))
        samples.push_back(usable[j]);
    if (samples.size() < 20) {
        why_not = "too few unclipped samples on the diffuse probe";
        return {};
    }
    std::vector<Vector3d> normals;
    std::vector<double> weights;
    for (int s : brightest) {
        normals.push_back(grid.samples[static_cast<size_t>(s)].normal_world);
        weights.push_back(grid.samples[static_cast<size_t>(s)].luma);
    }
    const Vector3d first = weightedMeanDirection(normals, weights).first;
    std::vector<FitSample> fit_samples;
    fit_samples.reserve(samples.size());
    for (const Sample* s : samples)
        fit_samples.push_back({s->normal_world, detail::luminance(s->linear_rgb)});
    const LambertFit fit = fitLambert(fit_samples, first, towards_camera, max_lights);

    // Colour: with the directions fixed each channel is linear in (ambient, strengths).
    const int k = static_cast<int>(fit.b.size());
    Eigen::MatrixXd A(static_cast<Eigen::Index>(samples.size()), 1 + k);
    Eigen::MatrixXd Y(static_cast<Eigen::Index>(samples.size()), 3);
    std::vector<int> lit(static_cast<size_t>(k), 0);
    for (size_t j = 0; j < samples.size(); ++j) {
        const auto r = static_cast<Eigen::Index>(j);
        A(r, 0) = 1;
        for (int i = 0; i < k; ++i) {
            const double c =
                samples[j]->normal_world.dot(fit.b[static_cast<size_t>(i)].normalized());
            A(r, 1 + i) = std::max(0.0, c);
            lit[static_cast<size_t>(i)] += c > 0;
        }
        Y.row(r) = samples[j]->linear_rgb.transpose();
    }
    const Eigen::MatrixXd X = A.colPivHouseholderQr().solve(Y);
    std::vector<EstimatedLight> lights;
    for (int i = 0; i < k; ++i) {
        EstimatedLight light;
        light.source = LightSource::kProbeDiffuse;
        light.to_light_world = fit.b[static_cast<size_t>(i)].normalized();
        light.intensity = X.row(1 + i).transpose().cwiseMax(0.0);
        light.weight = lit[static_cast<size_t>(i)];
        lights.push_back(light);
    }
    return lights;
}

}  // namespace

Result<ProbeResult> estimateProbeLights(const ImageView& color,
                                        const calibration::CameraModel& camera,
                                        const Eigen::Isometry3d& T_world_camera,
                                        const LightProbe& probe, const ProbeOptions& options) {
    MIXRAY_RETURN_IF_ERROR(probe.validate());
    MIXRAY_RETURN_IF_ERROR(options.validate());
    MIXRAY_RETURN_IF_ERROR(camera.validate().withContext("light probe camera"));
    MIXRAY_RETURN_IF_ERROR(
        detail::checkColorImage(color, camera.width, camera.height, "light probe image"));
    if (!T_world_camera.matrix().allFinite())
        return Status(ErrorCode::kInvalidArgument, "light probe: camera pose is not finite");
    const std::string name = "probe '" + probe.name + "'";
    auto not_found = [&](const std::string& why) {
        return Status(ErrorCode::kNotFound, name + ": " + why);
    };

    const Vector3d centre_cam = T_world_camera.inverse() * probe.centre_world;
    if (centre_cam.norm() <= probe.radius_m * 1.001)
        return not_found("the camera is inside the probe");
    if (centre_cam.z() <= 0)
        return not_found("out of view (behind the camera)");
    const Outline outline = outlineOf(camera, centre_cam, probe.radius_m);
    if (outline.visible_fraction < options.min_visible_fraction)
        return not_found("out of view (" +
                         std::to_string(static_cast<int>(100 * outline.visible_fraction)) +
                         "% of its outline in the image)");
    if (outline.outline.radius_px < 3)
        return not_found("too small in the image (radius " +
                         std::to_string(outline.outline.radius_px) + " px)");

    const SampleGrid grid =
        options.domain == ProbeDomain::kImage
            ? imageDomain(color, camera, T_world_camera, centre_cam, probe.radius_m, outline.box)
            : sphereDomain(color, camera, T_world_camera, probe.centre_world, probe.radius_m,
                           options.sphere_samples);
    if (grid.samples.size() < 20)
        return not_found("too few samples on the probe");
    double l_min = 1, l_max = 0;
    for (const Sample& s : grid.samples) {
        l_min = std::min(l_min, s.luma);
        l_max = std::max(l_max, s.luma);
    }
    // A black probe has no highlight; a flat one (uniform light, a covered probe) has none that
    // points anywhere.
    if (l_max < 0.05)
        return not_found("too dark (brightest " + std::to_string(l_max) + " of full scale)");
    if (l_max - l_min < 0.05)
        return not_found("no highlight (flat shading)");

    const auto components = maxLuminanceComponents(grid, options.max_luminance_tolerance);
    ProbeResult result;
    result.outline = outline.outline;
    if (probe.material == ProbeMaterial::kMirror) {
        result.lights = mirrorLights(grid, components, options.max_lights);
    } else {
        std::string why_not;
        const Vector3d towards_camera =
            (T_world_camera.translation() - probe.centre_world).normalized();
        result.lights =
            diffuseLights(grid, components.front(), towards_camera, options.max_lights, why_not);
        if (result.lights.empty())
            return not_found(why_not);
    }
    std::stable_sort(result.lights.begin(), result.lights.end(), [](const auto& a, const auto& b) {
        return detail::luminance(a.intensity) > detail::luminance(b.intensity);
    });
    const double top = detail::luminance(result.lights.front().intensity);
    if (top > 0)
        for (EstimatedLight& light : result.lights)
            light.intensity /= top;
    return result;
}

}  // namespace mixray::tracking
