// Camera models in mixray's YAML files.
#include "mixray/calibration/camera_model_yaml.h"

#include <algorithm>
#include <array>
#include <string>
#include <string_view>
#include <utility>

namespace mixray::calibration {
namespace {

using yaml::find;
using yaml::Item;

constexpr std::array<std::string_view, 8> kModelKeys = {"lens", "width", "height", "fx",
                                                        "fy",   "cx",    "cy",     "distortion"};
constexpr int64_t kMaxImageSide = 65535;

}  // namespace

Result<CameraModel> readCameraModel(const yaml::Reader& r, const Item& item) {
    auto fields = r.readMap(item, kModelKeys,
                            "a camera model mapping with lens:, width:, height:, fx:, fy:, cx: "
                            "and cy:");
    if (!fields)
        return fields.status();
    for (std::string_view key : {"width", "height", "fx", "fy", "cx", "cy"})
        MIXRAY_RETURN_IF_ERROR(r.require(*fields, item, key));
    CameraModel model;
    if (const Item* lens = find(*fields, "lens")) {
        auto parsed =
            lens->node.IsScalar() ? lensModelFromString(lens->node.Scalar()) : std::nullopt;
        if (!parsed) {
            return r.expected(*lens,
                              "pinhole, fisheye, stereographic or a configured "
                              "LENSMODEL_SPLINED_STEREOGRAPHIC_order=..._Nx=..._Ny=..."
                              "_fov_x_deg=...");
        }
        model.lens = *parsed;
        if (model.lens == LensModel::kSplinedStereographic) {
            auto config = splineConfigFromString(lens->node.Scalar());
            if (!config) {
                return r.expected(*lens,
                                  "a configured LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_"
                                  "Nx=16_Ny=12_fov_x_deg=120");
            }
            model.spline = *config;
        }
    }
    for (auto [key, out] : {std::pair{"width", &model.width}, std::pair{"height", &model.height}}) {
        auto v = r.integer(*find(*fields, key), 1, kMaxImageSide);
        if (!v)
            return v.status();
        *out = static_cast<int>(*v);
    }
    for (auto [key, out] : {std::pair{"fx", &model.fx}, std::pair{"fy", &model.fy}}) {
        auto v = r.number(*find(*fields, key), 0, 1e6, true);
        if (!v)
            return v.status();
        *out = *v;
    }
    for (auto [key, out] : {std::pair{"cx", &model.cx}, std::pair{"cy", &model.cy}}) {
        auto v = r.number(*find(*fields, key), -1e6, 1e6, false);
        if (!v)
            return v.status();
        *out = *v;
    }
    if (const Item* d = find(*fields, "distortion")) {
        const size_t n = d->node.IsSequence() ? d->node.size() : 0;
        const size_t spline_n =
            2 * static_cast<size_t>(model.spline.nx) * static_cast<size_t>(model.spline.ny);
        bool count_ok = false;
        std::string wanted;
        switch (model.lens) {
            case LensModel::kPinhole:
                count_ok = n == 0 || n == 4 || n == 5 || n == 8;
                wanted = "a list of 4, 5 or 8 coefficients k1 k2 p1 p2 [k3 [k4 k5 k6]]";
                break;
            case LensModel::kFisheye:
                count_ok = n == 0 || n == 4;
                wanted = "a list of 4 coefficients k1 k2 k3 k4";
                break;
            case LensModel::kStereographic:
                count_ok = n == 0;
                wanted = "an empty list (stereographic has no distortion)";
                break;
            case LensModel::kSplinedStereographic:
                count_ok = n == spline_n;
                wanted = "a list of 2*Nx*Ny = " + std::to_string(spline_n) +
                         " spline control-point values";
                break;
        }
        if (!d->node.IsSequence() || !count_ok)
            return r.expected(*d, wanted);
        auto elements = r.readList(*d, 0, std::max<size_t>(8, spline_n), "a list of coefficients");
        if (!elements)
            return elements.status();
        for (const Item& e : *elements) {
            auto v = r.number(e, -1e6, 1e6, false);
            if (!v)
                return v.status();
            model.distortion.push_back(*v);
        }
    }
    return model;
}

std::string cameraModelYaml(const CameraModel& m) {
    std::string distortion = "[";
    for (size_t i = 0; i < m.distortion.size(); ++i)
        distortion += (i ? ", " : "") + yaml::shortest(m.distortion[i]);
    distortion += "]";
    return "{lens: " + m.lensName() + ", width: " + std::to_string(m.width) +
           ", height: " + std::to_string(m.height) + ", fx: " + yaml::shortest(m.fx) +
           ", fy: " + yaml::shortest(m.fy) + ", cx: " + yaml::shortest(m.cx) +
           ", cy: " + yaml::shortest(m.cy) + ", distortion: " + distortion + "}";
}

}  // namespace mixray::calibration
