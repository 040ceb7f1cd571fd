// The device backends this build of mixray offers, in one registry.
#pragma once

#include "mixray/graph/device.h"

namespace mixray::cli {

// Every backend linked into the mixray binary, registered in a fresh registry.
BackendRegistry makeBackendRegistry();

}  // namespace mixray::cli
