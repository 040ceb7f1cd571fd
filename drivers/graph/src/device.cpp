// The backend registry.
#include "mixray/graph/device.h"

namespace mixray {

const char* toString(DeviceState state) {
    switch (state) {
        case DeviceState::kStreaming:
            return "streaming";
        case DeviceState::kLost:
            return "lost";
        case DeviceState::kReconnecting:
            return "reconnecting";
        case DeviceState::kEnded:
            return "ended";
        case DeviceState::kUnknown:
            break;
    }
    return "unknown";
}

Status BackendRegistry::add(std::unique_ptr<DeviceBackend> backend) {
    if (!backend)
        return {ErrorCode::kInvalidArgument, "null backend"};
    if (find(backend->name())) {
        return {ErrorCode::kInvalidArgument,
                "backend '" + std::string(backend->name()) + "' registered twice"};
    }
    backends_.push_back(std::move(backend));
    return Status::ok();
}

DeviceBackend* BackendRegistry::find(std::string_view name) const {
    for (const auto& b : backends_) {
        if (b->name() == name)
            return b.get();
    }
    return nullptr;
}

std::vector<DeviceBackend*> BackendRegistry::backends() const {
    std::vector<DeviceBackend*> out;
    for (const auto& b : backends_)
        out.push_back(b.get());
    return out;
}

Result<std::unique_ptr<Device>> BackendRegistry::open(const DeviceConfig& config) const {
    DeviceBackend* backend = find(config.driver);
    if (!backend) {
        std::string known;
        for (const auto& b : backends_)
            known += (known.empty() ? "" : ", ") + std::string(b->name());
        return {ErrorCode::kNotFound, "device '" + config.name + "': unknown driver '" +
                                          config.driver + "' (known: " + known + ")"};
    }
    auto device = backend->open(config);
    if (!device)
        return device.status().withContext("device '" + config.name + "'");
    return device;
}

}  // namespace mixray
