#include "network_namespaces.h"

#include <fcntl.h>
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <nlohmann/json.hpp>

namespace mixray::hosts {

int shell(const std::string& command) {
    const int status = std::system((command + " >/dev/null 2>&1").c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

bool linkNamespaces(const VethEnd& a, const VethEnd& b) {
    if (shell("ip link add " + a.name + " type veth peer name " + b.name) != 0)
        return false;
    for (const VethEnd* end : {&a, &b}) {
        if (shell("ip link set " + end->name + " netns " + end->ns) != 0 ||
            shell("ip -n " + end->ns + " addr add " + end->address + "/24 dev " + end->name) != 0 ||
            shell("ip -n " + end->ns + " link set " + end->name + " up") != 0)
            return false;
    }
    return true;
}

Result<std::unique_ptr<NamespacePair>> NamespacePair::create(const std::string& prefix,
                                                             const std::string& net) {
    if (geteuid() != 0) {
        return Status(ErrorCode::kUnsupported, "network namespaces need root (ip netns add)");
    }
    std::unique_ptr<NamespacePair> pair(new NamespacePair);
    pair->a_ = {.ns = prefix + "a", .name = prefix + "va", .address = net + ".1"};
    pair->b_ = {.ns = prefix + "b", .name = prefix + "vb", .address = net + ".2"};
    for (auto [end, made] : {std::pair{&pair->a_, &pair->made_a_}, {&pair->b_, &pair->made_b_}}) {
        if (shell("ip netns add " + end->ns) != 0)
            return Status(ErrorCode::kUnavailable, "ip netns add " + end->ns + " failed");
        *made = true;
        if (shell("ip -n " + end->ns + " link set lo up") != 0)
            return Status(ErrorCode::kUnavailable, "ip -n " + end->ns + " link set lo up failed");
    }
    if (!linkNamespaces(pair->a_, pair->b_)) {
        return Status(ErrorCode::kUnavailable,
                      "could not join " + pair->a_.ns + " and " + pair->b_.ns + " by a veth pair");
    }
    return pair;
}

Result<uint64_t> NamespacePair::bytesSent() const {
    uint64_t total = 0;
    for (const VethEnd* end : {&a_, &b_}) {
        const std::string command = "ip -n " + end->ns + " -s -j link show dev " + end->name;
        std::FILE* pipe = popen(command.c_str(), "r");
        std::string text;
        char buffer[4096];
        for (size_t n; pipe && (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;)
            text.append(buffer, n);
        if (!pipe || pclose(pipe) != 0)
            return Status(ErrorCode::kUnavailable, command + " failed");
        const auto json = nlohmann::json::parse(text, nullptr, false);
        if (json.is_discarded() || !json.is_array() || json.empty() || !json[0].contains("stats64"))
            return Status(ErrorCode::kUnavailable, command + " said no counters");
        total += json[0]["stats64"]["tx"]["bytes"].get<uint64_t>();
    }
    return total;
}

NamespacePair::~NamespacePair() {
    if (made_a_)
        shell("ip netns del " + a_.ns);
    if (made_b_)
        shell("ip netns del " + b_.ns);
}

Result<std::unique_ptr<InNamespace>> InNamespace::enter(const std::string& ns) {
    const int saved = open("/proc/thread-self/ns/net", O_RDONLY | O_CLOEXEC);
    const int target = open(("/run/netns/" + ns).c_str(), O_RDONLY | O_CLOEXEC);
    const int error = saved < 0 || target < 0 ? errno : 0;
    if (error == 0 && setns(target, CLONE_NEWNET) == 0) {
        close(target);
        return std::unique_ptr<InNamespace>(new InNamespace(saved));
    }
    const std::string why = std::strerror(error != 0 ? error : errno);
    if (saved >= 0)
        close(saved);
    if (target >= 0)
        close(target);
    return Status(ErrorCode::kUnavailable, "cannot enter network namespace " + ns + ": " + why);
}

InNamespace::~InNamespace() {
    (void)setns(saved_, CLONE_NEWNET);
    close(saved_);
}

}  // namespace mixray::hosts
