// The "dds" backend: another host's streams, published by its DdsPublisher, as a local device.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "mixray/dds/dds_options.h"
#include "mixray/graph/device.h"

namespace mixray::dds {

// How a remote device is opened. Parsed from DeviceConfig::options (all strings): the keys of
// DdsOptions (kDdsOptionKeys) and
//   discovery_timeout_ms  how long open() waits for the host to announce the device's
//                         streams, 0..600000 (default 5000)
//   buffers               frames each stream's pool holds, 2..256 (default 8)
//   history               frames DDS keeps per stream for this reader, 1..64 (default 4)
// DeviceConfig::id is "HOST/DEVICE" (the publishing host's name and its device) or "DEVICE"
// (whichever host announces it; two hosts announcing it is an error). DeviceConfig::streams
// lists the device's streams to receive ("color", "depth"; empty: every announced one).
struct DdsDeviceOptions {
    DdsOptions dds;
    int64_t discovery_timeout_ms = 5000;
    size_t buffers = 8;
    int history = 4;
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
// the graph's pools. Metadata arrives exactly as the publishing host had it; frames keep their
// sequence, device stamp, exposure and status, and are stamped on arrival with this host's
// CLOCK_MONOTONIC (host_stamp_ns, as every local device stamps its frames). A stream stamped
// by the publishing host's clock (clock domain 0 there) carries that stamp as its device stamp
// in clock domain deviceClockDomain("dds", HOST), so ClockSync and the synchronizer map the
// other host's clock onto this one like any device clock.
// Its state is streaming while the host's writers are alive, reconnecting once they are gone
// (the host left, crashed or became unreachable for DdsOptions::lease_s), and streaming again
// when they return.
class DdsDevice : public Device {
public:
    ~DdsDevice() override;
    std::string name() const override;
    DeviceDescriptor descriptor() const override;
    DeviceState state() const override;
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
