// mixray devices: every device every backend sees, with ids and modes.
#include <cstdio>
#include <nlohmann/json.hpp>

#include "backends.h"
#include "cli.h"
#include "dds_options_cli.h"

namespace mixray::cli {
namespace {

int runDevices(bool as_json, bool include_virtual, const dds::DdsOptions& dds) {
    BackendRegistry registry = makeBackendRegistry(dds);
    nlohmann::json j = nlohmann::json::array();
    size_t real_devices = 0;
    bool any_failed = false;
    for (DeviceBackend* backend : registry.backends()) {
        const bool is_virtual = backend->name() == "pattern" || backend->name() == "replay";
        if (is_virtual && !include_virtual)
            continue;
        auto devices = backend->enumerate();
        if (!devices) {
            any_failed = true;
            std::fprintf(stderr, "mixray devices: backend %s: %s\n",
                         std::string(backend->name()).c_str(), devices.status().toString().c_str());
            continue;
        }
        for (const auto& d : *devices) {
            if (!is_virtual)
                ++real_devices;
            if (as_json) {
                j.push_back({{"backend", d.backend},
                             {"id", d.id},
                             {"model", d.model},
                             {"serial", d.serial},
                             {"location", d.location},
                             {"modes", d.modes}});
                continue;
            }
            std::printf("%-8s %-16s %s", d.backend.c_str(), d.id.c_str(), d.model.c_str());
            if (!d.serial.empty())
                std::printf("  serial %s", d.serial.c_str());
            if (!d.location.empty())
                std::printf("  at %s", d.location.c_str());
            std::printf("\n");
            for (const auto& mode : d.modes)
                std::printf("           %s\n", mode.c_str());
        }
    }
    if (as_json) {
        std::printf("%s\n", j.dump(2).c_str());
    } else if (real_devices == 0 && !include_virtual) {
        std::printf("No camera or sensor found by any backend (");
        bool first = true;
        for (DeviceBackend* backend : registry.backends()) {
            if (backend->name() == "pattern" || backend->name() == "replay")
                continue;
            std::printf("%s%s", first ? "" : ", ", std::string(backend->name()).c_str());
            first = false;
        }
        std::printf(
            "%s).\nRecordings replay with the 'replay' driver; '--virtual' lists the "
            "built-in test-pattern devices.\n",
            first ? "no hardware backend in this build" : "");
    }
    return any_failed ? kExitUnavailable : kExitOk;
}

}  // namespace

void registerDevicesCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand("devices", "List every device each backend sees now");
    auto json = std::make_shared<bool>(false);
    auto include_virtual = std::make_shared<bool>(false);
    sub->add_flag("--json", *json, "Print the list as JSON");
    sub->add_flag("--virtual", *include_virtual,
                  "Also list the virtual test-pattern devices (driver 'pattern')");
    // Remote devices: what other hosts publish (mixray publish), listened for a second.
    auto dds = std::make_shared<dds::DdsOptions>();
    addDdsOptions(*sub, *dds);
    commands.push_back(
        {sub, [json, include_virtual, dds] { return runDevices(*json, *include_virtual, *dds); }});
}

}  // namespace mixray::cli
