// mixray publish: opens a rig's devices and publishes their streams over DDS, for mixray on
// other hosts (the dds backend) and for ROS 2 (--ros2).
#include <chrono>
#include <cstdio>
#include <thread>

#include "backends.h"
#include "cli.h"
#include "console.h"
#include "dds_options_cli.h"
#include "mixray/calibration/calibration_file.h"
#include "mixray/dds/dds_publisher.h"
#include "mixray/dds/ros_calibration.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/rig.h"

namespace mixray::cli {
namespace {

struct PublishOptions {
    std::string rig_path;
    std::string calibration;  // --calibration: every camera's, in place of the rig's files
    dds::DdsPublisherOptions publisher;
    double duration_s = 0;
    int wait_readers = 0;
    double wait_timeout_s = 60;
};

int runPublish(const PublishOptions& options) {
    InterruptFlag interrupt;
    auto rig = loadRig(options.rig_path);
    if (!rig)
        return fail("publish", rig.status());
    BackendRegistry registry = makeBackendRegistry();
    Graph graph;
    for (const auto& config : rig->deviceConfigs()) {
        auto device = registry.open(config);
        if (!device)
            return fail("publish", device.status());
        if (Status added = graph.addNode(std::move(*device)); !added)
            return fail("publish", added);
    }
    dds::DdsPublisherOptions publisher_options = options.publisher;
    if (!publisher_options.ros2_rig.empty()) {
        // --calibration stands for every calibration file the rig names (and for the rig's own
        // when it names none).
        RigDescription calibrated = *rig;
        if (!options.calibration.empty()) {
            calibrated.calibration = {{.device = "",
                                       .stream = "",
                                       .path = options.calibration,
                                       .resolved = options.calibration,
                                       .where = {}}};
        }
        auto ros =
            dds::rosCalibrationOf(calibrated, graph.streams(), [](const RigCalibrationFile& entry) {
                return calibration::importCalibration(entry.resolved);
            });
        if (!ros)
            return fail("publish", ros.status());
        publisher_options.ros2_camera_info = std::move(ros->camera_info);
        publisher_options.ros2_transforms = std::move(ros->transforms);
    } else if (!options.calibration.empty()) {
        return fail("publish",
                    {ErrorCode::kInvalidArgument,
                     "--calibration goes to ROS 2's camera_info and tf_static: add --ros2"});
    }
    auto publisher = dds::DdsPublisher::create(publisher_options);
    if (!publisher)
        return fail("publish", publisher.status());
    dds::DdsPublisher* dds = publisher->get();
    if (Status added = graph.addNode(std::move(*publisher)); !added)
        return fail("publish", added);
    if (options.wait_readers > 0) {
        std::printf("waiting for %d reader%s of every stream...\n", options.wait_readers,
                    options.wait_readers == 1 ? "" : "s");
        std::fflush(stdout);
        const auto timeout =
            std::chrono::milliseconds(static_cast<int64_t>(options.wait_timeout_s * 1000));
        if (!dds->waitForReaders(options.wait_readers, timeout)) {
            char text[160];
            std::snprintf(
                text, sizeof text, "not every stream had %d reader%s after %g s (--wait-readers)",
                options.wait_readers, options.wait_readers == 1 ? "" : "s", options.wait_timeout_s);
            return fail("publish", {ErrorCode::kUnavailable, text});
        }
    }
    // Watch queues (capacity 1, live) tell when a stream ended.
    std::vector<std::shared_ptr<FrameQueue>> watches;
    for (StreamId id = 0; id < graph.streamCount(); ++id) {
        auto queue = graph.subscribe(id, {.capacity = 1,
                                          .policy = QueuePolicy::kLive,
                                          .name = "publish-watch",
                                          .newest_only = true});
        if (!queue)
            return fail("publish", queue.status());
        watches.push_back(*queue);
    }
    if (Status started = graph.start(); !started)
        return fail("publish", started);

    const auto& o = options.publisher.dds;
    std::printf("publishing %zu streams as host '%s' in DDS domain %d on %s (%s)%s\n",
                dds->stats().size(), dds->host().c_str(), o.domain, o.address.c_str(),
                std::string(dds::toString(o.transport)).c_str(),
                options.publisher.ros2_rig.empty()
                    ? ""
                    : (", ROS 2 images under rt/" + options.publisher.ros2_rig + "/").c_str());
    for (const auto& [stream, info] : publisher_options.ros2_camera_info) {
        std::printf("  ROS 2 camera_info of %s: %ux%u, %s\n", stream.c_str(), info.width,
                    info.height, info.distortion_model.c_str());
    }
    if (!publisher_options.ros2_transforms.empty()) {
        std::printf("  ROS 2 tf_static: %zu transform%s (",
                    publisher_options.ros2_transforms.size(),
                    publisher_options.ros2_transforms.size() == 1 ? "" : "s");
        for (size_t i = 0; i < publisher_options.ros2_transforms.size(); ++i) {
            const auto& t = publisher_options.ros2_transforms[i];
            std::printf("%s%s in %s", i ? ", " : "", t.child.c_str(), t.parent.c_str());
        }
        std::printf(")\n");
    }
    StatusLine status;
    const int64_t t0 = monotonicNowNs();
    std::vector<uint64_t> last_written(dds->stats().size(), 0);
    int64_t last_tick = t0;
    for (;;) {
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
        const int64_t now = monotonicNowNs();
        const auto stats = dds->stats();
        bool all_ended = true;
        for (auto& watch : watches) {
            while (watch->tryPop()) {
            }
            all_ended = all_ended && watch->closed();
        }
        if (now - last_tick >= 500'000'000) {
            const double dt = static_cast<double>(now - last_tick) / 1e9;
            std::string line = formatDuration(now - t0);
            for (size_t i = 0; i < stats.size(); ++i) {
                char text[200];
                std::snprintf(text, sizeof text, " | %s %.1f fps, %d readers, %llu dropped",
                              stats[i].stream.c_str(),
                              static_cast<double>(stats[i].written - last_written[i]) / dt,
                              stats[i].matched_readers + stats[i].ros_matched_readers,
                              static_cast<unsigned long long>(stats[i].dropped));
                line += text;
                last_written[i] = stats[i].written;
            }
            status.update(line);
            last_tick = now;
        }
        if (interrupt.raised() || (options.duration_s > 0 && now - t0 >= options.duration_s * 1e9))
            break;
        if (all_ended) {
            // The publisher tells the readers once they have every frame; give it the time.
            std::this_thread::sleep_for(std::chrono::milliseconds(500));
            break;
        }
    }
    graph.stop();
    status.finish();
    for (const auto& s : dds->stats()) {
        std::printf("  %-24s %8llu written  %6llu dropped  %6llu refused by DDS  -> %s\n",
                    s.stream.c_str(), static_cast<unsigned long long>(s.written),
                    static_cast<unsigned long long>(s.dropped),
                    static_cast<unsigned long long>(s.write_errors), s.topic.c_str());
    }
    return interrupt.raised() ? interrupt.exitCode() : kExitOk;
}

}  // namespace

void registerPublishCommand(CLI::App& app, Commands& commands) {
    auto* sub = app.add_subcommand(
        "publish",
        "Open the devices of a rig file and publish their streams over DDS: other hosts receive "
        "them with the dds backend (a rig device with driver: dds), ROS 2 sees the images with "
        "--ros2. Runs until Ctrl-C or --duration. Binds loopback unless --address names an "
        "interface (docs/dds.md).");
    auto options = std::make_shared<PublishOptions>();
    sub->add_option("RIG", options->rig_path, "Rig description (YAML, see docs/rig-format.md)")
        ->required();
    sub->add_option("--streams", options->publisher.streams,
                    "Streams to publish, as device/stream (comma-separated; default: all)")
        ->delimiter(',');
    sub->add_option("--ros2", options->publisher.ros2_rig,
                    "Also publish image streams as ROS 2 topics rt/NAME/<stream>/image_raw "
                    "(sensor_msgs/msg/Image), with camera_info beside each calibrated one and the "
                    "rig's extrinsics on tf_static");
    sub->add_option("--calibration", options->calibration,
                    "With --ros2: the calibration file for camera_info and tf_static (any format "
                    "mixray imports; default: the files the rig names)")
        ->check(CLI::ExistingFile);
    sub->add_option("--duration", options->duration_s, "Stop after this many seconds")
        ->check(CLI::PositiveNumber);
    sub->add_option("--wait-readers", options->wait_readers,
                    "Start the devices only once every stream has this many mixray readers (a "
                    "finite source then loses no frame to discovery)")
        ->check(CLI::Range(1, 64));
    sub->add_option("--wait-timeout", options->wait_timeout_s,
                    "Give up waiting for --wait-readers after this many seconds")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    addDdsOptions(*sub, options->publisher.dds);
    commands.push_back({sub, [options] { return runPublish(*options); }});
}

}  // namespace mixray::cli
