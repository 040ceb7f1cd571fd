// Camera poses from a recording's pose stream (mixray/graph/pose.h), matched to colour frames.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "mixray/graph/frame.h"
#include "mixray/graph/pose.h"
#include "mixray/graph/result.h"

namespace mixray::cli {

// All records of one pose stream, read in a first pass over the recording. Plain value.
struct PoseTrack {
    std::string stream;   // the pose stream's name
    std::string pose_of;  // its `pose_of` tag: the stream whose frames the poses belong to
    std::map<uint64_t, PoseRecord> by_sequence;
    std::vector<PoseRecord> by_stamp;  // sorted by frame_device_stamp_ns

    // The pose of a frame of `stream`: by sequence when the poses belong to that stream, else
    // the nearest by device stamp within `tolerance_ns`. Lost poses are no pose.
    std::optional<Eigen::Isometry3d> poseFor(const std::string& stream, const FrameMetadata& meta,
                                             int64_t tolerance_ns) const;
};

// Reads the pose stream `name` of `recording` (empty: the only pose stream). kNotFound when
// it has none or no stream of that name, kInvalidArgument when several and none is named,
// kCorruptData for a record that does not decode.
Result<PoseTrack> readPoseTrack(const std::filesystem::path& recording, const std::string& name);

}  // namespace mixray::cli
