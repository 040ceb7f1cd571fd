// The graph over DDS on one machine: frames cross between two graphs bit for bit with their
// metadata, streams end, hosts leave and come back, and bad input is refused.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <thread>

#include "mixray/dds/dds_backend.h"
#include "mixray/dds/dds_publisher.h"
#include "mixray/dds/frame_message.h"
#include "mixray/dds/host_clock.h"
#include "mixray/graph/clock.h"
#include "mixray/graph/graph.h"
#include "proc_net.h"

namespace mixray::dds {
namespace {

using namespace std::chrono_literals;

// A domain of this test process alone, so tests running side by side never hear each other.
// Samples between its two graphs go over the wire, not Fast DDS's in-process shortcut.
int testDomain() {
    setIntraprocessDelivery(false);
    return 1 + static_cast<int>(getpid() % 200);
}

DdsOptions loopback(const std::string& host) {
    DdsOptions options;
    options.domain = testDomain();
    options.host = host;
    options.transport = DdsTransport::kUdp;
    return options;
}

StreamInfo colorStream() {
    StreamInfo info;
    info.name = "cam/color";
    info.device = "cam";
    info.kind = StreamKind::kColor;
    info.format = ImageDesc::packed(PixelFormat::kRGB8, 640, 480);
    info.nominal_fps = 30;
    info.clock_domain = deviceClockDomain("test", "cam");
    info.tags["model"] = "test camera";
    return info;
}

// Frame i's pixels: every byte depends on its position and i.
void fill(MutableImageView image, uint64_t i) {
    const size_t bytes = image.desc.bufferBytes();
    for (size_t k = 0; k < bytes; ++k)
        image.data[k] = static_cast<uint8_t>((k * 131 + i * 7 + (k >> 9)) & 0xff);
}

FrameMetadata metaOf(uint64_t i, StreamId stream, ClockDomainId domain) {
    FrameMetadata meta;
    meta.stream = stream;
    meta.sequence = 100 + i;
    meta.device_stamp_ns = 5'000'000'000 + static_cast<int64_t>(i) * 33'333'333;
    meta.host_stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                             std::chrono::steady_clock::now().time_since_epoch())
                             .count();
    meta.clock_domain = domain;
    meta.exposure_us = 1000 + static_cast<int64_t>(i);
    meta.status = i % 5 == 3 ? FrameStatus::kIncomplete : FrameStatus::kOk;
    return meta;
}

TEST(DdsFrame, SerializedFramesReadBackExactlyAndMisfitsAreRefused) {
    const StreamInfo stream = colorStream();
    Image image(stream.format);
    fill(image.mutableView(), 3);
    const FrameMetadata meta = metaOf(3, 0, stream.clock_domain);
    const std::vector<uint8_t> bytes = serializeFrame(meta, image.view());

    FrameMetadata back;
    Image back_image;
    ASSERT_TRUE(deserializeFrame(bytes, stream, &back, &back_image).isOk());
    EXPECT_TRUE(sameImage(back_image.view(), image.view()));
    EXPECT_EQ(back.sequence, meta.sequence);
    EXPECT_EQ(back.device_stamp_ns, meta.device_stamp_ns);
    EXPECT_EQ(back.host_stamp_ns, meta.host_stamp_ns);
    EXPECT_EQ(back.clock_domain, meta.clock_domain);
    EXPECT_EQ(back.exposure_us, meta.exposure_us);
    EXPECT_EQ(back.status, meta.status);

    // Truncated anywhere: refused, never a crash.
    for (size_t cut : {size_t{0}, size_t{3}, size_t{20}, bytes.size() / 2, bytes.size() - 1}) {
        const Status status =
            deserializeFrame(std::span(bytes.data(), cut), stream, &back, &back_image);
        EXPECT_EQ(status.code(), ErrorCode::kCorruptData) << cut;
    }
    // A frame of another layout than the stream's.
    StreamInfo mono = stream;
    mono.format = ImageDesc::packed(PixelFormat::kMono8, 640, 480);
    const Status wrong_format = deserializeFrame(bytes, mono, &back, &back_image);
    EXPECT_EQ(wrong_format.code(), ErrorCode::kCorruptData);
    EXPECT_NE(wrong_format.message().find("rgb8"), std::string::npos) << wrong_format.toString();
    StreamInfo small = stream;
    small.format = ImageDesc::packed(PixelFormat::kRGB8, 320, 240);
    EXPECT_EQ(deserializeFrame(bytes, small, &back, &back_image).code(), ErrorCode::kCorruptData);
}

// A clock answer as the hosts send it: every field back, the wall clock's included; names
// holding a NUL (which fastcdr would drop on the way back out) refused.
TEST(DdsTimeExchange, AnswersReadBackExactlyAndNamesWithANulAreRefused) {
    const TimeExchange answer{.requester = "hostC/123/left/0",
                              .responder = "hostA",
                              .sequence = 7,
                              .t1_ns = 5'000'000'000,
                              .t2_ns = 1'005'000'040'000,
                              .t3_ns = 1'005'000'050'000,
                              .protocol = kProtocolVersion,
                              .realtime_minus_monotonic_ns = 1'795'000'000'000'000'000,
                              .ptp_locked = true,
                              .ptp_grandmaster = "9ef2f2.fffe.4fa318"};
    const Result<TimeExchange> back = deserializeTimeExchange(serializeTimeExchange(answer));
    ASSERT_TRUE(back) << back.status().toString();
    EXPECT_EQ(back->requester, answer.requester);
    EXPECT_EQ(back->responder, answer.responder);
    EXPECT_EQ(back->sequence, answer.sequence);
    EXPECT_EQ(back->t1_ns, answer.t1_ns);
    EXPECT_EQ(back->t2_ns, answer.t2_ns);
    EXPECT_EQ(back->t3_ns, answer.t3_ns);
    EXPECT_EQ(back->protocol, answer.protocol);
    EXPECT_EQ(back->realtime_minus_monotonic_ns, answer.realtime_minus_monotonic_ns);
    EXPECT_EQ(back->ptp_locked, answer.ptp_locked);
    EXPECT_EQ(back->ptp_grandmaster, answer.ptp_grandmaster);

    // Sent by another implementation: fastcdr itself writes a string only up to its NUL.
    TimeExchange marked = answer;
    marked.ptp_grandmaster = "9ef2f2#fffe.4fa318";
    std::vector<uint8_t> bytes = serializeTimeExchange(marked);
    const auto mark = std::find(bytes.begin(), bytes.end(), uint8_t{'#'});
    ASSERT_NE(mark, bytes.end());
    *mark = 0;
    const Result<TimeExchange> refused = deserializeTimeExchange(bytes);
    ASSERT_FALSE(refused);
    EXPECT_EQ(refused.status().code(), ErrorCode::kCorruptData);
}

TEST(DdsOptionsTest, BadValuesAreNamed) {
    DdsOptions options;
    EXPECT_TRUE(options.validate().isOk());
    options.address = "localhost";
    EXPECT_NE(options.validate().message().find("address"), std::string::npos);
    options = {};
    options.domain = 233;
    EXPECT_NE(options.validate().message().find("domain"), std::string::npos);
    options = {};
    options.peers = {"10.0.0.300"};
    EXPECT_NE(options.validate().message().find("peers"), std::string::npos);

    DeviceConfig config{
        .name = "remote", .driver = "dds", .id = "a/cam", .options = {}, .streams = {}};
    config.options["transport"] = "tcp";
    DdsDeviceOptions device;
    const Status bad = parseDdsDeviceOptions(config, &device);
    EXPECT_NE(bad.message().find("transport"), std::string::npos) << bad.toString();
    config.options = {{"domian", "3"}};
    EXPECT_NE(parseDdsDeviceOptions(config, &device).message().find("domian"), std::string::npos);
    config.options = {{"domain", "7"}, {"peers", "10.0.0.2, 10.0.0.3"}, {"transport", "auto"}};
    ASSERT_TRUE(parseDdsDeviceOptions(config, &device).isOk());
    EXPECT_EQ(device.dds.domain, 7);
    EXPECT_EQ(device.dds.peers, (std::vector<std::string>{"10.0.0.2", "10.0.0.3"}));
}

// A graph publishing one stream as host `host`.
struct PublishingHost {
    Graph graph;
    PooledStream stream;
    DdsPublisher* publisher = nullptr;

    explicit PublishingHost(const std::string& host, StreamInfo info = colorStream())
        : PublishingHost(loopback(host), std::move(info)) {}
    explicit PublishingHost(const DdsOptions& dds, StreamInfo info = colorStream()) {
        auto pooled = addPooledStream(graph, info, 8);
        EXPECT_TRUE(pooled.isOk());
        stream = *pooled;
        DdsPublisherOptions options;
        options.dds = dds;
        options.ros2_rig = "testrig";
        auto made = DdsPublisher::create(options);
        EXPECT_TRUE(made.isOk());
        publisher = made->get();
        EXPECT_TRUE(graph.addNode(std::move(*made)).isOk());
        EXPECT_TRUE(graph.start().isOk());
    }

    void send(uint64_t i) {
        WritableFrame frame = stream.pool->acquire();
        ASSERT_TRUE(frame);
        fill(frame.image(), i);
        frame.meta() = metaOf(i, stream.id, graph.stream(stream.id).clock_domain);
        graph.publish(std::move(frame).publish());
    }
};

// Opens the remote device as `name` in `graph`, subscribed losslessly.
std::shared_ptr<FrameQueue> openRemote(Graph& graph, DdsDevice** device,
                                       const std::string& id = "hostA/cam",
                                       std::map<std::string, std::string> options = {}) {
    DdsBackend backend(loopback("hostB"));
    // Buffers for every frame a test sends before it reads them.
    options["buffers"] = "32";
    DeviceConfig config{
        .name = "remote", .driver = "dds", .id = id, .options = options, .streams = {}};
    auto opened = backend.open(config);
    EXPECT_TRUE(opened.isOk()) << opened.status().toString();
    if (!opened.isOk())
        return nullptr;
    *device = static_cast<DdsDevice*>(opened->get());
    EXPECT_TRUE(graph.addNode(std::move(*opened)).isOk());
    auto id_local = graph.findStream("remote/color");
    EXPECT_TRUE(id_local.has_value());
    auto queue = graph.subscribe(
        *id_local, {.capacity = 64, .policy = QueuePolicy::kLossless, .name = "test"});
    EXPECT_TRUE(queue.isOk());
    EXPECT_TRUE(graph.start().isOk());
    return *queue;
}

// Waits until the publisher's writer and the remote device's reader have matched each other
// (discovery is not symmetric in time, and frames sent before are not resent).
void waitMatched(const DdsPublisher& publisher, const DdsDevice& device) {
    const auto until = std::chrono::steady_clock::now() + 10s;
    while (std::chrono::steady_clock::now() < until) {
        if (publisher.stats().at(0).matched_readers > 0 && device.stats().at(0).matched_writers > 0)
            return;
        std::this_thread::sleep_for(10ms);
    }
    FAIL() << "the remote reader never matched";
}

TEST(DdsGraph, FramesCrossBitExactWithTheirMetadataAndTheStreamEnds) {
    PublishingHost a("hostA");
    Graph b;
    DdsDevice* device = nullptr;
    auto queue = openRemote(b, &device);
    ASSERT_TRUE(queue);
    const StreamInfo local = b.stream(*b.findStream("remote/color"));
    EXPECT_EQ(local.kind, StreamKind::kColor);
    EXPECT_EQ(local.format, colorStream().format);
    EXPECT_EQ(local.nominal_fps, 30);
    EXPECT_EQ(local.clock_domain, colorStream().clock_domain);
    EXPECT_EQ(local.tags.at("model"), "test camera");
    EXPECT_EQ(local.tags.at("dds.host"), "hostA");
    waitMatched(*a.publisher, *device);

    constexpr uint64_t kFrames = 24;
    std::vector<FrameMetadata> sent;
    for (uint64_t i = 0; i < kFrames; ++i) {
        a.send(i);
        sent.push_back(metaOf(i, 0, 0));
        std::this_thread::sleep_for(30ms);  // a 30 fps camera: the live edge keeps up
    }
    a.graph.endStream(a.stream.id);

    Image expected(colorStream().format);
    uint64_t got = 0;
    for (;;) {
        auto frame = queue->pop(10s);
        if (!frame)
            break;
        ASSERT_LT(got, kFrames);
        fill(expected.mutableView(), got);
        EXPECT_TRUE(sameImage(frame->image(), expected.view())) << "frame " << got;
        const FrameMetadata& meta = frame->meta();
        EXPECT_EQ(meta.sequence, 100 + got);
        EXPECT_EQ(meta.device_stamp_ns, sent[got].device_stamp_ns);
        EXPECT_EQ(meta.clock_domain, colorStream().clock_domain);
        EXPECT_EQ(meta.exposure_us, sent[got].exposure_us);
        EXPECT_EQ(meta.status, sent[got].status);
        ++got;
    }
    EXPECT_EQ(got, kFrames) << "every frame arrives, then the stream ends";
    EXPECT_TRUE(queue->closed());
    EXPECT_EQ(device->state(), DeviceState::kEnded);
    const DdsReceiveStats stats = device->stats().at(0);
    EXPECT_EQ(stats.published, kFrames);
    EXPECT_EQ(stats.lost_in_transit, 0u);
    EXPECT_EQ(stats.rejected, 0u);
    b.stop();
    a.graph.stop();
}

TEST(DdsGraph, AHostThatLeavesIsReconnectingAndRejoins) {
    auto a = std::make_unique<PublishingHost>("hostA");
    Graph b;
    DdsDevice* device = nullptr;
    auto queue = openRemote(b, &device);
    ASSERT_TRUE(queue);
    waitMatched(*a->publisher, *device);
    a->send(0);
    ASSERT_TRUE(queue->pop(10s).has_value());
    EXPECT_EQ(device->state(), DeviceState::kStreaming);

    a.reset();  // the host leaves
    const auto until = std::chrono::steady_clock::now() + 10s;
    while (device->state() != DeviceState::kReconnecting &&
           std::chrono::steady_clock::now() < until)
        std::this_thread::sleep_for(20ms);
    EXPECT_EQ(device->state(), DeviceState::kReconnecting);
    EXPECT_EQ(device->disconnections(), 1u);

    PublishingHost back("hostA");  // and comes back
    waitMatched(*back.publisher, *device);
    back.send(1);
    auto frame = queue->pop(10s);
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->meta().sequence, 101u);
    EXPECT_EQ(device->state(), DeviceState::kStreaming);
    EXPECT_EQ(device->reconnections(), 1u);
    b.stop();
}

// One receiving host stops reading: its consumer never pops, so its graph soon holds every
// buffer of the stream's pool. The publisher never waits for it, another receiving host gets
// every frame, and the stalled one counts each frame it could not keep.
TEST(DdsGraph, ASubscriberThatStopsReadingSlowsNoOneAndCountsItsLosses) {
    PublishingHost a("hostA");
    Graph stalled;
    DdsDevice* stalled_device = nullptr;
    auto stalled_queue = openRemote(stalled, &stalled_device);
    Graph healthy;
    DdsDevice* healthy_device = nullptr;
    auto healthy_queue = openRemote(healthy, &healthy_device);
    ASSERT_TRUE(stalled_queue && healthy_queue);
    waitMatched(*a.publisher, *stalled_device);
    waitMatched(*a.publisher, *healthy_device);

    constexpr uint64_t kFrames = 40;
    uint64_t got = 0;
    std::thread reader([&] {
        while (healthy_queue->pop(5s))
            ++got;
    });
    // Pools of 32 buffers: the stalled host's graph keeps its first 32 frames; for the rest
    // its receive thread finds no buffer, drops and counts (it never blocks DDS).
    const auto start = std::chrono::steady_clock::now();
    for (uint64_t i = 0; i < kFrames; ++i) {
        a.send(i);
        std::this_thread::sleep_for(20ms);
    }
    const auto sending = std::chrono::steady_clock::now() - start;
    a.graph.endStream(a.stream.id);
    reader.join();
    EXPECT_EQ(got, kFrames) << "the healthy host gets every frame";
    EXPECT_LT(sending, 3s) << "the publisher never waited";
    const DdsStreamStats published = a.publisher->stats().at(0);
    EXPECT_EQ(published.dropped, 0u);
    EXPECT_EQ(published.written, kFrames);

    uint64_t stalled_got = 0;
    while (stalled_queue->pop(2s))
        ++stalled_got;
    const DdsReceiveStats stats = stalled_device->stats().at(0);
    EXPECT_LT(stalled_got, kFrames);
    EXPECT_EQ(stats.published + stats.pool_exhausted + stats.lost_in_transit, kFrames)
        << "every frame it did not get is counted: published " << stats.published
        << ", pool exhausted " << stats.pool_exhausted << ", lost " << stats.lost_in_transit;
    stalled.stop();
    healthy.stop();
}

TEST(DdsGraph, WithClockArrivalHostClockStampsBecomeTheRemoteHostsClockDomain) {
    StreamInfo info = colorStream();
    info.clock_domain = kHostClockDomain;
    PublishingHost a("hostA", info);
    Graph b;
    DdsDevice* device = nullptr;
    auto queue = openRemote(b, &device, "hostA/cam", {{"clock", "arrival"}});
    ASSERT_TRUE(queue);
    const StreamInfo local = b.stream(*b.findStream("remote/color"));
    EXPECT_EQ(local.clock_domain, deviceClockDomain("dds", "hostA"));
    EXPECT_FALSE(device->hostClock().has_value());
    EXPECT_EQ(device->clockReport(), "stamped on arrival (clock: arrival)");
    waitMatched(*a.publisher, *device);
    const auto before = std::chrono::steady_clock::now().time_since_epoch();
    a.send(0);
    auto frame = queue->pop(10s);
    ASSERT_TRUE(frame.has_value());
    // The sender's host stamp is the device stamp in the sender's clock; the host stamp is
    // this host's arrival.
    EXPECT_EQ(frame->meta().clock_domain, local.clock_domain);
    EXPECT_GE(frame->meta().host_stamp_ns,
              std::chrono::duration_cast<std::chrono::nanoseconds>(before).count());
    EXPECT_LE(frame->meta().device_stamp_ns, frame->meta().host_stamp_ns);
    b.stop();
}

// Both "hosts" share one clock here, so the fit must find no offset, and the stamps the sender
// gave come out where they were.
TEST(DdsGraph, HostClockStampsReachThisHostsClockThroughClockExchanges) {
    StreamInfo info = colorStream();
    info.clock_domain = kHostClockDomain;
    PublishingHost a("hostA", info);
    Graph b;
    DdsDevice* device = nullptr;
    auto queue = openRemote(b, &device);
    ASSERT_TRUE(queue);
    const StreamInfo local = b.stream(*b.findStream("remote/color"));
    EXPECT_EQ(local.clock_domain, kHostClockDomain);
    const std::optional<HostClockEstimate> clock = device->hostClock();
    ASSERT_TRUE(clock.has_value()) << device->clockReport();
    EXPECT_LT(std::abs(clock->offset_ns), 2'000'000) << clock->describe();
    EXPECT_GE(clock->used, HostClockEstimator::kMinUsed);
    // The offset is a few microseconds either side of zero (its sign is noise), so the report
    // is checked for its parts, and the figure above for its size.
    const std::string report = device->clockReport();
    EXPECT_EQ(report.rfind("hostA clock ", 0), 0u) << report;
    EXPECT_NE(report.find(" s, drift "), std::string::npos) << report;
    EXPECT_NE(report.find("exchanges)"), std::string::npos) << report;
    waitMatched(*a.publisher, *device);
    const auto now = [] {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(
                   std::chrono::steady_clock::now().time_since_epoch())
            .count();
    };
    const int64_t before = now();
    a.send(0);
    auto frame = queue->pop(10s);
    const int64_t after = now();
    ASSERT_TRUE(frame.has_value());
    EXPECT_EQ(frame->meta().clock_domain, kHostClockDomain);
    EXPECT_NEAR(static_cast<double>(frame->meta().device_stamp_ns),
                static_cast<double>(metaOf(0, 0, kHostClockDomain).device_stamp_ns), 2e6);
    // Stamped by the sender between `before` and `after`, give or take the fit's error.
    EXPECT_GE(frame->meta().host_stamp_ns, before - 2'000'000);
    EXPECT_LE(frame->meta().host_stamp_ns, after + 2'000'000);
    // The exchanges go on while the device runs.
    const size_t exchanges = clock->exchanges;
    std::this_thread::sleep_for(700ms);
    EXPECT_GT(device->hostClock()->exchanges, exchanges);
    b.stop();
}

// clock: wall on one clock: the offset is the difference of the two ends' realtime − monotonic
// readings, which one machine's clocks make zero to within the reads' own gap; the exchanges'
// fit is kept beside it as a check.
TEST(DdsGraph, WithClockWallTheOffsetComesFromTheWallClocks) {
    StreamInfo info = colorStream();
    info.clock_domain = kHostClockDomain;
    PublishingHost a("hostA", info);
    Graph b;
    DdsDevice* device = nullptr;
    auto queue = openRemote(b, &device, "hostA/cam", {{"clock", "wall"}});
    ASSERT_TRUE(queue);
    const std::optional<HostClockEstimate> clock = device->hostClock();
    ASSERT_TRUE(clock.has_value()) << device->clockReport();
    EXPECT_EQ(clock->wall_clocks, "clock: wall");
    EXPECT_LT(std::abs(clock->offset_ns), 100'000) << clock->describe();
    EXPECT_EQ(clock->drift_ppm, 0);
    EXPECT_LT(std::abs(clock->exchange_offset_ns), 2'000'000) << clock->describe();
    const std::string report = device->clockReport();
    EXPECT_EQ(report.rfind("hostA clock ", 0), 0u) << report;
    EXPECT_NE(report.find(" s from the wall clocks (clock: wall), exchanges' fit "),
              std::string::npos)
        << report;
    b.stop();
}

TEST(DdsBackendTest, UnknownDevicesAreNamedWithWhatWasHeard) {
    PublishingHost a("hostA");
    DdsBackend backend(loopback("hostB"));
    DeviceConfig config{
        .name = "remote", .driver = "dds", .id = "hostA/kinect", .options = {}, .streams = {}};
    config.options["discovery_timeout_ms"] = "1500";
    auto opened = backend.open(config);
    ASSERT_FALSE(opened.isOk());
    EXPECT_EQ(opened.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(opened.status().message().find("hostA:cam/color"), std::string::npos)
        << opened.status().toString();

    auto listed = backend.enumerate();
    ASSERT_TRUE(listed.isOk());
    ASSERT_EQ(listed->size(), 1u);
    EXPECT_EQ(listed->at(0).id, "hostA/cam");
    EXPECT_EQ(listed->at(0).modes.at(0), "color 640x480@30 rgb8");
}

// Fast DDS would number a process's participants on and on, past the ids its peers' discovery
// reaches; mixray gives each the lowest free one, so a process that has made and closed a
// hundred still finds and is found.
TEST(DdsBackendTest, AProcessThatMadeAHundredParticipantsIsStillFound) {
    DdsBackend backend(loopback("hostB"));
    DeviceConfig config{
        .name = "remote", .driver = "dds", .id = "nobody/cam", .options = {}, .streams = {}};
    config.options["discovery_timeout_ms"] = "0";
    for (int i = 0; i < 100; ++i)
        ASSERT_EQ(backend.open(config).status().code(), ErrorCode::kNotFound) << i;
    PublishingHost a("hostA");
    auto listed = backend.enumerate();
    ASSERT_TRUE(listed.isOk());
    ASSERT_EQ(listed->size(), 1u) << "the 101st participant hears the publisher";
    EXPECT_EQ(listed->at(0).id, "hostA/cam");
}

// The local addresses ("a.b.c.d:port") of this process's UDP sockets.
std::vector<std::string> udpSocketsOfThisProcess() {
    const std::set<std::string> inodes = test::socketInodesOfThisProcess();
    std::vector<std::string> out;
    for (const test::Ipv4Socket& s : test::ipv4Sockets("/proc/net/udp"))
        if (inodes.count(s.inode))
            out.push_back(s.local_address + ":" + std::to_string(s.local_port));
    return out;
}

// Issue 31: the DDS transport exposes nothing by default. With the default options every UDP
// socket Fast DDS opens is bound to loopback (other hosts cannot even reach it), and a rig sees
// only the hosts of its domain and partition.
TEST(DdsExposure, DefaultsBindLoopbackOnlyAndOtherDomainsAndPartitionsHearNothing) {
    DdsOptions rig_a;  // the defaults a user gets, but for this test's own domain
    rig_a.domain = testDomain();
    rig_a.host = "hostA";
    rig_a.partition = "rig-a";
    PublishingHost a(rig_a);
    const std::vector<std::string> sockets = udpSocketsOfThisProcess();
    ASSERT_FALSE(sockets.empty()) << "Fast DDS opened no UDP socket";
    for (const std::string& socket : sockets)
        EXPECT_TRUE(socket.starts_with("127.0.0.1:")) << "a UDP socket on " << socket;

    DdsOptions same = rig_a;
    same.host = "hostB";
    DdsBackend same_rig(same);
    auto heard = same_rig.enumerate();
    ASSERT_TRUE(heard.isOk()) << heard.status().toString();
    ASSERT_EQ(heard->size(), 1u) << "the same domain and partition hear the publisher";
    EXPECT_EQ(heard->at(0).id, "hostA/cam");

    DdsOptions other_partition = same;
    other_partition.host = "hostC";
    other_partition.partition = "rig-b";
    DdsOptions default_partition = same;
    default_partition.host = "hostD";
    default_partition.partition = "";
    DdsOptions other_domain = same;
    other_domain.host = "hostE";
    other_domain.domain = rig_a.domain + 1;
    for (const DdsOptions& o : {other_partition, default_partition, other_domain}) {
        SCOPED_TRACE(o.host + " in domain " + std::to_string(o.domain) + ", partition '" +
                     o.partition + "'");
        DdsBackend backend(o);
        auto listed = backend.enumerate();
        ASSERT_TRUE(listed.isOk()) << listed.status().toString();
        EXPECT_TRUE(listed->empty()) << listed->at(0).id;
    }
}

}  // namespace
}  // namespace mixray::dds
