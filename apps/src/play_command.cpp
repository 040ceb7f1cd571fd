// mixray play: replays a recording through the device graph and reports per-stream rates.
#include <atomic>
#include <cstdio>
#include <thread>

#include "cli.h"
#include "console.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/mkv.h"
#include "mixray/replay/replay_backend.h"

namespace mixray::cli {
namespace {

struct PlayOptions {
    std::string path;
    bool fast = false;
    double speed = 1.0;
    bool loop = false;
    double start_s = 0;
    double duration_s = 0;
};

// Counts what one stream delivers, on its own thread, as a consumer would.
struct StreamCounter {
    std::string name;
    std::shared_ptr<FrameQueue> queue;
    std::atomic<uint64_t> frames{0};
    std::atomic<int64_t> first_ns{0};
    std::atomic<int64_t> last_ns{0};
    std::thread thread;
};

int runPlay(const PlayOptions& options) {
    setFfmpegLogging(false);
    DeviceConfig config;
    config.name = "replay";
    config.driver = "replay";
    config.id = options.path;
    config.options["pace"] = options.fast ? "fast" : "original";
    if (!options.fast)
        config.options["speed"] = std::to_string(options.speed);
    config.options["loop"] = options.loop ? "true" : "false";
    config.options["start"] = std::to_string(options.start_s);

    replay::ReplayBackend backend;
    auto device = backend.open(config);
    if (!device)
        return fail("play", device.status());
    auto* replay_device = static_cast<replay::ReplayDevice*>(device->get());

    Graph graph;
    Status added = graph.addNode(std::move(*device));
    if (!added)
        return fail("play", added);

    std::vector<std::unique_ptr<StreamCounter>> counters;
    for (StreamId id = 0; id < graph.streamCount(); ++id) {
        auto counter = std::make_unique<StreamCounter>();
        counter->name = graph.stream(id).name;
        auto queue = graph.subscribe(id, {4, QueuePolicy::kLive, "play"});
        if (!queue)
            return fail("play", queue.status());
        counter->queue = *queue;
        counters.push_back(std::move(counter));
    }
    for (auto& c : counters) {
        c->thread = std::thread([c = c.get()] {
            for (;;) {
                auto frame = c->queue->pop(std::chrono::milliseconds(200));
                if (!frame) {
                    if (c->queue->closed())
                        break;  // a timeout only means a pause
                    continue;
                }
                const int64_t now = monotonicNowNs();
                if (c->frames == 0)
                    c->first_ns = now;
                c->last_ns = now;
                ++c->frames;
            }
        });
    }

    InterruptFlag interrupt;
    StatusLine status;
    const int64_t started = monotonicNowNs();
    Status start_status = graph.start();
    if (start_status.isOk()) {
        while (!replay_device->finished() && !interrupt.raised()) {
            const int64_t elapsed = monotonicNowNs() - started;
            if (options.duration_s > 0 && elapsed >= options.duration_s * 1e9)
                break;
            std::string line = formatDuration(elapsed);
            for (const auto& c : counters) {
                line += "  " + c->name + " " + std::to_string(c->frames.load());
            }
            status.update(line);
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
    }
    graph.stop();
    for (auto& c : counters) {
        if (c->thread.joinable())
            c->thread.join();
    }
    status.finish();
    if (!start_status)
        return fail("play", start_status);

    const double seconds = static_cast<double>(monotonicNowNs() - started) / 1e9;
    std::printf("played %s in %.2f s (%s pace%s)\n", options.path.c_str(), seconds,
                options.fast ? "fast" : "original", options.loop ? ", looping" : "");
    auto edges = graph.edgeStats();
    for (size_t i = 0; i < counters.size(); ++i) {
        const auto& c = counters[i];
        const double span = static_cast<double>(c->last_ns - c->first_ns) / 1e9;
        const double rate =
            c->frames > 1 && span > 0 ? static_cast<double>(c->frames - 1) / span : 0;
        std::printf("  %-24s %8llu frames  %8.2f fps  %llu dropped by the live queue\n",
                    c->name.c_str(), static_cast<unsigned long long>(c->frames.load()), rate,
                    static_cast<unsigned long long>(i < edges.size() ? edges[i].queue.dropped : 0));
    }
    // A recording cut off or damaged: the frames before the damage were played (counted
    // above), and the damage is said.
    const Status input = replay_device->inputStatus();
    if (!input)
        std::fprintf(stderr, "mixray play: input incomplete: %s\n", input.message().c_str());
    if (interrupt.raised()) {
        std::fprintf(stderr, "mixray play: stopped by %s after %.2f s\n",
                     interrupt.signalName().c_str(), seconds);
        return interrupt.exitCode();
    }
    return input ? kExitOk : kExitIncomplete;
}

}  // namespace

void registerPlayCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "play", "Replay a recording through the device graph and print per-stream rates");
    auto options = std::make_shared<PlayOptions>();
    sub->add_option("FILE", options->path,
                    "Recording: mixray or Azure Kinect .mkv, TUM RGB-D folder, PCL TIFF folder")
        ->required();
    sub->add_flag("--fast", options->fast, "As fast as possible instead of the original pacing");
    sub->add_option("--speed", options->speed, "Playback speed with original pacing")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub->add_flag("--loop", options->loop, "Start over at the end (stop with Ctrl-C)");
    sub->add_option("--start", options->start_s, "Seek to this many seconds from the start")
        ->check(CLI::NonNegativeNumber);
    sub->add_option("--duration", options->duration_s, "Stop after this many seconds")
        ->check(CLI::NonNegativeNumber);
    commands.push_back({sub, [options] { return runPlay(*options); }});
}

}  // namespace mixray::cli
