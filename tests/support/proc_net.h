// IPv4 sockets as the kernel lists them (/proc/net/tcp, /proc/net/udp), for tests that check
// what an endpoint binds: the addresses, the TCP state and the inode that ties a socket to a
// process's descriptors.
#pragma once

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace mixray::test {

struct Ipv4Socket {
    std::string local_address;  // dotted, "127.0.0.1"
    int local_port = 0;
    std::string remote_address;
    int remote_port = 0;
    std::string state;  // the kernel's hex TCP state: "0A" listening; UDP "07"
    std::string inode;
};

// "0100007F:1CE8": the address as the kernel holds it (network order) printed as a native
// word, then the port.
inline void parseProcNetEndpoint(const std::string& text, std::string* address, int* port) {
    const auto word = static_cast<uint32_t>(std::strtoul(text.substr(0, 8).c_str(), nullptr, 16));
    *address = std::to_string(word & 0xff) + "." + std::to_string((word >> 8) & 0xff) + "." +
               std::to_string((word >> 16) & 0xff) + "." + std::to_string(word >> 24);
    *port = static_cast<int>(std::strtoul(text.substr(9).c_str(), nullptr, 16));
}

// Every socket of `table` ("/proc/net/tcp" or "/proc/net/udp"), the machine's.
inline std::vector<Ipv4Socket> ipv4Sockets(const char* table) {
    std::vector<Ipv4Socket> out;
    std::ifstream in(table);
    std::string line;
    std::getline(in, line);  // the header
    while (std::getline(in, line)) {
        std::istringstream fields(line);
        std::string slot, local, remote, queues, timer, retransmits, uid, timeout;
        Ipv4Socket s;
        fields >> slot >> local >> remote >> s.state >> queues >> timer >> retransmits >> uid >>
            timeout >> s.inode;
        if (local.size() < 10 || remote.size() < 10)
            continue;
        parseProcNetEndpoint(local, &s.local_address, &s.local_port);
        parseProcNetEndpoint(remote, &s.remote_address, &s.remote_port);
        out.push_back(std::move(s));
    }
    return out;
}

// The inodes of this process's sockets, from its descriptors' links ("socket:[123]").
inline std::set<std::string> socketInodesOfThisProcess() {
    std::set<std::string> inodes;
    for (const auto& fd : std::filesystem::directory_iterator("/proc/self/fd")) {
        std::error_code ec;
        const std::string target = std::filesystem::read_symlink(fd.path(), ec).string();
        if (!ec && target.starts_with("socket:["))
            inodes.insert(target.substr(8, target.size() - 9));
    }
    return inodes;
}

}  // namespace mixray::test
