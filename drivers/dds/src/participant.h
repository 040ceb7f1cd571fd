// One Fast DDS participant set up from DdsOptions, with the publisher, subscriber and topics
// that mixray's writers and readers share. Internal to drivers/dds.
#pragma once

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

#include "mixray/dds/dds_options.h"
#include "mixray/graph/result.h"

namespace mixray::dds::detail {

namespace fdds = eprosima::fastdds::dds;

// Participant ids a process uses, 0..kParticipantIds-1, and the ids of a peer that discovery
// reaches. The ports of id 119 would reach the next domain's.
inline constexpr int kParticipantIds = 64;

// Owns a DomainParticipant and everything made from it; the destructor deletes them all.
// Thread-safe: Fast DDS entities are, and topic() locks.
class Participant {
public:
    // `role` names the participant in DDS discovery ("mixray publish on <host>").
    static Result<std::shared_ptr<Participant>> create(const DdsOptions& options,
                                                       std::string_view role);
    ~Participant();
    Participant(const Participant&) = delete;
    Participant& operator=(const Participant&) = delete;

    fdds::DomainParticipant* participant() const { return participant_; }
    fdds::Publisher* publisher() const { return publisher_; }
    fdds::Subscriber* subscriber() const { return subscriber_; }
    const DdsOptions& options() const { return options_; }

    // The topic `name` of `type` (registered on first use), created once and shared.
    Result<fdds::Topic*> topic(const std::string& name, const fdds::TypeSupport& type);

private:
    explicit Participant(DdsOptions options) : options_(std::move(options)) {}

    DdsOptions options_;
    fdds::DomainParticipant* participant_ = nullptr;
    int id_ = -1;  // its participant id (ParticipantIds)
    fdds::Publisher* publisher_ = nullptr;
    fdds::Subscriber* subscriber_ = nullptr;
    std::mutex mutex_;
    std::map<std::string, fdds::Topic*> topics_;
};

// The frame topics' writer and reader QoS, in one place so both ends agree.
//   reliable, volatile, keep last `depth`: a reader that falls behind loses the oldest frames
//   (counted by their sequence gaps), and the writer never waits for it;
//   asynchronous publication: write() hands the frame to Fast DDS's sender thread and returns,
//   which is also what lets Fast DDS fragment frames over UDP's 64 KiB datagrams;
//   automatic liveliness with the writer's lease: a vanished host is noticed within its own
//   lease_s (readers accept any lease).
fdds::DataWriterQos frameWriterQos(const DdsOptions& options, int depth);
fdds::DataReaderQos frameReaderQos(int depth);

// The announcement topic's: reliable, transient-local, one sample per host and stream.
fdds::DataWriterQos announcementWriterQos();
fdds::DataReaderQos announcementReaderQos();

// The clock exchange topics' (mixray/time_request, mixray/time_answer): best effort, volatile,
// keep last 8. An exchange that is late measures the delay, not the clock, so a lost one is
// better than one resent.
fdds::DataWriterQos timeExchangeWriterQos();
fdds::DataReaderQos timeExchangeReaderQos();

// tf_static's, as tf2_ros's static broadcaster and listeners set it: reliable, transient-local,
// keep last 1 (one message holds every transform).
fdds::DataWriterQos rosTfStaticWriterQos();

// A ROS 2 topic's reader: best effort (matches every writer) or reliable, volatile, keep last
// `depth`.
fdds::DataReaderQos rosReaderQos(bool reliable, int depth);

// `qos` with the ROS 2 type hash of `ros_type` ("sensor_msgs/msg/Image") in its USER_DATA, as
// rmw_fastrtps and rmw_cyclonedds put it on every endpoint (ros_types.h).
fdds::DataWriterQos withRosTypeHash(fdds::DataWriterQos qos, std::string_view ros_type);
fdds::DataReaderQos withRosTypeHash(fdds::DataReaderQos qos, std::string_view ros_type);

}  // namespace mixray::dds::detail
