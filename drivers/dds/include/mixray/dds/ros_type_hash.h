// ROS 2 type hashes (REP-2011, "RIHS01"): the SHA-256 of a message type's description, which
// ROS 2 releases from Iron on put in every reader's and writer's USER_DATA
// ("typehash=RIHS01_<hex>;") and check against their own. Without it they warn and still
// match; with a wrong one they refuse to.
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

}  // namespace mixray::dds
