// Names of the estimate vocabulary.
#include "mixray/tracking/estimate.h"

namespace mixray::tracking {

std::string_view toString(LightSource source) {
    switch (source) {
        case LightSource::kProbeMirror:
            return "probe-mirror";
        case LightSource::kProbeDiffuse:
            return "probe-diffuse";
        case LightSource::kEnvironment:
            return "environment";
        case LightSource::kSun:
            return "sun";
    }
    return "unknown";
}

}  // namespace mixray::tracking
