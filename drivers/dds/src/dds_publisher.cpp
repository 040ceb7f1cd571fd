#include "mixray/dds/dds_publisher.h"

#include <atomic>
#include <chrono>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <mutex>
#include <optional>
#include <thread>

#include "frame_message.h"
#include "participant.h"
#include "ros_image.h"
#include "time_exchange.h"

namespace mixray::dds {

namespace fdds = eprosima::fastdds::dds;

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
    for (char c : ros2_rig) {
        const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                        (c >= '0' && c <= '9') || c == '_' || c == '/';
        if (!ok) {
            return {ErrorCode::kInvalidArgument,
                    "dds publisher: ros2 rig name: ROS 2 names take letters, digits, '_' and "
                    "'/', got '" +
                        ros2_rig + "'"};
        }
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
        std::optional<std::string_view> ros_encoding;
        fdds::InstanceHandle_t announcement;
        bool disposed = false;  // guarded by Impl::mutex
        std::thread thread;
        std::atomic<uint64_t> written{0};
        std::atomic<uint64_t> write_errors{0};
        std::atomic<uint64_t> ros_written{0};
    };

    DdsPublisherOptions options;
    std::string host;
    Graph* graph = nullptr;
    std::vector<std::unique_ptr<Stream>> streams;
    std::shared_ptr<detail::Participant> participant;
    fdds::DataWriter* announcer = nullptr;
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
};

void DdsPublisher::Impl::run(Stream& stream) {
    detail::FrameMessage message;
    detail::RosImage ros_message;
    const std::string frame_id = detail::rosFrameId(stream.info.name);
    while (!stopping.load(std::memory_order_relaxed)) {
        std::optional<FrameRef> frame = stream.queue->pop(std::chrono::milliseconds(100));
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
            detail::toRosImage(*frame, frame_id, &ros_message);
            if (stream.ros_writer->write(&ros_message))
                stream.ros_written.fetch_add(1, std::memory_order_relaxed);
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
        if (!options.ros2_rig.empty() && stream->ros_encoding) {
            auto ros_topic = participant->topic(
                detail::rosImageTopic(options.ros2_rig, stream->info.name), detail::rosImageType());
            if (!ros_topic)
                return ros_topic.status();
            // rviz2 and ros2 topic echo default to reliable readers; a reliable writer serves
            // best-effort (sensor data) readers as well.
            stream->ros_writer = participant->publisher()->create_datawriter(
                *ros_topic, detail::frameWriterQos(options.dds, options.history_depth));
            if (!stream->ros_writer)
                return {ErrorCode::kInternal,
                        "dds publisher: cannot create the ROS 2 writer of " + stream->info.name};
        }
        detail::AnnouncementMessage announcement =
            detail::toAnnouncement(stream->info, host, deviceStreams(stream->info.device));
        stream->announcement = announcer->register_instance(&announcement);
        if (!announcer->write(&announcement, stream->announcement))
            return {ErrorCode::kInternal, "dds publisher: cannot announce " + stream->info.name};
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
        auto queue = graph.subscribe(
            id,
            {.capacity = d.options.queue_capacity, .policy = QueuePolicy::kLive, .name = name()});
        if (!queue)
            return queue.status();
        stream->queue = *queue;
        d.streams.push_back(std::move(stream));
    }
    std::lock_guard lock(d.mutex);
    const Status made = d.createWriters();
    if (!made.isOk()) {
        d.time_responder.reset();
        d.participant.reset();
        for (auto& stream : d.streams)
            stream->writer = stream->ros_writer = nullptr;
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
        stream->thread = std::thread([&d, s = stream.get()] { d.run(*s); });
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
        stream->writer = stream->ros_writer = nullptr;
    }
    d.announcer = nullptr;
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
