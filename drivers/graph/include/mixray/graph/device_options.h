// Reading a device's rig-file options (DeviceConfig::options, all strings) into typed settings,
// with errors that name the device, the option, what was expected and what was given, and a
// final check that catches options no one read (typos).
#pragma once

#include <charconv>
#include <initializer_list>
#include <set>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "mixray/graph/device.h"
#include "mixray/graph/result.h"

namespace mixray {

// Splits an option's "a, b,c" into trimmed, non-empty items.
std::vector<std::string> splitOptionList(std::string_view text);

// Reads one device's options key by key, remembering which were read. Absent keys leave the
// output as it was (the backend's default). Thread-bound; does not own `config`.
class DeviceOptionReader {
public:
    enum class Bound : uint8_t { kClosed, kOpen };

    // `backend` names the device kind in messages: "aravis device 'cam': option 'fps': ...".
    DeviceOptionReader(const DeviceConfig& config, std::string backend)
        : config_(config), backend_(std::move(backend)) {}

    const DeviceConfig& config() const { return config_; }

    // The option's text, marking it read; nullptr when absent.
    const std::string* find(const std::string& key);

    // kInvalidArgument: "<backend> device '<name>': option '<key>': expected <expected>, got
    // '<value>'".
    Status error(const std::string& key, const std::string& value, std::string_view expected) const;

    // A whole decimal integer in [lo, hi].
    template <typename T>
    Status integer(const std::string& key, T& out, T lo, T hi, std::string_view expected) {
        const std::string* text = find(key);
        if (!text)
            return Status::ok();
        T value{};
        const char* end = text->data() + text->size();
        auto [ptr, ec] = std::from_chars(text->data(), end, value);
        if (ec != std::errc() || ptr != end || value < lo || value > hi)
            return error(key, *text, expected);
        out = value;
        return Status::ok();
    }

    // A finite decimal number between lo and hi, each bound closed or open.
    Status real(const std::string& key, double& out, double lo, double hi,
                std::string_view expected, Bound lo_bound = Bound::kClosed,
                Bound hi_bound = Bound::kClosed);

    // true/1/on/yes or false/0/off/no.
    Status boolean(const std::string& key, bool& out);

    // One of the named values.
    template <typename T>
    Status choice(const std::string& key, T& out,
                  std::initializer_list<std::pair<std::string_view, T>> values,
                  std::string_view expected) {
        const std::string* text = find(key);
        if (!text)
            return Status::ok();
        for (const auto& [name, value] : values) {
            if (*text == name) {
                out = value;
                return Status::ok();
            }
        }
        return error(key, *text, expected);
    }

    // kInvalidArgument naming the first option never read, with the list of `known` ones.
    Status leftovers(std::string_view known) const;

private:
    const DeviceConfig& config_;
    std::string backend_;
    std::set<std::string> used_;
};

}  // namespace mixray
