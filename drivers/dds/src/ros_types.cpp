#include "mixray/dds/ros_types.h"

#include <openssl/evp.h>

#include <array>
#include <set>
#include <vector>

namespace mixray::dds {
namespace {

// type_description_interfaces/msg/FieldType.msg: the ids of the field types mixray's messages
// use, and the offsets that make an element type an array or an unbounded sequence of it.
constexpr int kNestedType = 1;
constexpr int kUint8 = 3;
constexpr int kInt32 = 6;
constexpr int kUint32 = 7;
constexpr int kDouble = 11;
constexpr int kBoolean = 15;
constexpr int kString = 17;
constexpr int kArray = 48;
constexpr int kUnboundedSequence = 144;

struct Field {
    Field(std::string_view field_name, int id, int array_length = 0, std::string_view nested = {})
        : name(field_name), type_id(id), capacity(array_length), nested_type(nested) {}
    std::string_view name;
    int type_id;
    int capacity;                  // an array's length
    std::string_view nested_type;  // a message type's name
};

struct Type {
    std::string_view name;
    std::vector<Field> fields;
};

// The messages as ROS 2 defines them (common_interfaces, rcl_interfaces, geometry2), field by
// field in their order: the same definitions as drivers/dds/idl. The tests check every hash
// against the one ROS 2's own generator gives.
const std::vector<Type>& knownTypes() {
    static const std::vector<Type> types = {
        {"builtin_interfaces/msg/Time", {{"sec", kInt32}, {"nanosec", kUint32}}},
        {"std_msgs/msg/Header",
         {{"stamp", kNestedType, 0, "builtin_interfaces/msg/Time"}, {"frame_id", kString}}},
        {"sensor_msgs/msg/Image",
         {{"header", kNestedType, 0, "std_msgs/msg/Header"},
          {"height", kUint32},
          {"width", kUint32},
          {"encoding", kString},
          {"is_bigendian", kUint8},
          {"step", kUint32},
          {"data", kUint8 + kUnboundedSequence}}},
        {"sensor_msgs/msg/RegionOfInterest",
         {{"x_offset", kUint32},
          {"y_offset", kUint32},
          {"height", kUint32},
          {"width", kUint32},
          {"do_rectify", kBoolean}}},
        {"sensor_msgs/msg/CameraInfo",
         {{"header", kNestedType, 0, "std_msgs/msg/Header"},
          {"height", kUint32},
          {"width", kUint32},
          {"distortion_model", kString},
          {"d", kDouble + kUnboundedSequence},
          {"k", kDouble + kArray, 9},
          {"r", kDouble + kArray, 9},
          {"p", kDouble + kArray, 12},
          {"binning_x", kUint32},
          {"binning_y", kUint32},
          {"roi", kNestedType, 0, "sensor_msgs/msg/RegionOfInterest"}}},
        {"geometry_msgs/msg/Vector3", {{"x", kDouble}, {"y", kDouble}, {"z", kDouble}}},
        {"geometry_msgs/msg/Quaternion",
         {{"x", kDouble}, {"y", kDouble}, {"z", kDouble}, {"w", kDouble}}},
        {"geometry_msgs/msg/Transform",
         {{"translation", kNestedType, 0, "geometry_msgs/msg/Vector3"},
          {"rotation", kNestedType, 0, "geometry_msgs/msg/Quaternion"}}},
        {"geometry_msgs/msg/TransformStamped",
         {{"header", kNestedType, 0, "std_msgs/msg/Header"},
          {"child_frame_id", kString},
          {"transform", kNestedType, 0, "geometry_msgs/msg/Transform"}}},
        {"tf2_msgs/msg/TFMessage",
         {{"transforms", kNestedType + kUnboundedSequence, 0,
           "geometry_msgs/msg/TransformStamped"}}},
    };
    return types;
}

const Type* findType(std::string_view name) {
    for (const Type& type : knownTypes()) {
        if (type.name == name)
            return &type;
    }
    return nullptr;
}

// One type as Python's json.dumps(..., separators=(', ', ': ')) writes the dict that
// rosidl_generator_type_description hashes (default values removed). The names are
// identifiers, so nothing needs escaping.
std::string individualJson(const Type& type) {
    std::string out = "{\"type_name\": \"" + std::string(type.name) + "\", \"fields\": [";
    for (size_t i = 0; i < type.fields.size(); ++i) {
        const Field& f = type.fields[i];
        if (i > 0)
            out += ", ";
        out += "{\"name\": \"" + std::string(f.name) +
               "\", \"type\": {\"type_id\": " + std::to_string(f.type_id) +
               ", \"capacity\": " + std::to_string(f.capacity) +
               ", \"string_capacity\": 0, \"nested_type_name\": \"" + std::string(f.nested_type) +
               "\"}}";
    }
    return out + "]}";
}

// The types `type_name` references, directly or not, sorted by name: kNotFound for an unknown
// type_name.
Result<std::set<std::string_view>> referencedTypes(std::string_view type_name) {
    const Type* top = findType(type_name);
    if (!top) {
        return Status(ErrorCode::kNotFound,
                      "no ROS 2 type description for '" + std::string(type_name) + "'");
    }
    std::set<std::string_view> referenced;
    std::vector<const Type*> pending = {top};
    while (!pending.empty()) {
        const Type* type = pending.back();
        pending.pop_back();
        for (const Field& f : type->fields) {
            if (f.nested_type.empty() || !referenced.insert(f.nested_type).second)
                continue;
            const Type* nested = findType(f.nested_type);
            if (!nested) {
                return Status(ErrorCode::kInternal,
                              "ROS 2 type " + std::string(type->name) + " references " +
                                  std::string(f.nested_type) + ", which has no description");
            }
            pending.push_back(nested);
        }
    }
    return referenced;
}

// "sensor_msgs/msg/Image" as .msg files name it: "sensor_msgs/Image".
std::string msgName(std::string_view type_name) {
    std::string name(type_name);
    if (const size_t at = name.find("/msg/"); at != std::string::npos)
        name.erase(at, 4);
    return name;
}

// One field in .msg syntax: "uint8[] data", "float64[9] k", "std_msgs/Header header".
std::string msgField(const Field& f) {
    int element = f.type_id;
    std::string suffix;
    if (element > kUnboundedSequence) {
        element -= kUnboundedSequence;
        suffix = "[]";
    } else if (element > kArray) {
        element -= kArray;
        suffix = "[" + std::to_string(f.capacity) + "]";
    }
    std::string type;
    switch (element) {
        case kNestedType:
            type = msgName(f.nested_type);
            break;
        case kUint8:
            type = "uint8";
            break;
        case kInt32:
            type = "int32";
            break;
        case kUint32:
            type = "uint32";
            break;
        case kDouble:
            type = "float64";
            break;
        case kBoolean:
            type = "bool";
            break;
        default:
            type = "string";
            break;
    }
    return type + suffix + " " + std::string(f.name);
}

std::string msgFields(const Type& type) {
    std::string out;
    for (const Field& f : type.fields)
        out += msgField(f) + "\n";
    return out;
}

}  // namespace

Result<std::string> rosTypeHash(std::string_view type_name) {
    auto referenced = referencedTypes(type_name);
    if (!referenced)
        return referenced.status();
    const Type* top = findType(type_name);
    std::string json =
        "{\"type_description\": " + individualJson(*top) + ", \"referenced_type_descriptions\": [";
    bool first = true;
    for (std::string_view name : *referenced) {
        json += (first ? "" : ", ") + individualJson(*findType(name));
        first = false;
    }
    json += "]}";

    std::array<unsigned char, 32> digest{};
    unsigned int size = 0;
    if (EVP_Digest(json.data(), json.size(), digest.data(), &size, EVP_sha256(), nullptr) != 1 ||
        size != digest.size()) {
        return Status(ErrorCode::kInternal, "SHA-256 failed (OpenSSL)");
    }
    static constexpr char kHex[] = "0123456789abcdef";
    std::string hash = "RIHS01_";
    for (unsigned char byte : digest) {
        hash += kHex[byte >> 4];
        hash += kHex[byte & 15];
    }
    return hash;
}

std::string rosTypeHashUserData(std::string_view hash) {
    return "typehash=" + std::string(hash) + ";";
}

Result<std::string> rosMessageDefinition(std::string_view type_name) {
    auto referenced = referencedTypes(type_name);
    if (!referenced)
        return referenced.status();
    std::string text = msgFields(*findType(type_name));
    for (std::string_view name : *referenced)
        text +=
            std::string(80, '=') + "\nMSG: " + msgName(name) + "\n" + msgFields(*findType(name));
    return text;
}

}  // namespace mixray::dds
