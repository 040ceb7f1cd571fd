// Calibration targets and what a camera saw of them: the board geometry (chessboard, ChArUco,
// Kalibr's AprilGrid), and per-view corner observations, the common input of every solver and
// of the corners cache (corners_cache.h).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/result.h"

namespace mixray::calibration {

enum class TargetKind : uint8_t {
    kChessboard,  // inner corners of a black/white chessboard (OpenCV's order)
    kCharuco,     // OpenCV CharucoBoard: chessboard corners between ArUco markers
    kAprilGrid,   // Kalibr's AprilGrid: tag36h11 tags with black squares in the gaps
};

std::string_view toString(TargetKind kind);

// A planar target; every point has z = 0 in its frame. Chessboard and ChArUco use OpenCV's
// board frame: origin at the first corner (chessboard) or the board's top-left corner
// (ChArUco), +x along a row, +y down the columns, +z into the board. AprilGrid uses Kalibr's:
// origin at tag 0's lower-left corner, +x along the tag rows, +y up the print towards the
// higher tag rows, +z out of the print. Plain value.
struct CalibrationTarget {
    TargetKind kind = TargetKind::kChessboard;
    // kChessboard: inner corners per row (cols) and per column (rows), as OpenCV's patternSize;
    // kCharuco: squares in x (cols) and y (rows); kAprilGrid: tags in x (cols) and y (rows).
    int cols = 0, rows = 0;
    // kChessboard, kCharuco: the side of a square; kAprilGrid: the side of a tag's black border.
    double square_m = 0;
    double marker_m = 0;     // kCharuco: the side of each ArUco marker
    double tag_spacing = 0;  // kAprilGrid: gap between tags / tag side (Kalibr's tagSpacing)
    // kCharuco: an OpenCV dictionary name ("DICT_6X6_250"); kAprilGrid: "apriltag:tag36h11".
    std::string dictionary;

    // kInvalidArgument naming the field.
    Status validate() const;

    // Every point the target has, indexed by point id:
    // - kChessboard: id = row × cols + col at (col, row) × square_m (OpenCV's
    //   findChessboardCorners order);
    // - kCharuco: OpenCV's CharucoBoard corner ids, id = row × (cols − 1) + col at
    //   (col + 1, row + 1) × square_m (its chessboardCorners);
    // - kAprilGrid: Kalibr's GridCalibrationTargetAprilgrid grid of 2·cols × 2·rows points, id =
    //   r × 2·cols + c at x = ⌊c/2⌋·(1 + tag_spacing)·square_m + (c mod 2)·square_m, y likewise
    //   with r. Tag t (row-major from tag 0 at the origin: tag row ⌊t/cols⌋, column t mod cols)
    //   owns ids b, b + 1, b + 2·cols + 1, b + 2·cols with b = ⌊t/cols⌋·4·cols + (t mod cols)·2:
    //   its lower-left, lower-right, upper-right and upper-left corners as printed (libapriltag's
    //   p[0..3] for its tag image upright, Kalibr's p[0..3]).
    std::vector<Eigen::Vector3d> points() const;
    int pointCount() const;

    // The command-line and file form, parsed by parseTarget().
    std::string spec() const;
};

// "chessboard:COLSxROWS:SQUARE_M", "charuco:COLSxROWS:SQUARE_M:MARKER_M:DICT" or
// "aprilgrid:COLSxROWS:TAG_M:SPACING"; kInvalidArgument naming the part that is wrong.
Result<CalibrationTarget> parseTarget(std::string_view spec);

// One target point found in an image, in docs/conventions.md pixels (pixel (0,0) = the centre
// of the top-left pixel, as OpenCV and mrcal).
struct Corner {
    int id = 0;  // CalibrationTarget::points() index
    Eigen::Vector2d pixel{0, 0};
    // Relative confidence, 1 for full-resolution corners; mrcal's corner "level" l (found in an
    // image downsampled 2^l times) gives 0.5^l.
    double weight = 1;
};

// Why a view is left out of a solve.
enum class ViewRejection : uint8_t {
    kNone,           // used
    kUnreadable,     // the image could not be read
    kWrongSize,      // the image size differs from the camera's other images
    kNoTarget,       // no target found
    kPartialTarget,  // target found, but too few of its points (ChArUco/AprilGrid occluded)
    kBlurred,        // too little sharpness at the corners
    kTooOblique,     // the board's normal is too far from the viewing direction
    kOutliers,       // the solve rejected too many of its corners
    // A chessboard found as part of a larger one: its grid of X-junctions goes on beyond the
    // found corners (TargetView::seen_cols/seen_rows), so their ids are not the board's.
    kLargerBoard,
};

std::string_view toString(ViewRejection rejection);

// A square marker seen in a view besides the target (DetectionOptions::marker_dictionary, e.g.
// the world marker the environment camera is aligned to): its id and corners in ArUco's order,
// docs/conventions.md pixels.
struct SeenMarker {
    int id = 0;
    std::array<Eigen::Vector2d, 4> corners;
};

// One image of the target by one camera.
struct TargetView {
    // Where it came from: an image path, or "RECORDING#STREAM@FRAME".
    std::string source;
    // Views of different cameras with equal keys were taken at the same instant (the same board
    // pose); the rig solve links cameras through them. Image folders number their files in
    // order; recordings use the synchronised frame set's index.
    int64_t key = 0;
    std::vector<Corner> corners;
    ViewRejection rejection = ViewRejection::kNone;
    std::string why;  // the rejection's details, for reports ("sharpness 3.1 < 8")
    // kLargerBoard: the inner corners per row and column of the whole grid of X-junctions the
    // found corners are part of (the board's likely size); 0 otherwise.
    int seen_cols = 0, seen_rows = 0;
    // Markers of DetectionOptions::marker_dictionary in the image (also when the target was
    // not found), the target's own markers included when it uses that dictionary.
    std::vector<SeenMarker> markers;
};

// Everything one camera saw of one target.
struct CameraViews {
    std::string camera;  // stream name ("kinect/color") or a name of the user's choosing
    int width = 0, height = 0;
    CalibrationTarget target;
    std::vector<TargetView> views;

    // The views not rejected.
    std::vector<const TargetView*> usable() const;
};

}  // namespace mixray::calibration
