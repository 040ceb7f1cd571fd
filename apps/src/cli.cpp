// Exit-code mapping and error printing shared by all subcommands.
#include "cli.h"

#include <cstdio>
#include <map>

#include "mixray/liveview/live_view.h"

namespace mixray::cli {

std::string exitCodesHelp() {
    return "Exit codes: 0 done (warnings, such as an object never drawn, are printed); 1 internal "
           "error; 2 bad command line; 3 input refused (missing, malformed, cut off), nothing "
           "made; 4 device or resource unavailable; 5 input cut off or damaged, the output made "
           "from what was readable (the message names the damage); 130 stopped by SIGINT, 143 "
           "by SIGTERM (the output closed with what was done).";
}

int exitCodeFor(const Status& status) {
    switch (status.code()) {
        case ErrorCode::kOk:
            return kExitOk;
        case ErrorCode::kInvalidArgument:
            return kExitUsage;
        case ErrorCode::kNotFound:
        case ErrorCode::kCorruptData:
        case ErrorCode::kIoError:
        case ErrorCode::kUnsupported:
            return kExitBadInput;
        case ErrorCode::kUnavailable:
            return kExitUnavailable;
        case ErrorCode::kCancelled:
            return kExitInterrupted;
        case ErrorCode::kEndOfStream:
        case ErrorCode::kInternal:
            return kExitInternal;
    }
    return kExitInternal;
}

int fail(const std::string& command, const Status& status) {
    std::fprintf(stderr, "mixray %s: %s\n", command.c_str(), status.toString().c_str());
    return exitCodeFor(status);
}

CLI::Option* addCameraEnvironmentOption(CLI::App& command, int& width) {
    return command
        .add_option("--camera-environment", width,
                    "Without a fish-eye camera: width of the environment map built from the "
                    "colour camera's own tracked frames, which metal and glass reflect and which "
                    "lights the virtual objects (0: none; even, 16 to 8192)")
        ->check(CLI::Range(0, 8192))
        ->capture_default_str();
}

CLI::Option* addCompressionOption(CLI::App& command, MkvCompression& compression,
                                  const std::string& what_for) {
    std::map<std::string, MkvCompression> names;
    for (MkvCompression c :
         {MkvCompression::kFfv1, MkvCompression::kHuffyuv, MkvCompression::kNone})
        names[toString(c)] = c;
    return command
        .add_option("--compression", compression,
                    "How images are stored, all lossless: ffv1, files 8-40x smaller than raw for "
                    "10-15 ms of CPU a VGA frame; ffvhuff (Huffyuv), about 4x smaller for 2 ms; "
                    "none, uncompressed, bound by the disk (" +
                        what_for + ")")
        // The enum's values are bytes: the help and the error name the choices, not the map.
        ->transform(CLI::CheckedTransformer(names).description(""))
        ->transform(CLI::IsMember({"ffv1", "ffvhuff", "none"}).description(""))  // runs first
        ->type_name("ffv1|ffvhuff|none")
        ->default_str(toString(compression));
}

CLI::Option* addViewTokenOption(CLI::App& command, std::string& token) {
    return command.add_option(
        "--view-token", token,
        "The secret the live view requires in its URL (?token=...): 16..256 characters of "
        "A-Z a-z 0-9 - . _ ~. Default: none on loopback, a random one for any other address");
}

void printLiveViewUrls(const liveview::LiveView& view, const char* prefix) {
    if (const std::string warning = view.exposureWarning(); !warning.empty())
        std::fprintf(stderr, "%s\n", warning.c_str());
    for (const std::string& url : view.urls())
        std::printf("%s%s\n", prefix, url.c_str());
}

}  // namespace mixray::cli
