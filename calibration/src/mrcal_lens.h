// mrcal's C API for the calibration sources: its header (no extern "C", GNU C constructs), and
// the mapping between CameraModel and mrcal's lens models and intrinsics vectors.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "mixray/calibration/camera_model.h"

// mrcal.h is C with anonymous structs, empty structs and a flexible array member: valid GNU C,
// pedantic errors in C++.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpedantic"
extern "C" {
#include <mrcal.h>
}
#pragma GCC diagnostic pop

namespace mixray::calibration::detail {

// mrcal's model for `model`: pinhole without distortion → LENSMODEL_PINHOLE, with 4/5/8
// coefficients → LENSMODEL_OPENCV4/5/8, kStereographic → LENSMODEL_STEREOGRAPHIC,
// kSplinedStereographic → its configured LENSMODEL_SPLINED_STEREOGRAPHIC; nullopt for
// Kannala–Brandt (mrcal has no such model) and for invalid distortion counts.
std::optional<mrcal_lensmodel_t> mrcalLensModel(const CameraModel& model);

// mrcal's intrinsics vector: fx fy cx cy, then the distortion (same order in both).
std::vector<double> mrcalIntrinsics(const CameraModel& model);

// The CameraModel of a mrcal model and intrinsics vector; nullopt for mrcal models mixray has
// no lens for (CAHVOR, LONLAT, OPENCV12, ...).
std::optional<CameraModel> cameraModelFromMrcal(const mrcal_lensmodel_t& lens,
                                                const double* intrinsics, int width, int height);

// mrcal's configured name ("LENSMODEL_OPENCV8").
std::string mrcalLensModelName(const mrcal_lensmodel_t& lens);

// mrcal_lensmodel_t with the given type and a zeroed configuration (its union cannot be
// brace-initialised in C++).
mrcal_lensmodel_t makeMrcalLensModel(mrcal_lensmodel_type_t type);

}  // namespace mixray::calibration::detail
