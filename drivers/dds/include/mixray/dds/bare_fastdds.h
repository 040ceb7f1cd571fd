// The baseline of `mixray bench dds` (a bench-only seam): the same payload between a Fast DDS
// writer and reader of two participants, with mixray's participant and QoS settings, written
// and taken straight from the bench's threads: no graph, no pools, no publisher or receiver
// threads of mixray's. What mixray's path costs beyond it is mixray's.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "mixray/dds/dds_options.h"
#include "mixray/graph/result.h"

namespace mixray::dds {

// One bare run's figures.
struct BareRun {
    uint64_t sent = 0;
    uint64_t received = 0;
    double wall_s = 0;               // first write to last take
    std::vector<double> latency_ms;  // write to take, per received sample
};

// Frames a throughput run of `bench dds` lets be sent and not yet received: the writers'
// history depth (DdsPublisherOptions::history_depth), so that neither side drops a frame the
// other would still deliver and the figure is what the path sustains.
inline constexpr int kBenchWindow = 2;

// Waits while `sent` - `received` >= kBenchWindow, giving up 2 s after `now_ns` (a frame lost
// on the way must not stall the run). Polls every 20 µs.
void waitForWindow(uint64_t sent, const std::atomic<uint64_t>& received, int64_t now_ns);

// Runs `make` where one end's sockets and threads must be (its host: a network namespace, say);
// the default runs it here.
using HostScope = std::function<Status(const std::function<Status()>& make)>;

// Writes `frames` samples of `payload_bytes` each (mixray_msgs Frame, so the bytes on the wire
// match mixray's) from writer participant `writer` to reader participant `reader`, every
// `period_ns` (0: as fast as they are received, kBenchWindow in flight), and takes them on a
// thread of its own. Each participant and its endpoint are made inside its HostScope.
Result<BareRun> runBareFastDds(const DdsOptions& writer, const DdsOptions& reader,
                               size_t payload_bytes, uint64_t frames, int64_t period_ns,
                               const HostScope& writer_host = {},
                               const HostScope& reader_host = {});

}  // namespace mixray::dds
