// Registration of the backends linked into the mixray binary (apps is the only module that
// knows them by name).
#include "backends.h"

#include <cstdio>
#include <memory>

#include "cli.h"
#include "mixray/aravis/aravis_backend.h"
#include "mixray/dds/dds_backend.h"
#include "mixray/dds/ros2_source.h"
#include "mixray/openni2/oni_recording.h"
#include "mixray/openni2/openni2_backend.h"
#include "mixray/pattern/pattern_backend.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/replay_backend.h"
#include "mixray/usb/usb_backend.h"
#include "mixray/v4l2/v4l2_backend.h"

#if defined(__SANITIZE_ADDRESS__)
// OpenNI2 2.2.0.33 and its drivers leak on their own (the PS1080 and PSLink drivers at start-up,
// sensor info lists of the OniFile driver that nobody frees); a sanitizer build of mixray names
// those modules so that LeakSanitizer still reports mixray's own leaks and nothing else.
extern "C" const char* __lsan_default_suppressions() {
    return "leak:libOpenNI2.so\nleak:libOniFile.so\nleak:libDummyDevice.so\nleak:libPS1080.so\n"
           "leak:libPSLink.so\nleak:libjpeg.so\n"
           // libdogleg under mrcal_optimize, when mrcal rejects outliers and optimises again.
           "leak:libdogleg.so\n";
}
// The list of suppressions used would otherwise end every command's stderr (--json output too).
extern "C" const char* __lsan_default_options() {
    return "print_suppressions=0";
}
// Fast DDS 2.9.1 deletes one of a writer's internals through a pointer of a smaller type
// (tests/support/fastdds_asan_options.cpp says more); ASan cannot suppress that check per module.
extern "C" const char* __asan_default_options() {
    return "new_delete_type_mismatch=0";
}
#endif

namespace mixray::cli {

BackendRegistry makeBackendRegistry(const dds::DdsOptions& dds) {
    BackendRegistry registry;
    // Names are distinct by construction; add() cannot fail here.
    (void)registry.add(std::make_unique<replay::ReplayBackend>());
    (void)registry.add(std::make_unique<pattern::PatternBackend>());
    (void)registry.add(std::make_unique<aravis::AravisBackend>());
    (void)registry.add(std::make_unique<v4l2::V4l2Backend>());
    (void)registry.add(std::make_unique<openni2::OpenNI2Backend>());
    (void)registry.add(std::make_unique<usb::UsbBackend>());
    (void)registry.add(std::make_unique<dds::DdsBackend>(dds));
    (void)registry.add(std::make_unique<dds::Ros2Backend>(dds));
    return registry;
}

void registerRecordingFormats() {
    replay::registerRecordingFormat(
        {"oni", "an OpenNI .oni recording (played by OpenNI2)", openni2::looksLikeOni,
         [](const std::filesystem::path& path, const replay::OpenRecordingOptions& options) {
             return openni2::openOniRecording(path, options.buffers_per_stream);
         }});
}

Result<std::unique_ptr<render::ArPipeline>> recordingPipeline(const std::string& recording,
                                                              render::ArPipelineOptions options) {
    render::ArSource source;
    source.recording = recording;
    source.pace = render::ArSource::Pace::kFast;
    auto pipeline = render::ArPipeline::create(makeBackendRegistry(), source, std::move(options));
    if (!pipeline)
        return pipeline.status().withContext(recording);
    return pipeline;
}

Status runPipeline(render::ArPipeline& pipeline, const std::function<bool()>& stop_early) {
    MIXRAY_RETURN_IF_ERROR(pipeline.start());
    while (!pipeline.waitDone(std::chrono::milliseconds(50)))
        if (stop_early())
            break;
    pipeline.stop();
    return pipeline.status();
}

int finishPipelineRun(const std::string& command, const render::ArPipelineStats& stats) {
    for (const std::string& line : stats.warnings())
        std::fprintf(stderr, "mixray %s: %s\n", command.c_str(), line.c_str());
    // Damaged input (a cut-off file, corrupt frames, damaged records) made the output from
    // what was readable: exit 5 says so to scripts as the message says it to people.
    const bool damaged = stats.compositor && !stats.compositor->damage().empty();
    return stats.input && !damaged ? kExitOk : kExitIncomplete;
}

}  // namespace mixray::cli
