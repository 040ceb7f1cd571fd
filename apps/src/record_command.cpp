// mixray record: opens a rig's devices and records their streams into one Matroska file.
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <optional>
#include <thread>

#include "backends.h"
#include "cli.h"
#include "console.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/ptp.h"
#include "mixray/graph/recorder.h"
#include "mixray/graph/rig.h"
#include "mixray/graph/synchronizer.h"

namespace mixray::cli {
namespace {

struct RecordOptions {
    std::string rig_path;
    std::string output;
    double duration_s = 0;
    std::string policy;  // live | lossless; empty: from the rig
    size_t queue = 32;
    MkvCompression compression = MkvCompression::kFfv1;
    bool force = false;
    std::string ptp4l = PtpQueryOptions{}.socket;
};

// The rig file itself and every calibration file it names travel inside the recording.
Result<std::vector<Attachment>> attachmentsOf(const RigDescription& rig) {
    std::vector<Attachment> out;
    out.push_back({"rig.yaml", "application/x-yaml",
                   std::vector<uint8_t>(rig.source_text.begin(), rig.source_text.end())});
    for (const auto& calibration : rig.calibration) {
        std::ifstream in(calibration.resolved, std::ios::binary);
        if (!in) {
            return {ErrorCode::kNotFound, calibration.where.toString() + ": calibration file " +
                                              calibration.resolved.string() + " cannot be read"};
        }
        Attachment a;
        a.name = calibration.resolved.filename().string();
        a.mime_type =
            calibration.resolved.extension() == ".json" ? "application/json" : "application/x-yaml";
        a.data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
        if (a.data.empty()) {
            return {ErrorCode::kCorruptData, calibration.where.toString() + ": calibration file " +
                                                 calibration.resolved.string() + " is empty"};
        }
        for (const auto& existing : out) {
            if (existing.name == a.name) {
                return {ErrorCode::kInvalidArgument,
                        calibration.where.toString() + ": two attachments would be named " +
                            a.name + "; give calibration files distinct names"};
            }
        }
        out.push_back(std::move(a));
    }
    return out;
}

QueuePolicy policyOf(const RecordOptions& options, const RigDescription& rig) {
    if (options.policy == "live")
        return QueuePolicy::kLive;
    if (options.policy == "lossless")
        return QueuePolicy::kLossless;
    // The rig's choice: lossless unless every stream it configures asks for live.
    bool any = false;
    for (const auto& device : rig.devices) {
        for (const auto& stream : device.streams) {
            if (stream.queue == QueuePolicy::kLossless)
                return QueuePolicy::kLossless;
            any = true;
        }
    }
    return any ? QueuePolicy::kLive : QueuePolicy::kLossless;
}

// Why the recording loop stopped, said with the summary.
enum class StopReason { kDuration, kStreamsEnded, kInterrupted, kRecorderError };

std::string stopMessage(StopReason reason, int64_t elapsed_ns, double duration_s,
                        const std::string& signal) {
    char text[160];
    switch (reason) {
        case StopReason::kDuration:
            std::snprintf(text, sizeof text, "stopped after --duration %g s", duration_s);
            return text;
        case StopReason::kStreamsEnded:
            if (duration_s > 0) {
                std::snprintf(text, sizeof text,
                              "the rig's streams ended after %.1f s, before --duration %g s",
                              static_cast<double>(elapsed_ns) / 1e9, duration_s);
            } else {
                std::snprintf(text, sizeof text, "the rig's streams ended after %.1f s",
                              static_cast<double>(elapsed_ns) / 1e9);
            }
            return text;
        case StopReason::kInterrupted:
            std::snprintf(text, sizeof text, "stopped by %s after %.1f s", signal.c_str(),
                          static_cast<double>(elapsed_ns) / 1e9);
            return text;
        case StopReason::kRecorderError:
            return "stopped by a recording error";
    }
    return {};
}

int runRecord(const RecordOptions& options) {
    setFfmpegLogging(false);
    // Installed before the devices open: a signal during a slow open (OpenNI2, a GigE camera)
    // then stops the recording as soon as it started, with a valid file, instead of killing
    // the process with nothing written.
    InterruptFlag interrupt;
    if (std::filesystem::exists(options.output) && !options.force) {
        return fail("record", {ErrorCode::kInvalidArgument,
                               options.output + " exists (use --force to overwrite it)"});
    }
    auto rig = loadRig(options.rig_path);
    if (!rig)
        return fail("record", rig.status());
    auto attachments = attachmentsOf(*rig);
    if (!attachments)
        return fail("record", attachments.status());

    BackendRegistry registry = makeBackendRegistry();
    Graph graph;
    std::vector<const Device*> devices;  // owned by the graph
    for (const auto& config : rig->deviceConfigs()) {
        auto device = registry.open(config);
        if (!device)
            return fail("record", device.status());
        devices.push_back(device->get());
        Status added = graph.addNode(std::move(*device));
        if (!added)
            return fail("record", added);
    }
    if (graph.streamCount() == 0) {
        return fail("record", {ErrorCode::kInvalidArgument, "the rig's devices have no streams"});
    }

    // Watch queues (capacity 1, live) tell when a stream ended and how many frames it made.
    std::vector<std::shared_ptr<FrameQueue>> watches;
    for (StreamId id = 0; id < graph.streamCount(); ++id) {
        auto queue = graph.subscribe(id, {.capacity = 1,
                                          .policy = QueuePolicy::kLive,
                                          .name = "record-watch",
                                          .newest_only = true});
        if (!queue)
            return fail("record", queue.status());
        watches.push_back(*queue);
    }

    SyncNode* sync = nullptr;
    if (!rig->sync.streams.empty()) {
        SyncNodeOptions sync_options;
        sync_options.name = "record-sync";
        for (const auto& ref : rig->sync.streams)
            sync_options.streams.push_back(ref.name());
        sync_options.queue = {8, QueuePolicy::kLive, "record-sync"};
        sync_options.sync.max_skew_ns = static_cast<int64_t>(rig->sync.max_skew_ms * 1e6);
        auto node = std::make_unique<SyncNode>(sync_options, [](const SyncSet&) {});
        sync = node.get();
        Status added = graph.addNode(std::move(node));
        if (!added)
            return fail("record", added);
    }

    RecorderOptions recorder_options;
    recorder_options.path = options.output;
    recorder_options.policy = policyOf(options, *rig);
    recorder_options.queue_capacity = options.queue;
    recorder_options.writer.compression = options.compression;
    recorder_options.attachments = std::move(*attachments);
    recorder_options.tags["rig"] = rig->name;
    recorder_options.tags["software"] = "mixray 0.1.0";
    // Host stamps are the monotonic clock; this maps them to UTC (the sun's position needs it).
    recorder_options.tags[std::string(kUtcMinusHostTag)] =
        std::to_string(realtimeMinusMonotonicNs());
    // Whether this host's wall clock is PTP-locked, so that recordings made on several hosts
    // can be told to share one time base (or not).
    const Result<PtpState> ptp =
        queryPtp4l({.socket = options.ptp4l, .pmc = "pmc", .timeout_ms = 2000});
    const std::string host_clock =
        ptp ? ptp->describe() : "not PTP-locked: " + ptp.status().message();
    recorder_options.tags[std::string(kHostPtpTag)] = host_clock;
    auto recorder_node = std::make_unique<Recorder>(recorder_options);
    Recorder* recorder = recorder_node.get();
    Status added = graph.addNode(std::move(recorder_node));
    if (!added)
        return fail("record", added);

    StatusLine status;
    Status started = graph.start();
    if (!started)
        return fail("record", started);
    const int64_t t0 = monotonicNowNs();
    std::vector<uint64_t> last_published(graph.streamCount(), 0);
    int64_t last_tick = t0;
    std::string line;
    StopReason reason = StopReason::kInterrupted;
    int64_t stopped_at = t0;
    for (;;) {
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
        for (auto& watch : watches) {
            while (watch->tryPop()) {
            }
        }
        const int64_t now = monotonicNowNs();
        const bool all_ended =
            std::all_of(watches.begin(), watches.end(), [](const auto& w) { return w->closed(); });
        const bool timed_out = options.duration_s > 0 && now - t0 >= options.duration_s * 1e9;
        const RecorderStats stats = recorder->stats();
        if (now - last_tick >= 500'000'000 || all_ended || timed_out) {
            const double dt = static_cast<double>(now - last_tick) / 1e9;
            line = formatDuration(now - t0);
            for (StreamId id = 0; id < graph.streamCount(); ++id) {
                const uint64_t published = graph.publishedCount(id);
                char text[160];
                // Frames the recorder dropped and frames the source never delivered.
                const uint64_t dropped =
                    (id < stats.streams.size() ? stats.streams[id].dropped : 0) +
                    graph.lostCount(id);
                std::snprintf(text, sizeof text, " | %s %.1f fps, %llu dropped",
                              graph.stream(id).name.c_str(),
                              static_cast<double>(published - last_published[id]) / dt,
                              static_cast<unsigned long long>(dropped));
                line += text;
                last_published[id] = published;
            }
            if (sync) {
                const SyncStats s = sync->stats();
                char text[96];
                std::snprintf(text, sizeof text, " | sync %llu sets, skew mean %.2f max %.2f ms",
                              static_cast<unsigned long long>(s.sets_emitted), s.skew_mean_ns / 1e6,
                              static_cast<double>(s.skew_max_ns) / 1e6);
                line += text;
            }
            line += " | " + formatBytes(stats.bytes_written);
            status.update(line);
            last_tick = now;
        }
        stopped_at = now;
        if (!stats.error.isOk()) {
            reason = StopReason::kRecorderError;
            break;
        }
        if (interrupt.raised()) {
            reason = StopReason::kInterrupted;
            break;
        }
        if (all_ended) {
            reason = StopReason::kStreamsEnded;
            break;
        }
        if (timed_out) {
            reason = StopReason::kDuration;
            break;
        }
    }
    graph.stop();
    status.finish();

    const RecorderStats stats = recorder->stats();
    std::printf("%s: %s\n", options.output.c_str(), stats.summary().c_str());
    std::printf(
        "  %s\n",
        stopMessage(reason, stopped_at - t0, options.duration_s, interrupt.signalName()).c_str());
    for (const auto& s : stats.streams) {
        // Frames the device never delivered never reached the recorder: said beside its drops.
        const std::optional<StreamId> id = graph.findStream(s.stream);
        const uint64_t lost = id ? graph.lostCount(*id) : 0;
        std::printf("  %-24s %8llu written  %6llu dropped", s.stream.c_str(),
                    static_cast<unsigned long long>(s.written),
                    static_cast<unsigned long long>(s.dropped));
        if (lost)
            std::printf("  %6llu lost by the device", static_cast<unsigned long long>(lost));
        std::printf("\n");
    }
    std::printf("  host clock: %s\n", host_clock.c_str());
    // Devices on other hosts: how their clocks were tied to this one.
    for (const Device* device : devices)
        if (const std::string report = device->clockReport(); !report.empty())
            std::printf("  %s: %s\n", device->name().c_str(), report.c_str());
    if (!stats.error.isOk()) {
        return fail("record", stats.error.withContext(options.output + " (readable up to frame " +
                                                      std::to_string(stats.frames_written) + ")"));
    }
    return interrupt.raised() ? interrupt.exitCode() : kExitOk;
}

}  // namespace

void registerRecordCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "record",
        "Open the devices of a rig file and record their streams losslessly into one .mkv, "
        "with the rig and its calibration files attached. Stops after --duration, when every "
        "stream has ended, or on Ctrl-C; the file is valid in every case.");
    auto options = std::make_shared<RecordOptions>();
    sub->add_option("RIG", options->rig_path, "Rig description (YAML, see docs/rig-format.md)")
        ->required();
    sub->add_option("-o,--output", options->output, "Recording to write (.mkv)")->required();
    sub->add_option("--duration", options->duration_s,
                    "Stop after this many seconds (a finite number > 0; default: until every "
                    "stream ends or Ctrl-C)")
        ->check(CLI::Validator(
            [](std::string& text) -> std::string {
                double value = 0;
                const char* end = text.data() + text.size();
                const auto [ptr, ec] = std::from_chars(text.data(), end, value);
                if (ec != std::errc() || ptr != end)
                    return "expected seconds such as 10 or 2.5, got '" + text + "'";
                if (!std::isfinite(value) || value <= 0)
                    return "must be a finite number of seconds > 0, got '" + text + "'";
                return {};
            },
            "SECONDS > 0"));
    sub->add_option("--policy", options->policy,
                    "live: drivers never wait for the disk, drops are counted; lossless: drivers "
                    "wait (default: the rig's stream settings)")
        ->check(CLI::IsMember({"live", "lossless"}));
    sub->add_option("--queue", options->queue, "Frames queued per stream")
        ->check(CLI::Range(1, 4096))
        ->capture_default_str();
    addCompressionOption(*sub, options->compression,
                         "a fast stream on a fast disk may "
                         "outrun FFV1; none keeps up as long as the disk does");
    sub->add_flag("--force", options->force, "Overwrite an existing output file");
    sub->add_option("--ptp4l", options->ptp4l,
                    "ptp4l's management socket (its uds_address), asked through linuxptp's pmc "
                    "whether this host's clock is PTP-locked; the answer is printed and kept in "
                    "the recording's host_ptp tag")
        ->capture_default_str();
    commands.push_back({sub, [options] { return runRecord(*options); }});
}

}  // namespace mixray::cli
