#include "participant.h"

#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>

#include <cmath>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "mixray/dds/ros_types.h"

namespace mixray::dds::detail {
namespace {

using eprosima::fastrtps::Duration_t;
using eprosima::fastrtps::rtps::IPLocator;
using eprosima::fastrtps::rtps::Locator_t;

Duration_t duration(double seconds) {
    const double whole = std::floor(seconds);
    return Duration_t(static_cast<int32_t>(whole),
                      static_cast<uint32_t>(std::lround((seconds - whole) * 1e9)));
}

Locator_t udpLocator(const std::string& address) {
    Locator_t locator;
    locator.kind = LOCATOR_KIND_UDPv4;
    IPLocator::setIPv4(locator, address);
    locator.port = 0;  // 0: Fast DDS assigns the port from the domain and participant ids
    return locator;
}

Locator_t sharedMemoryLocator() {
    Locator_t locator;
    locator.kind = LOCATOR_KIND_SHM;
    locator.port = 0;
    return locator;
}

fdds::DomainParticipantQos participantQos(const DdsOptions& options, std::string_view role) {
    fdds::DomainParticipantQos qos = fdds::PARTICIPANT_QOS_DEFAULT;
    qos.name(std::string(role));
    auto& builtin = qos.wire_protocol().builtin;
    builtin.discovery_config.leaseDuration = duration(options.lease_s);
    builtin.discovery_config.leaseDuration_announcementperiod = duration(options.lease_s / 3);
    // Unless the user asks for every interface, discovery is unicast to the peers alone:
    // Fast DDS's default would also bind a multicast socket on every interface.
    const bool every_interface = options.address == "0.0.0.0";
    const bool udp = options.transport != DdsTransport::kSharedMemory;
    const bool shared_memory = options.transport != DdsTransport::kUdp;

    qos.transport().use_builtin_transports = false;
    if (udp) {
        auto descriptor = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
        if (!every_interface)
            descriptor->interfaceWhiteList.push_back(options.address);
        // Frames arrive as bursts of 64 KiB fragments: a socket buffer of several frames keeps
        // the kernel from dropping a burst (it caps the size at net.core.rmem_max).
        descriptor->sendBufferSize = 8u << 20;
        descriptor->receiveBufferSize = 8u << 20;
        // Unicast discovery sends to the ports of a peer's first kParticipantIds participant
        // ids; Participant::create numbers participants so that they stay below it.
        descriptor->maxInitialPeersRange = kParticipantIds;
        qos.transport().user_transports.push_back(descriptor);
    }
    if (shared_memory) {
        auto descriptor = std::make_shared<eprosima::fastdds::rtps::SharedMemTransportDescriptor>();
        descriptor->segment_size(static_cast<uint32_t>(options.shared_memory_mib) << 20);
        qos.transport().user_transports.push_back(descriptor);
    }
    // Shared memory alone needs no locators: Fast DDS's defaults for it open no socket.
    if (udp && !every_interface) {
        auto& metatraffic = builtin.metatrafficUnicastLocatorList;
        auto& data = qos.wire_protocol().default_unicast_locator_list;
        if (shared_memory) {
            metatraffic.push_back(sharedMemoryLocator());
            data.push_back(sharedMemoryLocator());
        }
        metatraffic.push_back(udpLocator(options.address));
        data.push_back(udpLocator(options.address));
        builtin.initialPeersList.push_back(udpLocator(options.address));
    }
    if (udp) {
        for (const std::string& peer : options.peers)
            builtin.initialPeersList.push_back(udpLocator(peer));
    }
    return qos;
}

// Fast DDS numbers a process's participants 0, 1, 2, ... and never reuses a number, while peers
// find a participant only by the ports of its number (maxInitialPeersRange). A process that
// makes many participants in its life (`bench dds` makes eight per row; a long-running host
// opening devices) would number past the range and go unheard. So each participant gets the
// lowest number no live participant of this process holds; one whose ports another process
// holds is passed over.
class ParticipantIds {
public:
    static ParticipantIds& get() {
        static ParticipantIds ids;
        return ids;
    }
    // The free numbers from the lowest, each marked used as it is offered; -1 when none is left.
    int take(int after) {
        std::lock_guard lock(mutex_);
        for (int id = after + 1; id < kParticipantIds; ++id) {
            if (used_.insert(id).second)
                return id;
        }
        return -1;
    }
    void give(int id) {
        std::lock_guard lock(mutex_);
        used_.erase(id);
    }

private:
    std::mutex mutex_;
    std::set<int> used_;
};

}  // namespace

Result<std::shared_ptr<Participant>> Participant::create(const DdsOptions& options,
                                                         std::string_view role) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    std::shared_ptr<Participant> self(new Participant(options));
    auto* factory = fdds::DomainParticipantFactory::get_instance();
    fdds::DomainParticipantQos qos = participantQos(options, role);
    for (int id = ParticipantIds::get().take(-1); id >= 0 && !self->participant_;) {
        qos.wire_protocol().participant_id = id;
        self->participant_ =
            factory->create_participant(static_cast<fdds::DomainId_t>(options.domain), qos);
        if (self->participant_) {
            self->id_ = id;
        } else {
            const int next = ParticipantIds::get().take(id);
            ParticipantIds::get().give(id);
            id = next;
        }
    }
    if (!self->participant_) {
        return Status{ErrorCode::kUnavailable, "dds: cannot create a participant in domain " +
                                                   std::to_string(options.domain) + " on " +
                                                   options.address + " (" +
                                                   std::string(toString(options.transport)) +
                                                   "): is the address one of this host's?"};
    }
    fdds::PublisherQos publisher_qos = fdds::PUBLISHER_QOS_DEFAULT;
    fdds::SubscriberQos subscriber_qos = fdds::SUBSCRIBER_QOS_DEFAULT;
    if (!options.partition.empty()) {
        publisher_qos.partition().push_back(options.partition.c_str());
        subscriber_qos.partition().push_back(options.partition.c_str());
    }
    self->publisher_ = self->participant_->create_publisher(publisher_qos);
    self->subscriber_ = self->participant_->create_subscriber(subscriber_qos);
    if (!self->publisher_ || !self->subscriber_)
        return Status{ErrorCode::kInternal, "dds: cannot create a publisher and subscriber"};
    return self;
}

Participant::~Participant() {
    if (!participant_)
        return;
    participant_->delete_contained_entities();
    fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
    ParticipantIds::get().give(id_);
}

Result<fdds::Topic*> Participant::topic(const std::string& name, const fdds::TypeSupport& type) {
    std::lock_guard lock(mutex_);
    if (auto found = topics_.find(name); found != topics_.end())
        return found->second;
    if (type.register_type(participant_) != ReturnCode_t::RETCODE_OK) {
        return Status{ErrorCode::kInternal, "dds: cannot register type " + type.get_type_name()};
    }
    fdds::Topic* topic =
        participant_->create_topic(name, type.get_type_name(), fdds::TOPIC_QOS_DEFAULT);
    if (!topic)
        return Status{ErrorCode::kInternal, "dds: cannot create topic " + name};
    topics_.emplace(name, topic);
    return topic;
}

namespace {

// What frame writers and readers agree on.
template <typename Qos>
Qos frameQos(Qos qos, int depth) {
    qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
    qos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
    qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    qos.history().depth = depth;
    qos.resource_limits().max_samples = depth;
    qos.resource_limits().max_instances = 1;
    qos.resource_limits().max_samples_per_instance = depth;
    qos.resource_limits().allocated_samples = depth;
    qos.liveliness().kind = fdds::AUTOMATIC_LIVELINESS_QOS;
    // Frames are large and their size is known per stream: buffers grow once and are reused.
    qos.endpoint().history_memory_policy = eprosima::fastrtps::rtps::DYNAMIC_REUSABLE_MEMORY_MODE;
    return qos;
}

// The small topics' QoS (announcements, clock exchanges): reliability, durability and a
// keep-last history of `depth` samples per instance.
template <typename Qos>
Qos keepLastQos(Qos qos, fdds::ReliabilityQosPolicyKind reliability,
                fdds::DurabilityQosPolicyKind durability, int32_t depth) {
    qos.reliability().kind = reliability;
    qos.durability().kind = durability;
    qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    qos.history().depth = depth;
    return qos;
}

// What announcement writers and readers agree on: reliable, and kept for late joiners, one
// sample per instance (host and stream).
template <typename Qos>
Qos announcementQos(Qos qos) {
    return keepLastQos(qos, fdds::RELIABLE_RELIABILITY_QOS, fdds::TRANSIENT_LOCAL_DURABILITY_QOS,
                       1);
}

// Clock exchanges: best effort, volatile, 8 deep. A late exchange measures the delay, not the
// clock, so a lost one is better than one resent.
template <typename Qos>
Qos timeExchangeQos(Qos qos) {
    return keepLastQos(qos, fdds::BEST_EFFORT_RELIABILITY_QOS, fdds::VOLATILE_DURABILITY_QOS, 8);
}

}  // namespace

fdds::DataWriterQos frameWriterQos(const DdsOptions& options, int depth) {
    fdds::DataWriterQos qos = frameQos(fdds::DATAWRITER_QOS_DEFAULT, depth);
    qos.publish_mode().kind = fdds::ASYNCHRONOUS_PUBLISH_MODE;
    // The writer's host says how soon its silence means it is gone. A reader asks for no
    // lease of its own (DDS's default, infinite): a reader lease shorter than a writer's is
    // incompatible QoS and the two would never match.
    qos.liveliness().lease_duration = duration(options.lease_s);
    qos.liveliness().announcement_period = duration(options.lease_s / 3);
    // A lost fragment is asked for again after the next heartbeat: the default of 3 s would
    // hold a reliable reader's frame for seconds.
    qos.reliable_writer_qos().times.heartbeatPeriod = duration(0.05);
    return qos;
}

fdds::DataReaderQos frameReaderQos(int depth) {
    return frameQos(fdds::DATAREADER_QOS_DEFAULT, depth);
}

fdds::DataWriterQos announcementWriterQos() {
    fdds::DataWriterQos qos = announcementQos(fdds::DATAWRITER_QOS_DEFAULT);
    // Disposed means the stream ended; a host that leaves only unregisters (DDS's default would
    // dispose on unregistering too, and readers would take a leaving host for ended streams).
    qos.writer_data_lifecycle().autodispose_unregistered_instances = false;
    return qos;
}

fdds::DataReaderQos announcementReaderQos() {
    return announcementQos(fdds::DATAREADER_QOS_DEFAULT);
}

fdds::DataWriterQos timeExchangeWriterQos() {
    return timeExchangeQos(fdds::DATAWRITER_QOS_DEFAULT);
}

fdds::DataReaderQos timeExchangeReaderQos() {
    return timeExchangeQos(fdds::DATAREADER_QOS_DEFAULT);
}

fdds::DataWriterQos rosTfStaticWriterQos() {
    return keepLastQos(fdds::DataWriterQos(fdds::DATAWRITER_QOS_DEFAULT),
                       fdds::RELIABLE_RELIABILITY_QOS, fdds::TRANSIENT_LOCAL_DURABILITY_QOS, 1);
}

fdds::DataReaderQos rosReaderQos(bool reliable, int depth) {
    return keepLastQos(
        fdds::DataReaderQos(fdds::DATAREADER_QOS_DEFAULT),
        reliable ? fdds::RELIABLE_RELIABILITY_QOS : fdds::BEST_EFFORT_RELIABILITY_QOS,
        fdds::VOLATILE_DURABILITY_QOS, depth);
}

namespace {

// Only types drivers/dds describes are used, so the hash is always there; a type without one
// would go without it, which ROS 2 accepts with a warning.
template <typename Qos>
Qos withTypeHash(Qos qos, std::string_view ros_type) {
    if (auto hash = rosTypeHash(ros_type)) {
        const std::string user_data = rosTypeHashUserData(*hash);
        qos.user_data().data_vec(
            std::vector<eprosima::fastrtps::rtps::octet>(user_data.begin(), user_data.end()));
    }
    return qos;
}

}  // namespace

fdds::DataWriterQos withRosTypeHash(fdds::DataWriterQos qos, std::string_view ros_type) {
    return withTypeHash(std::move(qos), ros_type);
}

fdds::DataReaderQos withRosTypeHash(fdds::DataReaderQos qos, std::string_view ros_type) {
    return withTypeHash(std::move(qos), ros_type);
}

}  // namespace mixray::dds::detail

namespace mixray::dds {

void setIntraprocessDelivery(bool enabled) {
    eprosima::fastrtps::LibrarySettingsAttributes settings;
    settings.intraprocess_delivery =
        enabled ? eprosima::fastrtps::INTRAPROCESS_FULL : eprosima::fastrtps::INTRAPROCESS_OFF;
    eprosima::fastrtps::xmlparser::XMLProfileManager::library_settings(settings);
}

}  // namespace mixray::dds
