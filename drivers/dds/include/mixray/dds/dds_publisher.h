// A graph sink that publishes streams over DDS: to other mixray hosts (mixray_msgs/msg/Frame,
// every byte and all metadata) and, for images, to ROS 2 (sensor_msgs/msg/Image and CameraInfo,
// tf_static).
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/calibration/ros_camera_info.h"
#include "mixray/dds/dds_options.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/result.h"

namespace mixray::dds {

// What a DdsPublisher publishes and how.
struct DdsPublisherOptions {
    DdsOptions dds;
    // Graph streams to publish, by name; empty: every stream in the graph at connect().
    std::vector<std::string> streams;
    // Frames each stream's edge holds for the publisher's thread: when DDS is slower than the
    // stream, the oldest is dropped and counted; the graph never waits (1..64).
    size_t queue_capacity = 2;
    // Frames DDS keeps per stream for readers that ask for a lost fragment again (1..64).
    int history_depth = 2;
    // Image streams also as ROS 2 topics rt/<rig>/<stream>/image_raw (sensor_msgs/msg/Image);
    // empty: no ROS 2 topics. Stream names keep their '/': rt/<rig>/kinect/color/image_raw.
    std::string ros2_rig;
    // With ros2_rig: image streams' calibrations by stream name, each published as
    // sensor_msgs/msg/CameraInfo on rt/<rig>/<stream>/camera_info with every image (the same
    // header: stamp and frame_id). Each must name a published image stream of its size.
    std::map<std::string, calibration::RosCameraInfo> ros2_camera_info;
    // With ros2_rig: the rig's calibrated extrinsics, published once on tf_static (reliable,
    // transient-local: ROS 2 nodes that start later get them too). Frames are named as the
    // images' frame_id: "kinect/color" is "kinect_color".
    std::vector<calibration::RosTransform> ros2_transforms;

    // kInvalidArgument naming the field.
    Status validate() const;
};

// The sensor_msgs/image_encodings name under which a stream of `format` goes to ROS 2
// ("rgb8", "16UC1"); nullopt for formats ROS 2 has no uncompressed encoding of (MJPEG, NV12,
// binary records), whose streams get no ROS 2 topics.
std::optional<std::string_view> rosImageEncoding(PixelFormat format);

// One stream's figures.
struct DdsStreamStats {
    std::string stream;
    std::string topic;
    uint64_t frames_in = 0;     // frames the graph handed to the publisher's edge
    uint64_t dropped = 0;       // replaced on the edge before DDS took them (DDS too slow)
    uint64_t written = 0;       // frames handed to DDS
    uint64_t write_errors = 0;  // frames DDS refused
    uint64_t ros_written = 0;   // sensor_msgs/Image messages handed to DDS
    uint64_t ros_camera_info_written = 0;  // sensor_msgs/CameraInfo messages handed to DDS
    int matched_readers = 0;               // mixray readers of the frame topic now
    int ros_matched_readers = 0;           // readers of the ROS 2 topic now
};

// Subscribes to its streams over live edges (the graph never waits for the network) and,
// once started, publishes each frame from a thread per stream. Announces every stream on
// kAnnouncementTopic (TRANSIENT_LOCAL, so hosts that join later learn it) and withdraws the
// announcements at stop().
// Thread-safety: create/connect/start/stop by the graph's owner; stats() from any thread.
class DdsPublisher : public Node {
public:
    static Result<std::unique_ptr<DdsPublisher>> create(DdsPublisherOptions options);
    ~DdsPublisher() override;
    DdsPublisher(const DdsPublisher&) = delete;
    DdsPublisher& operator=(const DdsPublisher&) = delete;

    std::string name() const override { return "dds-publisher"; }
    // Subscribes to the streams, joins DDS, creates the writers and announces the streams, so
    // that other hosts can open them before this graph starts (waitForReaders). kNotFound for
    // a named stream the graph lacks; kUnavailable when the participant cannot be made.
    Status connect(Graph& graph) override;
    // Starts publishing the frames.
    Status start() override;
    void stop() override;

    std::vector<DdsStreamStats> stats() const;
    // Waits until every stream's frame topic has at least `readers` mixray readers, so that a
    // finite source started afterwards loses no frame to discovery: true when they came
    // within `timeout`.
    bool waitForReaders(int readers, std::chrono::milliseconds timeout) const;
    // This host's name in the topics.
    std::string host() const;

private:
    struct Impl;
    explicit DdsPublisher(DdsPublisherOptions options);
    std::unique_ptr<Impl> impl_;
};

}  // namespace mixray::dds
