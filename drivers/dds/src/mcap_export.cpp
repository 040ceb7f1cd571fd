#include "mixray/dds/mcap_export.h"

#include <fastdds/rtps/common/SerializedPayload.h>
#include <unistd.h>

#include <charconv>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <span>

#include "frame_message.h"
#include "mcap_file.h"
#include "mixray/dds/ros_calibration.h"
#include "mixray/dds/ros_types.h"
#include "mixray/graph/rig.h"
#include "ros_camera.h"
#include "ros_image.h"

namespace mixray::dds {
namespace {

constexpr const char* kImageType = "sensor_msgs/msg/Image";
constexpr const char* kCameraInfoType = "sensor_msgs/msg/CameraInfo";
constexpr const char* kTfType = "tf2_msgs/msg/TFMessage";

// rosbag2's channel metadata: the QoS the topic was offered with, as ros2 bag play offers it
// again (rosbag2's YAML of rmw_qos_profile_t: reliable, volatile, keep last 10, no deadline,
// lifespan or lease). The mcap "ros2" profile requires the key.
constexpr const char* kOfferedQos =
    "- history: 1\n"
    "  depth: 10\n"
    "  reliability: 1\n"
    "  durability: 2\n"
    "  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  liveliness: 1\n"
    "  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  avoid_ros_namespace_conventions: false\n";

// tf_static's: reliable, transient-local, keep last 1, so a node that joins a replay late still
// gets the rig's extrinsics.
constexpr const char* kTfStaticQos =
    "- history: 1\n"
    "  depth: 1\n"
    "  reliability: 1\n"
    "  durability: 1\n"
    "  deadline:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  liveliness: 1\n"
    "  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
    "  avoid_ros_namespace_conventions: false\n";

// The rig's name as `mixray record` tags it (or, without the tag, from the recording's
// rig.yaml), made a ROS name ('-' and the like as '_'); "mixray" without either.
std::string rigNameOf(const RecordingHeader& header) {
    std::string name;
    if (const auto tag = header.tags.find("rig"); tag != header.tags.end())
        name = tag->second;
    for (const Attachment& a : header.attachments) {
        if (!name.empty() || a.name != "rig.yaml")
            continue;
        if (auto rig = parseRig(std::string(a.data.begin(), a.data.end()), "rig.yaml"))
            name = rig->name;
    }
    if (name.empty())
        return "mixray";
    for (char& c : name) {
        if (!detail::isRosName(std::string_view(&c, 1)))
            c = '_';
    }
    return name;
}

int64_t utcMinusHostNs(const RecordingHeader& header) {
    const auto tag = header.tags.find(std::string(kUtcMinusHostTag));
    int64_t value = 0;
    if (tag != header.tags.end())
        (void)std::from_chars(tag->second.data(), tag->second.data() + tag->second.size(), value);
    return value;
}

// What ROS 2 sees of the calibration the recording carries: its rig.yaml names the files, its
// attachments hold them (read back through a scratch folder, as calibration's readers take
// paths). Cameras whose size is not their stream's are left out, said in `notes`.
struct RecordedCalibration {
    RosCalibration ros;
    std::vector<std::string> notes;
};

RecordedCalibration recordedCalibration(const RecordingHeader& header) {
    RecordedCalibration out;
    const Attachment* rig_file = nullptr;
    for (const Attachment& a : header.attachments)
        rig_file = a.name == "rig.yaml" ? &a : rig_file;
    if (!rig_file)
        return out;
    auto rig = parseRig(std::string(rig_file->data.begin(), rig_file->data.end()), "rig.yaml");
    if (!rig || rig->calibration.empty())
        return out;
    namespace fs = std::filesystem;
    std::error_code ec;
    const fs::path scratch =
        fs::temp_directory_path(ec) / ("mixray-mcap-" + std::to_string(getpid()) + "-" +
                                       std::to_string(reinterpret_cast<uintptr_t>(&out)));
    fs::create_directories(scratch, ec);
    auto ros = rosCalibrationOf(
        *rig, header.streams,
        [&](const RigCalibrationFile& entry) -> Result<calibration::CalibrationFile> {
            const std::string name = fs::path(entry.path).filename().string();
            for (const Attachment& a : header.attachments) {
                if (a.name != name)
                    continue;
                const fs::path copy = scratch / name;
                std::ofstream(copy, std::ios::binary)
                    .write(reinterpret_cast<const char*>(a.data.data()),
                           static_cast<std::streamsize>(a.data.size()));
                return calibration::importCalibration(copy);
            }
            return Status(ErrorCode::kNotFound,
                          "the rig names calibration " + entry.path + ", which is not attached");
        });
    fs::remove_all(scratch, ec);
    if (!ros) {
        out.notes.push_back("camera_info and tf_static: " + ros.status().message());
        return out;
    }
    out.ros = std::move(ros).value();
    for (auto it = out.ros.camera_info.begin(); it != out.ros.camera_info.end();) {
        const StreamInfo* stream = nullptr;
        for (const StreamInfo& s : header.streams)
            stream = s.name == it->first ? &s : stream;
        if (stream && it->second.width == static_cast<uint32_t>(stream->format.width) &&
            it->second.height == static_cast<uint32_t>(stream->format.height)) {
            ++it;
            continue;
        }
        out.notes.push_back("camera_info of " + it->first + ": the calibration is for " +
                            std::to_string(it->second.width) + "x" +
                            std::to_string(it->second.height) +
                            " images, not the stream's: left out");
        it = out.ros.camera_info.erase(it);
    }
    return out;
}

class McapRecordingWriter : public RecordingWriter {
public:
    McapRecordingWriter(std::unique_ptr<detail::McapFile> file, const RecordingHeader& header,
                        const std::string& rig)
        : file_(std::move(file)),
          channels_(header.streams.size(), 0),
          sequences_(header.streams.size(), 0),
          utc_minus_host_ns_(utcMinusHostNs(header)) {
        // A type drivers/dds describes: its definition is always there.
        auto definition = rosMessageDefinition(kImageType);
        const uint16_t schema =
            file_->addSchema(kImageType, "ros2msg", definition ? *definition : std::string());
        for (size_t i = 0; i < header.streams.size(); ++i) {
            const StreamInfo& s = header.streams[i];
            frame_ids_.push_back(detail::rosFrameId(s.name));
            if (!detail::rosEncoding(s.format.format))
                continue;
            channels_[i] = file_->addChannel(schema, "/" + rig + "/" + s.name + "/image_raw", "cdr",
                                             {{"offered_qos_profiles", kOfferedQos}});
        }
        RecordedCalibration recorded = recordedCalibration(header);
        camera_info_.resize(header.streams.size());
        info_channels_.resize(header.streams.size(), 0);
        uint16_t info_schema = 0;
        for (size_t i = 0; i < header.streams.size(); ++i) {
            const auto found = recorded.ros.camera_info.find(header.streams[i].name);
            if (found == recorded.ros.camera_info.end() || channels_[i] == 0)
                continue;
            if (info_schema == 0) {
                auto text = rosMessageDefinition(kCameraInfoType);
                info_schema = file_->addSchema(kCameraInfoType, "ros2msg", text ? *text : "");
            }
            detail::toRosCameraInfo(found->second, &camera_info_[i]);
            info_channels_[i] = file_->addChannel(
                info_schema, "/" + rig + "/" + header.streams[i].name + "/camera_info", "cdr",
                {{"offered_qos_profiles", kOfferedQos}});
        }
        if (!recorded.ros.transforms.empty()) {
            auto text = rosMessageDefinition(kTfType);
            tf_channel_ =
                file_->addChannel(file_->addSchema(kTfType, "ros2msg", text ? *text : ""),
                                  "/tf_static", "cdr", {{"offered_qos_profiles", kTfStaticQos}});
            transforms_ = std::move(recorded.ros.transforms);
        }
    }

    Status write(const FrameRef& frame) override { return writeAs(frame.meta().stream, frame); }

    Status writeAs(StreamId stream, const FrameRef& frame) override {
        if (!frame || stream >= channels_.size())
            return {ErrorCode::kInvalidArgument, "mcap: a frame of no stream of the recording"};
        if (channels_[stream] == 0)
            return Status::ok();  // mcapUnwritableStreams() lists it
        const int64_t stamp = frame.meta().host_stamp_ns + utc_minus_host_ns_;
        detail::toRosImage(frame, frame_ids_[stream], stamp, &message_);
        const uint32_t size = type_.getSerializedSizeProvider(&message_)();
        payload_.reserve(size);
        if (!type_.serialize(&message_, &payload_))
            return {ErrorCode::kInternal,
                    "mcap: a frame would not serialize as " + std::string(kImageType)};
        const uint64_t time = stamp < 0 ? 0 : static_cast<uint64_t>(stamp);
        if (tf_channel_ != 0) {
            // The rig's extrinsics once, as a static broadcaster sends them, with the first image.
            detail::RosTfMessage tf = detail::toRosTf(transforms_, stamp);
            MIXRAY_RETURN_IF_ERROR(file_->write(
                tf_channel_, 0, time, time,
                detail::serializeSample<tf2_msgs::msg::dds_::TFMessage_PubSubType>(tf)));
            tf_channel_ = 0;
        }
        MIXRAY_RETURN_IF_ERROR(
            file_->write(channels_[stream], sequences_[stream], time, time,
                         std::span<const uint8_t>(payload_.data, payload_.length)));
        if (info_channels_[stream] != 0) {
            camera_info_[stream].header(message_.header());
            MIXRAY_RETURN_IF_ERROR(
                file_->write(info_channels_[stream], sequences_[stream], time, time,
                             detail::serializeSample<sensor_msgs::msg::dds_::CameraInfo_PubSubType>(
                                 camera_info_[stream])));
        }
        ++sequences_[stream];
        return Status::ok();
    }

    Status close() override { return file_->close(); }
    uint64_t bytesWritten() const override { return file_->bytesWritten(); }

    Status addRecordingData(const RecordingHeader& header) {
        for (const Attachment& a : header.attachments)
            MIXRAY_RETURN_IF_ERROR(file_->addAttachment(a.name, a.mime_type, a.data, 0));
        if (!header.tags.empty())
            MIXRAY_RETURN_IF_ERROR(file_->addMetadata("mixray", header.tags));
        return Status::ok();
    }

private:
    std::unique_ptr<detail::McapFile> file_;
    std::vector<uint16_t> channels_;  // per recording stream; 0: not written
    std::vector<uint32_t> sequences_;
    std::vector<std::string> frame_ids_;
    int64_t utc_minus_host_ns_;
    detail::RosImage message_;
    sensor_msgs::msg::dds_::Image_PubSubType type_;
    std::vector<detail::RosCameraInfoMessage> camera_info_;  // per stream: all but the header
    std::vector<uint16_t> info_channels_;                    // per stream; 0: no camera_info
    uint16_t tf_channel_ = 0;                                // until tf_static is written
    std::vector<calibration::RosTransform> transforms_;
    eprosima::fastrtps::rtps::SerializedPayload_t payload_;
};

}  // namespace

std::vector<std::pair<StreamId, std::string>> mcapUnwritableStreams(const RecordingHeader& header) {
    std::vector<std::pair<StreamId, std::string>> out;
    for (size_t i = 0; i < header.streams.size(); ++i) {
        const StreamInfo& s = header.streams[i];
        if (!detail::rosEncoding(s.format.format)) {
            out.emplace_back(static_cast<StreamId>(i),
                             s.name + ": sensor_msgs/Image has no encoding for " +
                                 std::string(toString(s.format.format)));
        }
    }
    return out;
}

std::vector<std::string> mcapChangedData(const RecordingHeader& header) {
    std::vector<std::string> out;
    if (mcapUnwritableStreams(header).size() < header.streams.size()) {
        out.push_back(
            "frame metadata sensor_msgs/Image has no field for (sequence, device stamp, clock "
            "domain, exposure, status): each image keeps its stamp");
    }
    for (std::string& note : recordedCalibration(header).notes)
        out.push_back(std::move(note));
    if (header.tags.find(std::string(kUtcMinusHostTag)) == header.tags.end()) {
        out.push_back("stamps: the recording has no " + std::string(kUtcMinusHostTag) +
                      " tag, so header.stamp is the recording host's clock, not UTC");
    }
    return out;
}

Result<std::unique_ptr<RecordingWriter>> createMcapWriter(const std::filesystem::path& path,
                                                          const RecordingHeader& header,
                                                          McapExportOptions options) {
    if (!options.rig.empty() && !detail::isRosName(options.rig)) {
        return Status(
            ErrorCode::kInvalidArgument,
            "mcap: ROS 2 names take letters, digits, '_' and '/', got '" + options.rig + "'");
    }
    const std::string rig = options.rig.empty() ? rigNameOf(header) : options.rig;
    auto file = detail::McapFile::create(path, "ros2", "mixray", options.chunk_bytes);
    if (!file)
        return file.status();
    auto writer = std::make_unique<McapRecordingWriter>(std::move(file).value(), header, rig);
    MIXRAY_RETURN_IF_ERROR(writer->addRecordingData(header));
    return std::unique_ptr<RecordingWriter>(std::move(writer));
}

}  // namespace mixray::dds
