#include "mixray/dds/dds_publisher.h"

#include <atomic>
#include <chrono>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <mutex>
#include <optional>
#include <thread>

#include "frame_message.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/pose.h"
#include "mixray/graph/thread_priority.h"
#include "participant.h"
#include "ros_camera.h"
#include "ros_image.h"
#include "time_exchange.h"

namespace mixray::dds {

namespace fdds = eprosima::fastdds::dds;

std::optional<std::string_view> rosImageEncoding(PixelFormat format) {
    return detail::rosEncoding(format);
}

Status DdsPublisherOptions::validate() const {
    MIXRAY_RETURN_IF_ERROR(dds.validate());
    if (queue_capacity < 1 || queue_capacity > 64) {
        return {ErrorCode::kInvalidArgument, "dds publisher: queue_capacity: expected 1..64, got " +
                                                 std::to_string(queue_capacity)};
    }
    if (history_depth < 1 || history_depth > 64) {
        return {ErrorCode::kInvalidArgument, "dds publisher: history_depth: expected 1..64, got " +
                                                 std::to_string(history_depth)};
    }
    if (!ros2_rig.empty() && !detail::isRosName(ros2_rig)) {
        return {ErrorCode::kInvalidArgument,
                "dds publisher: ros2 rig name: ROS 2 names take letters, digits, '_' and '/', "
                "got '" +
                    ros2_rig + "'"};
    }
    if (ros2_rig.empty() && (!ros2_camera_info.empty() || !ros2_transforms.empty())) {
        return {ErrorCode::kInvalidArgument,
                "dds publisher: camera calibrations and transforms go to ROS 2 topics: name the "
                "ROS 2 rig (ros2_rig, --ros2)"};
    }
    return Status::ok();
}

struct DdsPublisher::Impl {
    struct Stream {
        StreamInfo info;
        std::shared_ptr<FrameQueue> queue;
        std::string topic;
        fdds::DataWriter* writer = nullptr;
        fdds::DataWriter* ros_writer = nullptr;
        fdds::DataWriter* ros_camera_info_writer = nullptr;
        // A pose stream's poses go to ROS 2 as tf (the shared rt/tf writer), the camera its
        // `pose_of` tag names as the child frame.
        bool ros_tf = false;
        std::string tf_child;
        std::optional<std::string_view> ros_encoding;
        std::optional<calibration::RosCameraInfo> camera_info;
        fdds::InstanceHandle_t announcement;
        bool disposed = false;  // guarded by Impl::mutex
        std::thread thread;
        std::atomic<uint64_t> written{0};
        std::atomic<uint64_t> write_errors{0};
        std::atomic<uint64_t> ros_written{0};
        std::atomic<uint64_t> ros_camera_info_written{0};
    };

    DdsPublisherOptions options;
    std::string host;
    Graph* graph = nullptr;
    std::vector<std::unique_ptr<Stream>> streams;
    std::shared_ptr<detail::Participant> participant;
    fdds::DataWriter* announcer = nullptr;
    fdds::DataWriter* tf_static_writer = nullptr;
    fdds::DataWriter* tf_writer = nullptr;  // shared by every pose stream
    // Answers other hosts' clock requests for as long as this host publishes.
    std::unique_ptr<detail::TimeResponder> time_responder;
    std::atomic<bool> stopping{false};
    mutable std::mutex mutex;  // guards the writers' existence for stats()

    void run(Stream& stream);
    void endStream(Stream& stream);
    // The names of the published streams of `device`: a receiver opens the device once it has
    // heard all of them.
    std::vector<std::string> deviceStreams(const std::string& device) const {
        std::vector<std::string> out;
        for (const auto& s : streams) {
            if (s->info.device == device)
                out.push_back(s->info.name);
        }
        return out;
    }
    Status createWriters();
    Status createRosWriters(Stream& stream);
    // A valid pose as one tf transform, stamped as its frame; stale and lost poses are not
    // sent (tf would take them for current).
    void writeTf(Stream& stream, const FrameRef& frame);
    // Checks each calibration against the stream it names and hands it to the stream.
    Status assignCameraInfo();
};

void DdsPublisher::Impl::run(Stream& stream) {
    detail::FrameMessage message;
    detail::RosImage ros_message;
    detail::RosCameraInfoMessage camera_info_message;
    if (stream.camera_info)
        detail::toRosCameraInfo(*stream.camera_info, &camera_info_message);
    const std::string frame_id = detail::rosFrameId(stream.info.name);
    while (!stopping.load(std::memory_order_relaxed)) {
        std::optional<FrameRef> frame = stream.queue->pop(std::chrono::milliseconds(100));
        if (frame && stream.ros_tf)
            writeTf(stream, *frame);
        if (!frame) {
            if (stream.queue->closed()) {
                // Graph::stop() closes every queue too, after it stops running.
                if (!stopping.load() && graph->running())
                    endStream(stream);
                break;
            }
            continue;
        }
        detail::toMessage(frame->meta(), frame->image(), &message);
        if (stream.writer->write(&message))
            stream.written.fetch_add(1, std::memory_order_relaxed);
        else
            stream.write_errors.fetch_add(1, std::memory_order_relaxed);
        if (stream.ros_writer) {
            detail::toRosImage(*frame, frame_id, detail::liveRosStampNs(frame->meta()),
                               &ros_message);
            if (stream.ros_writer->write(&ros_message))
                stream.ros_written.fetch_add(1, std::memory_order_relaxed);
            else
                stream.write_errors.fetch_add(1, std::memory_order_relaxed);
        }
        if (stream.ros_camera_info_writer) {
            camera_info_message.header(ros_message.header());
            if (stream.ros_camera_info_writer->write(&camera_info_message))
                stream.ros_camera_info_written.fetch_add(1, std::memory_order_relaxed);
            else
                stream.write_errors.fetch_add(1, std::memory_order_relaxed);
        }
    }
}

// The graph ended the stream (a recording or finite source ran out): once every reader has
// acknowledged the last frames, disposing the announcement tells them it ended, so they end
// their own stream with nothing lost instead of waiting for a host that is still there.
void DdsPublisher::Impl::endStream(Stream& stream) {
    (void)stream.writer->wait_for_acknowledgments(eprosima::fastrtps::Duration_t(5, 0));
    std::lock_guard lock(mutex);
    detail::AnnouncementMessage announcement =
        detail::toAnnouncement(stream.info, host, deviceStreams(stream.info.device));
    (void)announcer->dispose(&announcement, stream.announcement);
    stream.disposed = true;
}

Status DdsPublisher::Impl::createWriters() {
    auto made = detail::Participant::create(options.dds, "mixray publisher on " + host);
    if (!made)
        return made.status();
    participant = *made;
    // Before the announcements: a receiver that hears them asks for this host's time at once.
    auto responder = detail::TimeResponder::create(participant, host, options.dds.ptp4l);
    if (!responder)
        return responder.status();
    time_responder = std::move(responder).value();

    auto announcement_topic =
        participant->topic(std::string(kAnnouncementTopic), detail::announcementType());
    if (!announcement_topic)
        return announcement_topic.status();
    announcer = participant->publisher()->create_datawriter(*announcement_topic,
                                                            detail::announcementWriterQos());
    if (!announcer)
        return {ErrorCode::kInternal, "dds publisher: cannot create the announcement writer"};

    for (auto& stream : streams) {
        auto topic = participant->topic(stream->topic, detail::frameType());
        if (!topic)
            return topic.status();
        stream->writer = participant->publisher()->create_datawriter(
            *topic, detail::frameWriterQos(options.dds, options.history_depth));
        if (!stream->writer)
            return {ErrorCode::kInternal,
                    "dds publisher: cannot create a writer for " + stream->topic};
        if (!options.ros2_rig.empty() && stream->ros_encoding)
            MIXRAY_RETURN_IF_ERROR(createRosWriters(*stream));
        if (stream->ros_tf && !tf_writer) {
            auto tf_topic = participant->topic(detail::kRosTfTopic, detail::rosTfType());
            if (!tf_topic)
                return tf_topic.status();
            // tf2_ros's broadcaster and listeners: reliable, volatile, keep last 100.
            tf_writer = participant->publisher()->create_datawriter(
                *tf_topic, detail::withRosTypeHash(detail::frameWriterQos(options.dds, 100),
                                                   "tf2_msgs/msg/TFMessage"));
            if (!tf_writer)
                return {ErrorCode::kInternal, "dds publisher: cannot create the tf writer"};
        }
        detail::AnnouncementMessage announcement =
            detail::toAnnouncement(stream->info, host, deviceStreams(stream->info.device));
        stream->announcement = announcer->register_instance(&announcement);
        if (!announcer->write(&announcement, stream->announcement))
            return {ErrorCode::kInternal, "dds publisher: cannot announce " + stream->info.name};
    }
    if (!options.ros2_transforms.empty()) {
        auto topic = participant->topic(detail::kRosTfStaticTopic, detail::rosTfType());
        if (!topic)
            return topic.status();
        tf_static_writer = participant->publisher()->create_datawriter(
            *topic,
            detail::withRosTypeHash(detail::rosTfStaticWriterQos(), "tf2_msgs/msg/TFMessage"));
        if (!tf_static_writer)
            return {ErrorCode::kInternal, "dds publisher: cannot create the tf_static writer"};
        detail::RosTfMessage transforms = detail::toRosTf(options.ros2_transforms, realtimeNowNs());
        if (!tf_static_writer->write(&transforms))
            return {ErrorCode::kInternal, "dds publisher: cannot write tf_static"};
    }
    return Status::ok();
}

void DdsPublisher::Impl::writeTf(Stream& stream, const FrameRef& frame) {
    auto pose = decodePoseRecord(frame.image());
    if (!pose || pose->status != PoseStatus::kValid)
        return;
    const Eigen::Isometry3d T = pose->transform();
    const Eigen::Quaterniond q(T.rotation());
    const calibration::RosTransform transform{
        .parent = pose->anchor,
        .child = stream.tf_child,
        .translation = {T.translation().x(), T.translation().y(), T.translation().z()},
        .rotation_xyzw = {q.x(), q.y(), q.z(), q.w()}};
    detail::RosTfMessage message =
        detail::toRosTf({transform}, detail::liveRosStampNs(frame.meta()));
    if (tf_writer->write(&message))
        stream.ros_written.fetch_add(1, std::memory_order_relaxed);
    else
        stream.write_errors.fetch_add(1, std::memory_order_relaxed);
}

Status DdsPublisher::Impl::createRosWriters(Stream& stream) {
    auto topic = participant->topic(detail::rosImageTopic(options.ros2_rig, stream.info.name),
                                    detail::rosImageType());
    if (!topic)
        return topic.status();
    // rviz2 and ros2 topic echo default to reliable readers; a reliable writer serves
    // best-effort (sensor data) readers as well.
    const fdds::DataWriterQos qos = detail::frameWriterQos(options.dds, options.history_depth);
    stream.ros_writer = participant->publisher()->create_datawriter(
        *topic, detail::withRosTypeHash(qos, "sensor_msgs/msg/Image"));
    if (!stream.ros_writer)
        return {ErrorCode::kInternal,
                "dds publisher: cannot create the ROS 2 writer of " + stream.info.name};
    if (!stream.camera_info)
        return Status::ok();
    auto info_topic =
        participant->topic(detail::rosCameraInfoTopic(options.ros2_rig, stream.info.name),
                           detail::rosCameraInfoType());
    if (!info_topic)
        return info_topic.status();
    stream.ros_camera_info_writer = participant->publisher()->create_datawriter(
        *info_topic, detail::withRosTypeHash(qos, "sensor_msgs/msg/CameraInfo"));
    if (!stream.ros_camera_info_writer)
        return {ErrorCode::kInternal,
                "dds publisher: cannot create the ROS 2 camera_info writer of " + stream.info.name};
    return Status::ok();
}

Status DdsPublisher::Impl::assignCameraInfo() {
    for (const auto& [name, info] : options.ros2_camera_info) {
        Stream* stream = nullptr;
        for (auto& s : streams) {
            if (s->info.name == name)
                stream = s.get();
        }
        if (!stream || !stream->ros_encoding) {
            return {ErrorCode::kNotFound,
                    "dds publisher: a calibration for '" + name +
                        "', which is not a published image stream with a ROS 2 encoding"};
        }
        const ImageDesc& image = stream->info.format;
        if (info.width != static_cast<uint32_t>(image.width) ||
            info.height != static_cast<uint32_t>(image.height)) {
            return {ErrorCode::kInvalidArgument,
                    "dds publisher: the calibration of " + name + " is for " +
                        std::to_string(info.width) + "x" + std::to_string(info.height) +
                        " images and the stream's are " + std::to_string(image.width) + "x" +
                        std::to_string(image.height)};
        }
        stream->camera_info = info;
    }
    return Status::ok();
}

DdsPublisher::DdsPublisher(DdsPublisherOptions options) : impl_(std::make_unique<Impl>()) {
    impl_->options = std::move(options);
    impl_->host = impl_->options.dds.hostName();
}

DdsPublisher::~DdsPublisher() {
    stop();
}

Result<std::unique_ptr<DdsPublisher>> DdsPublisher::create(DdsPublisherOptions options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    return std::unique_ptr<DdsPublisher>(new DdsPublisher(std::move(options)));
}

Status DdsPublisher::connect(Graph& graph) {
    Impl& d = *impl_;
    d.graph = &graph;
    std::vector<StreamId> ids;
    if (d.options.streams.empty()) {
        for (StreamId id = 0; id < graph.streamCount(); ++id)
            ids.push_back(id);
    } else {
        for (const std::string& name : d.options.streams) {
            auto id = graph.findStream(name);
            if (!id)
                return {ErrorCode::kNotFound,
                        "dds publisher: no stream '" + name + "' in the graph"};
            ids.push_back(*id);
        }
    }
    for (StreamId id : ids) {
        auto stream = std::make_unique<Impl::Stream>();
        stream->info = graph.stream(id);
        stream->topic = frameTopic(d.host, stream->info.name);
        stream->ros_encoding = detail::rosEncoding(stream->info.format.format);
        if (stream->info.kind == StreamKind::kPose && !d.options.ros2_rig.empty()) {
            const auto pose_of = stream->info.tags.find("pose_of");
            stream->ros_tf = pose_of != stream->info.tags.end();
            if (stream->ros_tf)
                stream->tf_child = pose_of->second;
        }
        auto queue = graph.subscribe(
            id,
            {.capacity = d.options.queue_capacity, .policy = QueuePolicy::kLive, .name = name()});
        if (!queue)
            return queue.status();
        stream->queue = *queue;
        d.streams.push_back(std::move(stream));
    }
    MIXRAY_RETURN_IF_ERROR(d.assignCameraInfo());
    std::lock_guard lock(d.mutex);
    const Status made = d.createWriters();
    if (!made.isOk()) {
        d.time_responder.reset();
        d.participant.reset();
        for (auto& stream : d.streams)
            stream->writer = stream->ros_writer = stream->ros_camera_info_writer = nullptr;
        d.announcer = d.tf_static_writer = d.tf_writer = nullptr;
        return made;
    }
    return Status::ok();
}

bool DdsPublisher::waitForReaders(int readers, std::chrono::milliseconds timeout) const {
    const auto until = std::chrono::steady_clock::now() + timeout;
    for (;;) {
        bool all = true;
        for (const DdsStreamStats& s : stats())
            all = all && s.matched_readers >= readers;
        if (all)
            return true;
        if (std::chrono::steady_clock::now() >= until)
            return false;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
}

Status DdsPublisher::start() {
    Impl& d = *impl_;
    if (!d.participant)
        return {ErrorCode::kInternal, "dds publisher: start() before a successful connect()"};
    d.stopping = false;
    for (auto& stream : d.streams)
        stream->thread = std::thread([&d, s = stream.get()] {
            runAs(ThreadRole::kPublisher);
            d.run(*s);
        });
    return Status::ok();
}

void DdsPublisher::stop() {
    Impl& d = *impl_;
    d.stopping = true;
    for (auto& stream : d.streams) {
        if (stream->queue)
            stream->queue->close();
        if (stream->thread.joinable())
            stream->thread.join();
    }
    std::lock_guard lock(d.mutex);
    if (!d.participant)
        return;
    // Withdraw the announcements so that other hosts stop listing the streams at once, rather
    // than when this participant's lease runs out.
    for (auto& stream : d.streams) {
        detail::AnnouncementMessage announcement =
            detail::toAnnouncement(stream->info, d.host, d.deviceStreams(stream->info.device));
        if (!stream->disposed)
            (void)d.announcer->unregister_instance(&announcement, stream->announcement);
        stream->writer = stream->ros_writer = stream->ros_camera_info_writer = nullptr;
    }
    d.announcer = d.tf_static_writer = d.tf_writer = nullptr;
    d.time_responder.reset();
    d.participant.reset();
}

std::vector<DdsStreamStats> DdsPublisher::stats() const {
    const Impl& d = *impl_;
    std::lock_guard lock(d.mutex);
    std::vector<DdsStreamStats> out;
    for (const auto& stream : d.streams) {
        DdsStreamStats s;
        s.stream = stream->info.name;
        s.topic = stream->topic;
        const QueueStats queue = stream->queue->stats();
        s.frames_in = queue.pushed;
        s.dropped = queue.dropped;
        s.written = stream->written.load(std::memory_order_relaxed);
        s.write_errors = stream->write_errors.load(std::memory_order_relaxed);
        s.ros_written = stream->ros_written.load(std::memory_order_relaxed);
        s.ros_camera_info_written = stream->ros_camera_info_written.load(std::memory_order_relaxed);
        fdds::PublicationMatchedStatus matched;
        if (stream->writer &&
            stream->writer->get_publication_matched_status(matched) == ReturnCode_t::RETCODE_OK)
            s.matched_readers = matched.current_count;
        if (stream->ros_writer &&
            stream->ros_writer->get_publication_matched_status(matched) == ReturnCode_t::RETCODE_OK)
            s.ros_matched_readers = matched.current_count;
        out.push_back(std::move(s));
    }
    return out;
}

std::string DdsPublisher::host() const {
    return impl_->host;
}

}  // namespace mixray::dds
