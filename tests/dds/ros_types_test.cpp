// ROS 2 type descriptions (mixray/dds/ros_types.h): hashes against the ones ROS 2's own generator
// (rosidl_generator_type_description) gives for the same messages, as its generated C code
// records them (ROS 2 Kilted's sensor_msgs, geometry_msgs, tf2_msgs, std_msgs and
// builtin_interfaces).
#include "mixray/dds/ros_types.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace mixray::dds {
namespace {

TEST(RosTypeHash, EveryTypeHashesAsRos2HashesIt) {
    const std::vector<std::pair<std::string, std::string>> ros2 = {
        {"builtin_interfaces/msg/Time",
         "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197"},
        {"std_msgs/msg/Header",
         "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01"},
        {"sensor_msgs/msg/Image",
         "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47"},
        {"sensor_msgs/msg/RegionOfInterest",
         "RIHS01_ad16bcba5f9131dcdba6fbded19f726f5440e3c513b4fb586dd3027eeed8abb1"},
        {"sensor_msgs/msg/CameraInfo",
         "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275"},
        {"geometry_msgs/msg/Vector3",
         "RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d"},
        {"geometry_msgs/msg/Quaternion",
         "RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684"},
        {"geometry_msgs/msg/Transform",
         "RIHS01_beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc"},
        {"geometry_msgs/msg/TransformStamped",
         "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206"},
        {"tf2_msgs/msg/TFMessage",
         "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"},
    };
    for (const auto& [type, expected] : ros2) {
        auto hash = rosTypeHash(type);
        ASSERT_TRUE(hash.isOk()) << type << ": " << hash.status().toString();
        EXPECT_EQ(*hash, expected) << type;
    }
}

TEST(RosTypeHash, AnUnknownTypeIsNotFoundAndTheUserDataIsRos2s) {
    auto unknown = rosTypeHash("sensor_msgs/msg/PointCloud2");
    ASSERT_FALSE(unknown.isOk());
    EXPECT_EQ(unknown.status().code(), ErrorCode::kNotFound);
    EXPECT_NE(unknown.status().message().find("PointCloud2"), std::string::npos);
    EXPECT_EQ(rosTypeHashUserData("RIHS01_ab"), "typehash=RIHS01_ab;");
}

// The schema MCAP files carry (rosbag2's "ros2msg"): the type's fields in .msg syntax, then each
// type it references. Foxglove's parser reads it back in tests/dds/mcap_export_test.cpp.
TEST(RosMessageDefinition, IsTheMsgTextWithEveryReferencedType) {
    const std::string separator(80, '=');
    EXPECT_EQ(rosMessageDefinition("sensor_msgs/msg/Image").value(),
              "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
              "uint8 is_bigendian\nuint32 step\nuint8[] data\n" +
                  separator + "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n" +
                  separator +
                  "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n");
    const std::string camera_info = rosMessageDefinition("sensor_msgs/msg/CameraInfo").value();
    EXPECT_NE(camera_info.find("\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\n"),
              std::string::npos)
        << camera_info;
    EXPECT_NE(camera_info.find("sensor_msgs/RegionOfInterest roi\n"), std::string::npos);
    EXPECT_NE(camera_info.find("MSG: sensor_msgs/RegionOfInterest\n"), std::string::npos);
    EXPECT_NE(camera_info.find("bool do_rectify\n"), std::string::npos);
    EXPECT_EQ(rosMessageDefinition("tf2_msgs/msg/TFMessage").value().substr(0, 43),
              "geometry_msgs/TransformStamped[] transforms");
    EXPECT_EQ(rosMessageDefinition("nav_msgs/msg/Odometry").status().code(), ErrorCode::kNotFound);
}

}  // namespace
}  // namespace mixray::dds
