// Recordings as MCAP files of ROS 2 messages (the "ros2" profile: CDR messages, .msg schemas),
// which ros2 bag (rosbag2's MCAP storage) and Foxglove open: `mixray convert --to mcap`.
#pragma once

#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "mixray/graph/recording.h"
#include "mixray/graph/result.h"

namespace mixray::dds {

struct McapExportOptions {
    // Topics are /<rig>/<stream>/image_raw; empty: the rig's name in the recording (its "rig"
    // tag, else its rig.yaml), else "mixray". ROS 2 names take letters, digits, '_' and '/'.
    std::string rig;
    // Messages gathered into one chunk before it is written (the unit a reader seeks to).
    size_t chunk_bytes = 4 << 20;
};

// The streams of `header` an export leaves out, each with why: those with no ROS 2 image
// encoding (MJPEG, NV12, binary records), indexed like header.streams.
std::vector<std::pair<StreamId, std::string>> mcapUnwritableStreams(const RecordingHeader& header);

// What the export keeps but changes, one line each (frame metadata that sensor_msgs/Image has
// no field for).
std::vector<std::string> mcapChangedData(const RecordingHeader& header);

// A RecordingWriter that writes each frame of an image stream as sensor_msgs/msg/Image on
// /<rig>/<stream>/image_raw: header.stamp is the frame's host stamp on UTC (the recording's
// utc_minus_host_ns tag; without it the host clock as is), frame_id the stream name with '_'
// for '/', the pixels byte for byte. Log and publish times are the stamp. The recording's
// attachments (rig.yaml, calibration files) become MCAP attachments and its tags a metadata
// record "mixray". Frames of mcapUnwritableStreams() are skipped. kInvalidArgument for a bad
// rig name; kIoError when the file cannot be written.
Result<std::unique_ptr<RecordingWriter>> createMcapWriter(const std::filesystem::path& path,
                                                          const RecordingHeader& header,
                                                          McapExportOptions options = {});

}  // namespace mixray::dds
