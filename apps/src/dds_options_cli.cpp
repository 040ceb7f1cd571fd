#include "dds_options_cli.h"

namespace mixray::cli {

void addDdsOptions(CLI::App& command, dds::DdsOptions& options) {
    const char* group = "DDS";
    command.add_option("--domain", options.domain, "DDS domain id")
        ->check(CLI::Range(0, 232))
        ->capture_default_str()
        ->group(group);
    command
        .add_option("--address", options.address,
                    "IPv4 address of the interface to use; the default keeps everything on this "
                    "computer; 0.0.0.0: every interface")
        ->capture_default_str()
        ->group(group);
    command
        .add_option("--peers", options.peers,
                    "IPv4 addresses of the other hosts, discovered by unicast (comma-separated)")
        ->delimiter(',')
        ->group(group);
    command
        .add_option("--transport", options.transport,
                    "udp; shm: shared memory, this host only; auto: shared memory to this host's "
                    "peers, udp to the others")
        ->transform(CLI::CheckedTransformer(
            std::map<std::string, dds::DdsTransport>{{"udp", dds::DdsTransport::kUdp},
                                                     {"shm", dds::DdsTransport::kSharedMemory},
                                                     {"auto", dds::DdsTransport::kAuto}}))
        ->default_str("auto")
        ->group(group);
    command.add_option("--host", options.host, "This host's name in topics (default: hostname)")
        ->group(group);
    command
        .add_option("--partition", options.partition,
                    "DDS partition: only hosts of the same partition see each other")
        ->group(group);
    command
        .add_option("--ptp4l", options.ptp4l,
                    "ptp4l's management socket: whether this host's wall clock is PTP-locked, "
                    "said in its clock exchanges")
        ->capture_default_str()
        ->group(group);
}

}  // namespace mixray::cli
