#include "mixray/dds/dds_options.h"

#include <arpa/inet.h>
#include <unistd.h>

#include <array>
#include <string>

namespace mixray::dds {
namespace {

bool isIpv4(const std::string& text) {
    in_addr address{};
    return inet_pton(AF_INET, text.c_str(), &address) == 1;
}

}  // namespace

std::string_view toString(DdsTransport transport) {
    switch (transport) {
        case DdsTransport::kUdp:
            return "udp";
        case DdsTransport::kSharedMemory:
            return "shm";
        case DdsTransport::kAuto:
            return "auto";
    }
    return "?";
}

Status DdsOptions::validate() const {
    auto bad = [](const std::string& field, const std::string& why) {
        return Status{ErrorCode::kInvalidArgument, "dds options: " + field + ": " + why};
    };
    if (domain < 0 || domain > 232)
        return bad("domain", "expected 0..232, got " + std::to_string(domain));
    if (!isIpv4(address))
        return bad("address", "expected an IPv4 address like 127.0.0.1, got '" + address + "'");
    for (const std::string& peer : peers) {
        if (!isIpv4(peer) || peer == "0.0.0.0")
            return bad("peers", "expected IPv4 addresses of hosts, got '" + peer + "'");
    }
    if (!(lease_s >= 0.2 && lease_s <= 600))
        return bad("lease_s", "expected 0.2..600 seconds, got " + std::to_string(lease_s));
    if (shared_memory_mib < 1 || shared_memory_mib > 4096) {
        return bad("shared_memory_mib",
                   "expected 1..4096, got " + std::to_string(shared_memory_mib));
    }
    for (char c : host) {
        const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                        (c >= '0' && c <= '9') || c == '-' || c == '_' || c == '.';
        if (!ok) {
            return bad("host", "expected letters, digits, '-', '_' and '.', got '" + host + "'");
        }
    }
    return Status::ok();
}

std::string DdsOptions::hostName() const {
    if (!host.empty())
        return host;
    std::array<char, 256> name{};
    if (gethostname(name.data(), name.size() - 1) != 0 || name[0] == '\0')
        return "localhost";
    return name.data();
}

Status readDdsOptions(DeviceOptionReader& reader, DdsOptions* options) {
    MIXRAY_RETURN_IF_ERROR(reader.integer("domain", options->domain, 0, 232, "a domain id 0..232"));
    if (const std::string* address = reader.find("address"))
        options->address = *address;
    if (const std::string* peers = reader.find("peers"))
        options->peers = splitOptionList(*peers);
    if (const std::string* partition = reader.find("partition"))
        options->partition = *partition;
    MIXRAY_RETURN_IF_ERROR(reader.choice("transport", options->transport,
                                         {{"udp", DdsTransport::kUdp},
                                          {"shm", DdsTransport::kSharedMemory},
                                          {"auto", DdsTransport::kAuto}},
                                         "udp, shm or auto"));
    if (const std::string* host = reader.find("host"))
        options->host = *host;
    MIXRAY_RETURN_IF_ERROR(reader.real("lease_s", options->lease_s, 0.2, 600, "0.2..600 seconds"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer("shared_memory_mib", options->shared_memory_mib, 1, 4096, "1..4096 MiB"));
    if (const std::string* ptp4l = reader.find("ptp4l"))
        options->ptp4l = *ptp4l;
    const Status valid = options->validate();
    if (!valid.isOk()) {
        return {ErrorCode::kInvalidArgument,
                "dds device '" + reader.config().name + "': " + valid.message()};
    }
    return Status::ok();
}

std::string frameTopic(std::string_view host, std::string_view stream) {
    std::string topic = "mixray/";
    topic += host;
    topic += '/';
    topic += stream;
    return topic;
}

}  // namespace mixray::dds
