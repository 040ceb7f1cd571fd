// Camera poses from a recording's pose stream, matched to colour frames.
#include "pose_track.h"

#include <algorithm>
#include <thread>

#include "mixray/replay/open_recording.h"
#include "recording_frames.h"

namespace mixray::cli {

std::optional<Eigen::Isometry3d> PoseTrack::poseFor(const std::string& frame_stream,
                                                    const FrameMetadata& meta,
                                                    int64_t tolerance_ns) const {
    const PoseRecord* found = nullptr;
    if (frame_stream == pose_of) {
        if (const auto it = by_sequence.find(meta.sequence); it != by_sequence.end())
            found = &it->second;
    }
    if (!found && !by_stamp.empty()) {
        const auto it = std::lower_bound(
            by_stamp.begin(), by_stamp.end(), meta.device_stamp_ns,
            [](const PoseRecord& r, int64_t t) { return r.frame_device_stamp_ns < t; });
        int64_t best = tolerance_ns + 1;
        for (auto c = it == by_stamp.begin() ? it : it - 1; c != by_stamp.end() && c <= it; ++c) {
            const int64_t gap = std::abs(c->frame_device_stamp_ns - meta.device_stamp_ns);
            if (gap < best) {
                best = gap;
                found = &*c;
            }
        }
    }
    if (!found || found->status == PoseStatus::kLost)
        return std::nullopt;
    return found->transform();
}

Result<PoseTrack> readPoseTrack(const std::filesystem::path& recording, const std::string& name) {
    auto reader = replay::openRecording(recording);
    if (!reader)
        return reader.status();
    const auto& streams = (*reader)->streams();
    StreamId id = kInvalidStream;
    std::string candidates;
    for (StreamId i = 0; i < streams.size(); ++i) {
        if (!name.empty() ? streams[i].name == name : streams[i].kind == StreamKind::kPose) {
            if (id != kInvalidStream && name.empty())
                return Status(ErrorCode::kInvalidArgument,
                              recording.string() + " has several pose streams (" +
                                  streams[id].name + ", " + streams[i].name +
                                  "); choose one with --pose-stream");
            id = i;
        }
        if (streams[i].kind == StreamKind::kPose)
            candidates += (candidates.empty() ? "" : ", ") + streams[i].name;
    }
    if (id == kInvalidStream)
        return Status(ErrorCode::kNotFound,
                      recording.string() +
                          (name.empty() ? " has no pose stream"
                                        : " has no stream '" + name + "' (pose streams: " +
                                              (candidates.empty() ? "none" : candidates) + ")"));
    if (streams[id].kind != StreamKind::kPose)
        return Status(ErrorCode::kInvalidArgument,
                      recording.string() + ": stream '" + name + "' is not a pose stream");
    PoseTrack track;
    track.stream = streams[id].name;
    if (const auto it = streams[id].tags.find("pose_of"); it != streams[id].tags.end())
        track.pose_of = it->second;
    while (true) {
        auto next = nextFrame(**reader);
        if (!next)
            return next.status();
        if (!*next)
            break;
        const FrameRef& frame = **next;
        if (frame.meta().stream != id)
            continue;
        auto record = decodePoseRecord(frame.image());
        if (!record)
            return record.status().withContext(recording.string() + ": " + track.stream +
                                               " frame " + std::to_string(frame.meta().sequence));
        track.by_sequence[record->frame_sequence] = *record;
        track.by_stamp.push_back(*record);
    }
    std::stable_sort(track.by_stamp.begin(), track.by_stamp.end(),
                     [](const PoseRecord& a, const PoseRecord& b) {
                         return a.frame_device_stamp_ns < b.frame_device_stamp_ns;
                     });
    if (track.by_stamp.empty())
        return Status(ErrorCode::kNotFound,
                      recording.string() + ": pose stream " + track.stream + " has no records");
    return track;
}

}  // namespace mixray::cli
