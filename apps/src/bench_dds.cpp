// mixray bench dds: one stream at a time between two graphs of this process over DDS (a
// DdsPublisher in one, a dds device in the other), as fast as it goes (frames/s) and at 30 fps
// (latency from the sender's stamp to the consumer's pop), with the whole process's CPU time per
// frame; beside it, bare Fast DDS (dds::runBareFastDds) with the same payload, participants and
// QoS. Fast DDS's in-process shortcut is off: every sample crosses the transport. On the veth
// path each end's participant lives in a network namespace of its own (its sockets and threads
// made there), so every sample crosses a veth pair as it would cross a link between hosts.
#include "bench_dds.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>

#include "console.h"
#include "mixray/dds/bare_fastdds.h"
#include "mixray/dds/dds_backend.h"
#include "mixray/dds/dds_publisher.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/host_time.h"
#include "network_namespaces.h"

namespace mixray::cli {
namespace {

struct BenchDdsOptions {
    uint64_t frames = 200;       // per throughput run
    uint64_t paced_frames = 60;  // per latency run, at 30 fps
    int domain = 0;              // 0: one from the process id
    std::vector<std::string> transports{"udp", "shm", "veth"};
};

// Where the two ends of a run are: both on this host's loopback, or each in a namespace of a
// NamespacePair (the veth path).
struct Ends {
    const hosts::NamespacePair* hosts = nullptr;

    // Runs `make` in the sender's (or receiver's) namespace, or here.
    dds::HostScope sender() const { return scope(hosts ? hosts->a().ns : ""); }
    dds::HostScope receiver() const { return scope(hosts ? hosts->b().ns : ""); }

private:
    static dds::HostScope scope(std::string ns) {
        return [ns](const std::function<Status()>& make) -> Status {
            if (ns.empty())
                return make();
            auto inside = hosts::InNamespace::enter(ns);
            if (!inside)
                return inside.status();
            return make();
        };
    }
};

// One run's figures, mixray's or bare Fast DDS's.
struct Figures {
    uint64_t sent = 0;
    uint64_t received = 0;
    double wall_s = 0;
    double cpu_s = 0;
    std::vector<double> latency_ms;

    double fps() const { return wall_s > 0 ? static_cast<double>(received) / wall_s : 0; }
    // Frames the receiver got of those the sender made: mixray's publisher drops the oldest
    // on its live edge when DDS is slower, bare Fast DDS's keep-last history drops inside DDS.
    double receivedPercent() const {
        return sent > 0 ? 100.0 * static_cast<double>(received) / static_cast<double>(sent) : 0;
    }
    double cpuMsPerFrame() const {
        return received > 0 ? cpu_s * 1e3 / static_cast<double>(received) : 0;
    }
    double percentile(double p) const {
        if (latency_ms.empty())
            return 0;
        std::vector<double> sorted = latency_ms;
        std::sort(sorted.begin(), sorted.end());
        const size_t rank = static_cast<size_t>(std::ceil(p * static_cast<double>(sorted.size())));
        return sorted[std::min(sorted.size() - 1, rank > 0 ? rank - 1 : 0)];
    }
};

dds::DdsOptions endpoint(const BenchDdsOptions& o, const std::string& transport,
                         const std::string& host, const Ends& ends, bool sender) {
    dds::DdsOptions options;
    options.domain = o.domain;
    options.host = host;
    options.transport =
        transport == "shm" ? dds::DdsTransport::kSharedMemory : dds::DdsTransport::kUdp;
    if (ends.hosts) {
        options.address = sender ? ends.hosts->a().address : ends.hosts->b().address;
        options.peers = {sender ? ends.hosts->b().address : ends.hosts->a().address};
    }
    return options;
}

// `frames` frames of `info` from a graph with a DdsPublisher to a graph with the dds device
// that receives them, one every `period_ns` (0: as fast as the sender goes).
Result<Figures> runMixray(const BenchDdsOptions& o, const std::string& transport, const Ends& ends,
                          const StreamInfo& info, uint64_t frames, int64_t period_ns) {
    Graph sender;
    auto pooled = addPooledStream(sender, info, 8);
    if (!pooled)
        return pooled.status();
    dds::DdsPublisher* pub = nullptr;
    MIXRAY_RETURN_IF_ERROR(ends.sender()([&]() -> Status {
        dds::DdsPublisherOptions publisher_options;
        publisher_options.dds = endpoint(o, transport, "bench-sender", ends, true);
        auto publisher = dds::DdsPublisher::create(publisher_options);
        if (!publisher)
            return publisher.status();
        pub = publisher->get();
        return sender.addNode(std::move(*publisher));
    }));

    Graph receiver;
    std::shared_ptr<FrameQueue> queue;
    const Status received_there = ends.receiver()([&]() -> Status {
        dds::DdsBackend backend(endpoint(o, transport, "bench-receiver", ends, false));
        DeviceConfig config;
        config.name = "remote";
        config.driver = "dds";
        config.id = "bench-sender/" + info.device;
        config.options["buffers"] = "16";
        auto device = backend.open(config);
        if (!device)
            return device.status();
        MIXRAY_RETURN_IF_ERROR(receiver.addNode(std::move(*device)));
        const std::string local = "remote/" + info.name.substr(info.device.size() + 1);
        auto subscribed =
            receiver.subscribe(*receiver.findStream(local), {16, QueuePolicy::kLossless, "bench"});
        if (!subscribed)
            return subscribed.status();
        queue = *subscribed;
        return receiver.start();
    });
    if (!received_there)
        return received_there;
    if (!pub->waitForReaders(1, std::chrono::seconds(20)))
        return Status{ErrorCode::kUnavailable, "bench dds: the receiver never matched"};

    Figures f;
    std::atomic<int64_t> last_pop{0};
    std::atomic<uint64_t> received{0};
    std::thread consumer([&] {
        while (auto frame = queue->pop(std::chrono::seconds(5))) {
            const int64_t now = monotonicNowNs();
            last_pop = now;
            f.latency_ms.push_back(static_cast<double>(now - frame->meta().device_stamp_ns) / 1e6);
            received.fetch_add(1);
        }
    });
    MIXRAY_RETURN_IF_ERROR(ends.sender()([&] { return sender.start(); }));
    const int64_t cpu0 = processCpuNs();
    const int64_t t0 = monotonicNowNs();
    for (uint64_t i = 0; i < frames; ++i) {
        if (period_ns > 0) {
            const int64_t due = t0 + static_cast<int64_t>(i) * period_ns;
            while (monotonicNowNs() < due)
                std::this_thread::sleep_for(std::chrono::microseconds(200));
        } else {
            dds::waitForWindow(f.sent, received, monotonicNowNs());
        }
        ++f.sent;
        WritableFrame frame = pooled->pool->acquire();
        if (!frame) {  // every buffer is in the publisher's edge or being written: the
            sender.countLost(pooled->id);  // sender outran DDS, as a camera would
            continue;
        }
        frame.meta().stream = pooled->id;
        frame.meta().sequence = i;
        frame.meta().host_stamp_ns = monotonicNowNs();
        frame.meta().device_stamp_ns = frame.meta().host_stamp_ns;
        sender.publish(std::move(frame).publish());
    }
    sender.endStream(pooled->id);  // the receiver's stream ends after the last frame
    consumer.join();
    f.received = received.load();
    f.cpu_s = static_cast<double>(processCpuNs() - cpu0) / 1e9;
    f.wall_s = static_cast<double>(last_pop.load() - t0) / 1e9;
    receiver.stop();
    sender.stop();
    return f;
}

Result<Figures> runBare(const BenchDdsOptions& o, const std::string& transport, const Ends& ends,
                        const StreamInfo& info, uint64_t frames, int64_t period_ns) {
    const int64_t cpu0 = processCpuNs();
    auto run = dds::runBareFastDds(endpoint(o, transport, "bare-sender", ends, true),
                                   endpoint(o, transport, "bare-receiver", ends, false),
                                   info.format.bufferBytes(), frames, period_ns, ends.sender(),
                                   ends.receiver());
    if (!run)
        return run.status();
    Figures f;
    f.sent = run->sent;
    f.received = run->received;
    f.wall_s = run->wall_s;
    f.cpu_s = static_cast<double>(processCpuNs() - cpu0) / 1e9;
    f.latency_ms = std::move(run->latency_ms);
    return f;
}

StreamInfo stream(const char* name, StreamKind kind, PixelFormat format, int width, int height) {
    StreamInfo info;
    info.name = std::string("cam/") + name;
    info.device = "cam";
    info.kind = kind;
    info.format = ImageDesc::packed(format, width, height);
    info.nominal_fps = 30;
    info.clock_domain = kHostClockDomain;
    return info;
}

int runBenchDds(BenchDdsOptions o) {
    dds::setIntraprocessDelivery(false);
    if (o.domain == 0)
        o.domain = 1 + static_cast<int>(getpid() % 200);
    const std::vector<StreamInfo> streams{
        stream("color", StreamKind::kColor, PixelFormat::kRGB8, 640, 480),
        stream("depth", StreamKind::kDepth, PixelFormat::kDepth16, 640, 480),
        stream("mono", StreamKind::kMono, PixelFormat::kMono8, 1280, 960)};
    std::printf(
        "bench dds: one stream between two graphs of this process; %llu frames sent as fast as "
        "they are received, at most %d in flight (fps), %llu at 30 fps (latency, sender stamp to "
        "consumer); CPU: the whole process per frame received; bare: Fast DDS writer and reader "
        "of the same payload, participants and QoS; ratio: mixray / bare; udp and shm: loopback, "
        "veth: UDP between two network namespaces joined by a veth pair\n",
        static_cast<unsigned long long>(o.frames), dds::kBenchWindow,
        static_cast<unsigned long long>(o.paced_frames));
    std::printf("%-18s %-4s %9s %9s %6s %7s %7s %9s %9s %9s %9s %9s %9s %6s %7s\n", "stream",
                "path", "mixray", "bare", "ratio", "mixray", "bare", "mixray", "mixray", "bare",
                "bare", "mixray", "bare", "ratio", "lost");
    std::printf("%-18s %-4s %9s %9s %6s %7s %7s %9s %9s %9s %9s %9s %9s %6s %7s\n", "", "", "fps",
                "fps", "fps", "recv %", "recv %", "p50 ms", "p99 ms", "p50 ms", "p99 ms",
                "CPU ms/f", "CPU ms/f", "CPU", "at 30");
    bool failed = false;
    for (const std::string& transport : o.transports) {
        Ends ends;
        std::unique_ptr<hosts::NamespacePair> namespaces;
        if (transport == "veth") {
            const int id = static_cast<int>(getpid() % 100000);
            auto made = hosts::NamespacePair::create("mxbench" + std::to_string(id),
                                                     "10.215." + std::to_string(id % 250));
            if (!made) {
                // Not root: the loopback rows stand; a broken ip is a failure.
                std::printf("%-18s %-4s skipped: %s\n", "every stream", "veth",
                            made.status().message().c_str());
                failed = failed || made.status().code() != ErrorCode::kUnsupported;
                continue;
            }
            namespaces = std::move(made).value();
            ends.hosts = namespaces.get();
        }
        for (const StreamInfo& info : streams) {
            auto fast = runMixray(o, transport, ends, info, o.frames, 0);
            auto paced = runMixray(o, transport, ends, info, o.paced_frames, 33'333'333);
            auto bare_fast = runBare(o, transport, ends, info, o.frames, 0);
            auto bare_paced = runBare(o, transport, ends, info, o.paced_frames, 33'333'333);
            char label[64];
            std::snprintf(label, sizeof label, "%s %dx%d",
                          std::string(toString(info.format.format)).c_str(), info.format.width,
                          info.format.height);
            for (const auto* r : {&fast, &paced, &bare_fast, &bare_paced}) {
                if (!r->isOk()) {
                    std::printf("%-18s %-4s %s\n", label, transport.c_str(),
                                r->status().toString().c_str());
                    failed = true;
                }
            }
            if (!fast || !paced || !bare_fast || !bare_paced)
                continue;
            std::printf(
                "%-18s %-4s %9.1f %9.1f %6.2f %7.1f %7.1f %9.2f %9.2f %9.2f %9.2f %9.3f %9.3f "
                "%6.2f "
                "%7llu\n",
                label, transport.c_str(), fast->fps(), bare_fast->fps(),
                bare_fast->fps() > 0 ? fast->fps() / bare_fast->fps() : 0, fast->receivedPercent(),
                bare_fast->receivedPercent(), paced->percentile(0.5), paced->percentile(0.99),
                bare_paced->percentile(0.5), bare_paced->percentile(0.99), fast->cpuMsPerFrame(),
                bare_fast->cpuMsPerFrame(),
                bare_fast->cpuMsPerFrame() > 0 ? fast->cpuMsPerFrame() / bare_fast->cpuMsPerFrame()
                                               : 0,
                static_cast<unsigned long long>(paced->sent - paced->received));
            std::fflush(stdout);
        }
        if (namespaces) {
            // Proof that the samples took the link, not a shortcut inside the machine.
            auto bytes = namespaces->bytesSent();
            if (bytes) {
                std::printf("%-18s %-4s %.1f MB crossed the veth pair\n", "", "veth",
                            static_cast<double>(*bytes) / 1e6);
            }
        }
    }
    return failed ? kExitUnavailable : kExitOk;
}

}  // namespace

void registerBenchDds(CLI::App& bench, Commands& commands) {
    auto* sub = bench.add_subcommand(
        "dds",
        "Frames/s, latency p50/p99 and CPU per frame of one stream between two graphs over DDS "
        "(640x480 rgb8 and depth16, 1280x960 mono8; loopback UDP and shared memory, and UDP "
        "between two network namespaces joined by a veth pair, which needs root), against bare "
        "Fast DDS with the same payload and settings, in the same run");
    auto options = std::make_shared<BenchDdsOptions>();
    sub->add_option("--frames", options->frames, "Frames per throughput run")
        ->check(CLI::Range(10, 100000))
        ->capture_default_str();
    sub->add_option("--paced-frames", options->paced_frames, "Frames per latency run (at 30 fps)")
        ->check(CLI::Range(10, 100000))
        ->capture_default_str();
    sub->add_option("--domain", options->domain, "DDS domain (default: one from the process id)")
        ->check(CLI::Range(0, 232));
    sub->add_option("--transports", options->transports,
                    "udp, shm (loopback), veth (between two network namespaces; root) "
                    "(comma-separated)")
        ->delimiter(',')
        ->check(CLI::IsMember({"udp", "shm", "veth"}))
        ->capture_default_str();
    commands.push_back({sub, [options] { return runBenchDds(*options); }});
}

}  // namespace mixray::cli
