// mixray convert: copies a recording between formats (mkv, TUM RGB-D folder, PCL TIFF folder).
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "cli.h"
#include "console.h"
#include "mixray/dds/mcap_export.h"
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
    std::string to;        // mkv | mcap | tum | pcl-tiff | ply | pcd; empty: from the output name
    std::string ros2_rig;  // --ros2: MCAP topics' prefix
    bool force = false;
    // Point clouds (--to ply|pcd).
    std::string intrinsics;           // "fx,fy,cx,cy"; empty: from the recording
    std::string pcd_data = "binary";  // ascii | binary
    bool no_color = false;
    bool drop_unsupported = false;
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

std::string targetFormat(const ConvertOptions& options) {
    if (!options.to.empty())
        return options.to;
    const auto extension = std::filesystem::path(options.output).extension();
    if (extension == ".mcap")
        return "mcap";
    return extension == ".mkv" ? "mkv" : "tum";
}

// What the target format would drop or change of the recording (mkv holds everything).
Result<replay::WriteLosses> lossesOf(const ConvertOptions& options, const RecordingHeader& header) {
    const std::string to = targetFormat(options);
    if (to == "tum")
        return replay::tumLosses(header);
    if (to == "pcl-tiff")
        return replay::pclTiffLosses(header);
    if (to == "mcap") {
        replay::WriteLosses losses;
        for (const auto& [stream, why] : dds::mcapUnwritableStreams(header)) {
            losses.dropped_streams.push_back(stream);
            losses.dropped.push_back(why);
        }
        losses.changed = dds::mcapChangedData(header);
        return losses;
    }
    if (to == "ply" || to == "pcd") {
        replay::PointCloudWriterOptions cloud;
        cloud.color = !options.no_color;
        return replay::pointCloudLosses(header, cloud);
    }
    return replay::WriteLosses{};
}

Result<std::unique_ptr<RecordingWriter>> createWriter(const ConvertOptions& options,
                                                      const RecordingHeader& header) {
    const std::string to = targetFormat(options);
    if (to == "mkv")
        return createMkvWriter(options.output, header);
    if (to == "mcap")
        return dds::createMcapWriter(options.output, header, {.rig = options.ros2_rig});
    if (to == "tum")
        return replay::createTumWriter(options.output, header);
    if (to == "pcl-tiff")
        return replay::createPclTiffWriter(options.output, header);
    if (to == "ply" || to == "pcd")
        return createCloudWriter(options, header);
    return {ErrorCode::kInvalidArgument,
            "--to " + to + ": expected mkv, mcap, tum, pcl-tiff, ply or pcd"};
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
    const RecordingHeader header = replay::headerOf(**reader);
    auto losses = lossesOf(options, header);
    if (!losses)
        return fail("convert", losses.status().withContext(options.output));
    // A point cloud is depth made into points by request: what else the recording holds is
    // listed, not refused.
    const bool cloud = targetFormat(options) == "ply" || targetFormat(options) == "pcd";
    if (losses->dropsData() && !options.drop_unsupported && !cloud) {
        std::string what;
        for (const std::string& line : losses->dropped)
            what += "\n  " + line;
        return fail("convert",
                    {ErrorCode::kUnsupported, options.output + " (" + targetFormat(options) +
                                                  ") cannot hold all of " + options.input +
                                                  "; nothing was written. Not writable:" + what +
                                                  "\n(--drop-unsupported converts without them)"});
    }
    for (const std::string& line : losses->dropped)
        std::fprintf(stderr, "convert: not written: %s\n", line.c_str());
    for (const std::string& line : losses->changed)
        std::fprintf(stderr, "convert: changed: %s\n", line.c_str());
    auto writer = createWriter(options, header);
    if (!writer)
        return fail("convert", writer.status().withContext(options.output));

    InterruptFlag interrupt;
    StatusLine status;
    auto summary = replay::convertRecording(
        **reader, **writer,
        [&](const replay::ConvertProgress& p) {
            status.update("converted " + std::to_string(p.frames) + " frames, " +
                          formatBytes(p.bytes_written) + " written");
            return !interrupt.raised();
        },
        replay::InputDamage::kKeepWhatWasRead);
    status.finish();
    if (!summary && interrupt.raised()) {
        std::fprintf(stderr, "mixray convert: stopped by %s (%s); %s is closed with them\n",
                     interrupt.signalName().c_str(), summary.status().message().c_str(),
                     options.output.c_str());
        return interrupt.exitCode();
    }
    if (!summary)
        return fail("convert", summary.status());
    // Frames of dropped streams went through the converter but not into the file.
    uint64_t written = summary->frames;
    for (StreamId id : losses->dropped_streams) {
        if (id < summary->frames_per_stream.size())
            written -= summary->frames_per_stream[id];
    }
    std::printf("%s (%s) -> %s: %llu of %llu frames written, %s, %.2f s\n", options.input.c_str(),
                (*reader)->format().c_str(), options.output.c_str(),
                static_cast<unsigned long long>(written),
                static_cast<unsigned long long>(summary->frames),
                formatBytes(summary->bytes_written).c_str(), summary->seconds);
    for (size_t i = 0; i < header.streams.size() && i < summary->frames_per_stream.size(); ++i) {
        const bool dropped =
            std::find(losses->dropped_streams.begin(), losses->dropped_streams.end(),
                      static_cast<StreamId>(i)) != losses->dropped_streams.end();
        std::printf("  %-24s %8llu frames %s\n", header.streams[i].name.c_str(),
                    static_cast<unsigned long long>(summary->frames_per_stream[i]),
                    dropped ? "not written (the format cannot hold them)" : "written");
    }
    if (!summary->input)
        std::fprintf(stderr, "mixray convert: input incomplete: %s; %s is partial\n",
                     summary->input.message().c_str(), options.output.c_str());
    for (const RecordingDamage& d : summary->damage)
        std::fprintf(stderr,
                     "mixray convert: input damaged at byte %lld (%s), skipped: its frames are "
                     "not in %s\n",
                     static_cast<long long>(d.byte_offset), d.what.c_str(), options.output.c_str());
    return summary->partial() ? kExitIncomplete : kExitOk;
}

}  // namespace

void registerConvertCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "convert",
        "Convert a recording: mkv <-> TUM RGB-D folder, PCL TIFF folder or Azure Kinect .mkv -> "
        "mkv; mkv -> MCAP of ROS 2 sensor_msgs/Image messages, which ros2 bag and Foxglove "
        "open (--to mcap, docs/dds.md). Frames, timestamps, attachments and tags are kept exactly "
        "where the target "
        "format can hold them; what it cannot hold is refused (or, with --drop-unsupported, "
        "left out and listed), and what was written is printed per stream. Also reads NYU Depth "
        "V2 raw and SUN RGB-D folders and OpenNI .oni files, and writes organized point clouds "
        "(--to ply|pcd, docs/rgbd-formats.md), which hold the depth stream and its registered "
        "colour: the other streams are listed as not written.");
    auto options = std::make_shared<ConvertOptions>();
    sub->add_option("INPUT", options->input, "Recording to read")->required();
    sub->add_option("OUTPUT", options->output,
                    "What to write: a .mkv or .mcap file, or a folder for TUM / PCL TIFF")
        ->required();
    sub->add_option("--to", options->to,
                    "Output format (default: mkv for *.mkv, mcap for *.mcap, else tum); ply and "
                    "pcd write one organized point cloud per depth frame into the OUTPUT folder")
        ->check(CLI::IsMember({"mkv", "mcap", "tum", "pcl-tiff", "ply", "pcd"}));
    sub->add_option("--ros2", options->ros2_rig,
                    "With --to mcap: topics are /NAME/<stream>/image_raw (default: the rig's name "
                    "in the recording, else mixray)");
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
    sub->add_flag("--drop-unsupported", options->drop_unsupported,
                  "Convert even when the target format cannot hold every stream or attachment "
                  "(TUM and PCL TIFF keep one colour and one depth stream); what is left out is "
                  "listed. Without it such a conversion is refused before anything is written");
    commands.push_back({sub, [options] { return runConvert(*options); }});
}

}  // namespace mixray::cli
