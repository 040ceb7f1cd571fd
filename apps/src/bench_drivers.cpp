// mixray bench drivers: frames/s and CPU time per frame of each backend that can run here,
// through mixray's device and graph against the peer's own API on the same source in the same
// run (the Matroska reader, OpenNI2's VideoStream, an ArvStream pop loop).
#include "bench_drivers.h"

#include <OpenNI.h>
#include <arv.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <thread>

#include "console.h"
#include "mixray/aravis/aravis_backend.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/host_time.h"
#include "mixray/openni2/openni2_backend.h"
#include "mixray/pattern/pattern_backend.h"
#include "mixray/replay/open_recording.h"
#include "mixray/replay/replay_backend.h"
#include "mixray/v4l2/v4l2_backend.h"
#include "test_data_paths.h"

extern char** environ;

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kGvSimulator = "/usr/bin/arv-fake-gv-camera-0.8";

struct BenchDriversOptions {
    uint64_t frames = 600;    // frames per run from files
    double duration_s = 2.0;  // seconds per run from live sources
    std::string backends = "pattern,replay,openni2,aravis,v4l2";
    std::string recording;  // default: fixtures/sessions/pattern_rgbd.mkv
    std::string shared_data;
};

// Frames delivered, wall time and the whole process's CPU time (every thread) of one run.
struct Run {
    uint64_t frames = 0;
    double wall_s = 0;
    double cpu_s = 0;
    double fps() const { return wall_s > 0 ? static_cast<double>(frames) / wall_s : 0; }
    double cpuMsPerFrame() const {
        return frames > 0 ? cpu_s * 1e3 / static_cast<double>(frames) : 0;
    }
};

class Meter {
public:
    Meter() : wall_(monotonicNowNs()), cpu_(processCpuNs()) {}
    double wallS() const { return static_cast<double>(monotonicNowNs() - wall_) / 1e9; }
    Run stop(uint64_t frames) const {
        return {frames, wallS(), static_cast<double>(processCpuNs() - cpu_) / 1e9};
    }

private:
    int64_t wall_;
    int64_t cpu_;
};

// One line of the table.
struct Row {
    std::string backend;
    std::string source;
    std::string peer;  // what the peer run used; empty: no peer
    std::optional<Run> mixray;
    std::optional<Run> peer_run;
    std::string note;     // why a run is missing
    bool failed = false;  // a run that could run returned an error (the note says which)
};

// Runs `config` through a graph: every stream subscribed (lossless for files, so every frame
// counts; live for cameras), one consumer thread per stream releasing each frame at once. Ends
// after `frames` frames or `duration_s` seconds.
Result<Run> runDevice(DeviceBackend& backend, const DeviceConfig& config, bool lossless,
                      uint64_t frames, double duration_s) {
    auto device = backend.open(config);
    if (!device)
        return device.status();
    Graph graph;
    MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(*device)));
    std::vector<std::shared_ptr<FrameQueue>> queues;
    for (StreamId id = 0; id < graph.streamCount(); ++id) {
        auto q = graph.subscribe(
            id, {8, lossless ? QueuePolicy::kLossless : QueuePolicy::kLive, "bench-drivers"});
        if (!q)
            return q.status();
        queues.push_back(*q);
    }
    std::atomic<uint64_t> count{0};
    std::atomic<bool> done{false};
    // The measuring thread sleeps until the last frame or the deadline: polling would add its
    // own wake-ups to the CPU time per frame.
    std::mutex mutex;
    std::condition_variable wake;
    size_t running = queues.size();
    std::vector<std::thread> consumers;
    const Meter meter;
    MIXRAY_RETURN_IF_ERROR(graph.start());
    for (const auto& queue : queues) {
        consumers.emplace_back([&, queue] {
            while (!done.load(std::memory_order_relaxed)) {
                auto frame = queue->pop(std::chrono::milliseconds(20));
                if (!frame) {
                    if (queue->closed())
                        break;
                    continue;
                }
                if (count.fetch_add(1, std::memory_order_relaxed) + 1 >= frames) {
                    std::lock_guard lock(mutex);
                    done = true;
                    wake.notify_all();
                }
            }
            std::lock_guard lock(mutex);
            --running;
            wake.notify_all();
        });
    }
    bool ended = false;
    {
        std::unique_lock lock(mutex);
        wake.wait_for(lock, std::chrono::duration<double>(duration_s),
                      [&] { return done.load() || running == 0; });
        ended = running == 0 && !done.load();
    }
    const Run run = meter.stop(count.load());
    done = true;
    graph.stop();
    for (auto& c : consumers)
        c.join();
    if (ended) {
        return Status(ErrorCode::kUnavailable, "the device ended its streams after " +
                                                   std::to_string(run.frames) + " frames");
    }
    return run;
}

// The Matroska reader itself, looping over the file as the replay device does.
Result<Run> runReader(const fs::path& path, uint64_t frames) {
    auto reader = replay::openRecording(path);
    if (!reader)
        return reader.status();
    const Meter meter;
    uint64_t count = 0;
    int64_t first_stamp = 0;
    bool have_first = false;
    while (count < frames) {
        auto frame = (*reader)->next();
        if (!frame) {
            if (frame.status().code() != ErrorCode::kEndOfStream || !have_first)
                return frame.status();
            MIXRAY_RETURN_IF_ERROR((*reader)->seek(first_stamp));
            continue;
        }
        if (!have_first) {
            first_stamp = frame->meta().host_stamp_ns;
            have_first = true;
        }
        ++count;
    }
    return meter.stop(count);
}

// OpenNI2's own API on the recording: manual playback (every frame, as fast as read), repeat
// on, readFrame on whichever stream is ready — what the backend does, without the graph.
Result<Run> runOpenNI2(const fs::path& path, uint64_t frames) {
    // The backend initialised OpenNI2 for the process; this adds a reference and keeps it.
    if (openni::OpenNI::initialize() != openni::STATUS_OK)
        return Status(ErrorCode::kUnavailable, "OpenNI2 did not initialise");
    openni::Device device;
    if (device.open(path.c_str()) != openni::STATUS_OK) {
        return Status(ErrorCode::kNotFound, "OpenNI2 cannot open " + path.string() + ": " +
                                                openni::OpenNI::getExtendedError());
    }
    openni::PlaybackControl* playback = device.getPlaybackControl();
    if (!playback)
        return Status(ErrorCode::kUnsupported, path.string() + " is no recording");
    playback->setSpeed(-1);
    playback->setRepeatEnabled(true);
    openni::VideoStream depth;
    openni::VideoStream color;
    std::vector<openni::VideoStream*> streams;
    if (depth.create(device, openni::SENSOR_DEPTH) == openni::STATUS_OK)
        streams.push_back(&depth);
    if (color.create(device, openni::SENSOR_COLOR) == openni::STATUS_OK)
        streams.push_back(&color);
    const Meter meter;
    for (auto* s : streams)
        s->start();
    uint64_t count = 0;
    openni::VideoFrameRef frame;
    while (count < frames) {
        int index = -1;
        if (openni::OpenNI::waitForAnyStream(streams.data(), static_cast<int>(streams.size()),
                                             &index, 2000) != openni::STATUS_OK)
            break;
        if (streams[static_cast<size_t>(index)]->readFrame(&frame) == openni::STATUS_OK)
            ++count;
    }
    const Run run = meter.stop(count);
    frame.release();
    for (auto* s : streams) {
        s->stop();
        s->destroy();
    }
    device.close();
    if (count < frames)
        return Status(ErrorCode::kUnavailable, "OpenNI2 stopped delivering frames");
    return run;
}

// An ArvStream pop loop with Aravis's own buffers, set up like the backend's device.
Result<Run> runAravis(const std::string& id, int width, int height, double fps, size_t buffers,
                      double duration_s) {
    GError* error = nullptr;
    ArvCamera* camera = arv_camera_new(id.c_str(), &error);
    if (!camera) {
        std::string why = error ? error->message : "unknown";
        g_clear_error(&error);
        return Status(ErrorCode::kNotFound, "Aravis camera '" + id + "': " + why);
    }
    arv_camera_set_pixel_format_from_string(camera, "Mono8", &error);
    if (!error)
        arv_camera_set_region(camera, 0, 0, width, height, &error);
    if (!error)
        arv_camera_set_frame_rate(camera, fps, &error);
    ArvStream* stream =
        error ? nullptr : arv_camera_create_stream(camera, nullptr, nullptr, &error);
    if (!stream) {
        std::string why = error ? error->message : "unknown";
        g_clear_error(&error);
        g_object_unref(camera);
        return Status(ErrorCode::kUnavailable, "Aravis camera '" + id + "': " + why);
    }
    if (ARV_IS_GV_STREAM(stream))
        g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, nullptr);
    const guint payload = arv_camera_get_payload(camera, &error);
    for (size_t i = 0; i < buffers; ++i)
        arv_stream_push_buffer(stream, arv_buffer_new_allocate(payload));
    const Meter meter;
    arv_camera_start_acquisition(camera, &error);
    uint64_t count = 0;
    while (!error && meter.wallS() < duration_s) {
        ArvBuffer* buffer = arv_stream_timeout_pop_buffer(stream, 100'000);
        if (!buffer)
            continue;
        if (arv_buffer_get_status(buffer) == ARV_BUFFER_STATUS_SUCCESS)
            ++count;
        arv_stream_push_buffer(stream, buffer);
    }
    const Run run = meter.stop(count);
    g_clear_error(&error);
    arv_camera_stop_acquisition(camera, &error);
    g_clear_error(&error);
    g_object_unref(stream);
    g_object_unref(camera);
    return run;
}

// `row` with both runs, or failed with the error of the first that did not run.
Row compared(Row row, const Result<Run>& run, const Result<Run>& peer) {
    if (run)
        row.mixray = *run;
    if (peer)
        row.peer_run = *peer;
    if (!run || !peer) {
        row.note = (!run ? run.status() : peer.status()).toString();
        row.failed = true;
    }
    return row;
}

// The GigE Vision simulator as a child process, killed on destruction.
class GvSimulator {
public:
    ~GvSimulator() {
        if (pid_ > 0) {
            kill(pid_, SIGKILL);
            waitpid(pid_, nullptr, 0);
        }
    }
    bool start() {
        const char* argv[] = {kGvSimulator, "-i", "127.0.0.1", "-s", "MIXRAYBENCH", nullptr};
        if (posix_spawn(&pid_, kGvSimulator, nullptr, nullptr, const_cast<char**>(argv), environ) !=
            0) {
            pid_ = -1;
            return false;
        }
        return true;
    }

private:
    pid_t pid_ = -1;
};

void benchPattern(const BenchDriversOptions& o, std::vector<Row>& rows) {
    Row row{"pattern", "rgbd 640x480 color+depth, simulated time", "", {}, {}, ""};
    pattern::PatternBackend backend;
    DeviceConfig config{"pat", "pattern", "rgbd", {}, {}};
    config.options = {{"realtime", "false"}, {"buffers", "8"}};
    auto run = runDevice(backend, config, true, o.frames, 1e9);
    if (run) {
        row.mixray = *run;
        row.note = "no peer: the backend is its own reference";
    } else {
        row.note = run.status().toString();
        row.failed = true;
    }
    rows.push_back(row);
}

void benchReplay(const BenchDriversOptions& o, std::vector<Row>& rows) {
    const fs::path path = o.recording.empty() ? sourceDir() / "fixtures/sessions/pattern_rgbd.mkv"
                                              : fs::path(o.recording);
    Row row{
        "replay", path.filename().string() + ", pace=fast loop", "Matroska reader next()", {}, {},
        ""};
    replay::ReplayBackend backend;
    DeviceConfig config{"rec", "replay", path.string(), {}, {}};
    config.options = {{"pace", "fast"}, {"loop", "true"}};
    auto run = runDevice(backend, config, true, o.frames, 1e9);
    auto peer = runReader(path, o.frames);
    rows.push_back(compared(std::move(row), run, peer));
}

void benchOpenNI2(const BenchDriversOptions& o, std::vector<Row>& rows) {
    const fs::path path = fs::path(o.shared_data) / "01_oni" / "3dj_kinect1_test.oni";
    Row row{"openni2",
            "3dj_kinect1_test.oni depth+color, pace=fast loop",
            "VideoStream::readFrame",
            {},
            {},
            ""};
    if (!fs::exists(path)) {
        row.note = "peer missing: " + path.string() + " (see ../shared/data/MANIFEST.md)";
        rows.push_back(row);
        return;
    }
    openni2::OpenNI2Backend backend;
    DeviceConfig config{"oni", "openni2", path.string(), {}, {}};
    config.options = {{"pace", "fast"}, {"loop", "true"}};
    auto run = runDevice(backend, config, true, o.frames, 1e9);
    auto peer = runOpenNI2(path, o.frames);
    rows.push_back(compared(std::move(row), run, peer));
}

// Both runs on one camera: mixray's device first, then the bare stream.
void benchAravisCamera(const BenchDriversOptions& o, const std::string& label,
                       const std::string& id, aravis::AravisBackend& backend,
                       std::vector<Row>& rows) {
    constexpr int kWidth = 512;
    constexpr int kHeight = 512;
    constexpr double kFps = 200;
    constexpr size_t kBuffers = 16;
    Row row{"aravis", label + " Mono8 512x512 at 200 fps", "ArvStream pop loop", {}, {}, ""};
    DeviceConfig config{"cam", "aravis", id, {}, {}};
    config.options = {{"pixel_format", "Mono8"},
                      {"width", std::to_string(kWidth)},
                      {"height", std::to_string(kHeight)},
                      {"fps", "200"},
                      {"buffers", std::to_string(kBuffers)}};
    auto run = runDevice(backend, config, false, UINT64_MAX, o.duration_s);
    auto peer = runAravis(id, kWidth, kHeight, kFps, kBuffers, o.duration_s);
    rows.push_back(compared(std::move(row), run, peer));
}

void benchAravis(const BenchDriversOptions& o, std::vector<Row>& rows) {
    aravis::AravisBackend fake({.fake_interface = true});
    benchAravisCamera(o, "in-process fake camera", "Fake_1", fake, rows);
    if (access(kGvSimulator, X_OK) != 0) {
        rows.push_back({"aravis",
                        "GigE Vision simulator",
                        "",
                        {},
                        {},
                        std::string("peer missing: ") + kGvSimulator + " (aravis-tools)"});
        return;
    }
    GvSimulator simulator;
    if (!simulator.start()) {
        rows.push_back({"aravis",
                        "GigE Vision simulator",
                        "",
                        {},
                        {},
                        std::string("cannot start ") + kGvSimulator,
                        true});
        return;
    }
    // It answers GVCP within a second or two.
    aravis::AravisBackend gv;
    for (int attempt = 0; attempt < 40; ++attempt) {
        DeviceConfig probe{"probe", "aravis", "127.0.0.1", {}, {}};
        if (gv.open(probe))
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
    benchAravisCamera(o, "GigE Vision simulator on loopback", "127.0.0.1", gv, rows);
}

void benchV4l2(const BenchDriversOptions& o, std::vector<Row>& rows) {
    v4l2::V4l2Backend backend;
    auto devices = backend.enumerate();
    if (!devices || devices->empty()) {
        rows.push_back({"v4l2",
                        "",
                        "",
                        {},
                        {},
                        "no V4L2 capture node here (the tests' UVC emulator runs only under "
                        "umockdev's preload library, inside the test executables)"});
        return;
    }
    const DeviceDescriptor& d = devices->front();
    Row row{"v4l2", d.id + " " + d.model + ", default mode", "", {}, {}, ""};
    DeviceConfig config{"cam", "v4l2", d.id, {}, {}};
    auto run = runDevice(backend, config, false, UINT64_MAX, o.duration_s);
    if (run)
        row.mixray = *run;
    row.note =
        run ? "no peer run: this benchmark has no raw DQBUF/QBUF loop" : run.status().toString();
    row.failed = !run;
    rows.push_back(row);
}

std::string fixed(double value, int digits) {
    char text[32];
    std::snprintf(text, sizeof text, "%.*f", digits, value);
    return text;
}

void printRows(const std::vector<Row>& rows) {
    std::printf("%-8s %-56s %9s %9s %7s %11s %11s %7s  %s\n", "backend", "source", "mixray/s",
                "peer/s", "ratio", "mixray CPU", "peer CPU", "ratio", "peer");
    std::printf("%-8s %-56s %9s %9s %7s %11s %11s %7s\n", "", "", "frames", "frames", "fps",
                "ms/frame", "ms/frame", "CPU");
    for (const Row& r : rows) {
        if (!r.mixray) {
            std::printf("%-8s %-56s %s\n", r.backend.c_str(), r.source.c_str(), r.note.c_str());
            continue;
        }
        const Run& m = *r.mixray;
        if (!r.peer_run) {
            std::printf("%-8s %-56s %9s %9s %7s %11s %11s %7s  %s\n", r.backend.c_str(),
                        r.source.c_str(), fixed(m.fps(), 0).c_str(), "-", "-",
                        fixed(m.cpuMsPerFrame(), 3).c_str(), "-", "-", r.note.c_str());
            continue;
        }
        const Run& p = *r.peer_run;
        std::printf(
            "%-8s %-56s %9s %9s %7s %11s %11s %7s  %s\n", r.backend.c_str(), r.source.c_str(),
            fixed(m.fps(), 0).c_str(), fixed(p.fps(), 0).c_str(),
            fixed(p.fps() > 0 ? m.fps() / p.fps() : 0, 2).c_str(),
            fixed(m.cpuMsPerFrame(), 3).c_str(), fixed(p.cpuMsPerFrame(), 3).c_str(),
            fixed(p.cpuMsPerFrame() > 0 ? m.cpuMsPerFrame() / p.cpuMsPerFrame() : 0, 2).c_str(),
            r.peer.c_str());
    }
}

int runBenchDrivers(BenchDriversOptions options) {
    if (options.shared_data.empty())
        options.shared_data = defaultSharedDataDir().string();
    std::set<std::string> wanted;
    std::stringstream list(options.backends);
    for (std::string item; std::getline(list, item, ',');) {
        if (item != "pattern" && item != "replay" && item != "openni2" && item != "aravis" &&
            item != "v4l2") {
            return fail("bench drivers", {ErrorCode::kInvalidArgument,
                                          "--backends: unknown backend '" + item +
                                              "' (known: pattern, replay, openni2, aravis, v4l2)"});
        }
        wanted.insert(item);
    }
    std::vector<Row> rows;
    if (wanted.count("pattern"))
        benchPattern(options, rows);
    if (wanted.count("replay"))
        benchReplay(options, rows);
    if (wanted.count("openni2"))
        benchOpenNI2(options, rows);
    if (wanted.count("aravis"))
        benchAravis(options, rows);
    if (wanted.count("v4l2"))
        benchV4l2(options, rows);
    std::printf(
        "bench drivers: %llu frames per file run, %.1f s per camera run; ratio = mixray "
        "/ peer (fps: higher is better; CPU: lower is better)\n",
        static_cast<unsigned long long>(options.frames), options.duration_s);
    printRows(rows);
    for (const Row& r : rows) {
        if (r.failed)
            return fail("bench drivers", {ErrorCode::kUnavailable, r.backend + ": " + r.note});
    }
    return kExitOk;
}

}  // namespace

void registerBenchDrivers(CLI::App& bench, Commands& commands) {
    auto* drivers = bench.add_subcommand(
        "drivers",
        "Frames/s and CPU time per frame of each backend that can run here, through mixray's "
        "device and graph against the peer's own API on the same source");
    auto options = std::make_shared<BenchDriversOptions>();
    drivers->add_option("--frames", options->frames, "Frames per run from files")
        ->check(CLI::Range(10, 100'000'000))
        ->capture_default_str();
    drivers->add_option("--duration", options->duration_s, "Seconds per run from cameras")
        ->check(CLI::Range(0.2, 3600.0))
        ->capture_default_str();
    drivers
        ->add_option("--backends", options->backends,
                     "Comma list of pattern, replay, openni2, aravis, v4l2")
        ->capture_default_str();
    drivers->add_option("--recording", options->recording,
                        "Recording for the replay runs (default: "
                        "fixtures/sessions/pattern_rgbd.mkv)");
    drivers->add_option("--shared-data", options->shared_data,
                        "Real third-party data (default: ../shared/data beside the source tree)");
    commands.push_back({drivers, [options] { return runBenchDrivers(*options); }});
}

}  // namespace mixray::cli
