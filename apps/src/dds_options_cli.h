// The DDS options of the commands that join DDS (publish, devices): --domain, --address,
// --peers, --transport, --host, --partition.
#pragma once

#include <CLI/CLI.hpp>

#include "mixray/dds/dds_options.h"

namespace mixray::cli {

// Adds the options to `command`, writing into `options` (defaults shown are its values).
void addDdsOptions(CLI::App& command, dds::DdsOptions& options);

}  // namespace mixray::cli
