// Fiducial marker detection with subpixel corners in mixray's pixel convention: ArUco through
// OpenCV contrib, AprilTag through libapriltag, corners refined by fitting the marker's outer
// edges, and ChArUco chessboard corners interpolated from the markers. The one place of this
// glue: calibration's targets and tracking's marker tracker both use it.
#pragma once

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// docs/conventions.md puts pixel (0,0) at the centre of the top-left pixel. Measured on
// antialiased synthetic renders (tests/tracking/marker_detect_test.cpp,
// tests/calibration/detect_test.cpp): OpenCV's aruco corners already follow it (mean offset
// < 0.05 px), libapriltag's are 0.5 px larger in x and y (it puts (0,0) at the top-left pixel's
// corner), and interpolateCornersCharuco's ChArUco corners are 0.5 px larger too. Every corner
// this header returns has the offset taken off.
inline constexpr double kOpenCvArucoOffsetPx = 0.0;
inline constexpr double kAprilTagOffsetPx = 0.5;
inline constexpr double kCharucoOffsetPx = 0.5;

// One detected marker. Corners follow docs/conventions.md in OpenCV's order: top-left,
// top-right, bottom-right, bottom-left of the upright marker as OpenCV draws it (for
// libapriltag's families: as OpenCV draws the same tag in DICT_APRILTAG_*; libapriltag's
// p[0..3] are corners[1], [0], [3], [2]). Plain value.
struct MarkerDetection {
    std::string dictionary;  // "DICT_6X6_250", "apriltag:tag36h11"
    int id = 0;
    std::array<Eigen::Vector2d, 4> corners;
};

// How markers are found. Every field has a working default.
struct DetectorOptions {
    // Corner refinement after detection: OpenCV's subpixel refinement alone is off by up to
    // 0.9 px on small markers (gamma pulls it inwards); this fits the marker's outer edges in
    // linear intensity and crosses the lines (≤ 0.13 px on synthetic markers; docs/tracking.md).
    // Off: OpenCV's subpixel corners, or libapriltag's.
    bool refine_corners = true;
    // AprilTag (libapriltag) settings, as its detector names them.
    float apriltag_quad_decimate = 1.0f;
    bool apriltag_refine_edges = true;
    int threads = 1;

    Status validate() const;
};

// Dictionary names: OpenCV's ("DICT_4X4_50" ... "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_36h11")
// and libapriltag's families ("apriltag:tag36h11", "apriltag:tag25h9", ...), plus
// "apriltag:tag36h11b2": tag36h11 with a black border two cells wide, as Kalibr prints its
// AprilGrids.
bool isKnownDictionary(std::string_view name);

// The value of OpenCV's cv::aruco::PREDEFINED_DICTIONARY_NAME for one of its dictionary names;
// nullopt for libapriltag families and unknown names. (An int keeps OpenCV out of this header.)
std::optional<int> openCvDictionaryId(std::string_view name);

// Markers in an OpenCV dictionary (250 for DICT_6X6_250); 0 for other names.
int openCvDictionarySize(std::string_view name);

// Finds every marker of `dictionary` in an 8-bit image (kMono8, kRGB8 or kBGR8). With `camera`
// (not owned; its size must be the image's), the edge refinement fits the marker's edges as
// straight lines in undistorted coordinates (straight in the world, curved in the image).
// kInvalidArgument for an unknown dictionary, another pixel format or a bad option. Reentrant.
Result<std::vector<MarkerDetection>> detectMarkers(const ImageView& image,
                                                   std::string_view dictionary,
                                                   const DetectorOptions& options = {},
                                                   const CameraModel* camera = nullptr);

// An OpenCV CharucoBoard as printed: its markers numbered from `first_id`.
struct CharucoBoardSpec {
    int squares_x = 0, squares_y = 0;
    double square_m = 0, marker_m = 0;
    std::string dictionary = "DICT_6X6_250";  // an OpenCV dictionary name
    int first_id = 0;
};

// The board's chessboard corners (ids as OpenCV's CharucoBoard numbers them, = the ChArUco
// CalibrationTarget's point ids) interpolated from `markers` found in the same 8-bit image by
// detectMarkers (OpenCV's interpolateCornersCharuco: a local homography from the neighbouring
// markers, then cornerSubPix), in docs/conventions.md pixels. Fewer than two of the board's
// markers: no corners. kInvalidArgument for a bad board, dictionary or image. Reentrant.
Result<std::vector<Corner>> charucoCorners(const ImageView& image, const CharucoBoardSpec& board,
                                           const std::vector<MarkerDetection>& markers);

}  // namespace mixray::calibration
