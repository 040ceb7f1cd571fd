// The "replay" backend: opens recordings by path as devices.
#include "mixray/replay/replay_backend.h"

#include "mixray/graph/thread_priority.h"
#include "mixray/replay/open_recording.h"

namespace mixray::replay {

Result<std::vector<DeviceDescriptor>> ReplayBackend::enumerate() {
    // Recordings are not discovered: a rig file names them by path.
    return std::vector<DeviceDescriptor>{};
}

Result<std::unique_ptr<Device>> ReplayBackend::open(const DeviceConfig& config) {
    if (config.id.empty()) {
        return {ErrorCode::kInvalidArgument,
                "replay device '" + config.name + "' needs id = the recording's path"};
    }
    // Options first: a typo is reported without touching the file.
    auto options = ReplayOptions::fromConfig(config.options);
    if (!options)
        return options.status();
    // The decoders' threads start here and keep this thread's priority: capture's.
    const ScopedThreadRole role(ThreadRole::kCapture);
    auto reader = openRecording(config.id, {options->buffers_per_stream});
    if (!reader)
        return reader.status();
    auto device = openReplayDevice(std::move(*reader), config);
    if (!device)
        return device.status();
    return std::unique_ptr<Device>(std::move(*device));
}

}  // namespace mixray::replay
