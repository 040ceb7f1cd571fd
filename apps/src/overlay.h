// Pictures of what tracking found, drawn over the camera image: marker outlines and ids, axes
// on each tracked target, probe outlines with the directions of their lights, the fish-eye's
// lights from the world origin, and the tracker's state.
#pragma once

#include "mixray/graph/image.h"
#include "mixray/tracking/pipeline.h"

namespace mixray::cli {

// An rgb8 copy of the frame's colour image with the overlay drawn in. Reentrant.
Image drawTrackingOverlay(const tracking::TrackedFrame& frame,
                          const tracking::TrackingSetup& setup);

}  // namespace mixray::cli
