// Finding calibration targets in images: chessboards (OpenCV's findChessboardCornersSB),
// ChArUco boards and Kalibr AprilGrids (marker_detection.h), with per-view rejection naming the
// reason and its numbers; and the collectors `mixray calibrate` runs over an image folder or a
// mixray recording.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "mixray/calibration/calibrate.h"
#include "mixray/calibration/camera_model.h"
#include "mixray/calibration/marker_detection.h"
#include "mixray/calibration/target.h"
#include "mixray/graph/image.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// How targets are found and views judged. Every field has a working default.
struct DetectionOptions {
    // ChArUco/AprilGrid views with fewer than this fraction of the target's points are
    // kPartialTarget (a chessboard is found whole or not at all). A quarter of the board
    // still constrains a pose, but few and clustered corners say little about distortion.
    double min_point_fraction = 0.25;
    // Edge blur at the corners: the median over the corners of (local contrast / steepest
    // Sobel gradient), in pixels. A sharp antialiased edge reads about 2 px, a Gaussian blur of
    // σ px about 2.6 σ (6.5 px at σ = 2.5); the 13 in-focus real photos left*.jpg of
    // ../shared/data read at most 2.8 px (tests/calibration/detect_test.cpp). Above this the
    // view is kBlurred (0: never): 4 px, a blur σ of about 1.5 px, lies between every sharp
    // image measured and the blurred ones, with a margin both ways.
    double max_edge_blur_px = 4.0;
    // The angle between the board's normal and the viewing ray to its centre, from a planar
    // pose (IPPE) through `camera`, or without one through a rough pinhole (focal length the
    // image's larger side, centred, no distortion). Above it the view is kTooOblique (0:
    // never): foreshortened squares put corners within a few pixels of each other.
    double max_tilt_deg = 75.0;
    // Square markers to report besides the target (TargetView::markers): an OpenCV or
    // libapriltag dictionary name (isKnownDictionary()); empty: none.
    std::string marker_dictionary;
    // A lens model for the tilt check (not for detection); its size must be the image's.
    std::optional<CameraModel> camera;
    // ArUco/AprilTag marker detection for ChArUco boards and AprilGrids.
    DetectorOptions markers;
    // When some of a ChArUco board's or AprilGrid's markers are missed, look again in the image
    // upsampled 2×, for markers too small for the detector (on sim_calibration.mkv this finds
    // 414 instead of 356 colour corners and 116 instead of 86 fish-eye corners, 16 or more in
    // all 6 instead of 3 views over it). Costs a second detection on partial views only.
    bool upsample_small_markers = true;
    // A chessboard whose grid of X-junctions goes on beyond the corners found (a board
    // declared smaller than printed, found as a sub-board) is kLargerBoard, with the size seen
    // (TargetView::seen_cols/seen_rows). Off: such views are used as found.
    bool check_larger_board = true;
    // Frames of different streams of a recording whose host stamps lie within this of each
    // other were taken at the same instant (one key). Keep it under half the frame period.
    int64_t max_skew_ns = 10'000'000;

    Status validate() const;
};

// Finds `target` in one image: kMono8, kRGB8, kBGR8, or kMono16/kIR16 (stretched to 8 bits
// between its 0.5th and 99.5th percentiles first). The view's `corners` are those found, in
// docs/conventions.md pixels, in point-id order; `rejection` and `why` say whether it is
// usable (its `source` and `key` are left to the caller). kInvalidArgument for a bad target or
// option or an unsupported pixel format. Reentrant.
Result<TargetView> detectTarget(const ImageView& image, const CalibrationTarget& target,
                                const DetectionOptions& options = {});

// Every image in `folder` whose file name matches `pattern` (shell wildcards * and ?), in
// name order; view keys count from 0 in that order (so the same file names in two folders, one
// per camera, give equal keys). The first image read sets the camera's size; unreadable files
// and images of another size are views rejected with the reason, never errors. `progress` (may
// be empty) is called after each image. kNotFound when the folder is missing or no file
// matches; kInvalidArgument for a bad target or option. The camera is named after the folder.
Result<CameraViews> detectInFolder(const std::filesystem::path& folder,
                                   const CalibrationTarget& target,
                                   const std::string& pattern = "*",
                                   const DetectionOptions& options = {},
                                   const ProgressCallback& progress = {});

// A depth image taken at the instant of a key.
struct KeyedDepthImage {
    int64_t key = 0;
    Image depth_mm;  // depth16
};

// A depth stream of a recording, with its frames at the keys where some camera saw the target
// (a depth calibration needs no others, and a long session's depth would not fit in memory).
struct RecordedDepth {
    std::string stream;         // "kinect/depth"
    std::string aligned_with;   // the stream's aligned_with tag (its IR camera); empty: none
    std::string registered_to;  // its registered_to tag; empty: none
    std::vector<KeyedDepthImage> frames;
};

struct RecordingDetection {
    std::vector<CameraViews> cameras;
    std::vector<RecordedDepth> depth;
};

// Every image stream of a mixray recording (mono8, rgb8, bgr8, mono16, ir16, and colour as
// mjpeg, nv12 or yuyv through its luma; binary streams are skipped), one CameraViews per stream
// named as the stream ("kinect/color"), and every depth16 stream's frames at the keys with a
// usable view. Keys number the capture instants: frames of different streams (depth included)
// whose host stamps lie within options.max_skew_ns share a key. Sources are
// "RECORDING#STREAM@SEQUENCE". Frames that cannot be decoded are kUnreadable views. `progress`
// is called after each image frame. The reader's error for a missing or corrupt file;
// kNotFound when the recording has no image stream.
Result<RecordingDetection> detectInRecording(const std::filesystem::path& recording,
                                             const CalibrationTarget& target,
                                             const DetectionOptions& options = {},
                                             const ProgressCallback& progress = {});

}  // namespace mixray::calibration
