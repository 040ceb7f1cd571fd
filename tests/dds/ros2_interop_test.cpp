// ROS 2 interoperability without ROS: Cyclone DDS, an independent DDS implementation, reads the
// ROS 2 topics a DdsPublisher writes, with C types its own idlc made from ROS 2's IDL.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <string>
#include <thread>

#include "dds/dds.h"
#include "mixray/dds/dds_publisher.h"
#include "mixray/graph/graph.h"
#include "sensor_msgs/msg/Image.h"

namespace mixray::dds {
namespace {

using namespace std::chrono_literals;

int testDomain() {
    return 1 + static_cast<int>(getpid() % 200);
}

// Cyclone on loopback alone, finding Fast DDS's participants by unicast as mixray's own do.
std::string cycloneLoopbackConfig() {
    return "<CycloneDDS><Domain id=\"any\"><General><Interfaces>"
           "<NetworkInterface address=\"127.0.0.1\"/></Interfaces>"
           "<AllowMulticast>false</AllowMulticast></General><Discovery>"
           "<ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>30"
           "</MaxAutoParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers>"
           "</Discovery></Domain></CycloneDDS>";
}

uint8_t pixel(size_t k, uint64_t i) {
    return static_cast<uint8_t>((k * 31 + i * 11 + (k >> 7)) & 0xff);
}

struct Case {
    PixelFormat format;
    StreamKind kind;
    const char* encoding;
    int bytes_per_pixel;
};

class Ros2Interop : public ::testing::TestWithParam<Case> {};

TEST_P(Ros2Interop, CycloneReceivesTheImagesByteForByte) {
    const Case c = GetParam();
    Graph graph;
    StreamInfo info;
    info.name = "cam/image";
    info.device = "cam";
    info.kind = c.kind;
    info.format = ImageDesc::packed(c.format, 640, 480);
    info.nominal_fps = 30;
    auto stream = addPooledStream(graph, info, 8);
    ASSERT_TRUE(stream.isOk());
    DdsPublisherOptions options;
    options.dds.domain = testDomain();
    options.dds.host = "hostA";
    options.dds.transport = DdsTransport::kUdp;
    options.ros2_rig = "testrig";
    auto publisher = DdsPublisher::create(options);
    ASSERT_TRUE(publisher.isOk());
    DdsPublisher* pub = publisher->get();
    ASSERT_TRUE(graph.addNode(std::move(*publisher)).isOk());
    ASSERT_TRUE(graph.start().isOk());

    const dds_domainid_t domain = static_cast<dds_domainid_t>(testDomain());
    const dds_entity_t cyclone_domain = dds_create_domain(domain, cycloneLoopbackConfig().c_str());
    ASSERT_GT(cyclone_domain, 0) << dds_strretcode(cyclone_domain);
    const dds_entity_t participant = dds_create_participant(domain, nullptr, nullptr);
    ASSERT_GT(participant, 0);
    const dds_entity_t topic = dds_create_topic(participant, &sensor_msgs_msg_dds__Image__desc,
                                                "rt/testrig/cam/image/image_raw", nullptr, nullptr);
    ASSERT_GT(topic, 0) << dds_strretcode(topic);
    // What rviz2 asks for by default: reliable, volatile, keep last.
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
    const dds_entity_t reader = dds_create_reader(participant, topic, qos, nullptr);
    dds_delete_qos(qos);
    ASSERT_GT(reader, 0);

    // Discovery is not symmetric in time: wait until each side has matched the other, or the
    // first frames go to a reader that does not know the writer yet (volatile: never resent).
    const auto until = std::chrono::steady_clock::now() + 15s;
    dds_subscription_matched_status_t cyclone_matched{};
    while (std::chrono::steady_clock::now() < until) {
        (void)dds_get_subscription_matched_status(reader, &cyclone_matched);
        if (pub->stats().at(0).ros_matched_readers > 0 && cyclone_matched.current_count > 0)
            break;
        std::this_thread::sleep_for(10ms);
    }
    ASSERT_GT(pub->stats().at(0).ros_matched_readers, 0) << "Cyclone's reader never matched";
    ASSERT_GT(cyclone_matched.current_count, 0u) << "Cyclone never matched mixray's writer";

    // Frame i's first byte is 11 i (i < 23): the reader knows which frame it got.
    const auto wall_before = std::chrono::system_clock::now();
    constexpr uint64_t kFrames = 5;
    uint64_t got = 0;
    uint64_t sent = 0;
    void* samples[1] = {nullptr};
    dds_sample_info_t sample_info[1];
    const auto deadline = std::chrono::steady_clock::now() + 15s;
    while (got < kFrames && std::chrono::steady_clock::now() < deadline) {
        if (sent < 23) {
            WritableFrame frame = stream->pool->acquire();
            ASSERT_TRUE(frame);
            for (size_t k = 0; k < info.format.bufferBytes(); ++k)
                frame.image().data[k] = pixel(k, sent);
            frame.meta().stream = stream->id;
            frame.meta().sequence = sent++;
            frame.meta().host_stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                             std::chrono::steady_clock::now().time_since_epoch())
                                             .count();
            graph.publish(std::move(frame).publish());
        }
        std::this_thread::sleep_for(40ms);
        const int n = dds_take(reader, samples, sample_info, 1, 1);
        if (n <= 0)
            continue;
        if (!sample_info[0].valid_data) {
            dds_return_loan(reader, samples, n);
            continue;
        }
        const auto* image = static_cast<const sensor_msgs_msg_dds__Image_*>(samples[0]);
        EXPECT_EQ(image->width, 640u);
        EXPECT_EQ(image->height, 480u);
        EXPECT_STREQ(image->encoding, c.encoding);
        EXPECT_EQ(image->step, 640u * c.bytes_per_pixel);
        EXPECT_EQ(image->is_bigendian, 0);
        EXPECT_STREQ(image->header.frame_id, "cam_image");
        // Stamped on the wall clock, as ROS time is.
        const auto stamp = std::chrono::system_clock::time_point(
            std::chrono::seconds(image->header.stamp.sec) +
            std::chrono::nanoseconds(image->header.stamp.nanosec));
        EXPECT_GT(stamp, wall_before - 1s);
        EXPECT_LT(stamp, std::chrono::system_clock::now() + 1s);
        ASSERT_EQ(image->data._length, info.format.bufferBytes());
        const uint64_t i = image->data._buffer[0] / 11u;
        size_t differing = 0;
        for (size_t k = 0; k < image->data._length; ++k)
            differing += image->data._buffer[k] != pixel(k, i);
        EXPECT_EQ(differing, 0u) << "image " << i;
        dds_return_loan(reader, samples, n);
        samples[0] = nullptr;
        ++got;
    }
    EXPECT_EQ(got, kFrames);
    dds_delete(cyclone_domain);
    graph.stop();
}

INSTANTIATE_TEST_SUITE_P(
    Formats, Ros2Interop,
    ::testing::Values(Case{PixelFormat::kRGB8, StreamKind::kColor, "rgb8", 3},
                      Case{PixelFormat::kDepth16, StreamKind::kDepth, "16UC1", 2},
                      Case{PixelFormat::kMono8, StreamKind::kMono, "mono8", 1}),
    [](const ::testing::TestParamInfo<Case>& param) {
        return std::string(param.param.encoding[0] == '1' ? "depth16" : param.param.encoding);
    });

}  // namespace
}  // namespace mixray::dds
