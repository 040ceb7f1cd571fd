// Devices and backends: how real and replayed sources enter the graph without the graph
// knowing any of them by name (libcamera's pipeline-handler registry).
#pragma once

#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/graph.h"
#include "mixray/graph/result.h"

namespace mixray {

// A device as a backend sees it before opening: enough to list and to pick one.
struct DeviceDescriptor {
    std::string backend;             // "openni2", "aravis", "replay", ...
    std::string id;                  // what DeviceConfig::id must say to open this one
    std::string model;               // human-readable model name
    std::string serial;              // empty when the device has none
    std::string location;            // URI, bus path or IP address
    std::vector<std::string> modes;  // "depth 640x480@30 depth16", ...
};

// How the rig file asks for one device.
struct DeviceConfig {
    std::string name;    // the device's name in the rig; prefix of its stream names
    std::string driver;  // backend name
    std::string id;      // id, serial or URI the backend understands; empty: the first found
    std::map<std::string, std::string> options;  // mode and backend-specific settings
    std::vector<std::string> streams;            // streams to enable; empty: all
};

// What a device says of itself while the graph runs. The drivers know more than the streams
// show: a camera that stopped sending may be a slow one or one being reopened.
enum class DeviceState {
    kUnknown,       // the device does not say: consumers judge from its streams' activity
    kStreaming,     // connected and delivering (or about to: started, nothing lost)
    kLost,          // gone and not coming back by itself (its streams end or stay silent)
    kReconnecting,  // gone; the device is trying to reopen it and its streams resume after
    kEnded,         // every stream ended (a recording or a finite source reached its end)
};

// "unknown", "streaming", "lost", "reconnecting", "ended": the words the live view shows.
const char* toString(DeviceState state);

// A source node backed by one physical or replayed device.
class Device : public Node {
public:
    virtual DeviceDescriptor descriptor() const = 0;
    // Its state now. Thread-safe in every implementation: status lines and the live view call
    // it from their own threads. The default says nothing (kUnknown).
    virtual DeviceState state() const { return DeviceState::kUnknown; }
    // How its stamps reach this host's time base when the device knows more than its stamps
    // show: another host's clock offset, drift and residual. Empty when it has nothing to say
    // (the default). Thread-safe like state().
    virtual std::string clockReport() const { return {}; }
    // What of its input it could not deliver: ok while it runs and after a clean end; for a
    // replayed recording cut off or damaged, kCorruptData naming the file, what is missing or
    // damaged and how many frames it read (the frames before were delivered exact). Live
    // devices say nothing here (the default): their losses are the graph's lost counts and
    // state(). Thread-safe like state().
    virtual Status inputStatus() const { return Status::ok(); }
};

// One device family. Implementations live in drivers/<backend>/ and are registered by apps.
// Thread-bound: call from one thread.
class DeviceBackend {
public:
    virtual ~DeviceBackend() = default;
    virtual std::string_view name() const = 0;
    // Devices present now. An empty list is not an error; a broken library is.
    virtual Result<std::vector<DeviceDescriptor>> enumerate() = 0;
    virtual Result<std::unique_ptr<Device>> open(const DeviceConfig& config) = 0;
};

// The set of backends an application offers. Not global: apps build one and pass it on.
class BackendRegistry {
public:
    // Takes ownership. A second backend of the same name replaces nothing and is refused.
    Status add(std::unique_ptr<DeviceBackend> backend);
    DeviceBackend* find(std::string_view name) const;
    std::vector<DeviceBackend*> backends() const;
    // Opens config.driver's device; NotFound naming the known backends when there is none.
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) const;

private:
    std::vector<std::unique_ptr<DeviceBackend>> backends_;
};

}  // namespace mixray
