#include "mixray/dds/ros2_source.h"

#include <atomic>
#include <cstring>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <mutex>
#include <thread>

#include "frame_message.h"
#include "mixray/graph/clock.h"
#include "mixray/graph/device_options.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"
#include "participant.h"
#include "ros_image.h"

namespace mixray::dds {

namespace fdds = eprosima::fastdds::dds;

namespace {

StreamKind kindOf(PixelFormat format) {
    switch (format) {
        case PixelFormat::kMono8:
        case PixelFormat::kMono16:
            return StreamKind::kMono;
        case PixelFormat::kDepth16:
            return StreamKind::kDepth;
        default:
            return StreamKind::kColor;
    }
}

int64_t stampNs(const detail::RosImage& image) {
    return int64_t{image.header().stamp().sec()} * 1'000'000'000 + image.header().stamp().nanosec();
}

// Whether `image` is a frame of `stream`: its encoding, size, row step and data length.
bool fitsStream(const detail::RosImage& image, const StreamInfo& stream) {
    const ImageDesc& desc = stream.format;
    return image.encoding() == detail::rosEncoding(desc.format) &&
           image.width() == static_cast<uint32_t>(desc.width) &&
           image.height() == static_cast<uint32_t>(desc.height) &&
           image.step() == static_cast<uint32_t>(desc.stride_bytes) && image.is_bigendian() == 0 &&
           image.data().size() == desc.bufferBytes();
}

// The stream `device` makes of `first`, an image of `topic`.
Result<StreamInfo> streamOf(const detail::RosImage& first, const std::string& device,
                            const std::string& topic) {
    const std::optional<PixelFormat> format = pixelFormatOfRosEncoding(first.encoding());
    if (!format) {
        return Status(ErrorCode::kUnsupported,
                      topic + " is " + first.encoding() +
                          ", which mixray has no pixel format for (rgb8, bgr8, mono8, mono16, "
                          "16UC1, bayer_*8, yuv422_yuy2)");
    }
    constexpr uint32_t kMaxSide = 1 << 15;
    if (first.width() == 0 || first.height() == 0 || first.width() > kMaxSide ||
        first.height() > kMaxSide) {
        return Status(ErrorCode::kCorruptData, topic + "'s image is " +
                                                   std::to_string(first.width()) + "x" +
                                                   std::to_string(first.height()));
    }
    ImageDesc desc = ImageDesc::packed(*format, static_cast<int>(first.width()),
                                       static_cast<int>(first.height()));
    if (first.is_bigendian() != 0 || first.step() < static_cast<uint32_t>(desc.stride_bytes) ||
        first.step() > static_cast<uint32_t>(desc.stride_bytes) + 4096 ||
        first.data().size() != size_t{first.step()} * first.height()) {
        return Status(ErrorCode::kCorruptData, topic + "'s images are not a " + first.encoding() +
                                                   " image of " + std::to_string(first.width()) +
                                                   "x" + std::to_string(first.height()) +
                                                   " in little-endian rows of step bytes (step " +
                                                   std::to_string(first.step()) + ", " +
                                                   std::to_string(first.data().size()) + " bytes)");
    }
    desc.stride_bytes = static_cast<int>(first.step());
    StreamInfo info;
    info.name = device + "/image";
    info.device = device;
    info.kind = kindOf(*format);
    info.format = desc;
    info.clock_domain = deviceClockDomain("ros2", topic);
    info.tags["ros2.topic"] = topic;
    info.tags["ros2.frame_id"] = first.header().frame_id();
    info.tags["ros2.encoding"] = first.encoding();
    return info;
}

}  // namespace

Result<StreamInfo> rosImageStream(std::span<const uint8_t> sample, const std::string& device,
                                  const std::string& topic) {
    detail::RosImage image;
    if (!detail::deserializeSample<sensor_msgs::msg::dds_::Image_PubSubType>(sample, &image))
        return Status(ErrorCode::kCorruptData, "ros2: not a sensor_msgs Image in CDR");
    return streamOf(image, device, topic);
}

Status rosImageFrame(std::span<const uint8_t> sample, const StreamInfo& stream, FrameMetadata* meta,
                     Image* image) {
    detail::RosImage message;
    if (!detail::deserializeSample<sensor_msgs::msg::dds_::Image_PubSubType>(sample, &message))
        return {ErrorCode::kCorruptData, "ros2: not a sensor_msgs Image in CDR"};
    if (!fitsStream(message, stream))
        return {ErrorCode::kCorruptData, "ros2: the image is not of stream " + stream.name};
    *meta = FrameMetadata{};
    meta->device_stamp_ns = stampNs(message);
    meta->clock_domain = stream.clock_domain;
    *image = Image(stream.format);
    image->bytes().assign(message.data().begin(), message.data().end());
    return Status::ok();
}

std::vector<uint8_t> serializeRosImage(const ImageView& image, int64_t stamp_ns,
                                       const std::string& frame_id) {
    detail::RosImage message;
    message.header().stamp(detail::rosTime(stamp_ns));
    message.header().frame_id(frame_id);
    message.height(static_cast<uint32_t>(image.desc.height));
    message.width(static_cast<uint32_t>(image.desc.width));
    message.encoding(std::string(detail::rosEncoding(image.desc.format).value_or("")));
    message.step(static_cast<uint32_t>(image.desc.stride_bytes));
    message.data().assign(image.data, image.data + image.size_bytes);
    return detail::serializeSample<sensor_msgs::msg::dds_::Image_PubSubType>(message);
}

std::optional<PixelFormat> pixelFormatOfRosEncoding(std::string_view encoding) {
    // The formats the publisher writes (rosEncoding), read back; mono16 is read as mono, not IR.
    for (PixelFormat format :
         {PixelFormat::kMono8, PixelFormat::kMono16, PixelFormat::kRGB8, PixelFormat::kBGR8,
          PixelFormat::kBayerRGGB8, PixelFormat::kBayerGRBG8, PixelFormat::kBayerGBRG8,
          PixelFormat::kBayerBGGR8, PixelFormat::kYUYV, PixelFormat::kDepth16}) {
        if (detail::rosEncoding(format) == encoding)
            return format;
    }
    return std::nullopt;
}

Status parseRos2SourceOptions(const DeviceConfig& config, Ros2SourceOptions* options) {
    DeviceOptionReader reader(config, "ros2");
    MIXRAY_RETURN_IF_ERROR(readDdsOptions(reader, &options->dds));
    MIXRAY_RETURN_IF_ERROR(reader.integer("discovery_timeout_ms", options->discovery_timeout_ms,
                                          int64_t{0}, int64_t{600000}, "0..600000"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer("buffers", options->buffers, size_t{2}, size_t{256}, "2..256"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("history", options->history, 1, 64, "1..64"));
    MIXRAY_RETURN_IF_ERROR(reader.choice("reliability", options->reliable,
                                         {{"best_effort", false}, {"reliable", true}},
                                         "best_effort or reliable"));
    return reader.leftovers(std::string(kDdsOptionKeys) +
                            ", discovery_timeout_ms, buffers, history, reliability");
}

struct Ros2ImageDevice::Impl {
    DeviceConfig config;
    Ros2SourceOptions options;
    std::string topic;  // the ROS 2 name, "/robot/camera/image_raw"
    std::shared_ptr<detail::Participant> participant;
    fdds::DataReader* reader = nullptr;
    StreamInfo info;
    PooledStream pooled;
    Graph* graph = nullptr;
    std::thread thread;
    std::atomic<bool> stopping{false};
    uint64_t sequence = 0;  // receive thread only
    std::atomic<uint64_t> received{0};
    std::atomic<uint64_t> published{0};
    std::atomic<uint64_t> rejected{0};
    std::atomic<uint64_t> pool_exhausted{0};
    std::atomic<bool> ever_matched{false};

    int matchedWriters() const {
        fdds::SubscriptionMatchedStatus matched;
        if (reader && reader->get_subscription_matched_status(matched) == ReturnCode_t::RETCODE_OK)
            return matched.current_count;
        return 0;
    }
    void take(detail::RosImage& image);
};

void Ros2ImageDevice::Impl::take(detail::RosImage& image) {
    fdds::SampleInfo sample;
    while (reader->take_next_sample(&image, &sample) == ReturnCode_t::RETCODE_OK) {
        if (!sample.valid_data)
            continue;
        const int64_t arrival_ns = monotonicNowNs();
        received.fetch_add(1, std::memory_order_relaxed);
        const bool fits = fitsStream(image, info);
        if (!fits) {
            rejected.fetch_add(1, std::memory_order_relaxed);
            continue;
        }
        WritableFrame frame = pooled.pool->acquire();
        if (!frame) {
            pool_exhausted.fetch_add(1, std::memory_order_relaxed);
            graph->countLost(pooled.id);
            continue;
        }
        frame.meta().stream = pooled.id;
        frame.meta().sequence = sequence++;
        frame.meta().host_stamp_ns = arrival_ns;
        frame.meta().device_stamp_ns = stampNs(image);
        frame.meta().clock_domain = info.clock_domain;
        std::memcpy(frame.image().data, image.data().data(), image.data().size());
        graph->publish(std::move(frame).publish());
        published.fetch_add(1, std::memory_order_relaxed);
    }
}

Ros2ImageDevice::Ros2ImageDevice(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Ros2ImageDevice::~Ros2ImageDevice() {
    stop();
}

std::string Ros2ImageDevice::name() const {
    return impl_->config.name;
}

DeviceDescriptor Ros2ImageDevice::descriptor() const {
    DeviceDescriptor d;
    d.backend = "ros2";
    d.id = impl_->topic;
    d.model = "ROS 2 topic " + impl_->topic + " (sensor_msgs/msg/Image)";
    d.location = "dds domain " + std::to_string(impl_->options.dds.domain);
    const ImageDesc& f = impl_->info.format;
    d.modes.push_back("image " + std::to_string(f.width) + "x" + std::to_string(f.height) + " " +
                      std::string(toString(f.format)));
    return d;
}

DeviceState Ros2ImageDevice::state() const {
    const int writers = impl_->matchedWriters();
    if (writers > 0)
        impl_->ever_matched = true;
    return writers == 0 && impl_->ever_matched ? DeviceState::kReconnecting
                                               : DeviceState::kStreaming;
}

std::string Ros2ImageDevice::clockReport() const {
    return "header.stamp of " + impl_->topic + " (the publisher's ROS time), fitted to arrival";
}

Status Ros2ImageDevice::connect(Graph& graph) {
    impl_->graph = &graph;
    auto pooled = addPooledStream(graph, impl_->info, impl_->options.buffers);
    if (!pooled)
        return pooled.status();
    impl_->pooled = *pooled;
    return Status::ok();
}

Status Ros2ImageDevice::start() {
    Impl& d = *impl_;
    if (!d.graph)
        return {ErrorCode::kInternal, "ros2 device: start() before connect()"};
    d.stopping = false;
    d.thread = std::thread([&d] {
        runAs(ThreadRole::kCapture);
        detail::RosImage image;
        while (!d.stopping.load(std::memory_order_relaxed)) {
            (void)d.reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 50'000'000));
            d.take(image);
        }
    });
    return Status::ok();
}

void Ros2ImageDevice::stop() {
    impl_->stopping = true;
    if (impl_->thread.joinable())
        impl_->thread.join();
}

Ros2SourceStats Ros2ImageDevice::stats() const {
    return {.received = impl_->received.load(std::memory_order_relaxed),
            .published = impl_->published.load(std::memory_order_relaxed),
            .rejected = impl_->rejected.load(std::memory_order_relaxed),
            .pool_exhausted = impl_->pool_exhausted.load(std::memory_order_relaxed),
            .matched_writers = impl_->matchedWriters()};
}

Result<std::unique_ptr<Device>> Ros2Backend::open(const DeviceConfig& config) {
    auto impl = std::make_unique<Ros2ImageDevice::Impl>();
    impl->config = config;
    impl->options.dds = defaults_;
    MIXRAY_RETURN_IF_ERROR(parseRos2SourceOptions(config, &impl->options));
    const std::string who = "ros2 device '" + config.name + "'";
    impl->topic = config.id.starts_with('/') ? config.id : "/" + config.id;
    if (config.id.empty() || !detail::isRosName(impl->topic) || impl->topic.ends_with('/')) {
        return Status(ErrorCode::kInvalidArgument,
                      who + ": id: expected a ROS 2 image topic such as /camera/image_raw, got '" +
                          config.id + "'");
    }
    if (!config.streams.empty() && (config.streams.size() > 1 || config.streams[0] != "image")) {
        return Status(ErrorCode::kInvalidArgument,
                      who + ": streams: a ROS 2 topic device has one stream, image");
    }
    auto participant =
        detail::Participant::create(impl->options.dds, "mixray ros2 device " + config.name);
    if (!participant)
        return participant.status().withContext(who);
    impl->participant = *participant;
    // ROS 2's DDS topic of a ROS name: "rt" and the name.
    auto topic = impl->participant->topic("rt" + impl->topic, detail::rosImageType());
    if (!topic)
        return topic.status().withContext(who);
    impl->reader = impl->participant->subscriber()->create_datareader(
        *topic,
        detail::withRosTypeHash(detail::rosReaderQos(impl->options.reliable, impl->options.history),
                                "sensor_msgs/msg/Image"));
    if (!impl->reader)
        return Status(ErrorCode::kInternal, who + ": cannot read " + impl->topic);

    // The first image says the stream's format.
    detail::RosImage first;
    fdds::SampleInfo sample;
    bool got = false;
    const int64_t until = monotonicNowNs() + impl->options.discovery_timeout_ms * 1'000'000;
    while (!got) {
        while (!got && impl->reader->take_next_sample(&first, &sample) == ReturnCode_t::RETCODE_OK)
            got = sample.valid_data;
        if (got || monotonicNowNs() >= until)
            break;
        (void)impl->reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 20'000'000));
    }
    if (!got) {
        return Status(ErrorCode::kNotFound,
                      who + ": no image on " + impl->topic + " within " +
                          std::to_string(impl->options.discovery_timeout_ms) +
                          " ms in dds domain " + std::to_string(impl->options.dds.domain) + " (" +
                          std::to_string(impl->matchedWriters()) + " publishers matched" +
                          (impl->options.reliable ? "; reliability: reliable matches reliable "
                                                    "publishers only"
                                                  : "") +
                          ")");
    }
    auto info = streamOf(first, config.name, impl->topic);
    if (!info)
        return info.status().withContext(who);
    impl->info = std::move(info).value();
    return std::unique_ptr<Device>(new Ros2ImageDevice(std::move(impl)));
}

}  // namespace mixray::dds
