// The mixray command line: one binary, one subcommand per job.
#include <CLI/CLI.hpp>

#include "backends.h"
#include "cli.h"

int main(int argc, char** argv) {
    using namespace mixray::cli;
    CLI::App app{
        "mixray: photoreal augmented reality from a rig of real cameras.\n"
        "Run 'mixray <command> --help' for the options of one command."};
    app.set_version_flag("--version", "mixray 0.1.0");
    app.require_subcommand(1, 1);
    app.footer(exitCodesHelp());

    registerRecordingFormats();
    Commands commands;
    registerDevicesCommand(app, commands);
    registerInfoCommand(app, commands);
    registerRecordCommand(app, commands);
    registerPlayCommand(app, commands);
    registerPublishCommand(app, commands);
    registerConvertCommand(app, commands);
    registerRenderCommand(app, commands);
    registerRunCommand(app, commands);
    registerCalibrateCommand(app, commands);
    registerDetectCommand(app, commands);
    registerTrackCommand(app, commands);
    registerSimulateCommand(app, commands);
    registerDemoCommand(app, commands);
    registerBenchCommand(app, commands);

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        const int rc = app.exit(e);  // prints help, or the usage error
        return rc == 0 ? kExitOk : kExitUsage;
    }
    for (const auto& command : commands) {
        if (command.app->parsed())
            return command.run();
    }
    return kExitUsage;
}
