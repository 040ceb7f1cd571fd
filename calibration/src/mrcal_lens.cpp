// The mapping between CameraModel and mrcal's lens models and intrinsics vectors.
#include "mrcal_lens.h"

#include <cstring>

namespace mixray::calibration::detail {

mrcal_lensmodel_t makeMrcalLensModel(mrcal_lensmodel_type_t type) {
    mrcal_lensmodel_t lens;
    std::memset(&lens, 0, sizeof lens);
    lens.type = type;
    return lens;
}

std::optional<mrcal_lensmodel_t> mrcalLensModel(const CameraModel& model) {
    switch (model.lens) {
        case LensModel::kPinhole:
            switch (model.distortion.size()) {
                case 0:
                    return makeMrcalLensModel(MRCAL_LENSMODEL_PINHOLE);
                case 4:
                    return makeMrcalLensModel(MRCAL_LENSMODEL_OPENCV4);
                case 5:
                    return makeMrcalLensModel(MRCAL_LENSMODEL_OPENCV5);
                case 8:
                    return makeMrcalLensModel(MRCAL_LENSMODEL_OPENCV8);
                default:
                    return std::nullopt;
            }
        case LensModel::kFisheye:
            return std::nullopt;
        case LensModel::kStereographic:
            return makeMrcalLensModel(MRCAL_LENSMODEL_STEREOGRAPHIC);
        case LensModel::kSplinedStereographic: {
            const SplineConfig& c = model.spline;
            auto in16 = [](int v) { return v > 0 && v <= 65535; };
            if (!in16(c.order) || !in16(c.nx) || !in16(c.ny) || !in16(c.fov_x_deg))
                return std::nullopt;
            mrcal_lensmodel_t lens = makeMrcalLensModel(MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC);
            auto& config = lens.LENSMODEL_SPLINED_STEREOGRAPHIC__config;
            config.order = static_cast<uint16_t>(c.order);
            config.Nx = static_cast<uint16_t>(c.nx);
            config.Ny = static_cast<uint16_t>(c.ny);
            config.fov_x_deg = static_cast<uint16_t>(c.fov_x_deg);
            return lens;
        }
    }
    return std::nullopt;
}

std::vector<double> mrcalIntrinsics(const CameraModel& model) {
    std::vector<double> intrinsics = {model.fx, model.fy, model.cx, model.cy};
    intrinsics.insert(intrinsics.end(), model.distortion.begin(), model.distortion.end());
    return intrinsics;
}

std::optional<CameraModel> cameraModelFromMrcal(const mrcal_lensmodel_t& lens,
                                                const double* intrinsics, int width, int height) {
    CameraModel model = CameraModel::pinhole(width, height, intrinsics[0], intrinsics[1],
                                             intrinsics[2], intrinsics[3]);
    switch (lens.type) {
        case MRCAL_LENSMODEL_PINHOLE:
            break;
        case MRCAL_LENSMODEL_OPENCV4:
        case MRCAL_LENSMODEL_OPENCV5:
        case MRCAL_LENSMODEL_OPENCV8:
            break;
        case MRCAL_LENSMODEL_STEREOGRAPHIC:
            model.lens = LensModel::kStereographic;
            break;
        case MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC: {
            const auto& config = lens.LENSMODEL_SPLINED_STEREOGRAPHIC__config;
            model.lens = LensModel::kSplinedStereographic;
            model.spline = {config.order, config.Nx, config.Ny, config.fov_x_deg};
            break;
        }
        default:
            return std::nullopt;
    }
    const int n = mrcal_lensmodel_num_params(&lens);
    model.distortion.assign(intrinsics + 4, intrinsics + n);
    return model;
}

std::string mrcalLensModelName(const mrcal_lensmodel_t& lens) {
    char name[256] = {};
    if (!mrcal_lensmodel_name(name, sizeof name, &lens))
        return "LENSMODEL_INVALID";
    return name;
}

}  // namespace mixray::calibration::detail
