// mrcal's .cameramodel files: read by mrcal_read_cameramodel_file, written in its format at full
// precision and checked by mrcal's reader.
#include "mrcal_format.h"

#include <cstdio>
#include <fstream>
#include <memory>
#include <system_error>

#include "mrcal_lens.h"

namespace mixray::calibration::detail {
namespace {

Eigen::Isometry3d isometryFromRt(const double rt[6]) {
    const Eigen::Vector3d r(rt[0], rt[1], rt[2]);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const double angle = r.norm();
    if (angle > 0)
        T.linear() = Eigen::AngleAxisd(angle, r / angle).toRotationMatrix();
    T.translation() = Eigen::Vector3d(rt[3], rt[4], rt[5]);
    return T;
}

void rtFromIsometry(const Eigen::Isometry3d& T, double rt[6]) {
    const Eigen::AngleAxisd aa(T.rotation());
    const Eigen::Vector3d r = aa.axis() * aa.angle();
    for (int k = 0; k < 3; ++k) {
        rt[k] = r[k];
        rt[3 + k] = T.translation()[k];
    }
}

struct CameramodelDeleter {
    void operator()(mrcal_cameramodel_t* model) const { mrcal_free_cameramodel(&model); }
};

}  // namespace

Result<CalibratedCamera> readMrcalCameramodel(const std::filesystem::path& path) {
    const std::string where = path.string() + ": ";
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        return Status(ErrorCode::kNotFound, where + "no such file");
    const std::unique_ptr<mrcal_cameramodel_t, CameramodelDeleter> model(
        mrcal_read_cameramodel_file(path.c_str()));
    if (!model) {
        return Status(ErrorCode::kCorruptData,
                      where +
                          "mrcal_read_cameramodel_file could not read it as a .cameramodel "
                          "(mrcal names the cause on stderr)");
    }
    const int width = static_cast<int>(model->imagersize[0]);
    const int height = static_cast<int>(model->imagersize[1]);
    const std::optional<CameraModel> camera_model =
        cameraModelFromMrcal(model->lensmodel, model->intrinsics, width, height);
    if (!camera_model) {
        return Status(ErrorCode::kUnsupported,
                      where + "mixray has no lens for mrcal's " +
                          mrcalLensModelName(model->lensmodel) +
                          " (it reads LENSMODEL_PINHOLE, OPENCV4/5/8, STEREOGRAPHIC and "
                          "SPLINED_STEREOGRAPHIC)");
    }
    if (Status valid = camera_model->validate(); !valid.isOk())
        return Status(ErrorCode::kCorruptData, where + valid.message());
    CalibratedCamera camera;
    camera.name = path.stem().string();
    camera.model = *camera_model;
    // mrcal stores rt_cam_ref, mapping the reference frame into the camera.
    camera.parent = "reference";
    camera.T_parent_camera = isometryFromRt(model->rt_cam_ref).inverse();
    return camera;
}

Status writeMrcalCameramodel(const std::filesystem::path& path, const CalibratedCamera& camera) {
    const std::string where = path.string() + ": ";
    if (Status valid = camera.model.validate(); !valid.isOk())
        return Status(ErrorCode::kInvalidArgument, where + valid.message());
    const std::optional<mrcal_lensmodel_t> lens = mrcalLensModel(camera.model);
    if (!lens) {
        return Status(ErrorCode::kInvalidArgument,
                      where + "mrcal has no model for camera " + camera.name + "'s " +
                          camera.model.lensName() + " lens (Kannala–Brandt fish-eye)");
    }
    // mrcal 2.2's mrcal_write_cameramodel_file prints every number with "%f", six decimals,
    // which moves a splined model's control points by up to 5e-7 (~1e-3 px on a 1700 px lens)
    // and rounds small OpenCV coefficients away. The file is mrcal's format written at full
    // precision instead, and read back through mrcal's own reader before it is accepted.
    double rt[6];
    rtFromIsometry(camera.T_parent_camera.inverse(), rt);
    auto numbers = [](const double* values, size_t count) {
        std::string list;
        char number[32];
        for (size_t k = 0; k < count; ++k) {
            std::snprintf(number, sizeof number, "%.17g", values[k]);
            list += (k ? ", " : " ") + std::string(number);
        }
        return list + " ";
    };
    const std::vector<double> intrinsics = mrcalIntrinsics(camera.model);
    std::string text = "# " + camera.name + ", written by mixray\n{\n";
    text += "    'lensmodel':  '" + mrcalLensModelName(*lens) + "',\n\n";
    text += "    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....\n";
    text += "    'intrinsics': [" + numbers(intrinsics.data(), intrinsics.size()) + "],\n\n";
    text += "    # extrinsics are rt_fromref\n";
    text += "    'extrinsics': [" + numbers(rt, 6) + "],\n\n";
    text += "    'imagersize': [ " + std::to_string(camera.model.width) + ", " +
            std::to_string(camera.model.height) + " ]\n}\n";
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out << text;
        out.close();
        if (!out)
            return Status(ErrorCode::kIoError, where + "cannot write the file");
    }
    const std::unique_ptr<mrcal_cameramodel_t, CameramodelDeleter> check(
        mrcal_read_cameramodel_string(text.c_str(), static_cast<int>(text.size())));
    if (!check || check->lensmodel.type != lens->type)
        return Status(ErrorCode::kInternal, where + "mrcal cannot read back what was written");
    return Status::ok();
}

}  // namespace mixray::calibration::detail
