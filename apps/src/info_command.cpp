// mixray info: what a recording holds (filled in when recordings land).
#include "cli.h"

namespace mixray::cli {

void registerInfoCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand("info", "Describe a recording: streams, formats, frame counts, "
                                           "duration, timestamp gaps, attachments");
    auto file = std::make_shared<std::string>();
    sub->add_option("FILE", *file, "Recording (.mkv, TUM folder, ...)")->required();
    commands.push_back({sub, [file] {
                            return fail("info", {ErrorCode::kUnsupported,
                                                 "cannot read recordings yet: " + *file});
                        }});
}

}  // namespace mixray::cli
