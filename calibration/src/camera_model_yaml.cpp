// Camera models in mixray's YAML files.
#include "mixray/calibration/camera_model_yaml.h"

#include <array>
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
        if (!parsed)
            return r.expected(*lens, "pinhole or fisheye");
        model.lens = *parsed;
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
        const bool fisheye = model.lens == LensModel::kFisheye;
        const size_t n = d->node.IsSequence() ? d->node.size() : 0;
        const bool count_ok = fisheye ? (n == 0 || n == 4) : (n == 0 || n == 4 || n == 5 || n == 8);
        if (!d->node.IsSequence() || !count_ok) {
            return r.expected(*d, fisheye ? "a list of 4 coefficients k1 k2 k3 k4"
                                          : "a list of 4, 5 or 8 coefficients k1 k2 p1 p2 "
                                            "[k3 [k4 k5 k6]]");
        }
        auto elements = r.readList(*d, 0, 8, "a list of coefficients");
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
    return "{lens: " + std::string(toString(m.lens)) + ", width: " + std::to_string(m.width) +
           ", height: " + std::to_string(m.height) + ", fx: " + yaml::shortest(m.fx) +
           ", fy: " + yaml::shortest(m.fy) + ", cx: " + yaml::shortest(m.cx) +
           ", cy: " + yaml::shortest(m.cy) + ", distortion: " + distortion + "}";
}

}  // namespace mixray::calibration
