// The device backends this build of mixray offers, in one registry.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "mixray/dds/dds_options.h"
#include "mixray/graph/device.h"
#include "mixray/render/ar_pipeline.h"

namespace mixray::cli {

// Every backend linked into the mixray binary, registered in a fresh registry. `dds`: the DDS
// settings the dds backend lists remote devices with, and opens them with where a rig
// device's options do not say.
BackendRegistry makeBackendRegistry(const dds::DdsOptions& dds = {});

// Teaches replay::openRecording() (mixray info, convert, the replay backend) the recording
// formats that backends read: OpenNI .oni files through the openni2 backend.
void registerRecordingFormats();

// A recording through the AR pipeline as fast as the pipeline takes it (every frame: mixray
// demo, track and render), its devices opened through makeBackendRegistry(). Errors name the
// recording.
Result<std::unique_ptr<render::ArPipeline>> recordingPipeline(const std::string& recording,
                                                              render::ArPipelineOptions options);

// Starts `pipeline`, waits until it is done or `stop_early` says so (polled every 50 ms), and
// stops it: the start error, else the pipeline's own status.
Status runPipeline(render::ArPipeline& pipeline, const std::function<bool()>& stop_early);

// The end of a pipeline run that made its output: prints each of stats.warnings() (the input
// cut off or damaged, corrupt colour frames and damaged records, objects never drawn) as
// "mixray <command>: <line>" and returns the exit code: kExitIncomplete when the input was
// incomplete or damaged, else kExitOk (an object never drawn is a warning, not a failure).
int finishPipelineRun(const std::string& command, const render::ArPipelineStats& stats);

}  // namespace mixray::cli
