// mixray simulate: renders a synthetic rig session with ground truth (docs/simulation.md).
#include <cstdio>
#include <filesystem>
#include <string>

#include "cli.h"
#include "console.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/mkv.h"
#include "mixray/render/simulator.h"
#include "size_option.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;

struct SimulateCommandOptions {
    std::string scenario = "tabletop";
    std::string output;  // empty: sim_<scenario>.mkv
    int frames = 0;
    uint64_t seed = 1;
    std::string size = "640x480";
    int samples = 4;
    int env_every = 0;
    int threads = 0;
    std::string depth;  // registered | raw; empty: the scenario's default
};

int runSimulate(const SimulateCommandOptions& o) {
    setFfmpegLogging(false);
    render::SimulatorOptions options;
    const auto scenario = render::simScenarioFromString(o.scenario);
    if (!scenario)
        return fail("simulate",
                    {ErrorCode::kInvalidArgument,
                     "--scenario " + o.scenario + ": expected tabletop or calibration"});
    options.scenario = *scenario;
    auto size = parseSize("--size", o.size);
    if (!size)
        return fail("simulate", size.status());
    options.width = size->first;
    options.height = size->second;
    options.frames = o.frames;
    options.seed = o.seed;
    options.samples_per_pixel = o.samples;
    options.env_every = o.env_every;
    options.threads = o.threads;
    if (!o.depth.empty())
        options.register_depth = o.depth == "registered";
    if (Status s = options.validate(); !s)
        return fail("simulate", s);
    const fs::path output =
        o.output.empty() ? fs::path("sim_" + o.scenario + ".mkv") : fs::path(o.output);
    if (output.extension() != ".mkv")
        return fail("simulate", {ErrorCode::kInvalidArgument,
                                 "-o " + output.string() + ": the recording must be a .mkv file"});

    // A signal stops the session within an image tile; the recording is closed with the frames
    // done.
    InterruptFlag interrupt;
    options.stop = interrupt.token();
    StatusLine status;
    const int64_t start = monotonicNowNs();
    auto summary = render::simulateSession(options, output, [&](int done, int total) {
        const double per_frame = static_cast<double>(monotonicNowNs() - start) * 1e-6 / done;
        char line[128];
        std::snprintf(line, sizeof line, "frame %d/%d: %.0f ms per frame", done, total, per_frame);
        status.update(line);
    });
    status.finish();
    if (!summary)
        return fail("simulate", summary.status());
    if (summary->recording_written)
        std::printf("%s: %d frames (%d environment frames) in %.1f s, %.0f ms per frame\n",
                    output.string().c_str(), summary->frames, summary->env_frames, summary->seconds,
                    summary->frames ? summary->seconds * 1e3 / summary->frames : 0.0);
    for (size_t i = 0; i < summary->files.size(); ++i) {
        std::error_code ec;
        const auto bytes = fs::file_size(summary->files[i], ec);
        std::printf("  %s  %s\n", summary->files[i].string().c_str(),
                    ec ? "?" : formatBytes(bytes).c_str());
    }
    if (summary->stopped && !summary->recording_written) {
        std::fprintf(stderr,
                     "mixray simulate: stopped by %s before the first of %d frames; no recording "
                     "written (%s would hold no frame)\n",
                     interrupt.signalName().c_str(), summary->frames_planned,
                     output.string().c_str());
        return interrupt.exitCode();
    }
    if (summary->stopped) {
        std::fprintf(stderr,
                     "mixray simulate: stopped by %s after %d of %d frames; %s holds %d frame%s "
                     "(the truth files describe all %d)\n",
                     interrupt.signalName().c_str(), summary->frames, summary->frames_planned,
                     output.string().c_str(), summary->frames, summary->frames == 1 ? "" : "s",
                     summary->frames_planned);
        return interrupt.exitCode();
    }
    return kExitOk;
}

}  // namespace

void registerSimulateCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "simulate",
        "Render a synthetic rig session with ground truth: Kinect-like colour and depth, a "
        "fish-eye environment camera and a ground-truth pose stream, written as an ordinary "
        "recording plus NAME.truth.yaml, NAME.tum and NAME.scene.yaml beside it "
        "(docs/simulation.md)");
    sub->footer(signalHelp("the recording"));
    auto o = std::make_shared<SimulateCommandOptions>();
    sub->add_option("--scenario", o->scenario,
                    "tabletop (marker, light probes, boxes, moving camera) or calibration "
                    "(ChArUco board views)")
        ->check(CLI::IsMember({"tabletop", "calibration"}))
        ->capture_default_str();
    sub->add_option("-o,--output", o->output,
                    "Recording to write (.mkv); default sim_SCENARIO.mkv");
    sub->add_option("--frames", o->frames,
                    "Colour frames / board views (0: 45 for tabletop, 20 for calibration)")
        ->check(CLI::Range(0, 100000))
        ->capture_default_str();
    sub->add_option("--seed", o->seed, "Seed of depth noise, board poses and sampling")
        ->capture_default_str();
    sub->add_option("--size", o->size, "Kinect colour/depth size WIDTHxHEIGHT (intrinsics scale)")
        ->capture_default_str();
    sub->add_option("--samples", o->samples, "Antialiasing samples per pixel (a square number)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    sub->add_option("--env-every", o->env_every,
                    "An environment-camera frame every N colour frames (0: 15 tabletop, 1 "
                    "calibration)")
        ->check(CLI::Range(0, 100000))
        ->capture_default_str();
    sub->add_option("--depth", o->depth,
                    "kinect/depth registered to colour, or raw (aligned with the IR camera, as a "
                    "Kinect records with registration off); default: registered for tabletop, raw "
                    "for calibration")
        ->check(CLI::IsMember({"registered", "raw"}));
    sub->add_option("--threads", o->threads, "Render threads (0: all cores)")
        ->check(CLI::Range(0, 1024));
    commands.push_back({sub, [o] { return runSimulate(*o); }});
}

}  // namespace mixray::cli
