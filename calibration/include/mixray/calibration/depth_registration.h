// Kinect depth↔colour: the depth (IR) camera's geometry, its pose in the colour camera, and the
// correction of its depth readings; registration of a depth image into the colour camera; the
// depth-correction fit and the whole Kinect calibration; factory calibrations (Azure Kinect).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/calibrate.h"
#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// Corrects a raw depth reading z (metres, along the depth camera's axis) at pixel (u, v):
// z' = scale · z + offset_m, then, when `distortion` is present, Herrera et al.'s spatially
// varying term (Herrera, Kannala, Heikkilä, "Joint depth and color camera calibration with
// distortion correction", TPAMI 2012): z'' = z' + D(u, v) · exp(α0 − α1 · z'), D sampled on
// the depth image's pixel grid (row-major, width × height of the depth camera). Plain value.
struct DepthCorrection {
    double scale = 1;
    double offset_m = 0;
    std::vector<float> distortion;  // empty: no spatial term
    double alpha0 = 0, alpha1 = 0;

    bool isIdentity() const { return scale == 1 && offset_m == 0 && distortion.empty(); }
};

// The corrected depth (metres) of a raw reading `z_m` at depth pixel (x, y) of an image
// `width` pixels wide (the distortion map's row length). Reentrant.
double correctedDepth(const DepthCorrection& correction, double z_m, int x, int y, int width);

// How a depth image maps into the colour camera. Plain value.
struct DepthRegistration {
    CameraModel depth;  // the IR camera the depth image is aligned with
    CameraModel color;
    Eigen::Isometry3d T_color_depth = Eigen::Isometry3d::Identity();
    DepthCorrection correction;

    // kInvalidArgument naming the field: both models valid, a rigid finite pose, a distortion
    // map of depth.width × depth.height when present, finite correction terms.
    Status validate() const;
    // Whether the depth image is already the colour camera's (same model, identity pose,
    // no correction): registration would only copy it.
    bool isIdentity() const;
};

struct RegistrationOptions {
    // Neighbouring depth samples whose depths differ by more than this fraction of the nearer
    // one lie on different surfaces: no surface is drawn between them (default 4 %: a Kinect's
    // depth step at 4 m is ~1 %, steep surfaces change by < 1 % per pixel at 1 m).
    double max_jump_rel = 0.04;
};

// Maps depth images into the colour camera. Each depth pixel is drawn as its footprint, the
// quadrilateral of its pixel corners (u ± ½, v ± ½) lifted to 3-D, transformed by
// T_color_depth, projected through the colour model and rasterised (a fan of four triangles
// from the sample's own point, depth interpolated in 1/z, exact for planes) into a z-buffer
// where the nearest surface wins. A
// corner shared by neighbouring samples of one surface (depths within max_jump_rel) is lifted
// once at their mean inverse depth, so footprints of a continuous surface meet edge to edge
// and leave no cracks however the colour camera sees them; at a depth discontinuity each side
// keeps its own corners, so nothing is stretched across the gap and the silhouette lies half a
// depth pixel beyond the last sample (within ½ depth pixel of the true edge). Colour pixels no
// footprint covers (disoccluded background, no reading) are 0. The depth correction is applied
// to every reading first. Scratch buffers are kept: frames of one size allocate nothing after
// the first. Thread-bound.
class Registrar {
public:
    // kInvalidArgument when the registration does not validate.
    static Result<Registrar> create(DepthRegistration registration,
                                    RegistrationOptions options = {});

    // `depth_mm`: depth16 of depth.width × depth.height (0: no reading). `out_mm`: depth16 of
    // color.width × color.height, the caller's memory, overwritten: colour-camera z in mm.
    // kInvalidArgument on wrong formats or sizes.
    Status registerDepth(const ImageView& depth_mm, const MutableImageView& out_mm);

    // The last registerDepth()'s z-buffer before rounding to mm: colour-camera z in metres per
    // colour pixel (row-major), 0 where nothing was drawn.
    const std::vector<float>& colorDepth() const { return color_z_; }
    const DepthRegistration& registration() const { return registration_; }

private:
    Registrar(DepthRegistration registration, RegistrationOptions options);
    struct Corner {
        float x = 0, y = 0;  // colour pixel
        float inv_z = 0;     // 1 / colour-camera z; 0: no corner
        uint8_t state = 0;   // kUnused, kShared or kSplit
    };
    bool lift(int cx, int cy, float inv_z_depth, Corner& out) const;
    bool liftPoint(int x, int y, float z, Corner& out) const;
    bool project(const Eigen::Vector3d& p_depth, Corner& out) const;
    void drawFootprint(const Corner& centre, const Corner* c[4]);
    void drawTriangle(const Corner& a, const Corner& b, const Corner& d, int width, int height);

    DepthRegistration registration_;
    RegistrationOptions options_;
    std::vector<Eigen::Vector2f> corner_rays_;  // (W+1)×(H+1): normalised x/z, y/z; NaN: none
    std::vector<Eigen::Vector2f> centre_rays_;  // W×H, the same through pixel centres
    std::vector<float> z_;                      // corrected depth per depth pixel, metres
    std::vector<Corner> corners_;               // (W+1)×(H+1)
    std::vector<float> color_z_;                // the z-buffer, colour pixels
};

// Registers one depth image (Registrar::create + registerDepth into a new image).
Result<Image> registerDepth(const DepthRegistration& registration, const ImageView& depth_mm,
                            const RegistrationOptions& options = {});

// ---- the depth-correction fit ----

// One IR view's board pose and the depth image taken with it (aligned with the IR camera).
struct DepthPlaneView {
    Eigen::Isometry3d T_ir_board = Eigen::Isometry3d::Identity();
    ImageView depth_mm;  // depth16; not owned
};

struct DepthCorrectionOptions {
    // Also fit Herrera's per-pixel term D(u, v) · exp(α0 − α1 z'); else scale and offset only.
    bool per_pixel = false;
    // D is solved on a grid of nodes this many depth pixels apart (bilinear between them), so
    // each node pools a few hundred readings and pixels between boards get a smooth value.
    int grid_step_px = 16;
    // Weight of the squared differences of neighbouring grid nodes (a membrane), relative to
    // the average number of readings per node: smooths D and carries it into pixels no board
    // covered. Larger: smoother D, smaller: D follows the noise.
    double smoothness = 3.0;
    // Weight pulling D towards 0, relative as above (small: keeps the system regular where no
    // data pins D).
    double ridge = 0.01;
    // Depth readings this close to the board's outline (metres, in the board plane) are left
    // out: mixed pixels at the edge.
    double board_margin_m = 0.01;
    // Readings farther than this from the board plane after a first fit are dropped (hands,
    // the stand, multipath), and the fit is repeated.
    double max_residual_m = 0.03;
    // α1's search interval (1/m); α0 is then set so that D is the correction at the median
    // depth of the data (α0 = α1 · z_median), which makes D's scale interpretable.
    double max_alpha1 = 3.0;
};

struct DepthCorrectionFit {
    DepthCorrection correction;
    int samples = 0;            // depth readings used
    double rms_before_m = 0;    // readings vs the board planes, uncorrected
    double rms_after_m = 0;     // after the correction
    double median_depth_m = 0;  // of the readings used
};

// Fits the correction that maps the depth readings inside each board's outline onto the board
// plane seen by the IR camera (z along the pixel's ray): scale and offset by linear least
// squares, then optionally D on a grid (regularised least squares with the smoothness
// membrane, jointly with scale and offset) for each α1 of a golden-section search, the α1 with
// the least residual winning. The outline is the bounding rectangle of `board_points` (the
// target's points, CalibrationTarget::points(), board frame, z = 0) less the margin.
// kInvalidArgument naming the cause: no views, depth images of another size than `ir`, fewer
// than 100 usable readings, readings spanning < 5 cm of depth (scale not observable).
Result<DepthCorrectionFit> fitDepthCorrection(const CameraModel& ir,
                                              const std::vector<Eigen::Vector3d>& board_points,
                                              const std::vector<DepthPlaneView>& views,
                                              const DepthCorrectionOptions& options = {});

// ---- the whole Kinect calibration ----

// A depth image taken at the same instant as the IR view with this key.
struct KeyedDepth {
    int64_t key = 0;
    ImageView depth_mm;  // depth16 aligned with the IR camera; not owned
};

struct KinectCalibrationOptions {
    RigOptions rig;  // both cameras' own solves (rig.camera) and the joint one
    DepthCorrectionOptions depth;
};

struct KinectCalibration {
    RigCalibration rig;              // cameras: [colour, IR]; reference: the colour camera
    DepthRegistration registration;  // IR model, colour model, T_color_ir, correction
    DepthCorrectionFit depth_fit;
};

// IR intrinsics and colour intrinsics (their own solves), T_color_ir (calibrateRig of the two,
// the colour camera the reference), then kinectCalibrationFromRig(). Errors from the solves,
// with the stage named.
Result<KinectCalibration> calibrateKinect(const CameraViews& color, const CameraViews& ir,
                                          const std::vector<KeyedDepth>& depth,
                                          const KinectCalibrationOptions& options = {});

namespace detail {
// calibrateKinect() with the rig solver and the target's validate() and points() passed in.
Result<KinectCalibration> calibrateKinectWith(
    const CameraViews& color, const CameraViews& ir, const std::vector<KeyedDepth>& depth,
    const KinectCalibrationOptions& options,
    Result<RigCalibration> (*solve_rig)(const std::vector<CameraViews>&, const RigOptions&),
    Status (*validate_target)(const CalibrationTarget&),
    std::vector<Eigen::Vector3d> (*target_points)(const CalibrationTarget&));
}  // namespace detail

// The depth half of calibrateKinect() for a rig already solved (cameras named `color_camera`
// and ir.camera among rig.cameras, poses in rig.reference = the colour camera's frame): the
// IR views' board poses (rig's IR CameraCalibration::views) with the depth images of the same
// keys fit the correction, and the registration is assembled. `board_points`: the target's
// points (CalibrationTarget::points()). kInvalidArgument naming the cause: a camera missing
// from the rig, a rig whose reference is not the colour camera, no depth image at the key of
// a used IR view.
Result<KinectCalibration> kinectCalibrationFromRig(const RigCalibration& rig,
                                                   std::string_view color_camera,
                                                   const CameraViews& ir,
                                                   const std::vector<KeyedDepth>& depth,
                                                   const std::vector<Eigen::Vector3d>& board_points,
                                                   const DepthCorrectionOptions& options = {});

// ---- factory calibrations ----

// The Azure Kinect factory calibration (the device's calibration.json, attached to its MKV
// recordings as "calibration.json"), for one depth mode and colour resolution.
struct AzureKinectCalibration {
    DepthRegistration registration;  // depth: the depth/IR camera at the mode's resolution
    // The radius (normalised image coordinates, x/z and y/z) within which the factory fit is
    // valid; k4a projects nothing beyond it. 0 where the file marks it invalid.
    double depth_metric_radius = 0;
    double color_metric_radius = 0;
    std::string serial;
};

// `json`: the file's text. `depth_mode`: "NFOV_UNBINNED", "NFOV_2X2BINNED", "WFOV_UNBINNED",
// "WFOV_2X2BINNED" or "PASSIVE_IR"; `color_resolution`: "720P", "1080P", "1440P", "1536P",
// "2160P" or "3072P" (the K4A_DEPTH_MODE / K4A_COLOR_RESOLUTION tags of a recording, "MJPG_720P"
// accepted). Follows the Azure Kinect SDK (transformation_get_mode_specific_camera_calibration):
// intrinsics are stored divided by the sensor's size with (0,0) at the top-left pixel's corner,
// scaled to the mode's binned sensor, cropped, then shifted by −½ px to mixray's pixel-centre
// convention; Brown–Conrady is OpenCV's 8-coefficient rational model with the file's order
// cx cy fx fy k1..k6 codx cody p2 p1; each camera's Rt maps the depth camera's frame into its
// own (rotation row-major, translation in metres). kCorruptData naming the field (also for a
// field of another type); kUnsupported for a lens model other than Brown–Conrady or a centre of
// distortion off the principal point.
Result<AzureKinectCalibration> parseAzureKinectCalibration(std::string_view json,
                                                           std::string_view depth_mode,
                                                           std::string_view color_resolution);

// How far an own calibration is from another (a factory one): intrinsics, projection of a grid
// of points through both, and the pose.
struct CameraComparison {
    std::string name;
    double dfx = 0, dfy = 0, dcx = 0, dcy = 0;  // own − reference, pixels
    // A grid over the image unprojected through the reference at `distance_m` and projected
    // through the own model: the pixel displacement, RMS and largest.
    double grid_rms_px = 0, grid_max_px = 0;
};

struct RegistrationComparison {
    CameraComparison depth, color;
    double rotation_deg = 0;   // angle of T_own⁻¹ · T_reference's rotation
    double translation_m = 0;  // |t_own − t_reference|
    // Depth pixels mapped into the colour image at `distance_m` through both registrations:
    // how far apart they land (RMS, largest), in colour pixels.
    double registration_rms_px = 0, registration_max_px = 0;

    std::string report() const;  // a few lines of text for the calibration report
};

// kInvalidArgument when the image sizes differ.
Result<RegistrationComparison> compareRegistrations(const DepthRegistration& own,
                                                    const DepthRegistration& reference,
                                                    double distance_m = 1.5, double step_px = 16);

}  // namespace mixray::calibration
