// mixray convert: copies a recording between formats (mkv, TUM RGB-D folder, PCL TIFF folder).
#include <cstdio>
#include <filesystem>

#include "cli.h"
#include "console.h"
#include "mixray/graph/mkv.h"
#include "mixray/replay/convert.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/pcl_tiff.h"
#include "mixray/replay/tum.h"

namespace mixray::cli {
namespace {

struct ConvertOptions {
    std::string input;
    std::string output;
    std::string to;  // mkv | tum | pcl-tiff; empty: from the output name
    bool force = false;
};

Result<std::unique_ptr<RecordingWriter>> createWriter(const ConvertOptions& options,
                                                      const RecordingHeader& header) {
    std::string to = options.to;
    if (to.empty())
        to = std::filesystem::path(options.output).extension() == ".mkv" ? "mkv" : "tum";
    if (to == "mkv")
        return createMkvWriter(options.output, header);
    if (to == "tum")
        return replay::createTumWriter(options.output, header);
    if (to == "pcl-tiff")
        return replay::createPclTiffWriter(options.output, header);
    return {ErrorCode::kInvalidArgument, "--to " + to + ": expected mkv, tum or pcl-tiff"};
}

int runConvert(const ConvertOptions& options) {
    setFfmpegLogging(false);
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::equivalent(options.input, options.output, ec)) {
        return fail("convert", {ErrorCode::kInvalidArgument, "input and output are the same"});
    }
    if (fs::exists(options.output) && !options.force &&
        !(fs::is_directory(options.output) && fs::is_empty(options.output))) {
        return fail("convert", {ErrorCode::kInvalidArgument,
                                options.output + " exists (use --force to overwrite a file)"});
    }
    auto reader = replay::openRecording(options.input);
    if (!reader)
        return fail("convert", reader.status());
    auto writer = createWriter(options, replay::headerOf(**reader));
    if (!writer)
        return fail("convert", writer.status().withContext(options.output));

    InterruptFlag interrupt;
    StatusLine status;
    auto summary =
        replay::convertRecording(**reader, **writer, [&](const replay::ConvertProgress& p) {
            status.update("converted " + std::to_string(p.frames) + " frames, " +
                          formatBytes(p.bytes_written) + " written");
            return !interrupt.raised();
        });
    status.finish();
    if (!summary)
        return fail("convert", summary.status());
    std::printf("%s (%s) -> %s: %llu frames, %s, %.2f s\n", options.input.c_str(),
                (*reader)->format().c_str(), options.output.c_str(),
                static_cast<unsigned long long>(summary->frames),
                formatBytes(summary->bytes_written).c_str(), summary->seconds);
    return kExitOk;
}

}  // namespace

void registerConvertCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "convert",
        "Convert a recording: mkv <-> TUM RGB-D folder, PCL TIFF folder or Azure Kinect .mkv -> "
        "mkv. Frames, timestamps, attachments and tags are kept exactly where the target "
        "format can hold them.");
    auto options = std::make_shared<ConvertOptions>();
    sub->add_option("INPUT", options->input, "Recording to read")->required();
    sub->add_option("OUTPUT", options->output,
                    "What to write: a .mkv file, or a folder for TUM / PCL TIFF")
        ->required();
    sub->add_option("--to", options->to, "Output format (default: mkv for *.mkv, else tum)")
        ->check(CLI::IsMember({"mkv", "tum", "pcl-tiff"}));
    sub->add_flag("--force", options->force, "Overwrite an existing output file");
    commands.push_back({sub, [options] { return runConvert(*options); }});
}

}  // namespace mixray::cli
