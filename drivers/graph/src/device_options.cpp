// Typed reading of a device's rig-file options (device_options.h).
#include "mixray/graph/device_options.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace mixray {

std::vector<std::string> splitOptionList(std::string_view text) {
    std::vector<std::string> out;
    size_t pos = 0;
    while (pos <= text.size()) {
        size_t comma = text.find(',', pos);
        if (comma == std::string_view::npos)
            comma = text.size();
        std::string_view item = text.substr(pos, comma - pos);
        while (!item.empty() && item.front() == ' ')
            item.remove_prefix(1);
        while (!item.empty() && item.back() == ' ')
            item.remove_suffix(1);
        if (!item.empty())
            out.emplace_back(item);
        pos = comma + 1;
    }
    return out;
}

const std::string* DeviceOptionReader::find(const std::string& key) {
    auto it = config_.options.find(key);
    if (it == config_.options.end())
        return nullptr;
    used_.insert(key);
    return &it->second;
}

Status DeviceOptionReader::error(const std::string& key, const std::string& value,
                                 std::string_view expected) const {
    return {ErrorCode::kInvalidArgument, backend_ + " device '" + config_.name + "': option '" +
                                             key + "': expected " + std::string(expected) +
                                             ", got '" + value + "'"};
}

Status DeviceOptionReader::real(const std::string& key, double& out, double lo, double hi,
                                std::string_view expected, Bound lo_bound, Bound hi_bound) {
    const std::string* text = find(key);
    if (!text)
        return Status::ok();
    double value = 0;
    const char* end = text->data() + text->size();
    auto [ptr, ec] = std::from_chars(text->data(), end, value);
    const bool above = lo_bound == Bound::kClosed ? value >= lo : value > lo;
    const bool below = hi_bound == Bound::kClosed ? value <= hi : value < hi;
    if (ec != std::errc() || ptr != end || !std::isfinite(value) || !above || !below)
        return error(key, *text, expected);
    out = value;
    return Status::ok();
}

Status DeviceOptionReader::boolean(const std::string& key, bool& out) {
    const std::string* text = find(key);
    if (!text)
        return Status::ok();
    static const std::array<std::string_view, 4> kTrue = {"true", "1", "on", "yes"};
    static const std::array<std::string_view, 4> kFalse = {"false", "0", "off", "no"};
    if (std::find(kTrue.begin(), kTrue.end(), *text) != kTrue.end())
        out = true;
    else if (std::find(kFalse.begin(), kFalse.end(), *text) != kFalse.end())
        out = false;
    else
        return error(key, *text, "true or false");
    return Status::ok();
}

Status DeviceOptionReader::leftovers(std::string_view known) const {
    for (const auto& [key, value] : config_.options) {
        if (used_.count(key))
            continue;
        return {ErrorCode::kInvalidArgument, backend_ + " device '" + config_.name +
                                                 "': unknown option '" + key +
                                                 "' (known: " + std::string(known) + ")"};
    }
    return Status::ok();
}

}  // namespace mixray
