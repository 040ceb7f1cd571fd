#include "mixray/dds/dds_backend.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "frame_message.h"
#include "mixray/graph/clock.h"
#include "mixray/graph/device_options.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"
#include "participant.h"
#include "time_exchange.h"

namespace mixray::dds {

namespace fdds = eprosima::fastdds::dds;

namespace {

using Clock = std::chrono::steady_clock;

// One announced stream as a listener sees it.
struct Announced {
    std::string host;
    StreamInfo info;                          // as announced: name "device/stream"
    std::vector<std::string> device_streams;  // every stream of its device the host publishes
    std::string topic;
    bool disposed = false;  // the stream ended on its host
};

// Reads kAnnouncementTopic: every host's streams, kept current as hosts come, end streams and
// leave. Thread-bound.
class AnnouncementListener {
public:
    static Result<std::unique_ptr<AnnouncementListener>> create(detail::Participant& participant) {
        auto topic = participant.topic(std::string(kAnnouncementTopic), detail::announcementType());
        if (!topic)
            return topic.status();
        auto listener = std::make_unique<AnnouncementListener>();
        listener->reader_ =
            participant.subscriber()->create_datareader(*topic, detail::announcementReaderQos());
        if (!listener->reader_)
            return Status{ErrorCode::kInternal,
                          "dds: cannot read " + std::string(kAnnouncementTopic)};
        return listener;
    }

    // Takes what arrived; announcements this build cannot use are remembered in rejected().
    void poll() {
        detail::AnnouncementMessage message;
        fdds::SampleInfo info;
        while (reader_->take_next_sample(&message, &info) == ReturnCode_t::RETCODE_OK) {
            if (info.valid_data) {
                auto stream = detail::streamOf(message);
                if (!stream) {
                    rejected_.insert(stream.status().message());
                    continue;
                }
                streams_[info.instance_handle] = {message.host(), *stream, message.device_streams(),
                                                  message.topic(), false};
            } else if (info.instance_state == fdds::NOT_ALIVE_DISPOSED_INSTANCE_STATE) {
                if (auto found = streams_.find(info.instance_handle); found != streams_.end())
                    found->second.disposed = true;
            } else if (info.instance_state == fdds::NOT_ALIVE_NO_WRITERS_INSTANCE_STATE) {
                streams_.erase(info.instance_handle);
            }
        }
    }

    // Polls until `done` says so or `timeout_ms` passes.
    template <typename Done>
    void listen(int64_t timeout_ms, Done done) {
        const auto until = Clock::now() + std::chrono::milliseconds(timeout_ms);
        for (;;) {
            poll();
            if (done() || Clock::now() >= until)
                return;
            (void)reader_->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 20'000'000));
        }
    }

    std::vector<Announced> streams() const {
        std::vector<Announced> out;
        for (const auto& [handle, announced] : streams_)
            out.push_back(announced);
        return out;
    }
    const std::set<std::string>& rejected() const { return rejected_; }
    fdds::DataReader* reader() const { return reader_; }

private:
    fdds::DataReader* reader_ = nullptr;
    std::map<fdds::InstanceHandle_t, Announced> streams_;
    std::set<std::string> rejected_;
};

// A name for this device's clock requests that no other requester in the domain has: the
// answers are addressed to it.
std::string requesterName(const DeviceConfig& config) {
    static std::atomic<uint64_t> count{0};
    char host[256] = {};
    (void)gethostname(host, sizeof host - 1);
    return std::string(host) + "/" + std::to_string(getpid()) + "/" + config.name + "/" +
           std::to_string(count.fetch_add(1));
}

}  // namespace

Status parseDdsDeviceOptions(const DeviceConfig& config, DdsDeviceOptions* options) {
    DeviceOptionReader reader(config, "dds");
    MIXRAY_RETURN_IF_ERROR(readDdsOptions(reader, &options->dds));
    MIXRAY_RETURN_IF_ERROR(reader.integer("discovery_timeout_ms", options->discovery_timeout_ms,
                                          int64_t{0}, int64_t{600000}, "0..600000"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer("buffers", options->buffers, size_t{2}, size_t{256}, "2..256"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("history", options->history, 1, 64, "1..64"));
    MIXRAY_RETURN_IF_ERROR(reader.choice("clock", options->clock,
                                         {{"exchange", DdsDeviceOptions::Clock::kExchange},
                                          {"wall", DdsDeviceOptions::Clock::kWall},
                                          {"arrival", DdsDeviceOptions::Clock::kArrival}},
                                         "exchange, wall or arrival"));
    return reader.leftovers(std::string(kDdsOptionKeys) +
                            ", discovery_timeout_ms, buffers, history, clock");
}

struct DdsDevice::Impl {
    struct Stream {
        Announced remote;
        StreamInfo local;
        PooledStream pooled;
        fdds::DataReader* reader = nullptr;
        std::thread thread;
        int64_t last_arrival_ns = 0;  // receive thread only
        bool has_sequence = false;
        uint64_t last_sequence = 0;
        bool alive = false;  // its writer is alive now (guarded by Impl::state_mutex)
        bool ended = false;
        std::atomic<uint64_t> received{0};
        std::atomic<uint64_t> published{0};
        std::atomic<uint64_t> lost_in_transit{0};
        std::atomic<uint64_t> pool_exhausted{0};
        std::atomic<uint64_t> rejected{0};
    };

    DeviceConfig config;
    DdsDeviceOptions options;
    std::string host;    // the publishing host
    std::string device;  // its device name there
    std::shared_ptr<detail::Participant> participant;
    std::unique_ptr<AnnouncementListener> listener;
    // With clock: exchange and an answer at open(): the host's clock, fitted all along.
    std::unique_ptr<detail::TimeRequester> time;
    std::string clock_note;  // why the arrival is the time base, when it is
    std::vector<std::unique_ptr<Stream>> streams;
    Graph* graph = nullptr;
    std::atomic<bool> stopping{false};
    std::thread watcher;

    mutable std::mutex state_mutex;
    bool ever_alive = false;
    bool device_alive = false;
    size_t ended_streams = 0;
    uint64_t disconnections = 0;
    uint64_t reconnections = 0;

    void receive(Stream& stream);
    void take(Stream& stream, detail::FrameMessage& message);
    void setAlive(Stream& stream, bool alive);
    void watchAnnouncements();
};

void DdsDevice::Impl::setAlive(Stream& stream, bool alive) {
    std::lock_guard lock(state_mutex);
    stream.alive = alive;
    bool any = false;
    for (const auto& s : streams)
        any = any || s->alive;
    if (any == device_alive)
        return;
    device_alive = any;
    if (any && ever_alive)
        ++reconnections;
    if (!any)
        ++disconnections;
    ever_alive = ever_alive || any;
}

void DdsDevice::Impl::take(Stream& stream, detail::FrameMessage& message) {
    fdds::SampleInfo info;
    while (stream.reader->take_next_sample(&message, &info) == ReturnCode_t::RETCODE_OK) {
        if (!info.valid_data)
            continue;
        const int64_t arrival_ns = monotonicNowNs();
        stream.received.fetch_add(1, std::memory_order_relaxed);
        // A frame is proof of life before DDS's liveliness status says so: the device is
        // streaming by the time a consumer sees the frame.
        stream.last_arrival_ns = arrival_ns;
        setAlive(stream, true);
        if (!detail::checkMessage(message, stream.remote.info).isOk()) {
            stream.rejected.fetch_add(1, std::memory_order_relaxed);
            continue;
        }
        FrameMetadata meta = detail::metadataOf(message);
        // A gap in the device's numbering is frames lost between the hosts (or before them).
        if (stream.has_sequence && meta.sequence > stream.last_sequence + 1) {
            const uint64_t gap = meta.sequence - stream.last_sequence - 1;
            stream.lost_in_transit.fetch_add(gap, std::memory_order_relaxed);
            graph->countLost(stream.pooled.id, gap);
        }
        stream.has_sequence = true;
        stream.last_sequence = meta.sequence;

        WritableFrame frame = stream.pooled.pool->acquire();
        if (!frame) {
            stream.pool_exhausted.fetch_add(1, std::memory_order_relaxed);
            graph->countLost(stream.pooled.id);
            continue;
        }
        if (time) {
            // The host's stamps on this host's clock; its device clocks stay theirs.
            const std::optional<HostClockEstimate> clock = time->estimate();
            if (meta.clock_domain == kHostClockDomain)
                meta.device_stamp_ns = clock->toLocal(meta.device_stamp_ns);
            meta.host_stamp_ns = clock->toLocal(meta.host_stamp_ns);
        } else {
            if (meta.clock_domain == kHostClockDomain) {
                meta.device_stamp_ns = meta.host_stamp_ns;
                meta.clock_domain = stream.local.clock_domain;
            }
            meta.host_stamp_ns = arrival_ns;
        }
        meta.stream = stream.pooled.id;
        meta.graph_stamp_ns = 0;
        frame.meta() = meta;
        if (stream.local.format.format == PixelFormat::kBinary) {
            ImageDesc desc = stream.local.format;
            desc.width = message.width();
            desc.stride_bytes = message.stride_bytes();
            frame.setDesc(desc);
        }
        std::memcpy(frame.image().data, message.data().data(), message.data().size());
        frame.setPayloadBytes(message.data().size());
        graph->publish(std::move(frame).publish());
        stream.published.fetch_add(1, std::memory_order_relaxed);
    }
}

void DdsDevice::Impl::receive(Stream& stream) {
    detail::FrameMessage message;
    while (!stopping.load(std::memory_order_relaxed)) {
        (void)stream.reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 50'000'000));
        take(stream, message);
        fdds::LivelinessChangedStatus liveliness;
        if (stream.reader->get_liveliness_changed_status(liveliness) == ReturnCode_t::RETCODE_OK) {
            const bool recent_frame =
                stream.last_arrival_ns != 0 && monotonicNowNs() - stream.last_arrival_ns <
                                                   static_cast<int64_t>(options.dds.lease_s * 1e9);
            setAlive(stream, liveliness.alive_count > 0 ||
                                 (recent_frame && liveliness.not_alive_count == 0));
        }
        bool ended = false;
        {
            std::lock_guard lock(state_mutex);
            ended = stream.ended;
        }
        if (ended) {
            // The host acknowledged-waited its last frames before it disposed the stream: they
            // are in this reader's history already.
            take(stream, message);
            graph->endStream(stream.pooled.id);
            return;
        }
    }
}

void DdsDevice::Impl::watchAnnouncements() {
    while (!stopping.load(std::memory_order_relaxed)) {
        listener->listen(100, [] { return false; });
        std::lock_guard lock(state_mutex);
        for (const Announced& announced : listener->streams()) {
            if (!announced.disposed || announced.host != host)
                continue;
            for (auto& stream : streams) {
                if (stream->remote.info.name == announced.info.name && !stream->ended) {
                    stream->ended = true;
                    ++ended_streams;
                }
            }
        }
        if (ended_streams == streams.size())
            return;
    }
}

DdsDevice::DdsDevice(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

DdsDevice::~DdsDevice() {
    stop();
}

std::string DdsDevice::name() const {
    return impl_->config.name;
}

DeviceDescriptor DdsDevice::descriptor() const {
    DeviceDescriptor d;
    d.backend = "dds";
    d.id = impl_->host + "/" + impl_->device;
    d.model = "mixray device '" + impl_->device + "' on " + impl_->host;
    d.location = "dds domain " + std::to_string(impl_->options.dds.domain);
    for (const auto& stream : impl_->streams)
        d.modes.push_back(stream->remote.info.name);
    return d;
}

DeviceState DdsDevice::state() const {
    std::lock_guard lock(impl_->state_mutex);
    if (impl_->ended_streams == impl_->streams.size() && !impl_->streams.empty())
        return DeviceState::kEnded;
    if (impl_->ever_alive && !impl_->device_alive)
        return DeviceState::kReconnecting;
    return DeviceState::kStreaming;
}

std::string DdsDevice::clockReport() const {
    if (!impl_->time)
        return "stamped on arrival (" + impl_->clock_note + ")";
    const std::optional<HostClockEstimate> clock = impl_->time->estimate();
    return impl_->host + " clock " + clock->describe();
}

std::optional<HostClockEstimate> DdsDevice::hostClock() const {
    if (!impl_->time)
        return std::nullopt;
    return impl_->time->estimate();
}

Status DdsDevice::connect(Graph& graph) {
    Impl& d = *impl_;
    d.graph = &graph;
    for (auto& stream : d.streams) {
        auto pooled = addPooledStream(graph, stream->local, d.options.buffers);
        if (!pooled)
            return pooled.status();
        stream->pooled = *pooled;
    }
    return Status::ok();
}

Status DdsDevice::start() {
    Impl& d = *impl_;
    d.stopping = false;
    for (auto& stream : d.streams) {
        auto topic = d.participant->topic(stream->remote.topic, detail::frameType());
        if (!topic)
            return topic.status();
        stream->reader = d.participant->subscriber()->create_datareader(
            *topic, detail::frameReaderQos(d.options.history));
        if (!stream->reader)
            return {ErrorCode::kInternal, "dds device '" + d.config.name +
                                              "': cannot create a reader for " +
                                              stream->remote.topic};
    }
    for (auto& stream : d.streams)
        stream->thread = std::thread([&d, s = stream.get()] {
            runAs(ThreadRole::kCapture);  // another host's frames: lost if late
            d.receive(*s);
        });
    d.watcher = std::thread([&d] { d.watchAnnouncements(); });
    return Status::ok();
}

void DdsDevice::stop() {
    Impl& d = *impl_;
    d.stopping = true;
    for (auto& stream : d.streams) {
        if (stream->thread.joinable())
            stream->thread.join();
    }
    if (d.watcher.joinable())
        d.watcher.join();
}

std::vector<DdsReceiveStats> DdsDevice::stats() const {
    std::vector<DdsReceiveStats> out;
    for (const auto& stream : impl_->streams) {
        DdsReceiveStats s;
        s.stream = stream->local.name;
        s.topic = stream->remote.topic;
        s.received = stream->received.load(std::memory_order_relaxed);
        s.published = stream->published.load(std::memory_order_relaxed);
        s.lost_in_transit = stream->lost_in_transit.load(std::memory_order_relaxed);
        s.pool_exhausted = stream->pool_exhausted.load(std::memory_order_relaxed);
        s.rejected = stream->rejected.load(std::memory_order_relaxed);
        fdds::SubscriptionMatchedStatus matched;
        if (stream->reader &&
            stream->reader->get_subscription_matched_status(matched) == ReturnCode_t::RETCODE_OK)
            s.matched_writers = matched.current_count;
        out.push_back(std::move(s));
    }
    return out;
}

uint64_t DdsDevice::disconnections() const {
    std::lock_guard lock(impl_->state_mutex);
    return impl_->disconnections;
}

uint64_t DdsDevice::reconnections() const {
    std::lock_guard lock(impl_->state_mutex);
    return impl_->reconnections;
}

DdsBackend::DdsBackend(DdsOptions defaults, int64_t listen_ms)
    : defaults_(std::move(defaults)), listen_ms_(listen_ms) {}

Result<std::vector<DeviceDescriptor>> DdsBackend::enumerate() {
    auto participant = detail::Participant::create(defaults_, "mixray devices");
    if (!participant)
        return participant.status();
    auto listener = AnnouncementListener::create(**participant);
    if (!listener)
        return listener.status();
    (*listener)->listen(listen_ms_, [] { return false; });
    std::map<std::string, DeviceDescriptor> devices;
    for (const Announced& announced : (*listener)->streams()) {
        const std::string id = announced.host + "/" + announced.info.device;
        DeviceDescriptor& d = devices[id];
        d.backend = "dds";
        d.id = id;
        d.model = "mixray device '" + announced.info.device + "' on " + announced.host;
        d.location = "dds domain " + std::to_string(defaults_.domain);
        const ImageDesc& f = announced.info.format;
        std::string mode = announced.info.name.substr(announced.info.device.size() + 1) + " " +
                           std::to_string(f.width) + "x" + std::to_string(f.height);
        if (announced.info.nominal_fps > 0)
            mode += "@" + std::to_string(static_cast<int>(announced.info.nominal_fps + 0.5));
        mode += " " + std::string(toString(f.format));
        d.modes.push_back(mode);
    }
    std::vector<DeviceDescriptor> out;
    for (auto& [id, d] : devices)
        out.push_back(std::move(d));
    return out;
}

Result<std::unique_ptr<Device>> DdsBackend::open(const DeviceConfig& config) {
    auto impl = std::make_unique<DdsDevice::Impl>();
    impl->config = config;
    impl->options.dds = defaults_;
    MIXRAY_RETURN_IF_ERROR(parseDdsDeviceOptions(config, &impl->options));
    const std::string who = "dds device '" + config.name + "'";
    if (config.id.empty()) {
        return Status{ErrorCode::kInvalidArgument,
                      who + ": id: expected HOST/DEVICE or DEVICE, the remote device to receive"};
    }
    const size_t slash = config.id.find('/');
    std::string want_host = slash == std::string::npos ? "" : config.id.substr(0, slash);
    const std::string want_device =
        slash == std::string::npos ? config.id : config.id.substr(slash + 1);

    auto participant =
        detail::Participant::create(impl->options.dds, "mixray dds device " + config.name);
    if (!participant)
        return participant.status().withContext(who);
    impl->participant = *participant;
    auto listener = AnnouncementListener::create(*impl->participant);
    if (!listener)
        return listener.status().withContext(who);
    impl->listener = std::move(*listener);

    // Wait until every named stream (or, with none named, the device at all) is announced.
    auto matching = [&] {
        std::vector<Announced> out;
        for (Announced& a : impl->listener->streams()) {
            if (a.info.device == want_device && (want_host.empty() || a.host == want_host) &&
                !a.disposed)
                out.push_back(std::move(a));
        }
        return out;
    };
    // Announcements of one device's streams arrive one by one; each names them all.
    auto complete = [&] {
        const std::vector<Announced> found = matching();
        if (found.empty())
            return false;
        std::vector<std::string> wanted;
        for (const std::string& s : config.streams)
            wanted.push_back(want_device + "/" + s);
        if (wanted.empty())
            wanted = found.front().device_streams;
        for (const std::string& name : wanted) {
            bool has = false;
            for (const Announced& a : found)
                has = has || a.info.name == name;
            if (!has)
                return false;
        }
        return true;
    };
    impl->listener->listen(impl->options.discovery_timeout_ms, complete);
    std::vector<Announced> found = matching();
    std::set<std::string> hosts;
    for (const Announced& a : found)
        hosts.insert(a.host);
    if (hosts.size() > 1) {
        std::string list;
        for (const std::string& h : hosts)
            list += (list.empty() ? "" : ", ") + h;
        return Status{ErrorCode::kInvalidArgument, who + ": device '" + want_device +
                                                       "' is announced by several hosts (" + list +
                                                       "): name one as id: HOST/" + want_device};
    }
    if (!complete()) {
        std::string seen;
        for (const Announced& a : impl->listener->streams())
            seen += (seen.empty() ? "" : ", ") + a.host + ":" + a.info.name;
        for (const std::string& r : impl->listener->rejected())
            seen += (seen.empty() ? "" : "; ") + ("refused: " + r);
        return Status{ErrorCode::kNotFound,
                      who + ": no host announced " + config.id +
                          (config.streams.empty() ? "" : " with every stream asked for") +
                          " within " + std::to_string(impl->options.discovery_timeout_ms) +
                          " ms in dds domain " + std::to_string(impl->options.dds.domain) +
                          " (heard: " + (seen.empty() ? "nothing" : seen) + ")"};
    }
    impl->host = found.front().host;
    impl->device = want_device;
    if (impl->options.clock != DdsDeviceOptions::Clock::kArrival) {
        auto time = detail::TimeRequester::create(
            impl->participant, requesterName(config), impl->host,
            impl->options.clock == DdsDeviceOptions::Clock::kWall, impl->options.dds.ptp4l);
        if (!time)
            return time.status().withContext(who);
        // A fit needs HostClockEstimator::kMinUsed answers; the first come 20 ms apart.
        if ((*time)->waitEstimate(std::chrono::milliseconds(2000)))
            impl->time = std::move(time).value();
        else
            impl->clock_note = impl->host + " answered no clock request within 2 s";
    } else {
        impl->clock_note = "clock: arrival";
    }
    for (Announced& a : found) {
        const std::string short_name = a.info.name.substr(want_device.size() + 1);
        if (!config.streams.empty() && std::find(config.streams.begin(), config.streams.end(),
                                                 short_name) == config.streams.end())
            continue;
        auto stream = std::make_unique<DdsDevice::Impl::Stream>();
        stream->local = a.info;
        stream->local.name = config.name + "/" + short_name;
        stream->local.device = config.name;
        if (stream->local.clock_domain == kHostClockDomain && !impl->time)
            stream->local.clock_domain = deviceClockDomain("dds", impl->host);
        stream->local.tags["dds.host"] = impl->host;
        stream->local.tags["dds.topic"] = a.topic;
        stream->remote = std::move(a);
        impl->streams.push_back(std::move(stream));
    }
    return std::unique_ptr<Device>(new DdsDevice(std::move(impl)));
}

}  // namespace mixray::dds
