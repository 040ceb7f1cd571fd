// Registration of the backends linked into the mixray binary (apps is the only module that
// knows them by name).
#include "backends.h"

#include <memory>

#include "mixray/openni2/openni2_backend.h"
#include "mixray/pattern/pattern_backend.h"
#include "mixray/replay/replay_backend.h"

namespace mixray::cli {

BackendRegistry makeBackendRegistry() {
    BackendRegistry registry;
    // Names are distinct by construction; add() cannot fail here.
    (void)registry.add(std::make_unique<replay::ReplayBackend>());
    (void)registry.add(std::make_unique<pattern::PatternBackend>());
    (void)registry.add(std::make_unique<openni2::OpenNI2Backend>());
    return registry;
}

}  // namespace mixray::cli
