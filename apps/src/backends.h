// The device backends this build of mixray offers, in one registry.
#pragma once

#include "mixray/graph/device.h"

namespace mixray::cli {

// Every backend linked into the mixray binary, registered in a fresh registry.
BackendRegistry makeBackendRegistry();

// Teaches replay::openRecording() (mixray info, convert, the replay backend) the recording
// formats that backends read: OpenNI .oni files through the openni2 backend.
void registerRecordingFormats();

}  // namespace mixray::cli
