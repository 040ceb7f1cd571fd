// Markers, ChArUco diamonds and boards found in single images (`mixray detect`): what to look
// for, the detections as a plain struct, and their CSV, JSON and overlay-picture forms.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "mixray/calibration/detect.h"
#include "mixray/calibration/marker_detection.h"
#include "mixray/calibration/marker_dictionary.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// What to find in each image. At least one of the dictionaries or the board must be given.
struct ImageDetectionOptions {
    // Markers of an OpenCV or libapriltag dictionary (isKnownDictionary()); empty: none.
    std::string dictionary;
    // Markers of a custom ArUco dictionary (readMarkerDictionary()); in place of `dictionary`,
    // not beside it. Default: none.
    std::optional<MarkerDictionary> custom_dictionary;
    // ChArUco diamonds made of those markers: their square side / marker side (> 1, OpenCV's
    // squareMarkerLengthRate); 0 (default): no diamonds. Needs an ArUco dictionary (OpenCV's
    // DICT_* or custom), not a libapriltag family.
    double diamond_square_to_marker = 0;
    // A chessboard, ChArUco board or AprilGrid (parseTarget()); default none.
    std::optional<CalibrationTarget> board;
    // Marker detection for markers, diamonds and the board's markers: corner refinement and
    // libapriltag's decimation, edge refinement, blur and threads.
    DetectorOptions detector;

    // kInvalidArgument naming the option.
    Status validate() const;
};

// Sets the markers to find from a command-line word: an OpenCV or libapriltag dictionary name,
// else the path of an OpenCV dictionary file (readMarkerDictionary()). kInvalidArgument
// "unknown marker dictionary" for a word that is neither; the file's own error when it exists
// but does not parse.
Status setDictionary(ImageDetectionOptions& options, const std::string& name_or_file);

// What one image holds. Plain value.
struct ImageDetections {
    std::string image;  // the file as named on the command line, or the caller's label
    int width = 0, height = 0;
    std::vector<MarkerDetection> markers;
    std::vector<DiamondDetection> diamonds;
    // The board's corners found (TargetView::corners, point-id order) and whether the view
    // would be used for calibration (rejection, why); absent without a board.
    std::optional<TargetView> board;
    CalibrationTarget board_target;  // the board looked for, when `board` is set

    // Nothing at all was found.
    bool empty() const;
};

// An image file as the detectors take it: kMono8, kBGR8, or kMono16 for 16-bit grey (colour
// with alpha loses the alpha, 16-bit colour becomes grey). kNotFound when the file is missing,
// kCorruptData "FILE: not an image OpenCV can read" (or the unsupported sample type) else.
Result<Image> readImageFile(const std::filesystem::path& path);

// Finds what `options` asks for in one image (kMono8, kRGB8, kBGR8, kMono16 or kIR16; 16-bit
// images are stretched to 8 bits between their 0.5th and 99.5th percentiles for markers and
// boards alike). An image with nothing in it gives empty lists, not an error.
// kInvalidArgument for bad options or an unsupported pixel format. Reentrant.
Result<ImageDetections> detectInImage(const ImageView& image, const ImageDetectionOptions& options);

// One row per corner: `image,kind,dictionary,id,corner,x,y` with a header line. kind is
// "marker" (corner 0..3 in OpenCV's order, top-left first, clockwise), "diamond" (id is its
// four marker ids joined by '_', corner 0..3 as OpenCV's detectCharucoDiamond orders them),
// or the board's kind, "chessboard" / "charuco" / "aprilgrid" (id is the point id, corner 0,
// dictionary the board's spec). x, y in docs/conventions.md pixels (pixel (0,0) is the centre
// of the top-left pixel), 4 decimals. Fields are quoted as RFC 4180 when they need it.
std::string detectionsCsv(const std::vector<ImageDetections>& images);

// The same as one JSON document: {"convention": ..., "images": [{"image", "width", "height",
// "markers": [{"dictionary", "id", "corners": [[x, y] × 4]}], "diamonds": [{"dictionary",
// "ids": [4], "corners": [[x, y] × 4]}], "board": {"target", "corners": [{"id", "x", "y"}],
// "usable", "rejection", "why"}}]}; "board" only when a board was looked for.
std::string detectionsJson(const std::vector<ImageDetections>& images);

// Writes detectionsCsv() and detectionsJson() as `dir`/detections.csv and
// `dir`/detections.json (each replaced whole, never left half written). kIoError naming the file.
Status writeDetections(const std::filesystem::path& dir,
                       const std::vector<ImageDetections>& images);

// A bgr8 copy of `image` (any format detectInImage takes) with what was found drawn in:
// marker and diamond outlines with their ids at the centre and each corner's index beside it
// (corner 0 boxed), board corners as dots joined in point-id order with every id written.
// Reentrant.
Result<Image> drawDetections(const ImageView& image, const ImageDetections& found);

// Writes an 8-bit image (kMono8, kRGB8, kBGR8) as PNG. kIoError naming the file.
Status writePng(const std::filesystem::path& path, const ImageView& image);

}  // namespace mixray::calibration
