// The ROS 2 message types mixray writes, described once (their fields as ROS 2's definitions
// have them), for what ROS 2 tools need besides the IDL:
// - type hashes (REP-2011, "RIHS01"): the SHA-256 of a type's description, which ROS 2 releases
//   from Iron on put in every reader's and writer's USER_DATA ("typehash=RIHS01_<hex>;") and
//   check against their own. Without it they warn and still match; with a wrong one they
//   refuse to;
// - message definitions (.msg text), which MCAP files of the ros2 profile carry as schemas.
#pragma once

#include <string>
#include <string_view>

#include "mixray/graph/result.h"

namespace mixray::dds {

// The hash of a ROS 2 type mixray publishes or reads, by its ROS name
// ("sensor_msgs/msg/Image"), as "RIHS01_" and 64 lowercase hex digits: computed as
// rosidl_generator_type_description does (the type's fields and those of every type it
// references, as JSON, hashed with SHA-256). kNotFound for a type mixray does not know.
Result<std::string> rosTypeHash(std::string_view type_name);

// The USER_DATA that carries `hash` on an endpoint: "typehash=<hash>;".
std::string rosTypeHashUserData(std::string_view hash);

// The type's definition as rosbag2 stores it in MCAP (schema encoding "ros2msg"): its fields in
// .msg syntax, then each type it references after a line of 80 '=' and "MSG: pkg/Name".
// kNotFound for a type mixray does not know.
Result<std::string> rosMessageDefinition(std::string_view type_name);

}  // namespace mixray::dds
