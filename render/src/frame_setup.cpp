// Setting up one frame (embree_renderer.h): its inputs checked, poses of objects and lights,
// the depth image registered and meshed, the camera's rays, and the screen footprint.
#include <cmath>
#include <string>

#include "embree_renderer.h"

namespace mixray::render::detail {
namespace {

Status checkPose(const Eigen::Isometry3d& T, const std::string& what) {
    if (!T.matrix().allFinite())
        return {ErrorCode::kInvalidArgument, what + ": pose has non-finite entries"};
    const Eigen::Matrix3d R = T.linear();
    const bool orthonormal = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-5;
    const bool last_row = T.matrix().row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1));
    if (!orthonormal || std::abs(R.determinant() - 1) > 1e-5 || !last_row)
        return {ErrorCode::kInvalidArgument, what + ": pose is not a rigid transform"};
    return Status::ok();
}

bool sameRegistration(const calibration::DepthRegistration& a,
                      const calibration::DepthRegistration& b) {
    return sameModel(a.depth, b.depth) && sameModel(a.color, b.color) &&
           a.T_color_depth.matrix() == b.T_color_depth.matrix() &&
           a.correction.scale == b.correction.scale &&
           a.correction.offset_m == b.correction.offset_m &&
           a.correction.alpha0 == b.correction.alpha0 &&
           a.correction.alpha1 == b.correction.alpha1 &&
           a.correction.distortion == b.correction.distortion;
}

}  // namespace

Status EmbreeRenderer::checkInputs(const RenderInputs& in) const {
    const auto bad = [](const std::string& what) {
        return Status(ErrorCode::kInvalidArgument, "render inputs: " + what);
    };
    MIXRAY_RETURN_IF_ERROR(in.camera.validate().withContext("render inputs: camera model"));
    const ImageDesc& c = in.camera_image.desc;
    if (c.format != PixelFormat::kRGB8)
        return bad("camera image must be rgb8, got " + std::string(toString(c.format)));
    if (c.width != in.camera.width || c.height != in.camera.height)
        return bad("camera image is " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                   ", the camera model " + std::to_string(in.camera.width) + "x" +
                   std::to_string(in.camera.height));
    if (in.camera_image.data == nullptr || c.stride_bytes < 3 * c.width ||
        in.camera_image.size_bytes <
            static_cast<size_t>(c.stride_bytes) * static_cast<size_t>(c.height - 1) +
                3 * static_cast<size_t>(c.width))
        return bad("camera image buffer is too small for its size");
    const ImageDesc& dd = in.depth_mm.desc;
    const calibration::DepthRegistration* reg = in.depth_registration;
    // The registration itself is validated once, when its Registrar is made (registeredDepth).
    if (reg) {
        if (!sameModel(reg->color, in.camera))
            return bad("the depth registration's colour camera is not the camera model");
    }
    if (in.depth_mm.data != nullptr || dd.width != 0 || dd.height != 0) {
        if (dd.format != PixelFormat::kDepth16)
            return bad("depth image must be depth16, got " + std::string(toString(dd.format)));
        if (reg && !reg->isIdentity()) {
            if (dd.width != reg->depth.width || dd.height != reg->depth.height)
                return bad("depth image is " + std::to_string(dd.width) + "x" +
                           std::to_string(dd.height) + ", the registration's depth camera " +
                           std::to_string(reg->depth.width) + "x" +
                           std::to_string(reg->depth.height));
        } else if (dd.width != c.width || dd.height != c.height) {
            return bad("depth image size differs from the camera image");
        }
        if (in.depth_mm.data == nullptr || dd.stride_bytes < 2 * dd.width ||
            in.depth_mm.size_bytes <
                static_cast<size_t>(dd.stride_bytes) * static_cast<size_t>(dd.height - 1) +
                    2 * static_cast<size_t>(dd.width))
            return bad("depth image buffer is too small for its size");
    }
    MIXRAY_RETURN_IF_ERROR(checkPose(in.T_world_cam, "render inputs: T_world_cam"));
    if (in.shutter) {
        MIXRAY_RETURN_IF_ERROR(
            checkPose(in.shutter->T_world_cam_open, "render inputs: shutter T_world_cam_open"));
        MIXRAY_RETURN_IF_ERROR(
            checkPose(in.shutter->T_world_cam_close, "render inputs: shutter T_world_cam_close"));
    }
    for (const auto& [name, T] : in.T_world_anchor)
        MIXRAY_RETURN_IF_ERROR(checkPose(T, "render inputs: T_world_anchor[" + name + "]"));
    return Status::ok();
}

// What the screen footprint needs of this frame, and whether the lone-flat-ghost shortcut of
// ghostInfluenced() holds.
void EmbreeRenderer::prepareFootprint(Frame& f) const {
    int ghosts = 0;
    bool flat = false;
    for (const ObjectData& o : objects_)
        if (o.active && o.role == ObjectRole::kGhost) {
            ++ghosts;
            flat = o.shape == ShapeType::kPlane || o.shape == ShapeType::kDisk;
        }
    f.lone_flat_ghost = ghosts == 1 && flat;
    FootprintScene& fp = f.footprint;
    fp.R_world_cam = f.R_world_cam;
    fp.t_world_cam = f.t_world_cam;
    fp.virtual_bounds = f.virtual_bounds;
    if (options_.shadows)
        for (const LightData* light : f.lights)
            fp.lights.push_back(
                {light->light.type == LightType::kDirectional, light->position_world,
                 light->direction_world,
                 light->light.type == LightType::kSphere ? light->light.radius : 0.f});
    for (size_t i = 0; i < objects_.size(); ++i) {
        const ObjectData& o = objects_[i];
        if (!o.active || o.role != ObjectRole::kGhost || i == depth_object_)
            continue;
        FootprintGhost g;
        g.bound = {o.R_world_object * o.bound_centre + o.t_world_object,
                   o.bound_radius * 1.001f + 1e-4f};
        g.flat = o.shape == ShapeType::kPlane || o.shape == ShapeType::kDisk;
        g.plane_point = o.t_world_object;
        g.plane_normal = o.R_world_object.col(2);
        const Material& mat = materials_[static_cast<size_t>(o.material)].material;
        const bool lambert = mat.type == MaterialType::kDiffuse || mat.type == MaterialType::kPhong;
        const bool reflects = !lambert || mat.reflectance > 0;
        g.always = mat.type == MaterialType::kGlass || (reflects && !f.lone_flat_ghost);
        g.receives = lambert;
        if (reflects && !g.always) {
            // ghostInfluenced()'s slack for hit points anywhere on the ghost.
            const float slack = 2e-4f * (1 + g.bound.centre.cwiseAbs().maxCoeff() + g.bound.radius);
            for (const BoundSphere& b : f.virtual_bounds)
                fp.mirrored_bounds.push_back(
                    {b.centre - 2 * g.plane_normal.dot(b.centre - g.plane_point) * g.plane_normal,
                     b.radius + slack});
        }
        fp.ghosts.push_back(g);
    }
    if (f.depth_mesh)
        depthRegions(f, fp);
}

float EmbreeRenderer::spreadRadiusPx(const Frame& f, float nearest_m) const {
    const calibration::CameraModel& camera = f.inputs->camera;
    const double f_px = std::max(camera.fx, camera.fy);
    float spread = lens_.blurRadiusPx(f_px, nearest_m);
    if (f.shutter) {
        // A point at depth d moves across the image by at most f·|Δt|/d for the camera's
        // travel, and by f·θ·(1 + u² + v²) for a turn of θ where the image reaches tan⁻¹ u and
        // tan⁻¹ v off its axis (the pinhole's d(f·tan)/dθ, small turns).
        const float travel = (f.shutter->t_close - f.shutter->t_open).norm();
        const float turn = f.shutter->q_open.angularDistance(f.shutter->q_close);
        const double u = std::max(camera.cx + 1, camera.width - camera.cx) / camera.fx;
        const double v = std::max(camera.cy + 1, camera.height - camera.cy) / camera.fy;
        spread += static_cast<float>(f_px * (travel / nearest_m + turn * (1 + u * u + v * v)));
    }
    return spread;
}

float EmbreeRenderer::nearestInfluencedDepth(const Frame& f) const {
    // What virtual objects touch lies on them or on real surfaces: the ghosts, and the depth
    // camera's surfaces, never nearer than a Kinect measures.
    constexpr float kNearestMeasured_m = 0.25f, kNearest_m = 0.05f;
    const Eigen::Matrix3f R_cam_world = f.R_world_cam.transpose();
    const auto toCam = [&](const Vec3& p) { return Vec3(R_cam_world * (p - f.t_world_cam)); };
    float nearest = f.depth ? kNearestMeasured_m : kInf;
    for (const BoundSphere& b : f.footprint.virtual_bounds)
        nearest = std::min(nearest, toCam(b.centre).z() - b.radius);
    const calibration::CameraModel& camera = f.inputs->camera;
    // A plane's depth along the rays of a rectangle of pixels is nearest at a corner (it is
    // h / n·(u, v, 1), and n·(u, v, 1) is linear in u and v). Its points outside the frame
    // blur into it from at most the blur radius away: the frame grown by that much.
    const auto planeNearest = [&](const Vec3& n, float h, float margin_px) {
        float z = kInf;
        for (const double u : {-0.5 - margin_px, camera.width - 0.5 + margin_px})
            for (const double v : {-0.5 - margin_px, camera.height - 0.5 + margin_px}) {
                const Vec3 d(static_cast<float>((u - camera.cx) / camera.fx),
                             static_cast<float>((v - camera.cy) / camera.fy), 1.f);
                const float nd = n.dot(d);
                if (nd * h > 0)
                    z = std::min(z, h / nd);
            }
        return z;
    };
    const auto ghostsNearest = [&](float margin_px) {
        float z = kInf;
        for (const FootprintGhost& g : f.footprint.ghosts) {
            const Vec3 c = toCam(g.bound.centre);
            if (!g.flat) {
                z = std::min(z, c.z() - g.bound.radius);
                continue;
            }
            // Also never nearer than the disk where its plane cuts its bound, whose nearest
            // point lies its radius times the plane's tilt from the camera's axis nearer than
            // its centre: the larger of the two bounds holds.
            const Vec3 n = R_cam_world * g.plane_normal;
            const float h = n.dot(toCam(g.plane_point));
            const float off = n.dot(c) - h;
            const float r = std::sqrt(std::max(0.f, g.bound.radius * g.bound.radius - off * off));
            const float disk = (c - off * n).z() - r * std::sqrt(std::max(0.f, 1 - n.z() * n.z()));
            z = std::min(z, std::max(disk, planeNearest(n, h, margin_px)));
        }
        return z;
    };
    // Grow the frame by the blur of the nearest point found so far until that stops growing:
    // a nearer point outside blurs further in.
    float found = std::max(std::min(nearest, ghostsNearest(0)), kNearest_m);
    for (int i = 0; i < 4; ++i) {
        const float grown =
            std::max(std::min(nearest, ghostsNearest(spreadRadiusPx(f, found) + 1)), kNearest_m);
        const bool settled = grown > 0.99f * found;
        found = std::min(found, grown);
        if (settled)
            break;
    }
    return found;
}

// The footprint of the depth mesh: finishPrimaryHit() traces it where depthSurfaceInfluenced()
// holds for the measured point, with a margin of 5 % of its distance; each tile's sphere holds
// every such point and its margin.
void EmbreeRenderer::depthRegions(const Frame& f, FootprintScene& fp) const {
    const int w = f.inputs->camera.width, h = f.inputs->camera.height;
    const int spp = options_.samples_per_pixel, ts = options_.tile_size;
    const int tiles_x = (w + ts - 1) / ts, tiles_y = (h + ts - 1) / ts;
    fp.depth_reflects =
        materials_[static_cast<size_t>(objects_[*depth_object_].material)].material.reflectance > 0;
    fp.depth_regions.assign(static_cast<size_t>(tiles_x) * tiles_y, {Vec3::Zero(), -1.f});
    for (int ty = 0; ty < tiles_y; ++ty)
        for (int tx = 0; tx < tiles_x; ++tx) {
            Vec3 lo = Vec3::Constant(kInf), hi = Vec3::Constant(-kInf);
            float margin = 0;
            for (int y = ty * ts; y < std::min(h, (ty + 1) * ts); ++y)
                for (int x = tx * ts; x < std::min(w, (tx + 1) * ts); ++x) {
                    const std::optional<float> dist = rays_.rayDistanceAt(*f.depth, x, y);
                    if (!dist)
                        continue;
                    for (int k = 0; k < spp; ++k) {
                        const Vec3& d =
                            rays_.directions[(static_cast<size_t>(y) * w + x) * spp + k];
                        if (!d.allFinite())
                            continue;
                        const Vec3 p = *dist * d;
                        lo = lo.cwiseMin(p);
                        hi = hi.cwiseMax(p);
                        margin = std::max(margin, 0.05f * *dist);
                    }
                }
            if (!(lo.array() <= hi.array()).all())
                continue;
            const Vec3 centre_cam = 0.5f * (lo + hi);
            fp.depth_regions[static_cast<size_t>(ty) * tiles_x + tx] = {
                rotate(f.R_world_cam, centre_cam) + f.t_world_cam,
                0.5f * (hi - lo).norm() + margin};
        }
}

Result<ImageView> EmbreeRenderer::registeredDepth(const RenderInputs& in) {
    const calibration::DepthRegistration* reg = in.depth_registration;
    if (!reg || reg->isIdentity())
        return in.depth_mm;
    if (!registrar_ || !sameRegistration(registrar_->registration(), *reg)) {
        auto created = calibration::Registrar::create(*reg);
        if (!created)
            return created.status().withContext("render inputs: depth registration");
        registrar_.emplace(std::move(created).value());
    }
    const ImageDesc desc =
        ImageDesc::packed(PixelFormat::kDepth16, in.camera.width, in.camera.height);
    if (!(registered_depth_.desc() == desc))
        registered_depth_ = Image(desc);
    MIXRAY_RETURN_IF_ERROR(registrar_->registerDepth(in.depth_mm, registered_depth_.mutableView()));
    return registered_depth_.view();
}

Status EmbreeRenderer::prepareFrame(const RenderInputs& in, Frame& f) {
    f.inputs = &in;
    f.R_world_cam = in.T_world_cam.linear().cast<float>();
    f.t_world_cam = in.T_world_cam.translation().cast<float>();
    if (in.shutter) {
        const auto& s = *in.shutter;
        f.shutter = Frame::Shutter{Eigen::Quaternionf(s.T_world_cam_open.linear().cast<float>()),
                                   Eigen::Quaternionf(s.T_world_cam_close.linear().cast<float>()),
                                   s.T_world_cam_open.translation().cast<float>(),
                                   s.T_world_cam_close.translation().cast<float>()};
        // The shorter way round, for the interpolation.
        if (f.shutter->q_open.dot(f.shutter->q_close) < 0)
            f.shutter->q_close.coeffs() = -f.shutter->q_close.coeffs();
    }
    const Eigen::Isometry3d T_cam_world = in.T_world_cam.inverse();
    f.R_cam_world = T_cam_world.linear();
    f.t_cam_world = T_cam_world.translation();
    for (int i = 0; i < 256; ++i)
        f.srgb_lut[i] = optics::srgbToLinear(i / 255.f);

    const auto anchorPose = [&](const std::string& anchor) -> std::optional<Eigen::Isometry3d> {
        if (anchor == "world")
            return Eigen::Isometry3d::Identity();
        const auto it = in.T_world_anchor.find(anchor);
        if (it == in.T_world_anchor.end())
            return std::nullopt;
        return it->second;
    };
    if (in.depth_mm.data != nullptr) {
        auto depth = registeredDepth(in);
        if (!depth)
            return depth.status();
        f.depth = DepthView{*depth, in.camera};
    }
    updateDepthMesh(f);
    for (ObjectData& object : objects_) {
        if (object.depth_surface)
            continue;  // posed by updateDepthMesh
        const auto T_world_anchor = anchorPose(object.anchor);
        object.active = T_world_anchor.has_value();
        if (!object.active)
            continue;
        const Eigen::Isometry3f T = T_world_anchor->cast<float>() * object.T_anchor_object;
        object.R_world_object = T.linear();
        object.t_world_object = T.translation();
        if (object.role == ObjectRole::kVirtual)
            f.virtual_bounds.push_back(
                {object.R_world_object * object.bound_centre + object.t_world_object,
                 object.bound_radius * 1.001f + 1e-4f});
    }
    MIXRAY_RETURN_IF_ERROR(scene_->setPoses(objects_));
    for (LightData& light : lights_) {
        const auto T_world_anchor = anchorPose(light.light.anchor);
        light.active = T_world_anchor.has_value();
        if (!light.active)
            continue;
        const Eigen::Isometry3d T = *T_world_anchor;
        light.position_world = (T * light.light.position).cast<float>();
        light.direction_world = (T.linear() * light.light.direction).normalized().cast<float>();
        if (light.light.type == LightType::kEnvironment) {
            light.R_environment_world =
                (T * light.light.T_world_environment).inverse().linear().cast<float>();
            f.environments.push_back(&light);
        } else {
            f.lights.push_back(&light);
        }
    }
    if (!updateRayCache(rays_, in.camera, options_.samples_per_pixel, options_.seed,
                        options_.tile_size, lens_, in.shutter.has_value(), in.stop))
        return frameCancelled();
    return Status::ok();
}

// kMesh: the depth map as a mesh in the camera frame, instanced at T_world_cam.
void EmbreeRenderer::updateDepthMesh(Frame& f) {
    if (!depth_object_)
        return;
    ObjectData& object = objects_[*depth_object_];
    TriangleMesh& mesh = object.meshes->front();
    if (f.depth) {
        mesher_.build(*f.depth, DepthMeshOptions{}, mesh);
    } else {
        mesh.positions.clear();
        mesh.normals.clear();
        mesh.uvs.clear();
        mesh.triangles.clear();
    }
    scene_->setDepthMesh(mesh);
    object.active = !mesh.empty();
    object.R_world_object = f.R_world_cam;
    object.t_world_object = f.t_world_cam;
    f.depth_mesh = object.active;
}

}  // namespace mixray::render::detail
