// Depth frames as organized point clouds: deprojection, PCD and PLY files, and reading them back.
//
// A cloud keeps the depth image's grid (width x height points, row-major), so tools that work on
// organized clouds (PCL's normal estimation, Open3D's RGBD code) see the image layout; pixels
// without depth are NaN points, as PCL's grabbers make them. Deprojection is PCL's
// (pcl::ImageGrabber) in single precision, operation for operation, so a frame gives the same
// floats PCL gives:
//   z = float(depth) * float(1 / depth_per_m);  x = (float(u) - cx) * (1 / fx) * z;  y likewise
// with pixel (0,0) the centre of the top-left pixel (docs/conventions.md).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/image.h"
#include "mixray/graph/recording.h"
#include "mixray/replay/convert.h"

namespace mixray::replay {

// Stream tag of a depth stream: the pinhole intrinsics of its pixels, "fx,fy,cx,cy" (pixels,
// decimal). Readers that know them set it (SUN RGB-D's intrinsics.txt, NYU's published
// Kinect calibration, an .oni recording's field of view).
inline constexpr const char* kIntrinsicsTag = "pinhole_intrinsics";
// Stream tag of a depth stream whose pixels are registered to a colour stream of the same size:
// the colour stream's full name. Pixel (u,v) of both images sees the same point.
inline constexpr const char* kRegisteredToTag = "registered_to";

// Pinhole intrinsics (no distortion). Plain value.
struct PinholeIntrinsics {
    double fx = 0;  // focal lengths, pixels
    double fy = 0;
    double cx = 0;  // principal point, pixels
    double cy = 0;
    // kInvalidArgument unless fx, fy > 0 and every value is finite.
    Status validate() const;
    bool operator==(const PinholeIntrinsics&) const = default;
};

// "fx,fy,cx,cy" (as the --intrinsics option and kIntrinsicsTag write them); kInvalidArgument
// naming the field that is not a number, or when there are not exactly four.
Result<PinholeIntrinsics> parseIntrinsics(std::string_view text);
// The inverse: shortest decimal forms that parse back to the same doubles.
std::string formatIntrinsics(const PinholeIntrinsics& k);

// The <depth> intrinsics of a PCL recorder sidecar (frame_<stamp>.xml: focal_length_x/y,
// principal_point_x/y). kCorruptData naming `file_name` and the missing or bad element.
Result<PinholeIntrinsics> parsePclCameraXml(std::string_view text, std::string_view file_name);

// An organized cloud. Plain value.
struct PointCloud {
    int width = 0;
    int height = 0;
    std::vector<float> xyz;    // 3 floats per point, metres, row-major; NaN: no depth
    std::vector<uint8_t> rgb;  // 3 bytes per point (R, G, B), or empty: no colour
    size_t size() const { return static_cast<size_t>(width) * static_cast<size_t>(height); }
    bool hasColor() const { return !rgb.empty(); }
};

// Deprojects a kDepth16 image in `depth_per_m` units per metre (1000: mm) through `k`. `color`,
// when given, must be rgb8 or bgr8 of the same size, registered to the depth: point (u,v) takes
// pixel (u,v)'s colour. kInvalidArgument for bad intrinsics, formats or sizes.
Result<PointCloud> deprojectDepth(const ImageView& depth, int depth_per_m,
                                  const PinholeIntrinsics& k, const ImageView* color = nullptr);

enum class PcdEncoding : uint8_t { kAscii, kBinary };
enum class PointCloudFormat : uint8_t { kPly, kPcd };

// PCD v0.7: FIELDS x y z [rgb] (rgb: TYPE U, 0x00RRGGBB as PCL packs it), WIDTH/HEIGHT of the
// grid, DATA ascii or binary; NaN points kept ("nan" in ASCII).
std::string encodePcd(const PointCloud& cloud, PcdEncoding encoding);
// PLY 1.0 binary_little_endian: vertex x y z float [red green blue uchar]; the grid is given
// by "obj_info num_cols/num_rows" (PCL's PLY reader makes the cloud organized from them) and
// "comment width/height"; NaN points kept.
std::string encodePly(const PointCloud& cloud);
// Writes the encoding of `cloud` to `file`; kIoError naming the file.
Status writePointCloud(const std::filesystem::path& file, const PointCloud& cloud,
                       PointCloudFormat format, PcdEncoding pcd_encoding = PcdEncoding::kBinary);

// Parses PCD files as PCL writes them: DATA ascii, binary or binary_compressed (LZF); fields x y z
// (F 4) and optionally rgb or rgba (packed 4 bytes); other fields are skipped. PLY files with a
// vertex element of float x y z and optional uchar red green blue, ascii or
// binary_little_endian; organized when num_cols/num_rows or width/height say so, else one row.
// kCorruptData naming `name` and what is wrong; never reads out of bounds.
Result<PointCloud> parsePcd(std::string_view bytes, std::string_view name);
Result<PointCloud> parsePly(std::string_view bytes, std::string_view name);
// Reads a .pcd or .ply file (by content: "ply\n" starts a PLY file).
Result<PointCloud> readPointCloud(const std::filesystem::path& file);

struct PointCloudWriterOptions {
    PointCloudFormat format = PointCloudFormat::kPly;
    PcdEncoding pcd_encoding = PcdEncoding::kBinary;  // PCD only
    // Intrinsics of the depth stream's pixels. Absent: the stream's kIntrinsicsTag, else the
    // recording's PCL sidecar (*.xml attachment), else creating the writer fails.
    std::optional<PinholeIntrinsics> intrinsics;
    std::string depth_stream;  // full or short name; empty: the first depth16 stream
    // Colour points from the stream the depth is registered to (kRegisteredToTag), with the
    // latest frame of that stream at or before each depth frame; false: no colour.
    bool color = true;
    Status validate() const;
};

// The intrinsics a point-cloud writer would use for `depth` (see PointCloudWriterOptions).
// kNotFound saying how to give them when the recording carries none.
Result<PinholeIntrinsics> depthIntrinsics(const RecordingHeader& header, StreamId depth,
                                          const PointCloudWriterOptions& options);

// Creates a folder of per-frame point clouds at `dir` (new or empty): one file per depth frame,
// cloud_<n>.ply or .pcd (n counting from 000000), and clouds.txt listing "timestamp file" per
// line as TUM's lists do (host stamps, 9 fractional digits), so every cloud keeps its time.
// Other streams are ignored. Errors name the stream and the missing piece.
// What point clouds of `header` leave out: every stream but the depth stream and its registered
// colour, and the attachments (mixray convert lists them).
Result<WriteLosses> pointCloudLosses(const RecordingHeader& header,
                                     const PointCloudWriterOptions& options = {});

Result<std::unique_ptr<RecordingWriter>> createPointCloudWriter(
    const std::filesystem::path& dir, const RecordingHeader& header,
    const PointCloudWriterOptions& options = {});

}  // namespace mixray::replay
