// ROS 2 interoperability without ROS: Cyclone DDS, an independent DDS implementation, reads the
// ROS 2 topics a DdsPublisher writes, with C types its own idlc made from ROS 2's IDL.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "dds/dds.h"
#include "mixray/dds/dds_publisher.h"
#include "mixray/dds/ros2_source.h"
#include "mixray/dds/ros_types.h"
#include "mixray/graph/graph.h"
#include "mixray/graph/pose.h"
#include "sensor_msgs/msg/CameraInfo.h"
#include "sensor_msgs/msg/Image.h"
#include "tf2_msgs/msg/TFMessage.h"

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

// A Cyclone DDS participant in the test's domain, on loopback; deleted with it.
class Cyclone {
public:
    Cyclone()
        : domain_(dds_create_domain(static_cast<dds_domainid_t>(testDomain()),
                                    cycloneLoopbackConfig().c_str())),
          participant_(dds_create_participant(static_cast<dds_domainid_t>(testDomain()), nullptr,
                                              nullptr)) {}
    ~Cyclone() {
        if (domain_ > 0)
            dds_delete(domain_);
    }
    Cyclone(const Cyclone&) = delete;
    Cyclone& operator=(const Cyclone&) = delete;

    bool ok() const { return domain_ > 0 && participant_ > 0; }
    // A reader of `topic` with rviz2's default QoS (reliable, keep last 10) and `durability`;
    // a negative return code when it cannot be made.
    dds_entity_t reader(const dds_topic_descriptor_t* type, const char* topic,
                        dds_durability_kind_t durability = DDS_DURABILITY_VOLATILE) const {
        const dds_entity_t made = dds_create_topic(participant_, type, topic, nullptr, nullptr);
        if (made < 0)
            return made;
        dds_qos_t* qos = dds_create_qos();
        dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
        dds_qset_durability(qos, durability);
        dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 10);
        const dds_entity_t reader = dds_create_reader(participant_, made, qos, nullptr);
        dds_delete_qos(qos);
        return reader;
    }

    // A writer of `topic` as a ROS 2 camera driver makes one: reliable (which best-effort
    // readers match too), keep last 4.
    dds_entity_t writer(const dds_topic_descriptor_t* type, const char* topic) const {
        const dds_entity_t made = dds_create_topic(participant_, type, topic, nullptr, nullptr);
        if (made < 0)
            return made;
        dds_qos_t* qos = dds_create_qos();
        dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
        dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 4);
        const dds_entity_t writer = dds_create_writer(participant_, made, qos, nullptr);
        dds_delete_qos(qos);
        return writer;
    }

private:
    dds_entity_t domain_;
    dds_entity_t participant_;
};

// A publisher as host "hostA" on loopback UDP in the test's domain, its ROS 2 topics under
// `rig`.
DdsPublisherOptions rosPublisher(const std::string& rig) {
    DdsPublisherOptions options;
    options.dds.domain = testDomain();
    options.dds.host = "hostA";
    options.dds.transport = DdsTransport::kUdp;
    options.ros2_rig = rig;
    return options;
}

// Adds a publisher of `options` to `graph` and starts the graph; nullptr when either fails.
DdsPublisher* startPublishing(Graph& graph, const DdsPublisherOptions& options) {
    auto publisher = DdsPublisher::create(options);
    if (!publisher)
        return nullptr;
    DdsPublisher* pub = publisher->get();
    if (!graph.addNode(std::move(*publisher)).isOk() || !graph.start().isOk())
        return nullptr;
    return pub;
}

// A 30 fps image stream `device`/`stream` of `format` at width x height.
StreamInfo imageStream(const std::string& device, const std::string& stream, StreamKind kind,
                       PixelFormat format, int width, int height) {
    StreamInfo info;
    info.name = device + "/" + stream;
    info.device = device;
    info.kind = kind;
    info.format = ImageDesc::packed(format, width, height);
    info.nominal_fps = 30;
    return info;
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
    const StreamInfo info = imageStream("cam", "image", c.kind, c.format, 640, 480);
    auto stream = addPooledStream(graph, info, 8);
    ASSERT_TRUE(stream.isOk());
    DdsPublisherOptions options = rosPublisher("testrig");
    DdsPublisher* pub = startPublishing(graph, options);
    ASSERT_NE(pub, nullptr);

    const Cyclone cyclone;
    ASSERT_TRUE(cyclone.ok());
    const dds_entity_t reader =
        cyclone.reader(&sensor_msgs_msg_dds__Image__desc, "rt/testrig/cam/image/image_raw");
    ASSERT_GT(reader, 0) << dds_strretcode(reader);

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

// The USER_DATA of the writer a Cyclone reader matched, as text ("" when it has none).
std::string matchedWriterUserData(dds_entity_t reader) {
    dds_instance_handle_t writers[4];
    const dds_return_t n = dds_get_matched_publications(reader, writers, 4);
    if (n < 1)
        return "";
    dds_builtintopic_endpoint_t* endpoint = dds_get_matched_publication_data(reader, writers[0]);
    if (!endpoint)
        return "";
    void* value = nullptr;
    size_t size = 0;
    std::string text;
    if (dds_qget_userdata(endpoint->qos, &value, &size) && value)
        text.assign(static_cast<const char*>(value), size);
    dds_free(value);
    dds_builtintopic_free_endpoint(endpoint);
    return text;
}

// A calibrated rig as ROS 2 tools see it: every image comes with its camera_info (the same
// header), the extrinsics are on tf_static for a reader that joins after they were written,
// and every writer carries the type hash newer ROS 2 releases check.
TEST(Ros2Calibration, CycloneReadsCameraInfoTfStaticAndTheTypeHashes) {
    Graph graph;
    auto stream = addPooledStream(
        graph, imageStream("kinect", "color", StreamKind::kColor, PixelFormat::kRGB8, 640, 480), 8);
    ASSERT_TRUE(stream.isOk());

    calibration::RosCameraInfo camera;
    camera.width = 640;
    camera.height = 480;
    camera.distortion_model = "plumb_bob";
    camera.d = {0.1, -0.2, 1e-3, -2e-3, 0.05};
    camera.k = {525.5, 0, 319.25, 0, 526.5, 241.75, 0, 0, 1};
    camera.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    camera.p = {525.5, 0, 319.25, 0, 0, 526.5, 241.75, 0, 0, 0, 1, 0};
    DdsPublisherOptions options = rosPublisher("studio");
    options.ros2_camera_info["kinect/color"] = camera;
    options.ros2_transforms = {{.parent = "world",
                                .child = "kinect/color",
                                .translation = {0.5, -0.25, 1.5},
                                .rotation_xyzw = {0, 0, 0.6, 0.8}},
                               {.parent = "kinect/color",
                                .child = "env/color",
                                .translation = {0.1, 0, 0},
                                .rotation_xyzw = {0, 0, 0, 1}}};
    DdsPublisher* pub = startPublishing(graph, options);
    ASSERT_NE(pub, nullptr);

    const Cyclone cyclone;
    ASSERT_TRUE(cyclone.ok());
    const dds_entity_t images =
        cyclone.reader(&sensor_msgs_msg_dds__Image__desc, "rt/studio/kinect/color/image_raw");
    const dds_entity_t infos = cyclone.reader(&sensor_msgs_msg_dds__CameraInfo__desc,
                                              "rt/studio/kinect/color/camera_info");
    // tf_static was written when the publisher connected, before this reader existed.
    const dds_entity_t tf_static = cyclone.reader(&tf2_msgs_msg_dds__TFMessage__desc,
                                                  "rt/tf_static", DDS_DURABILITY_TRANSIENT_LOCAL);
    ASSERT_GT(images, 0);
    ASSERT_GT(infos, 0);
    ASSERT_GT(tf_static, 0);

    const auto until = std::chrono::steady_clock::now() + 15s;
    dds_subscription_matched_status_t image_matched{}, info_matched{};
    while (std::chrono::steady_clock::now() < until) {
        (void)dds_get_subscription_matched_status(images, &image_matched);
        (void)dds_get_subscription_matched_status(infos, &info_matched);
        if (image_matched.current_count > 0 && info_matched.current_count > 0 &&
            pub->stats().at(0).ros_matched_readers > 0)
            break;
        std::this_thread::sleep_for(10ms);
    }
    ASSERT_GT(image_matched.current_count, 0u);
    ASSERT_GT(info_matched.current_count, 0u);
    std::this_thread::sleep_for(200ms);  // mixray's camera_info writer has matched too

    EXPECT_EQ(matchedWriterUserData(images),
              "typehash=" + rosTypeHash("sensor_msgs/msg/Image").value() + ";");
    EXPECT_EQ(matchedWriterUserData(infos),
              "typehash=RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275;");

    void* samples[1] = {nullptr};
    dds_sample_info_t sample_info[1];
    // The late tf_static reader gets the transforms DDS kept for it.
    bool got_tf = false;
    const auto tf_deadline = std::chrono::steady_clock::now() + 10s;
    while (!got_tf && std::chrono::steady_clock::now() < tf_deadline) {
        const int n = dds_take(tf_static, samples, sample_info, 1, 1);
        if (n <= 0) {
            std::this_thread::sleep_for(20ms);
            continue;
        }
        if (sample_info[0].valid_data) {
            const auto* tf = static_cast<const tf2_msgs_msg_dds__TFMessage_*>(samples[0]);
            ASSERT_EQ(tf->transforms._length, 2u);
            const auto& first = tf->transforms._buffer[0];
            EXPECT_STREQ(first.header.frame_id, "world");
            EXPECT_STREQ(first.child_frame_id, "kinect_color");
            EXPECT_EQ(first.transform.translation.x, 0.5);
            EXPECT_EQ(first.transform.translation.y, -0.25);
            EXPECT_EQ(first.transform.translation.z, 1.5);
            EXPECT_EQ(first.transform.rotation.z, 0.6);
            EXPECT_EQ(first.transform.rotation.w, 0.8);
            EXPECT_STREQ(tf->transforms._buffer[1].header.frame_id, "kinect_color");
            EXPECT_STREQ(tf->transforms._buffer[1].child_frame_id, "env_color");
            got_tf = true;
        }
        dds_return_loan(tf_static, samples, n);
        samples[0] = nullptr;
    }
    EXPECT_TRUE(got_tf) << "tf_static never reached a late reader";
    EXPECT_EQ(matchedWriterUserData(tf_static),
              "typehash=RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087;");

    // Each image's camera_info carries the calibration and the image's own header.
    int paired = 0;
    uint64_t sent = 0;
    std::vector<std::pair<int32_t, uint32_t>> image_stamps;
    std::vector<std::pair<int32_t, uint32_t>> info_stamps;
    const auto takeImages = [&] {
        for (;;) {
            const int n = dds_take(images, samples, sample_info, 1, 1);
            if (n <= 0)
                return;
            if (sample_info[0].valid_data) {
                const auto* image = static_cast<const sensor_msgs_msg_dds__Image_*>(samples[0]);
                image_stamps.emplace_back(image->header.stamp.sec, image->header.stamp.nanosec);
            }
            dds_return_loan(images, samples, n);
            samples[0] = nullptr;
        }
    };
    const auto deadline = std::chrono::steady_clock::now() + 15s;
    while ((paired < 3 || image_stamps.size() < 3) && std::chrono::steady_clock::now() < deadline) {
        if (sent < 20) {
            WritableFrame frame = stream->pool->acquire();
            ASSERT_TRUE(frame);
            frame.meta().stream = stream->id;
            frame.meta().sequence = sent++;
            frame.meta().host_stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                             std::chrono::steady_clock::now().time_since_epoch())
                                             .count();
            graph.publish(std::move(frame).publish());
        }
        std::this_thread::sleep_for(40ms);
        takeImages();
        const int n = dds_take(infos, samples, sample_info, 1, 1);
        if (n <= 0)
            continue;
        if (sample_info[0].valid_data) {
            const auto* got = static_cast<const sensor_msgs_msg_dds__CameraInfo_*>(samples[0]);
            EXPECT_EQ(got->width, 640u);
            EXPECT_EQ(got->height, 480u);
            EXPECT_STREQ(got->distortion_model, "plumb_bob");
            ASSERT_EQ(got->d._length, 5u);
            for (size_t i = 0; i < 5; ++i)
                EXPECT_EQ(got->d._buffer[i], camera.d[i]);
            for (size_t i = 0; i < 9; ++i) {
                EXPECT_EQ(got->k[i], camera.k[i]) << "k[" << i << "]";
                EXPECT_EQ(got->r[i], camera.r[i]) << "r[" << i << "]";
            }
            for (size_t i = 0; i < 12; ++i)
                EXPECT_EQ(got->p[i], camera.p[i]) << "p[" << i << "]";
            EXPECT_STREQ(got->header.frame_id, "kinect_color");
            info_stamps.emplace_back(got->header.stamp.sec, got->header.stamp.nanosec);
            ++paired;
        }
        dds_return_loan(infos, samples, n);
        samples[0] = nullptr;
    }
    EXPECT_GE(paired, 3);
    std::this_thread::sleep_for(200ms);
    takeImages();
    for (int n; (n = dds_take(infos, samples, sample_info, 1, 1)) > 0; samples[0] = nullptr) {
        if (sample_info[0].valid_data) {
            const auto* got = static_cast<const sensor_msgs_msg_dds__CameraInfo_*>(samples[0]);
            info_stamps.emplace_back(got->header.stamp.sec, got->header.stamp.nanosec);
        }
        dds_return_loan(infos, samples, n);
    }
    // Large images may be lost to a reader whose socket overflows (reliable, but the writer
    // keeps only the last two); the small camera_info messages all arrive. Every image that
    // came has its camera_info, stamped alike.
    ASSERT_GE(image_stamps.size(), 3u);
    for (const auto& stamp : image_stamps) {
        EXPECT_NE(std::find(info_stamps.begin(), info_stamps.end(), stamp), info_stamps.end())
            << "an image without its camera_info: " << stamp.first << " s " << stamp.second
            << " ns";
    }

    EXPECT_GE(pub->stats().at(0).ros_camera_info_written, 3u);
    graph.stop();
}

// Tracked poses (a kPose stream, as tracking/pose is in `mixray run`) go to ROS 2's tf: each
// valid pose as the camera's transform in its anchor's frame, stamped as its frame; stale and
// lost poses are not sent.
TEST(Ros2Calibration, ValidTrackedPosesGoToTf) {
    Graph graph;
    auto stream =
        addPooledStream(graph, makePoseStreamInfo("tracking/pose", "kinect/color", 30, false), 8);
    ASSERT_TRUE(stream.isOk());
    DdsPublisherOptions options = rosPublisher("studio");
    DdsPublisher* pub = startPublishing(graph, options);
    ASSERT_NE(pub, nullptr);
    const Cyclone cyclone;
    ASSERT_TRUE(cyclone.ok());
    const dds_entity_t tf = cyclone.reader(&tf2_msgs_msg_dds__TFMessage__desc, "rt/tf");
    ASSERT_GT(tf, 0) << dds_strretcode(tf);
    const auto until = std::chrono::steady_clock::now() + 15s;
    dds_subscription_matched_status_t matched{};
    while (std::chrono::steady_clock::now() < until) {
        (void)dds_get_subscription_matched_status(tf, &matched);
        if (matched.current_count > 0)
            break;
        std::this_thread::sleep_for(10ms);
    }
    ASSERT_GT(matched.current_count, 0u);
    std::this_thread::sleep_for(300ms);  // mixray's writer has matched Cyclone's reader too

    // Sent: a valid pose in the marker's frame, a lost one, then a valid one in the world's.
    const auto send = [&](uint64_t i, PoseStatus status, const std::string& anchor, int marker) {
        PoseRecord pose;
        pose.frame_sequence = i;
        pose.status = status;
        pose.anchor = anchor;
        pose.marker_id = marker;
        pose.translation = Eigen::Vector3d(0.1 * static_cast<double>(i + 1), -0.2, 1.5);
        pose.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()));
        if (status != PoseStatus::kValid)
            pose.reason = "marker 23 not seen";
        auto bytes = encodePoseRecord(pose);
        ASSERT_TRUE(bytes.isOk()) << bytes.status().toString();
        WritableFrame frame = stream->pool->acquire();
        ASSERT_TRUE(frame);
        std::memcpy(frame.image().data, bytes->data(), bytes->size());
        frame.setPayloadBytes(bytes->size());
        frame.meta().stream = stream->id;
        frame.meta().sequence = i;
        frame.meta().host_stamp_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                         std::chrono::steady_clock::now().time_since_epoch())
                                         .count();
        graph.publish(std::move(frame).publish());
        // Paced as a camera's: the publisher's live edge keeps the newest two.
        std::this_thread::sleep_for(50ms);
    };
    send(0, PoseStatus::kValid, "marker:23", 23);
    send(1, PoseStatus::kLost, "marker:23", 23);
    send(2, PoseStatus::kValid, "world", -1);

    std::vector<std::tuple<std::string, std::string, double, double>> got;
    void* samples[1] = {nullptr};
    dds_sample_info_t info[1];
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    while (got.size() < 2 && std::chrono::steady_clock::now() < deadline) {
        const int n = dds_take(tf, samples, info, 1, 1);
        if (n <= 0) {
            std::this_thread::sleep_for(20ms);
            continue;
        }
        if (info[0].valid_data) {
            const auto* message = static_cast<const tf2_msgs_msg_dds__TFMessage_*>(samples[0]);
            EXPECT_EQ(message->transforms._length, 1u);
            const auto& t = message->transforms._buffer[0];
            got.emplace_back(t.header.frame_id, t.child_frame_id, t.transform.translation.x,
                             t.transform.rotation.z);
        }
        dds_return_loan(tf, samples, n);
        samples[0] = nullptr;
    }
    std::this_thread::sleep_for(300ms);
    EXPECT_LE(dds_take(tf, samples, info, 1, 1), 0) << "the lost pose went to tf";
    ASSERT_EQ(got.size(), 2u);
    EXPECT_EQ(std::get<0>(got[0]), "marker_23");
    EXPECT_EQ(std::get<1>(got[0]), "kinect_color");
    EXPECT_DOUBLE_EQ(std::get<2>(got[0]), 0.1);
    EXPECT_NEAR(std::get<3>(got[0]), std::sin(0.15), 1e-12);
    EXPECT_EQ(std::get<0>(got[1]), "world");
    EXPECT_DOUBLE_EQ(std::get<2>(got[1]), 0.30000000000000004);
    graph.stop();
}

// A calibration must describe a published image stream of its size.
TEST(Ros2Calibration, ACalibrationOfAnotherSizeOrStreamIsRefused) {
    Graph graph;
    ASSERT_TRUE(addPooledStream(
                    graph,
                    imageStream("cam", "image", StreamKind::kMono, PixelFormat::kMono8, 1280, 960),
                    2)
                    .isOk());
    calibration::RosCameraInfo camera;
    camera.width = 640;
    camera.height = 480;

    DdsPublisherOptions no_rig;
    no_rig.ros2_camera_info["cam/image"] = camera;
    EXPECT_EQ(DdsPublisher::create(no_rig).status().code(), ErrorCode::kInvalidArgument);

    DdsPublisherOptions options;
    options.dds.domain = testDomain();
    options.ros2_rig = "studio";
    options.ros2_camera_info["cam/image"] = camera;
    auto sized = DdsPublisher::create(options);
    ASSERT_TRUE(sized.isOk());
    const Status wrong_size = (*sized)->connect(graph);
    EXPECT_EQ(wrong_size.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(wrong_size.message().find("1280x960"), std::string::npos) << wrong_size.message();

    options.ros2_camera_info.clear();
    options.ros2_camera_info["cam/other"] = camera;
    auto named = DdsPublisher::create(options);
    ASSERT_TRUE(named.isOk());
    EXPECT_EQ((*named)->connect(graph).code(), ErrorCode::kNotFound);
}

// The other way: a ROS 2 node's image topic (here Cyclone's writer, as rmw_cyclonedds would
// write it) as a mixray device. Every image arrives byte for byte, in order, numbered, with the
// publisher's header.stamp as its device stamp.
TEST(Ros2Source, AnImageTopicOfAnotherDdsIsAMixrayDeviceByteForByte) {
    const Cyclone cyclone;
    ASSERT_TRUE(cyclone.ok());
    const dds_entity_t writer =
        cyclone.writer(&sensor_msgs_msg_dds__Image__desc, "rt/robot/camera/image_raw");
    ASSERT_GT(writer, 0) << dds_strretcode(writer);
    // A 62x30 mono16 image whose rows are padded to 128 bytes, as some drivers pad them.
    constexpr uint32_t kWidth = 62, kHeight = 30, kStep = 128;
    std::atomic<bool> stop{false};
    std::atomic<int> written{0};
    std::thread publisher([&] {
        std::vector<uint8_t> data(kStep * kHeight);
        char encoding[] = "mono16";
        char frame_id[] = "robot_camera";
        for (int i = 0; !stop; ++i) {
            for (size_t k = 0; k < data.size(); ++k)
                data[k] = pixel(k, static_cast<uint64_t>(i));
            sensor_msgs_msg_dds__Image_ image{};
            image.header.stamp.sec = 1'700'000'000 + i;
            image.header.stamp.nanosec = 250'000'000;
            image.header.frame_id = frame_id;
            image.height = kHeight;
            image.width = kWidth;
            image.encoding = encoding;
            image.step = kStep;
            image.data._buffer = data.data();
            image.data._length = image.data._maximum = static_cast<uint32_t>(data.size());
            image.data._release = false;
            if (dds_write(writer, &image) == DDS_RETCODE_OK)
                ++written;
            std::this_thread::sleep_for(30ms);
        }
    });

    DeviceConfig config;
    config.name = "robot";
    config.driver = "ros2";
    config.id = "/robot/camera/image_raw";
    config.options = {{"domain", std::to_string(testDomain())},
                      {"transport", "udp"},
                      {"discovery_timeout_ms", "15000"}};
    Ros2Backend backend;
    auto opened = backend.open(config);
    ASSERT_TRUE(opened.isOk()) << opened.status().toString();
    auto* device = static_cast<Ros2ImageDevice*>(opened->get());
    Graph graph;
    ASSERT_TRUE(graph.addNode(std::move(*opened)).isOk());
    const auto id = graph.findStream("robot/image");
    ASSERT_TRUE(id);
    const StreamInfo& info = graph.stream(*id);
    EXPECT_EQ(info.kind, StreamKind::kMono);
    EXPECT_EQ(info.format.format, PixelFormat::kMono16);
    EXPECT_EQ(info.format.width, 62);
    EXPECT_EQ(info.format.height, 30);
    EXPECT_EQ(info.format.stride_bytes, 128);
    EXPECT_EQ(info.tags.at("ros2.frame_id"), "robot_camera");
    auto queue =
        graph.subscribe(*id, {.capacity = 16, .policy = QueuePolicy::kLossless, .name = "test"});
    ASSERT_TRUE(queue.isOk());
    ASSERT_TRUE(graph.start().isOk());

    std::vector<FrameRef> frames;
    const auto deadline = std::chrono::steady_clock::now() + 15s;
    while (frames.size() < 5 && std::chrono::steady_clock::now() < deadline) {
        if (auto frame = (*queue)->pop(100ms))
            frames.push_back(*frame);
    }
    stop = true;
    publisher.join();
    ASSERT_EQ(frames.size(), 5u);
    for (size_t n = 0; n < frames.size(); ++n) {
        const FrameRef& frame = frames[n];
        EXPECT_EQ(frame.meta().sequence, n);
        // Which image it was, from its stamp: the bytes must be that image's.
        const int64_t stamp = frame.meta().device_stamp_ns;
        const auto i = static_cast<uint64_t>(stamp / 1'000'000'000 - 1'700'000'000);
        EXPECT_EQ(stamp % 1'000'000'000, 250'000'000);
        EXPECT_EQ(frame.meta().clock_domain, info.clock_domain);
        EXPECT_NE(frame.meta().clock_domain, kHostClockDomain);
        size_t differing = 0;
        for (size_t k = 0; k < kStep * kHeight; ++k)
            differing += frame.image().data[k] != pixel(k, i);
        EXPECT_EQ(differing, 0u) << "image " << i;
        if (n > 0) {
            EXPECT_GT(stamp, frames[n - 1].meta().device_stamp_ns) << "out of order";
        }
    }
    EXPECT_EQ(device->stats().rejected, 0u);
    EXPECT_GE(device->stats().matched_writers, 1);
    EXPECT_EQ(device->state(), DeviceState::kStreaming);
    frames.clear();
    graph.stop();
}

// The conversion the device makes, on bytes (the fuzz target's seam): a padded mono16 image
// makes a mono16 stream of its stride, and comes back as a frame of it byte for byte.
TEST(Ros2Source, AnImageSampleMakesItsStreamAndFrame) {
    Image padded(
        ImageDesc{.format = PixelFormat::kMono16, .width = 5, .height = 3, .stride_bytes = 16});
    for (size_t k = 0; k < padded.bytes().size(); ++k)
        padded.bytes()[k] = static_cast<uint8_t>(k * 3);
    const auto sample = serializeRosImage(padded.view(), 1'700'000'000'250'000'000, "cam");
    auto stream = rosImageStream(sample, "robot", "/robot/image_raw");
    ASSERT_TRUE(stream.isOk()) << stream.status().toString();
    EXPECT_EQ(stream->name, "robot/image");
    EXPECT_EQ(stream->format, padded.desc());
    EXPECT_EQ(stream->kind, StreamKind::kMono);
    FrameMetadata meta;
    Image image;
    ASSERT_TRUE(rosImageFrame(sample, *stream, &meta, &image).isOk());
    EXPECT_EQ(meta.device_stamp_ns, 1'700'000'000'250'000'000);
    EXPECT_EQ(image.bytes(), padded.bytes());
    const std::vector<uint8_t> garbage{0, 1, 0, 0, 9, 9, 9};
    EXPECT_EQ(rosImageStream(garbage, "robot", "/t").status().code(), ErrorCode::kCorruptData);
}

TEST(Ros2Source, NoPublisherAnOddEncodingAndABadTopicAreSaid) {
    Ros2Backend backend;
    DeviceConfig config;
    config.name = "robot";
    config.driver = "ros2";
    config.options = {{"domain", std::to_string(testDomain())},
                      {"transport", "udp"},
                      {"discovery_timeout_ms", "300"}};
    config.id = "/nobody/image_raw";
    auto silent = backend.open(config);
    EXPECT_EQ(silent.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(silent.status().message().find("no image on /nobody/image_raw within 300 ms"),
              std::string::npos)
        << silent.status().message();

    config.id = "/camera/image-raw";
    EXPECT_EQ(backend.open(config).status().code(), ErrorCode::kInvalidArgument);

    const Cyclone cyclone;
    ASSERT_TRUE(cyclone.ok());
    const dds_entity_t writer = cyclone.writer(&sensor_msgs_msg_dds__Image__desc, "rt/float/image");
    ASSERT_GT(writer, 0);
    std::atomic<bool> stop{false};
    std::thread publisher([&] {
        std::vector<uint8_t> data(4 * 8 * 8);
        char encoding[] = "32FC1";
        char frame_id[] = "f";
        while (!stop) {
            sensor_msgs_msg_dds__Image_ image{};
            image.header.frame_id = frame_id;
            image.height = image.width = 8;
            image.encoding = encoding;
            image.step = 32;
            image.data._buffer = data.data();
            image.data._length = image.data._maximum = static_cast<uint32_t>(data.size());
            (void)dds_write(writer, &image);
            std::this_thread::sleep_for(30ms);
        }
    });
    config.id = "/float/image";
    config.options["discovery_timeout_ms"] = "15000";
    auto odd = backend.open(config);
    stop = true;
    publisher.join();
    EXPECT_EQ(odd.status().code(), ErrorCode::kUnsupported);
    EXPECT_NE(odd.status().message().find("32FC1"), std::string::npos) << odd.status().message();
}

}  // namespace
}  // namespace mixray::dds
