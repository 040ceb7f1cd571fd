// The mixray command line: one binary, one subcommand per job.
#include <CLI/CLI.hpp>

int main(int argc, char** argv) {
    CLI::App app{"mixray: photoreal augmented reality from a rig of real cameras"};
    app.require_subcommand(1);
    CLI11_PARSE(app, argc, argv);
    return 0;
}
