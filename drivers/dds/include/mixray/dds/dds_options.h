// Where and how a mixray host takes part in DDS: domain, the address it binds, the peers it
// discovers, its transport and its name in topics.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/device_options.h"
#include "mixray/graph/result.h"

namespace mixray::dds {

// How DDS moves a host's samples.
enum class DdsTransport : uint8_t {
    kUdp,           // UDPv4 only, also to peers on this host
    kSharedMemory,  // shared memory only: every peer on this host, none beyond it
    kAuto,          // shared memory to peers on this host, UDPv4 to the others
};

std::string_view toString(DdsTransport transport);

// One DDS participant's settings. Plain value; every field has a working default, and the
// default binds loopback only: nothing leaves this computer unless the user names an address.
struct DdsOptions {
    int domain = 0;  // DDS domain id, 0..232 (the RTPS port formula's limit)
    // IPv4 address of the interface UDP binds to: "127.0.0.1" (loopback, the default),
    // an interface's own address, or "0.0.0.0" for every interface.
    std::string address = "127.0.0.1";
    // IPv4 addresses of hosts to discover by unicast. Loopback has no multicast, so with the
    // default address 127.0.0.1 is always a peer; on a real network, multicast discovery
    // finds the others and peers add hosts that multicast does not reach.
    std::vector<std::string> peers;
    // DDS partition: participants see only topics of the same partition ("": the default
    // partition), so two rigs can share a domain.
    std::string partition;
    DdsTransport transport = DdsTransport::kAuto;
    // This host's name in topics and announcements ("": the machine's host name).
    std::string host;
    // A peer that sends nothing (not even DDS's liveliness messages) for this long is gone:
    // its streams' devices turn reconnecting. Also how often liveliness is asserted (a third
    // of it). Seconds, 0.2..600.
    double lease_s = 2.0;
    // The shared-memory segment of each participant, in MiB: a frame must fit, with room for a
    // few in flight (1..4096).
    int shared_memory_mib = 64;
    // ptp4l's management socket: this host says in its clock exchanges whether its wall clock
    // is PTP-locked (mixray/graph/ptp.h), and hosts locked to one grandmaster map each other's
    // stamps through their wall clocks. Not asked when the socket does not exist.
    std::string ptp4l = "/var/run/ptp4l";

    // kInvalidArgument naming the field for a value out of range or an address that is not a
    // dotted IPv4 quad.
    Status validate() const;
    // host, or the machine's host name when host is empty.
    std::string hostName() const;
};

// Reads the DDS options a device's rig-file options may set (domain, address, peers,
// partition, transport, host, lease_s, shared_memory_mib, ptp4l) into `options`, leaving absent
// ones as they are.
Status readDdsOptions(DeviceOptionReader& reader, DdsOptions* options);

// The DDS option keys readDdsOptions() knows, comma-separated, for DeviceOptionReader::leftovers.
inline constexpr std::string_view kDdsOptionKeys =
    "domain, address, peers, partition, transport, host, lease_s, shared_memory_mib, ptp4l";

// Whether Fast DDS hands samples between a writer and a reader of the same process directly,
// without serializing them or using the transport (its default). Tests and benchmarks that
// mean to cross the wire between two graphs of one process turn it off before creating
// anything. Process-wide.
void setIntraprocessDelivery(bool enabled);

// The topic a stream's frames are published on: "mixray/<host>/<stream>", stream being the
// graph name "device/stream".
std::string frameTopic(std::string_view host, std::string_view stream);

// The topic every host announces its streams on.
inline constexpr std::string_view kAnnouncementTopic = "mixray/streams";

// The version of mixray_msgs this build speaks; announcements of a newer one are ignored.
inline constexpr uint32_t kProtocolVersion = 1;

}  // namespace mixray::dds
