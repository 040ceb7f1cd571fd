// Network namespaces as extra hosts on one machine (root only): `mixray bench dds` measures DDS
// across a veth pair between two of them, and the tests run hosts in them.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "mixray/graph/result.h"

namespace mixray::hosts {

// Runs `command` through the shell, its output discarded; its exit status, or -1.
int shell(const std::string& command);

// One end of a veth pair: the namespace it goes into, its name and its address (a /24).
struct VethEnd {
    std::string ns;
    std::string name;
    std::string address;
};

// Makes the veth pair a–b, moves each end into its namespace, addresses it and brings it up.
// False on the first command that fails.
bool linkNamespaces(const VethEnd& a, const VethEnd& b);

// Two namespaces joined by a veth pair, deleted with this object.
class NamespacePair {
public:
    // Namespaces "<prefix>a" and "<prefix>b" with addresses <net>.1 and <net>.2 (net: "10.214.7").
    // kUnsupported without root; kUnavailable naming the command that failed.
    static Result<std::unique_ptr<NamespacePair>> create(const std::string& prefix,
                                                         const std::string& net);
    ~NamespacePair();
    NamespacePair(const NamespacePair&) = delete;
    NamespacePair& operator=(const NamespacePair&) = delete;

    const VethEnd& a() const { return a_; }
    const VethEnd& b() const { return b_; }
    // Bytes the two ends have sent over the pair so far (the kernel's counters, read with ip);
    // kUnavailable when ip cannot say.
    Result<uint64_t> bytesSent() const;

private:
    NamespacePair() = default;
    VethEnd a_, b_;
    bool made_a_ = false, made_b_ = false;
};

// While it lives, the calling thread is in network namespace `ns` (ip netns's name): sockets it
// opens and threads it starts are that host's. Thread-bound; restores the thread's namespace.
class InNamespace {
public:
    // kUnavailable when the namespace cannot be entered (absent, or not root).
    static Result<std::unique_ptr<InNamespace>> enter(const std::string& ns);
    ~InNamespace();
    InNamespace(const InNamespace&) = delete;
    InNamespace& operator=(const InNamespace&) = delete;

private:
    explicit InNamespace(int saved) : saved_(saved) {}
    int saved_;
};

}  // namespace mixray::hosts
