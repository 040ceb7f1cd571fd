// Network namespaces as extra hosts for tests that run as root: a shell helper and a veth pair
// between two namespaces.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <string>

namespace mixray::test {

// Runs `command` through the shell, its output discarded; its exit status, or -1.
inline int shell(const std::string& command) {
    const int status = std::system((command + " >/dev/null 2>&1").c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// One end of a veth pair: the namespace it goes into, its name and its address (a /24).
struct VethEnd {
    std::string ns;
    std::string name;
    std::string address;
};

// Makes the veth pair a–b, moves each end into its namespace, addresses it and brings it up.
// False on the first command that fails.
inline bool linkNamespaces(const VethEnd& a, const VethEnd& b) {
    if (shell("ip link add " + a.name + " type veth peer name " + b.name) != 0)
        return false;
    for (const VethEnd* end : {&a, &b})
        if (shell("ip link set " + end->name + " netns " + end->ns) != 0 ||
            shell("ip -n " + end->ns + " addr add " + end->address + "/24 dev " + end->name) != 0 ||
            shell("ip -n " + end->ns + " link set " + end->name + " up") != 0)
            return false;
    return true;
}

}  // namespace mixray::test
