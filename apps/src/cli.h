// Shared plumbing of the mixray subcommands: registration, exit codes, error printing.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

#include "mixray/graph/mkv.h"
#include "mixray/graph/result.h"

namespace mixray::liveview {
class LiveView;
}

namespace mixray::cli {

// Exit codes, stable for scripts: what went wrong, not where. exitCodesHelp() and
// docs/architecture.md ("Errors and threads") say them to users.
enum ExitCode : int {
    kExitOk = 0,
    kExitInternal = 1,     // a bug or a library failure
    kExitUsage = 2,        // bad command line (CLI11 uses it too)
    kExitBadInput = 3,     // input refused: missing, malformed, truncated; no output made
    kExitUnavailable = 4,  // a device or resource is not there now
    // The input was cut off or damaged and the output was made from what was readable
    // (run, render, track, demo, play, convert): distinct from 3, so a script knows there is
    // an output, and that it is partial.
    kExitIncomplete = 5,
    kExitInterrupted = 130,  // SIGINT (Ctrl-C): 128 + 2, as shells report it
    kExitTerminated = 143,   // SIGTERM: 128 + 15 (InterruptFlag::exitCode() picks)
};

// The exit codes in words, for the help's footer.
std::string exitCodesHelp();

int exitCodeFor(const Status& status);

// Prints "mixray <command>: <status>" to stderr and returns the matching exit code.
int fail(const std::string& command, const Status& status);

// --camera-environment WIDTH of the commands that composite (run, demo): without a fish-eye,
// the environment map built from the colour camera's own tracked frames
// (tracking::PipelineOptions::camera_environment); 0: none.
inline constexpr int kDefaultCameraEnvironmentWidth = 128;
CLI::Option* addCameraEnvironmentOption(CLI::App& command, int& width);

// --compression of the commands that record (record, run): how images are stored
// (mixray/graph/mkv.h). `what_for` ends the help text: why this command's default is what it is.
CLI::Option* addCompressionOption(CLI::App& command, MkvCompression& compression,
                                  const std::string& what_for);
// --view-token TOKEN of the commands with --view (liveview::LiveViewOptions::token).
CLI::Option* addViewTokenOption(CLI::App& command, std::string& token);
// Once the view listens: its warning on stderr (not on loopback), each URL on stdout after
// `prefix` ("live view: ").
void printLiveViewUrls(const liveview::LiveView& view, const char* prefix);

// A subcommand and what to run when it was chosen.
struct Command {
    CLI::App* app = nullptr;
    std::function<int()> run;
};
using Commands = std::vector<Command>;

// One per subcommand, each in its own <name>_command.cpp.
void registerBenchCommand(CLI::App& app, Commands& commands);
void registerCalibrateCommand(CLI::App& app, Commands& commands);
void registerConvertCommand(CLI::App& app, Commands& commands);
void registerDemoCommand(CLI::App& app, Commands& commands);
void registerDetectCommand(CLI::App& app, Commands& commands);
void registerDevicesCommand(CLI::App& app, Commands& commands);
void registerInfoCommand(CLI::App& app, Commands& commands);
void registerPlayCommand(CLI::App& app, Commands& commands);
void registerPublishCommand(CLI::App& app, Commands& commands);
void registerTrackCommand(CLI::App& app, Commands& commands);
void registerRecordCommand(CLI::App& app, Commands& commands);
void registerRenderCommand(CLI::App& app, Commands& commands);
void registerRunCommand(CLI::App& app, Commands& commands);
void registerSimulateCommand(CLI::App& app, Commands& commands);

}  // namespace mixray::cli
