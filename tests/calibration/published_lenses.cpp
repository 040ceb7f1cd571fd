// The published lens models the calibration tests share (published_lenses.h).
#include "published_lenses.h"

#include <stdexcept>
#include <utility>

namespace mixray::calibration::test {

CameraModel withDistortion(CameraModel model, std::vector<double> distortion) {
    model.distortion = std::move(distortion);
    return model;
}

CameraModel fisheye(int width, int height, double fx, double fy, double cx, double cy,
                    std::vector<double> k) {
    CameraModel model = CameraModel::pinhole(width, height, fx, fy, cx, cy);
    model.lens = LensModel::kFisheye;
    model.distortion = std::move(k);
    return model;
}

std::vector<NamedModel> pinholeModels() {
    return {
        {"ideal", CameraModel::pinhole(640, 480, 525, 525, 319.5, 239.5)},
        // OpenCV samples/data/left_intrinsics.yml (5 coefficients).
        {"opencv_left",
         withDistortion(
             CameraModel::pinhole(640, 480, 535.91573396, 535.91573396, 342.28315473, 235.57082910),
             {-0.26637261, -0.03858890, 0.00178319, -0.00028122, 0.23839153})},
        // TUM RGB-D freiburg1 (ORB_SLAM2 TUM1.yaml).
        {"tum_fr1", withDistortion(CameraModel::pinhole(640, 480, 517.306408, 516.469215,
                                                        318.643040, 255.313989),
                                   {0.262383, -0.953104, -0.005358, 0.002628, 1.163314})},
        // ArUco tutorial camera (4 usable coefficients; k3 = 0 dropped).
        {"aruco_tutorial",
         withDistortion(CameraModel::pinhole(640, 480, 628.158, 628.156, 324.099, 260.908),
                        {0.0995485, -0.206384, 0.00754589, 0.00336531})},
        // mrcal test/data/cam0.opencv8.cameramodel (rational model, 8 coefficients).
        {"mrcal_cam0_opencv8",
         withDistortion(
             CameraModel::pinhole(4000, 2200, 1761.181055, 1761.250444, 1965.706996, 1087.518797),
             {-0.01266096516, 0.03590794372, -0.0002547045941, 0.0005275929652, 0.01968883397,
              0.01482863541, -0.0562239888, 0.0500223357})},
    };
}

std::vector<NamedModel> fisheyeModels() {
    return {
        // OpenCV's own fish-eye test camera (modules/calib3d/test/test_fisheye.cpp), 1280x800.
        {"opencv_fisheye_test",
         fisheye(1280, 800, 558.478087865323, 560.506767351568, 620.458515360843, 381.939424848348,
                 {-0.0014613319981768, -0.00329861110580401, 0.00605760088590183,
                  -0.00374209380722371})},
        // A nearly equidistant wide lens: the image corners are ~97° off axis (z < 0).
        {"wide_equidistant",
         fisheye(1024, 768, 380, 380, 511.5, 383.5, {0.01, -0.002, 0.0005, -0.0001})},
    };
}

CameraModel publishedModel(std::string_view name) {
    for (const auto& list : {pinholeModels(), fisheyeModels()}) {
        for (const NamedModel& named : list) {
            if (named.name == name)
                return named.model;
        }
    }
    throw std::out_of_range("no published lens model named " + std::string(name));
}

}  // namespace mixray::calibration::test
