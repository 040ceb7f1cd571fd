// Corner observations on disk in mrcal's corners-cache format (a vnlog, "# filename x y level"),
// so solves can be rerun without the images, and mrcal-calibrate-cameras --corners-cache can
// read what mixray found.
#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include "mixray/calibration/target.h"
#include "mixray/graph/result.h"

namespace mixray::calibration {

// The file, as mrcal reads it: for every view one row per point of the target's grid in point-
// id order ("filename x y level"; level l means found at 1/2^l resolution, so the weight is
// 0.5^l; points not seen are "filename - - -"), or, for a view without usable corners, the one
// row "filename - -" (mrcal's "no board here"). Filenames are the views' sources.
//
// The grid mrcal is told about (--object-width-n, --object-height-n, --object-spacing):
// - chessboard: cols × rows, spacing square_m: mrcal's own chessboard order;
// - ChArUco: its (cols − 1) × (rows − 1) chessboard corners, spacing square_m (mrcal's
//   object frame is then ours shifted by one square in x and y); corners not seen are "- - -";
// - AprilGrid: Kalibr's 2·cols × 2·rows grid, unseen tags' corners "- - -". Its spacing
//   alternates between the tag side and the gap, which mrcal's regular grid cannot describe:
//   mixray reads it back exactly, mrcal-calibrate-cameras cannot use it.
//
// What mrcal has no column for rides in vnlog comment rows ("## ...", which mrcal skips): the
// target's spec, each camera's name and size, each view's key, and a rejected view's reason
// (its corners are not written: mrcal would use them).
Status writeCornersCache(const std::filesystem::path& path,
                         const std::vector<CameraViews>& cameras);

// An image's size in pixels.
struct ImageSize {
    int width = 0;
    int height = 0;
};

// Reads a cache written by writeCornersCache (cameras, keys, rejections as written), or one
// written by mrcal (mrgingham): then `target` must be given, every view goes to one camera
// named after the file, and keys count views in file order. Views whose row count is not the
// target's point count are kCorruptData naming the file and line.
//
// mrcal's caches have no image size, and the solvers need it (mrcal's regularisation pulls the
// principal point to the image centre). As mrcal-calibrate-cameras, the size is `image_size`
// when given, else that of the image the cache's first view names (a relative name is found
// from the working directory if it is there, else next to the cache); kInvalidArgument naming
// that file when it is not there or not an image. A mixray cache's own sizes stand:
// `image_size` fills only a camera of unknown size (0x0), and one that differs from a known
// size is kInvalidArgument.
//
// kNotFound for a missing file; kInvalidArgument when no target is known or the file's differs
// from `target`.
Result<std::vector<CameraViews>> readCornersCache(
    const std::filesystem::path& path, const std::optional<CalibrationTarget>& target = {},
    const std::optional<ImageSize>& image_size = {});

}  // namespace mixray::calibration
