// mixray convert: copies a recording between formats (mkv, TUM RGB-D folder, PCL TIFF folder).
#include <cstdio>
#include <filesystem>

#include "cli.h"
#include "console.h"
#include "mixray/graph/mkv.h"
#include "mixray/replay/convert.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/pcl_tiff.h"
#include "mixray/replay/point_cloud.h"
#include "mixray/replay/tum.h"

namespace mixray::cli {
namespace {

struct ConvertOptions {
    std::string input;
    std::string output;
    std::string to;  // mkv | tum | pcl-tiff | ply | pcd; empty: from the output name
    bool force = false;
    // Point clouds (--to ply|pcd).
    std::string intrinsics;           // "fx,fy,cx,cy"; empty: from the recording
    std::string pcd_data = "binary";  // ascii | binary
    bool no_color = false;
};

Result<std::unique_ptr<RecordingWriter>> createCloudWriter(const ConvertOptions& options,
                                                           const RecordingHeader& header) {
    replay::PointCloudWriterOptions cloud;
    cloud.format =
        options.to == "pcd" ? replay::PointCloudFormat::kPcd : replay::PointCloudFormat::kPly;
    cloud.pcd_encoding =
        options.pcd_data == "ascii" ? replay::PcdEncoding::kAscii : replay::PcdEncoding::kBinary;
    cloud.color = !options.no_color;
    if (!options.intrinsics.empty()) {
        auto k = replay::parseIntrinsics(options.intrinsics);
        if (!k)
            return k.status().withContext("--intrinsics");
        cloud.intrinsics = *k;
    }
    return replay::createPointCloudWriter(options.output, header, cloud);
}

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
    if (to == "ply" || to == "pcd")
        return createCloudWriter(options, header);
    return {ErrorCode::kInvalidArgument,
            "--to " + to + ": expected mkv, tum, pcl-tiff, ply or pcd"};
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
        "format can hold them. Also reads NYU Depth V2 raw and SUN RGB-D folders and OpenNI "
        ".oni files, and writes organized point clouds (--to ply|pcd, docs/rgbd-formats.md).");
    auto options = std::make_shared<ConvertOptions>();
    sub->add_option("INPUT", options->input, "Recording to read")->required();
    sub->add_option("OUTPUT", options->output,
                    "What to write: a .mkv file, or a folder for TUM / PCL TIFF")
        ->required();
    sub->add_option("--to", options->to,
                    "Output format (default: mkv for *.mkv, else tum); ply and pcd write one "
                    "organized point cloud per depth frame into the OUTPUT folder")
        ->check(CLI::IsMember({"mkv", "tum", "pcl-tiff", "ply", "pcd"}));
    sub->add_option("--intrinsics", options->intrinsics,
                    "With --to ply|pcd: the depth camera's pinhole intrinsics fx,fy,cx,cy in "
                    "pixels (default: what the recording carries; an error when it has none)");
    sub->add_option("--pcd-data", options->pcd_data,
                    "With --to pcd: DATA ascii or binary (default binary)")
        ->check(CLI::IsMember({"ascii", "binary"}));
    sub->add_flag("--no-color", options->no_color,
                  "With --to ply|pcd: points without colour even when the depth is registered "
                  "to a colour stream");
    sub->add_flag("--force", options->force, "Overwrite an existing output file");
    commands.push_back({sub, [options] { return runConvert(*options); }});
}

}  // namespace mixray::cli
