// The "dds" backend: another host's streams, published by its DdsPublisher, as a local device.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mixray/dds/dds_options.h"
#include "mixray/dds/host_clock.h"
#include "mixray/graph/device.h"

namespace mixray::dds {

// How a remote device is opened. Parsed from DeviceConfig::options (all strings): the keys of
// DdsOptions (kDdsOptionKeys) and
//   discovery_timeout_ms  how long open() waits for the host to announce the device's
//                         streams, 0..600000 (default 5000)
//   buffers               frames each stream's pool holds, 2..256 (default 16: half a
//                         second at 30 fps, for consumers that order frames of several hosts
//                         by capture time and so wait for the slowest host's network)
//   history               frames DDS keeps per stream for this reader, 1..64 (default 4)
//   clock                 how the host's stamps reach this host's time base: "exchange"
//                         (default: NTP-style exchanges with the host over DDS, waiting up to
//                         2 s for a fit at open(), else as "arrival"; the hosts' wall clocks
//                         instead when both are PTP-locked to one grandmaster), "wall" (the
//                         hosts' wall clocks are in step, by PTP, chrony or NTP: the offset is
//                         the difference of their realtime − monotonic clocks, which the
//                         exchanges carry, and the exchanges' fit only checks it) or "arrival"
//                         (its clock is a device clock fitted to the frames' arrival)
// DeviceConfig::id is "HOST/DEVICE" (the publishing host's name and its device) or "DEVICE"
// (whichever host announces it; two hosts announcing it is an error). DeviceConfig::streams
// lists the device's streams to receive ("color", "depth"; empty: every announced one).
struct DdsDeviceOptions {
    enum class Clock : uint8_t { kExchange, kWall, kArrival };
    DdsOptions dds;
    int64_t discovery_timeout_ms = 5000;
    size_t buffers = 16;
    int history = 4;
    Clock clock = Clock::kExchange;
};

// Reads DeviceConfig::options into `options` (starting from its values); kInvalidArgument
// naming the device and option for a bad value or an unknown key.
Status parseDdsDeviceOptions(const DeviceConfig& config, DdsDeviceOptions* options);

// One remote stream's figures.
struct DdsReceiveStats {
    std::string stream;            // the local graph name
    std::string topic;             // the DDS topic it comes from
    uint64_t received = 0;         // frame messages taken from DDS
    uint64_t published = 0;        // frames published into the graph
    uint64_t lost_in_transit = 0;  // frames missing from the sequence (dropped on the way)
    uint64_t pool_exhausted = 0;   // frames dropped because the graph held every buffer
    uint64_t rejected = 0;         // messages that did not fit the announced stream
    int matched_writers = 0;       // the host's writers this reader has matched now
};

// A remote device: one DataReader per stream; a thread takes frames and publishes them into
// the graph's pools. Metadata arrives exactly as the publishing host had it, and frames keep
// their sequence, device stamp, exposure and status; the stamps then reach this host's time
// base one of two ways (DdsDeviceOptions::clock):
//   exchange: the device asks the host for its time over DDS (mixray/time_request) all along
//     and fits the host's CLOCK_MONOTONIC to this one (HostClockEstimator). Stamps of the
//     host's clock become this host's: a stream the host stamped (clock domain 0 there) is in
//     clock domain 0 here, and every frame's host stamp is the host's, mapped. clockReport()
//     says the offset, drift and residual. When both hosts' wall clocks are PTP-locked to one
//     grandmaster, or with clock: wall, the offset comes from the wall clocks instead
//     (fromWallClocks()), the exchanges' fit kept as a check.
//   arrival (or no answer within 2 s): frames are stamped on arrival with this host's
//     CLOCK_MONOTONIC (host_stamp_ns), and a stream the host stamped carries that stamp as its
//     device stamp in clock domain deviceClockDomain("dds", HOST), so ClockSync maps the other
//     host's clock like any device clock, network latency included.
// A stream from a device with its own clock keeps that clock's domain either way.
// Its state is streaming while the host's writers are alive, reconnecting once they are gone
// (the host left, crashed or became unreachable for DdsOptions::lease_s), and streaming again
// when they return.
class DdsDevice : public Device {
public:
    ~DdsDevice() override;
    std::string name() const override;
    DeviceDescriptor descriptor() const override;
    DeviceState state() const override;
    // "hostA clock +1000.000123 s, drift ..." (HostClockEstimate::describe()), or why the
    // frames' arrival is the time base.
    std::string clockReport() const override;
    // The current fit of the host's clock; nullopt with clock: arrival or before any answer.
    std::optional<HostClockEstimate> hostClock() const;
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    std::vector<DdsReceiveStats> stats() const;
    // Times the host's writers went away, and came back, since start().
    uint64_t disconnections() const;
    uint64_t reconnections() const;

private:
    friend class DdsBackend;
    struct Impl;
    explicit DdsDevice(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

class DdsBackend : public DeviceBackend {
public:
    // `defaults`: the DDS options of enumerate(), and of open() where the device's options do
    // not say. enumerate() listens `listen_ms` for announcements.
    explicit DdsBackend(DdsOptions defaults = {}, int64_t listen_ms = 1000);
    std::string_view name() const override { return "dds"; }
    // Every remote device announced within listen_ms: id "HOST/DEVICE", one mode per stream.
    Result<std::vector<DeviceDescriptor>> enumerate() override;
    // Waits up to discovery_timeout_ms for the device's streams. kNotFound naming the devices
    // that were announced when it is not among them.
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;

private:
    DdsOptions defaults_;
    int64_t listen_ms_;
};

}  // namespace mixray::dds
