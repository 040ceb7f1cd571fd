// OpenNI .oni recordings as RecordingReaders (mixray info, mixray convert), played by OpenNI2.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>

#include "mixray/graph/recording.h"

namespace mixray::openni2 {

// Whether `file` starts like an OpenNI recording: the magic "NI10" (OpenNI 1.x, which the
// Kinect-era recorders wrote and OpenNI2's OniFile driver plays) or "NI20".
bool looksLikeOni(const std::filesystem::path& file);

// Stream tag of the depth stream (the same key as replay::kIntrinsicsTag, which this module
// cannot include): pinhole intrinsics "fx,fy,cx,cy" derived from the recorded field of view,
// fx = (w / 2) / tan(hfov / 2), fy likewise with h, the principal point at the image centre
// ((w - 1) / 2, (h - 1) / 2) as OpenNI2's own depth-to-world conversion assumes.
inline constexpr const char* kOniIntrinsicsTag = "pinhole_intrinsics";

// Opens `file` through the openni2 backend in OpenNI2's manual playback (every frame, as fast
// as it is read) as a RecordingReader of format "oni": streams "oni/depth" (depth16 mm),
// "oni/color" (rgb8), "oni/ir" as recorded, un-mirrored like the backend does. Frames come in
// recorded-time order; host and device stamps both hold OpenNI2's recorded timestamp (µs to
// ns, rebased to 0 by OpenNI2), sequence its frame index. seek() is unsupported (OpenNI2
// cannot seek these files reliably, see the backend's README) except to the start before the
// first frame. kCorruptData when OpenNI2 cannot play the file (a recording with no frames).
// Thread-bound.
Result<std::unique_ptr<RecordingReader>> openOniRecording(const std::filesystem::path& file,
                                                          size_t buffers_per_stream = 8);

}  // namespace mixray::openni2
