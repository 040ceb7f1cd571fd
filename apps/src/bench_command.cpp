// mixray bench: measured throughput of mixray's hot paths, with a baseline from the same run.
#include <fcntl.h>
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>
#include <utility>

#include "alloc_counter.h"
#include "backends.h"
#include "bench_calibrate.h"
#include "bench_dds.h"
#include "bench_drivers.h"
#include "bench_pipeline.h"
#include "bench_render.h"
#include "bench_track.h"
#include "cli.h"
#include "console.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/mkv.h"
#include "mixray/graph/synchronizer.h"
#include "mixray/replay/open_recording.h"
#include "test_data_paths.h"

namespace mixray::cli {
namespace {

namespace fs = std::filesystem;

struct BenchGraphOptions {
    uint64_t frames = 3000;        // capture instants for the synchronizer run
    uint64_t record_frames = 300;  // frame pairs for the recording run
    uint64_t disk_mb = 256;        // raw write size for the disk baseline
    std::string dir;               // where to write; default: the system temp folder
    std::string shared_data;       // ../shared/data
};

double seconds(int64_t ns) {
    return static_cast<double>(ns) / 1e9;
}

// Pins the calling thread (and threads it starts later) to one CPU; restores on destruction.
class PinToOneCore {
public:
    PinToOneCore() {
        pinned_ = sched_getaffinity(0, sizeof saved_, &saved_) == 0;
        if (!pinned_)
            return;
        cpu_set_t one;
        CPU_ZERO(&one);
        for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
            if (CPU_ISSET(cpu, &saved_)) {
                CPU_SET(cpu, &one);
                cpu_ = cpu;
                break;
            }
        }
        pinned_ = sched_setaffinity(0, sizeof one, &one) == 0;
    }
    ~PinToOneCore() {
        if (pinned_)
            sched_setaffinity(0, sizeof saved_, &saved_);
    }
    bool pinned() const { return pinned_; }
    int cpu() const { return cpu_; }

private:
    cpu_set_t saved_{};
    bool pinned_ = false;
    int cpu_ = -1;
};

// Distinct payload addresses seen per stream: more addresses than the source's pool holds
// would mean someone on the way made copies.
struct AddressSet {
    std::array<const uint8_t*, 64> seen{};
    size_t count = 0;
    bool overflow = false;
    void add(const uint8_t* p) {
        for (size_t i = 0; i < count; ++i) {
            if (seen[i] == p)
                return;
        }
        if (count < seen.size()) {
            seen[count++] = p;
        } else {
            overflow = true;
        }
    }
};

Status benchSynchronizer(const BenchGraphOptions& options) {
    constexpr size_t kPoolBuffers = 8;
    PinToOneCore pin;
    BackendRegistry registry = makeBackendRegistry();
    Graph graph;
    const std::string frames = std::to_string(options.frames);
    const std::string buffers = std::to_string(kPoolBuffers);
    DeviceConfig rgbd{"rgbd", "pattern", "rgbd", {}, {"color", "depth"}};
    rgbd.options = {{"realtime", "false"}, {"fill", "stamp"},   {"frames", frames},
                    {"buffers", buffers},  {"drift_ppm", "40"}, {"jitter_us", "200"}};
    DeviceConfig mono{"mono", "pattern", "mono", {}, {"mono"}};
    mono.options = {{"realtime", "false"}, {"fill", "stamp"},    {"frames", frames},
                    {"buffers", buffers},  {"drift_ppm", "-60"}, {"jitter_us", "200"}};
    for (const auto& config : {rgbd, mono}) {
        auto device = registry.open(config);
        if (!device)
            return device.status();
        MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(*device)));
    }

    SyncNodeOptions sync_options;
    sync_options.streams = {"rgbd/color", "rgbd/depth", "mono/mono"};
    sync_options.queue = {4, QueuePolicy::kLossless, "bench-sync"};
    sync_options.sync.max_skew_ns = 5'000'000;
    std::atomic<uint64_t> sets{0};
    std::array<AddressSet, 3> addresses;
    const uint64_t warmup = std::min<uint64_t>(100, options.frames / 10);
    std::atomic<uint64_t> allocs_at_warmup{0}, allocs_at_end{0};
    std::atomic<int64_t> t_warmup{0}, t_end{0};
    auto node = std::make_unique<SyncNode>(sync_options, [&](const SyncSet& set) {
        for (size_t i = 0; i < set.frames.size(); ++i)
            addresses[i].add(set.frames[i].data());
        const uint64_t n = ++sets;
        if (n == warmup) {
            allocs_at_warmup = heapAllocations();
            t_warmup = monotonicNowNs();
        }
        allocs_at_end = heapAllocations();
        t_end = monotonicNowNs();
    });
    SyncNode* sync = node.get();
    MIXRAY_RETURN_IF_ERROR(graph.addNode(std::move(node)));
    MIXRAY_RETURN_IF_ERROR(graph.start());
    if (!sync->waitDone(std::chrono::minutes(5))) {
        graph.stop();
        return {ErrorCode::kInternal, "synchronizer benchmark did not finish in 5 minutes"};
    }
    graph.stop();

    const uint64_t steady_sets = sets - warmup;
    const double rate = steady_sets / seconds(t_end - t_warmup);
    const double allocs_per_set =
        static_cast<double>(allocs_at_end - allocs_at_warmup) / std::max<uint64_t>(steady_sets, 1);
    const SyncStats stats = sync->stats();
    std::printf("graph + synchronizer: 640x480 rgb8 + 640x480 depth16 + 1280x960 mono8, %s\n",
                pin.pinned() ? ("pinned to CPU " + std::to_string(pin.cpu())).c_str()
                             : "not pinned (sched_setaffinity failed)");
    std::printf(
        "  %llu sets from %llu instants, %llu frames dropped, skew mean %.3f ms max %.3f ms\n",
        static_cast<unsigned long long>(sets.load()),
        static_cast<unsigned long long>(options.frames),
        static_cast<unsigned long long>(stats.framesDropped()), stats.skew_mean_ns / 1e6,
        static_cast<double>(stats.skew_max_ns) / 1e6);
    std::printf("  synchronized sets/s (1 core):       %10.0f   (aim >= 2000)\n", rate);
    std::printf("  heap allocations per set (steady):  %10.3f\n", allocs_per_set);
    size_t max_addresses = 0;
    bool overflow = false;
    for (const auto& a : addresses) {
        max_addresses = std::max(max_addresses, a.count);
        overflow |= a.overflow;
    }
    const bool zero_copy = !overflow && max_addresses <= kPoolBuffers;
    std::printf("  distinct buffers per stream:        %10zu   (driver pool holds %zu)\n",
                max_addresses, kPoolBuffers);
    std::printf("  pixel copies per frame:             %10s\n",
                zero_copy ? "0" : ">0 (copies seen)");
    return Status::ok();
}

// Raw sequential write speed of the disk holding `dir`: large write() calls, then fdatasync.
Result<double> rawDiskMBps(const fs::path& dir, uint64_t megabytes) {
    const fs::path path = dir / "mixray-bench-raw.bin";
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0)
        return {ErrorCode::kIoError, "cannot create " + path.string()};
    std::vector<uint8_t> chunk(4 << 20);
    for (size_t i = 0; i < chunk.size(); ++i)
        chunk[i] = static_cast<uint8_t>(i * 2654435761u >> 13);
    const int64_t t0 = monotonicNowNs();
    bool ok = true;
    for (uint64_t written = 0; ok && written < megabytes << 20; written += chunk.size()) {
        ok = ::write(fd, chunk.data(), chunk.size()) == static_cast<ssize_t>(chunk.size());
    }
    ok = ok && ::fdatasync(fd) == 0;
    const int64_t t1 = monotonicNowNs();
    ::close(fd);
    fs::remove(path);
    if (!ok)
        return {ErrorCode::kIoError, "writing " + path.string() + " failed"};
    return static_cast<double>(megabytes << 20) / 1e6 / seconds(t1 - t0);
}

// The first frame of the first stream of `kind` in a recording, as an owned image.
Result<Image> firstFrameOf(const fs::path& path, StreamKind kind) {
    auto reader = replay::openRecording(path);
    if (!reader)
        return reader.status();
    for (;;) {
        auto frame = (*reader)->next();
        if (!frame)
            return frame.status();
        if ((*reader)->streams()[frame->meta().stream].kind == kind) {
            return Image::copyOf(frame->image());
        }
    }
}

// A TUM folder with the real TUM frame pair from shared data, in `dir`.
Result<fs::path> makeTumFolder(const fs::path& shared, const fs::path& dir) {
    const fs::path src = shared / "02_rgbd_single_frames_open3d";
    if (!fs::exists(src / "TUM_depth.png"))
        return {ErrorCode::kNotFound, src.string()};
    const fs::path tum = dir / "mixray-bench-tum";
    fs::remove_all(tum);
    fs::create_directories(tum / "rgb");
    fs::create_directories(tum / "depth");
    fs::copy_file(src / "TUM_color.png", tum / "rgb" / "1.000000.png");
    fs::copy_file(src / "TUM_depth.png", tum / "depth" / "1.000000.png");
    std::ofstream(tum / "rgb.txt") << "# color images\n1.000000 rgb/1.000000.png\n";
    std::ofstream(tum / "depth.txt") << "# depth maps\n1.000000 depth/1.000000.png\n";
    return tum;
}

// Writes `count` copies of each image (one stream each) into an mkv as fast as possible.
// Frames come from pools filled once, so the time is the writer's alone.
struct WriteResult {
    double seconds = 0;
    uint64_t raw_bytes = 0;
    uint64_t file_bytes = 0;
};
Result<WriteResult> writeCopies(const fs::path& path, const std::vector<Image>& images,
                                uint64_t count,
                                MkvCompression compression = MkvCompression::kFfv1) {
    RecordingHeader header;
    std::vector<std::shared_ptr<BufferPool>> pools;
    for (size_t i = 0; i < images.size(); ++i) {
        StreamInfo info;
        info.name = "bench/stream" + std::to_string(i);
        info.device = "bench";
        info.kind = images[i].desc().format == PixelFormat::kDepth16 ? StreamKind::kDepth
                                                                     : StreamKind::kColor;
        info.format = images[i].desc();
        info.nominal_fps = 30;
        header.streams.push_back(info);
        pools.push_back(BufferPool::create({info.format, 0, 2, info.name}));
        if (!pools.back())
            return {ErrorCode::kInvalidArgument, "bad image layout for " + info.name};
        // Fill both buffers once; the pool hands them out again with their pixels intact.
        std::vector<WritableFrame> fill;
        for (int b = 0; b < 2; ++b) {
            fill.push_back(pools.back()->acquire());
            std::memcpy(fill.back().image().data, images[i].view().data,
                        images[i].desc().bufferBytes());
        }
    }
    MkvWriterOptions writer_options;
    writer_options.compression = compression;
    auto writer = createMkvWriter(path, header, writer_options);
    if (!writer)
        return writer.status();
    WriteResult result;
    const int64_t t0 = monotonicNowNs();
    for (uint64_t k = 0; k < count; ++k) {
        for (size_t i = 0; i < images.size(); ++i) {
            WritableFrame w = pools[i]->acquire();
            w.meta().stream = static_cast<StreamId>(i);
            w.meta().sequence = k;
            w.meta().host_stamp_ns = w.meta().device_stamp_ns =
                1'000'000'000 + static_cast<int64_t>(k) * 33'333'333;
            FrameRef frame = std::move(w).publish();
            MIXRAY_RETURN_IF_ERROR((*writer)->write(frame));
            result.raw_bytes += frame.image().size_bytes;
        }
    }
    MIXRAY_RETURN_IF_ERROR((*writer)->close());
    const int fd = ::open(path.c_str(), O_RDONLY);
    if (fd >= 0) {
        ::fdatasync(fd);
        ::close(fd);
    }
    result.seconds = seconds(monotonicNowNs() - t0);
    result.file_bytes = fs::file_size(path);
    return result;
}

Status benchRecording(const BenchGraphOptions& options, const fs::path& dir) {
    std::vector<Image> images;
    std::string source = "real TUM RGB-D frame pair (640x480 rgb8 + depth16)";
    auto tum = makeTumFolder(options.shared_data, dir);
    if (tum) {
        auto color = firstFrameOf(*tum, StreamKind::kColor);
        auto depth = firstFrameOf(*tum, StreamKind::kDepth);
        if (color && depth)
            images = {std::move(*color), std::move(*depth)};
        fs::remove_all(*tum);
    }
    if (images.empty()) {
        return {ErrorCode::kNotFound, "real TUM frames not found under " + options.shared_data +
                                          " (see ../shared/data/MANIFEST.md)"};
    }
    // The disk baseline writes as many bytes as the uncompressed recording, once before and
    // once after the recordings; the faster of the two is the disk's speed.
    uint64_t raw_bytes_per_pair = 0;
    for (const auto& image : images)
        raw_bytes_per_pair += image.desc().bufferBytes();
    const uint64_t baseline_mb =
        std::max<uint64_t>(options.disk_mb, (raw_bytes_per_pair * options.record_frames) >> 20);
    auto disk_before = rawDiskMBps(dir, baseline_mb);
    if (!disk_before)
        return disk_before.status();
    const fs::path path = dir / "mixray-bench-record.mkv";
    std::printf("recording: %llu frame pairs of the %s, fdatasync at the end\n",
                static_cast<unsigned long long>(options.record_frames), source.c_str());
    std::vector<std::pair<std::string, double>> rates;
    double ffv1_disk_mbps = 0;
    double ffv1_ratio = 0;
    for (const auto& [compression, name] : {std::pair{MkvCompression::kNone, "uncompressed"},
                                            std::pair{MkvCompression::kFfv1, "FFV1"}}) {
        auto written = writeCopies(path, images, options.record_frames, compression);
        fs::remove(path);
        if (!written)
            return written.status();
        rates.emplace_back(name, static_cast<double>(written->raw_bytes) / 1e6 / written->seconds);
        if (compression == MkvCompression::kFfv1) {
            ffv1_disk_mbps = static_cast<double>(written->file_bytes) / 1e6 / written->seconds;
            ffv1_ratio = static_cast<double>(written->raw_bytes) / written->file_bytes;
        }
    }
    auto disk_after = rawDiskMBps(dir, baseline_mb);
    if (!disk_after)
        return disk_after.status();
    const double disk = std::max(*disk_before, *disk_after);
    std::printf("  raw disk write, %4llu MB (same folder): %8.1f MB/s  (best of %.1f, %.1f; %s)\n",
                static_cast<unsigned long long>(baseline_mb), disk, *disk_before, *disk_after,
                dir.c_str());
    for (const auto& [name, mbps] : rates) {
        std::printf("  recording %-13s input        %10.1f MB/s  = %3.0f %% of raw disk%s\n",
                    (name + ",").c_str(), mbps, 100.0 * mbps / disk,
                    name == "uncompressed" ? " (aim >= 80 %)" : "");
    }
    std::printf("  recording FFV1, bytes to disk:      %10.1f MB/s  (%.2f:1 compression)\n",
                ffv1_disk_mbps, ffv1_ratio);
    return Status::ok();
}

// FFV1's compression of one real depth frame: the payload of one frame is the size difference
// between files holding 31 and 1 copies, divided by 30, which cancels the header.
Status benchDepthCompression(const BenchGraphOptions& options, const fs::path& dir) {
    const fs::path shared = options.shared_data;
    struct Source {
        std::string name;
        Result<fs::path> path;
    };
    std::vector<Source> sources;
    sources.push_back({"TUM RGB-D (Kinect v1, 640x480)", makeTumFolder(shared, dir)});
    sources.push_back({"PCL OpenNI TIFF (640x480)", fs::path(shared / "02_rgbd_pcl_openni_tiff")});
    sources.push_back({"Azure Kinect NFOV (640x576)",
                       fs::path(shared / "07_azure_kinect_mkv" / "pyk4a_recording.mkv")});
    std::printf("FFV1 compression of real depth frames (raw bytes : stored bytes):\n");
    for (auto& source : sources) {
        if (!source.path || !fs::exists(*source.path)) {
            std::printf("  %-34s skipped: data not found under %s\n", source.name.c_str(),
                        shared.c_str());
            continue;
        }
        auto depth = firstFrameOf(*source.path, StreamKind::kDepth);
        if (!depth) {
            std::printf("  %-34s failed: %s\n", source.name.c_str(),
                        depth.status().toString().c_str());
            continue;
        }
        std::vector<Image> images;
        images.push_back(std::move(*depth));
        const fs::path one = dir / "mixray-bench-depth1.mkv";
        const fs::path many = dir / "mixray-bench-depth31.mkv";
        auto a = writeCopies(one, images, 1);
        auto b = writeCopies(many, images, 31);
        fs::remove(one);
        fs::remove(many);
        if (!a || !b)
            return !a ? a.status() : b.status();
        const double stored = static_cast<double>(b->file_bytes - a->file_bytes) / 30.0;
        const double raw = static_cast<double>(images[0].desc().bufferBytes());
        std::printf("  %-34s %6.2f:1  (%.0f kB -> %.0f kB per frame)\n", source.name.c_str(),
                    raw / stored, raw / 1e3, stored / 1e3);
    }
    if (sources[0].path)
        fs::remove_all(*sources[0].path);
    return Status::ok();
}

int runBenchGraph(BenchGraphOptions options) {
    setFfmpegLogging(false);
    const fs::path dir = options.dir.empty() ? fs::temp_directory_path() : fs::path(options.dir);
    if (!fs::is_directory(dir)) {
        return fail("bench graph", {ErrorCode::kNotFound, "no folder " + dir.string()});
    }
    if (options.shared_data.empty())
        options.shared_data = defaultSharedDataDir().string();
    Status status = benchSynchronizer(options);
    if (!status)
        return fail("bench graph", status);
    status = benchRecording(options, dir);
    if (!status)
        return fail("bench graph", status);
    status = benchDepthCompression(options, dir);
    if (!status)
        return fail("bench graph", status);
    return kExitOk;
}

}  // namespace

void registerBenchCommand(CLI::App& app, Commands& commands) {
    auto* bench = app.add_subcommand("bench",
                                     "Measure mixray's hot paths against baselines "
                                     "taken in the same run");
    bench->require_subcommand(1, 1);
    auto* graph = bench->add_subcommand(
        "graph",
        "Synchronized sets/s through graph + synchronizer (one core), heap allocations and "
        "pixel copies per frame, recording MB/s against raw disk writes, FFV1 compression of "
        "real depth frames");
    auto options = std::make_shared<BenchGraphOptions>();
    graph->add_option("--frames", options->frames, "Capture instants for the synchronizer run")
        ->check(CLI::Range(200, 10'000'000))
        ->capture_default_str();
    graph
        ->add_option("--record-frames", options->record_frames, "Frame pairs for the recording run")
        ->check(CLI::Range(10, 1'000'000))
        ->capture_default_str();
    graph->add_option("--disk-mb", options->disk_mb, "Megabytes for the raw disk baseline")
        ->check(CLI::Range(16, 65536))
        ->capture_default_str();
    graph->add_option("--dir", options->dir, "Folder to write to (default: the temp folder)");
    graph->add_option("--shared-data", options->shared_data,
                      "Real third-party data (default: ../shared/data beside the source tree)");
    commands.push_back({graph, [options] { return runBenchGraph(*options); }});
    registerBenchCalibrate(*bench, commands);
    registerBenchDds(*bench, commands);
    registerBenchDrivers(*bench, commands);
    registerBenchPipeline(*bench, commands);
    registerBenchRender(*bench, commands);
    registerBenchTrack(*bench, commands);
}

}  // namespace mixray::cli
