// Lens models from published calibrations, for the tests that check projections, costs and
// solves on realistic lenses.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"

namespace mixray::calibration::test {

struct NamedModel {
    std::string name;
    CameraModel model;
};

CameraModel withDistortion(CameraModel model, std::vector<double> distortion);
CameraModel fisheye(int width, int height, double fx, double fy, double cx, double cy,
                    std::vector<double> k);

// Published calibrations (numbers from /work/shared/data/MANIFEST.md and the files it names):
// pinhole with OpenCV's distortion, and Kannala–Brandt fish-eye.
std::vector<NamedModel> pinholeModels();
std::vector<NamedModel> fisheyeModels();
// The model of either list named `name`; std::out_of_range for a name neither has.
CameraModel publishedModel(std::string_view name);

}  // namespace mixray::calibration::test
