// The "ros2" backend: a ROS 2 image topic (sensor_msgs/msg/Image, from any ROS 2 node: a
// camera driver, a bag played back, a simulator) as a local device, over the same DDS as the
// rest of drivers/dds, without ROS installed.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "mixray/dds/dds_options.h"
#include "mixray/graph/device.h"
#include "mixray/graph/image.h"

namespace mixray::dds {

// How a topic is opened. Parsed from DeviceConfig::options (all strings): the keys of
// DdsOptions (kDdsOptionKeys) and
//   discovery_timeout_ms  how long open() waits for the first image, which says the stream's
//                         encoding and size, 0..600000 (default 5000)
//   buffers               frames the stream's pool holds, 2..256 (default 8)
//   history               images DDS keeps for this reader, 1..64 (default 4)
//   reliability           "best_effort" (default: matches every publisher, the sensor-data
//                         QoS camera drivers use included) or "reliable" (matches reliable
//                         publishers only, and has lost images sent again)
// DeviceConfig::id is the ROS 2 topic ("/robot/camera/image_raw"); the device has one stream,
// "<device>/image".
struct Ros2SourceOptions {
    DdsOptions dds;
    int64_t discovery_timeout_ms = 5000;
    size_t buffers = 8;
    int history = 4;
    bool reliable = false;
};

// Reads DeviceConfig::options into `options` (starting from its values); kInvalidArgument
// naming the device and option for a bad value or an unknown key.
Status parseRos2SourceOptions(const DeviceConfig& config, Ros2SourceOptions* options);

// The graph pixel format of a sensor_msgs/image_encodings name ("rgb8", "16UC1"); nullopt for
// encodings mixray has no format for (32FC1, rgba8, 16-bit colour, ...).
std::optional<PixelFormat> pixelFormatOfRosEncoding(std::string_view encoding);

// A sensor_msgs/msg/Image sample as the ros2 device reads it, for tests and fuzzing (the device
// converts the same way):
//   rosImageStream: the stream `device` makes of its first sample from `topic`;
//   rosImageFrame: a later sample as a frame of that stream (its header stamp as device stamp).
// kCorruptData when the bytes are not an Image in CDR, or the image is not what its encoding,
// width, height and step say (or not of the stream); kUnsupported for an encoding mixray has
// no format for. Never throws.
Result<StreamInfo> rosImageStream(std::span<const uint8_t> sample, const std::string& device,
                                  const std::string& topic);
Status rosImageFrame(std::span<const uint8_t> sample, const StreamInfo& stream, FrameMetadata* meta,
                     Image* image);
// An image as a ROS 2 node sends it (sensor_msgs/msg/Image in CDR), for tests and seeds.
std::vector<uint8_t> serializeRosImage(const ImageView& image, int64_t stamp_ns,
                                       const std::string& frame_id);

struct Ros2SourceStats {
    uint64_t received = 0;        // images taken from DDS
    uint64_t published = 0;       // frames published into the graph
    uint64_t rejected = 0;        // images of another encoding or size than the stream's
    uint64_t pool_exhausted = 0;  // images dropped because the graph held every buffer
    int matched_writers = 0;      // publishers of the topic this reader has matched now
};

// One topic: a DataReader whose thread copies each image into the graph's pool. Frames are
// numbered in arrival order (sequence), stamped on arrival with this host's CLOCK_MONOTONIC
// (host_stamp_ns), and carry the image's header.stamp (ROS time, the publisher's wall clock) as
// their device stamp in clock domain deviceClockDomain("ros2", TOPIC), so ClockSync maps the
// publisher's clock like any device clock. The image open() waited for tells the stream's
// format and is not published. Reconnecting while the topic has no publisher after it had one.
class Ros2ImageDevice : public Device {
public:
    ~Ros2ImageDevice() override;
    std::string name() const override;
    DeviceDescriptor descriptor() const override;
    DeviceState state() const override;
    std::string clockReport() const override;
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;
    Ros2SourceStats stats() const;

private:
    friend class Ros2Backend;
    struct Impl;
    explicit Ros2ImageDevice(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

class Ros2Backend : public DeviceBackend {
public:
    // `defaults`: the DDS options where the device's options do not say.
    explicit Ros2Backend(DdsOptions defaults = {}) : defaults_(std::move(defaults)) {}
    std::string_view name() const override { return "ros2"; }
    // ROS 2 topics are not listed (DDS discovery would need each one's type); rig files name
    // them.
    Result<std::vector<DeviceDescriptor>> enumerate() override {
        return std::vector<DeviceDescriptor>{};
    }
    // Waits up to discovery_timeout_ms for the topic's first image. kInvalidArgument for a bad
    // topic name; kNotFound when no image came (saying how many publishers matched);
    // kUnsupported naming an encoding mixray has no format for.
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;

private:
    DdsOptions defaults_;
};

}  // namespace mixray::dds
