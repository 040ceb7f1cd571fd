// Names of stream kinds; the least frame period a consumer may count on.
#include "mixray/graph/stream.h"

#include <array>
#include <utility>

namespace mixray {
namespace {
constexpr std::array<std::pair<StreamKind, std::string_view>, 7> kKinds = {{
    {StreamKind::kColor, "color"},
    {StreamKind::kDepth, "depth"},
    {StreamKind::kInfrared, "infrared"},
    {StreamKind::kMono, "mono"},
    {StreamKind::kImu, "imu"},
    {StreamKind::kPose, "pose"},
    {StreamKind::kData, "data"},
}};
}  // namespace

std::string_view toString(StreamKind kind) {
    for (const auto& [k, name] : kKinds) {
        if (k == kind)
            return name;
    }
    return "data";
}

std::optional<StreamKind> streamKindFromString(std::string_view name) {
    for (const auto& [k, n] : kKinds) {
        if (n == name)
            return k;
    }
    return std::nullopt;
}

int64_t minFramePeriodNs(const StreamInfo& stream) {
    return stream.nominal_fps > 0 ? static_cast<int64_t>(0.8e9 / stream.nominal_fps) : 0;
}

}  // namespace mixray
