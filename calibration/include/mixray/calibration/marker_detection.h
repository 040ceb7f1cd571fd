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
#include "mixray/calibration/marker_dictionary.h"
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
    // quad_decimate: find quads in an image decimated this many times ([1, 8]; faster, fewer
    // small tags; the decode still reads the full image). refine_edges: move each quad's edges
    // to the strongest gradient nearby. quad_sigma: Gaussian blur (σ px, [0, 10]) of the image
    // the quads are segmented in; negative ([-10, 0)) sharpens. libapriltag's defaults.
    float apriltag_quad_decimate = 1.0f;
    bool apriltag_refine_edges = true;
    float apriltag_quad_sigma = 0.0f;
    // libapriltag's worker threads (nthreads), [1, 256].
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

// The same for the markers of a custom ArUco dictionary (marker_dictionary.h), detected with
// OpenCV's aruco; detections carry dictionary.name. kInvalidArgument when it fails validate().
Result<std::vector<MarkerDetection>> detectMarkers(const ImageView& image,
                                                   const MarkerDictionary& dictionary,
                                                   const DetectorOptions& options = {},
                                                   const CameraModel* camera = nullptr);

// Bits of an OpenCV dictionary's markers as a MarkerDictionary (named as the dictionary), so
// that predefined and custom dictionaries can be handled alike. kInvalidArgument for a name
// openCvDictionaryId() does not know.
Result<MarkerDictionary> openCvDictionary(std::string_view name);

// A ChArUco diamond: four markers of one dictionary around the centre square of a 3x3
// chessboard (OpenCV's drawCharucoDiamond). `ids` as OpenCV's detectCharucoDiamond gives them
// (the top marker first, then clockwise: left, right, bottom as drawn); `corners` are the four
// inner chessboard corners of the diamond in docs/conventions.md pixels, in OpenCV's order.
struct DiamondDetection {
    std::string dictionary;
    std::array<int, 4> ids{};
    std::array<Eigen::Vector2d, 4> corners;
};

// The diamonds made of `markers` (found by detectMarkers in the same 8-bit image with
// `dictionary`), whose squares are `square_to_marker` times the side of their markers (> 1;
// OpenCV's squareMarkerLengthRate): OpenCV's detectCharucoDiamond. Corners are interpolated
// as for ChArUco boards. kInvalidArgument for a bad ratio, dictionary or image. Reentrant.
Result<std::vector<DiamondDetection>> detectDiamonds(const ImageView& image,
                                                     const MarkerDictionary& dictionary,
                                                     double square_to_marker,
                                                     const std::vector<MarkerDetection>& markers);

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
