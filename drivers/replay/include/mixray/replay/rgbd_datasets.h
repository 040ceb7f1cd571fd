// NYU Depth V2 raw scene folders and SUN RGB-D frame folders as mixray recordings (depth in mm).
//
// NYU Depth V2 raw (one folder per scene, as its raw archives unpack):
//   d-<seconds>.<fraction>-<n>.pgm   16-bit raw Kinect depth: 11-bit disparity-like values
//                                    (depth_units.h: convertNyuRawToMm), 640x480
//   r-<seconds>.<fraction>-<n>.ppm   8-bit RGB, 640x480
//   a-*.dump, INDEX.txt              accelerometer records and the toolbox's index (not read)
// The name's <seconds>.<fraction> is the frame's Unix time. Depth is not registered to colour
// (the toolbox registers it with its own calibration); the depth stream carries the toolbox's
// published depth intrinsics (camera_params.m: fx_d 582.62448167737955, fy_d 582.69103270988637,
// cx_d 313.04475870804731, cy_d 238.44389626620386, MATLAB's 1-based pixels; tagged 0-based,
// cx and cy minus 1).
//
// SUN RGB-D (one folder per frame, as SUNRGBD/<sensor>/<set>/<frame>/):
//   image/<name>.jpg    colour
//   depth/<name>.png    16-bit mm rotated left by 3 bits (depth_units.h: sunDepthToMm)
//   intrinsics.txt      3x3 K, row-major, MATLAB 1-based pixels (read3dPoints.m)
//   depth_bfx/, extrinsics/, annotation*/, scene.txt   not read (depth_bfx is hole-filled)
// The depth is registered to the image (read3dPoints colours point (u,v) with pixel (u,v)).
#pragma once

#include <filesystem>
#include <memory>
#include <string_view>

#include "mixray/graph/recording.h"
#include "mixray/replay/point_cloud.h"

namespace mixray::replay {

// The NYU toolbox's depth intrinsics, 0-based (see above).
PinholeIntrinsics nyuDepthIntrinsics();

// The stamp of an NYU raw file name ("d-1294886362.665769-3143255701.pgm" ->
// 1294886362665769000 ns); kCorruptData for a name of another shape.
Result<int64_t> parseNyuFileName(std::string_view name);

// SUN RGB-D's intrinsics.txt as 0-based pinhole intrinsics. kCorruptData naming `file_name`
// unless it holds nine numbers K = [fx 0 cx; 0 fy cy; 0 0 1].
Result<PinholeIntrinsics> parseSunIntrinsics(std::string_view text, std::string_view file_name);

// Layout rules (docs/rgbd-formats.md; content checks follow when opening):
// NYU: a folder holding at least one file named d-<digits>.<digits>-<digits>.pgm.
bool looksLikeNyuRaw(const std::filesystem::path& dir);
// SUN RGB-D: a folder holding intrinsics.txt, a depth/ folder with a .png and an image/ folder.
bool looksLikeSunRgbd(const std::filesystem::path& dir);

struct DatasetReaderOptions {
    size_t buffers_per_stream = 8;  // frames of one stream a consumer may hold at once
};

// Opens an NYU raw scene folder (format "nyu-raw"): streams "nyu/color" (rgb8) and "nyu/depth"
// (depth16 mm, converted from raw per frame), each present when such files are. Checks at open
// that the first depth file is Kinect raw depth in one byte order (else kCorruptData naming it).
Result<std::unique_ptr<RecordingReader>> openNyuRaw(const std::filesystem::path& dir,
                                                    const DatasetReaderOptions& options = {});

// Opens a SUN RGB-D frame folder (format "sun-rgbd"): one frame of "sun/color" (rgb8) and
// "sun/depth" (depth16 mm) at stamp 0, depth tagged with the intrinsics and registered to the
// colour. kCorruptData when the depth PNG does not look rotated (fewer than 95 % of its
// non-zero values with the low 3 bits clear: plain mm, not SUN RGB-D's encoding) or the
// intrinsics do not parse. intrinsics.txt is kept as an attachment.
Result<std::unique_ptr<RecordingReader>> openSunRgbd(const std::filesystem::path& dir,
                                                     const DatasetReaderOptions& options = {});

}  // namespace mixray::replay
