// Rig file parsing: a cheap pre-scan, yaml-cpp (exceptions caught here), then a strict walk of
// the schema into plain structs, then cross-entry validation.
#include "mixray/graph/rig.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <span>
#include <variant>

#include "mixray/graph/field_errors.h"
#include "mixray/graph/yaml_reader.h"

namespace mixray {
namespace {

constexpr size_t kMaxNameLength = 64;
constexpr size_t kMaxCapacity = 4096;
constexpr int kMaxImageSide = 65535;
constexpr double kMaxFps = 10000;
constexpr double kMaxSkewMs = 10000;
constexpr std::string_view kModeSyntax = "WIDTHxHEIGHT@FPS like 640x480@30";
// Quaternions written by hand or printed by an IMU carry a few digits; a norm this close to 1
// is a rotation, anything further off is a mistake.
constexpr double kUnitQuaternionTolerance = 1e-3;

bool isUnitNorm(double norm) {
    return std::abs(norm - 1) <= kUnitQuaternionTolerance;
}

// Six significant digits, no trailing zeros: "0.001", "0.707107".
std::string formatNumber(double value) {
    std::array<char, 32> text{};
    std::snprintf(text.data(), text.size(), "%g", value);
    return text.data();
}

// ---------------------------------------------------------------------------------------------
// Messages

bool isNameChar(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-';
}

// Device, stream and driver names: they become parts of "device/stream" and option keys.
bool isValidName(std::string_view name) {
    return !name.empty() && name.size() <= kMaxNameLength &&
           std::all_of(name.begin(), name.end(), isNameChar);
}

bool isValidOptionKey(std::string_view key) {
    return !key.empty() && key.size() <= kMaxNameLength &&
           std::all_of(key.begin(), key.end(), [](char c) { return isNameChar(c) || c == '.'; });
}

std::vector<std::string_view> knownPixelFormats() {
    std::vector<std::string_view> names;
    for (int i = 1;; ++i) {
        auto name = toString(static_cast<PixelFormat>(i));
        if (name == toString(PixelFormat::kUnknown))
            break;
        names.push_back(name);
    }
    return names;
}

std::string unknownFormatMessage(std::string_view name) {
    auto known = knownPixelFormats();
    return "unknown pixel format " + quote(name) + " (known: " + joinNames(known) + ")";
}

// ---------------------------------------------------------------------------------------------
// Scalar syntax

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t'))
        s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t'))
        s.remove_suffix(1);
    return s;
}

// "640x480", "640x480@30", "640x480@29.97 rgb8".
struct StreamMode {
    int width = 0;
    int height = 0;
    std::optional<double> fps;
    std::optional<PixelFormat> format;
};

// Parses a stream mode; on failure returns the message (without location).
std::variant<StreamMode, std::string> parseStreamMode(std::string_view text) {
    const std::string syntax_error = "expected " + std::string(kModeSyntax) +
                                     " (fps and a pixel format after a space are "
                                     "optional), got " +
                                     quote(text);
    StreamMode mode;
    std::string_view rest = trim(text);
    std::string_view format_name;
    if (auto space = rest.find_first_of(" \t"); space != std::string_view::npos) {
        format_name = trim(rest.substr(space));
        rest = rest.substr(0, space);
    }
    const size_t x = rest.find('x');
    if (x == std::string_view::npos)
        return syntax_error;
    const size_t at = rest.find('@', x);
    const std::string_view width = rest.substr(0, x);
    const std::string_view height =
        rest.substr(x + 1, at == std::string_view::npos ? std::string_view::npos : at - x - 1);
    if (!yaml::parseWhole(width, mode.width) || !yaml::parseWhole(height, mode.height))
        return syntax_error;
    if (mode.width < 1 || mode.width > kMaxImageSide || mode.height < 1 ||
        mode.height > kMaxImageSide) {
        return "image size out of range (1 to " + std::to_string(kMaxImageSide) +
               " pixels a side), got " + quote(text);
    }
    if (at != std::string_view::npos) {
        double fps = 0;
        if (!yaml::parseWhole(rest.substr(at + 1), fps))
            return syntax_error;
        if (!(fps > 0 && fps <= kMaxFps)) {
            return "frame rate out of range (more than 0, at most " +
                   std::to_string(static_cast<int>(kMaxFps)) + "), got " + quote(text);
        }
        mode.fps = fps;
    }
    if (!format_name.empty()) {
        mode.format = pixelFormatFromString(format_name);
        if (!mode.format)
            return unknownFormatMessage(format_name);
    }
    return mode;
}

// ---------------------------------------------------------------------------------------------
// Schema walk

using yaml::Fields;
using yaml::find;
using yaml::Item;

// " (first at rig.yaml:3:5)", or nothing for entries built in code.
std::string firstAt(const SourceLocation& where) {
    const std::string text = where.toString();
    return text.empty() ? "" : " (first at " + text + ")";
}

// The rig schema walked with the strict reader's typed accessors (mixray/graph/yaml_reader.h).
class RigParser : private yaml::Reader {
public:
    RigParser(std::string file, std::filesystem::path base)
        : yaml::Reader(std::move(file)), base_(std::move(base)) {}

    Status parse(std::string_view text, RigDescription& rig);

private:
    Result<std::string> name(const Item& item) const;

    Status parseDevice(const Item& item, RigDescription& rig);
    Status parseStreams(const Item& item, RigDevice& device, RigDescription& rig);
    Status parseStreamSettings(const Fields& fields, const Item& item, RigStream& stream,
                               const std::string& device, RigDescription& rig);
    Status parseMode(const Item& item, RigDevice& device, bool streams_listed,
                     std::map<std::string, SourceLocation>& option_where);
    Status parseSync(const Item& item, RigDescription& rig);
    Status parseSite(const Item& item, RigDescription& rig);
    Result<RigCalibrationFile> calibrationFile(const Item& item, std::string device,
                                               std::string stream) const;

    std::filesystem::path base_;
};

Result<std::string> RigParser::name(const Item& item) const {
    if (!item.node.IsScalar() || !isValidName(item.node.Scalar())) {
        return expected(item, "a name of up to " + std::to_string(kMaxNameLength) +
                                  " letters, digits, '_' or '-'");
    }
    return item.node.Scalar();
}

Result<RigCalibrationFile> RigParser::calibrationFile(const Item& item, std::string device,
                                                      std::string stream) const {
    auto path = text(item);
    if (!path)
        return path.status();
    RigCalibrationFile file{std::move(device), std::move(stream), *path, {}, item.where};
    const std::filesystem::path written(*path);
    file.resolved =
        written.is_absolute() ? written.lexically_normal() : (base_ / written).lexically_normal();
    return file;
}

Status RigParser::parse(std::string_view source, RigDescription& rig) {
    auto loaded = load(source, kMaxRigFileBytes, kMaxRigNesting, "a rig file");
    if (!loaded)
        return loaded.status();
    const Item& root = *loaded;
    if (root.node.IsNull()) {
        return corrupt(root.where, "",
                       "the file is empty; expected a mapping with rig: and devices:");
    }
    static constexpr std::array<std::string_view, 6> kRootKeys = {
        "version", "rig", "devices", "sync", "calibration", "site"};
    auto fields = readMap(root, kRootKeys, "a mapping with rig: and devices: at the top");
    if (!fields)
        return fields.status();
    MIXRAY_RETURN_IF_ERROR(require(*fields, root, "rig"));
    MIXRAY_RETURN_IF_ERROR(require(*fields, root, "devices"));

    if (const Item* version = find(*fields, "version")) {
        auto v = integer(*version, 1, INT32_MAX);
        if (!v)
            return v.status();
        if (*v != 1) {
            return fail(*version, "unsupported rig format version " + std::to_string(*v) +
                                      "; this mixray reads version 1");
        }
        rig.version = static_cast<int>(*v);
    }
    auto rig_name = text(*find(*fields, "rig"));
    if (!rig_name)
        return rig_name.status();
    rig.name = *rig_name;

    const Item& devices = *find(*fields, "devices");
    if (!devices.node.IsSequence() || devices.node.size() == 0) {
        return expected(devices, "a list of at least one device");
    }
    size_t index = 0;
    for (const auto& node : devices.node) {
        MIXRAY_RETURN_IF_ERROR(parseDevice(element(devices, node, index++), rig));
    }
    if (const Item* calibration = find(*fields, "calibration")) {
        auto file = calibrationFile(*calibration, "", "");
        if (!file)
            return file.status();
        rig.calibration.insert(rig.calibration.begin(), std::move(*file));
    }
    if (const Item* sync = find(*fields, "sync"))
        MIXRAY_RETURN_IF_ERROR(parseSync(*sync, rig));
    if (const Item* site = find(*fields, "site"))
        MIXRAY_RETURN_IF_ERROR(parseSite(*site, rig));
    return Status::ok();
}

Status RigParser::parseDevice(const Item& item, RigDescription& rig) {
    static constexpr std::array<std::string_view, 9> kDeviceKeys = {
        "name", "driver", "id", "serial", "uri", "mode", "options", "streams", "calibration"};
    auto fields = readMap(item, kDeviceKeys, "a device mapping with name: and driver:");
    if (!fields)
        return fields.status();
    MIXRAY_RETURN_IF_ERROR(require(*fields, item, "name"));
    MIXRAY_RETURN_IF_ERROR(require(*fields, item, "driver"));

    RigDevice device;
    device.where = item.where;
    auto device_name = name(*find(*fields, "name"));
    if (!device_name)
        return device_name.status();
    device.config.name = *device_name;
    auto driver = name(*find(*fields, "driver"));
    if (!driver)
        return driver.status();
    device.config.driver = *driver;

    const Item* id_item = nullptr;
    for (auto [key, kind] :
         {std::pair{"id", DeviceIdKind::kId}, std::pair{"serial", DeviceIdKind::kSerial},
          std::pair{"uri", DeviceIdKind::kUri}}) {
        const Item* given = find(*fields, key);
        if (!given)
            continue;
        if (id_item) {
            return fail(*given,
                        "give one of id, serial and uri; " + id_item->path + " is already given");
        }
        auto value = text(*given);
        if (!value)
            return value.status();
        device.config.id = *value;
        device.id_kind = kind;
        id_item = given;
    }

    // Where each option key came from, so collisions point at both entries.
    std::map<std::string, SourceLocation> option_where;
    if (const Item* options = find(*fields, "options")) {
        auto entries = readMap(*options, {}, "a mapping of backend settings");
        if (!entries)
            return entries.status();
        for (const auto& [key, key_where, value] : *entries) {
            if (!isValidOptionKey(key)) {
                return corrupt(key_where, value.path,
                               "an option name has letters, digits, '_', '-' and '.'");
            }
            if (!value.node.IsScalar())
                return expected(value, "a single value");
            device.config.options[key] = value.node.Scalar();
            option_where[key] = key_where;
        }
    }
    bool streams_listed = false;
    if (const Item* streams = find(*fields, "streams")) {
        MIXRAY_RETURN_IF_ERROR(parseStreams(*streams, device, rig));
        streams_listed = true;
    }
    if (const Item* mode = find(*fields, "mode")) {
        MIXRAY_RETURN_IF_ERROR(parseMode(*mode, device, streams_listed, option_where));
    }
    // Stream modes reach the backend through the options, under "<stream>.<setting>".
    for (const auto& stream : device.streams) {
        auto put = [&](std::string_view setting, std::string value) -> Status {
            const std::string key = stream.name + "." + std::string(setting);
            if (auto it = option_where.find(key); it != option_where.end()) {
                return corrupt(it->second, item.path + ".options." + key,
                               "collides with the " + std::string(setting) + " of stream " +
                                   stream.name + " (line " + std::to_string(stream.where.line) +
                                   ")");
            }
            device.config.options[key] = std::move(value);
            return Status::ok();
        };
        if (stream.width)
            MIXRAY_RETURN_IF_ERROR(put("width", std::to_string(*stream.width)));
        if (stream.height)
            MIXRAY_RETURN_IF_ERROR(put("height", std::to_string(*stream.height)));
        if (stream.fps) {
            std::array<char, 32> buffer{};
            auto [end, ec] =
                std::to_chars(buffer.data(), buffer.data() + buffer.size(), *stream.fps);
            (void)ec;
            MIXRAY_RETURN_IF_ERROR(put("fps", std::string(buffer.data(), end)));
        }
        if (stream.format)
            MIXRAY_RETURN_IF_ERROR(put("format", std::string(toString(*stream.format))));
        if (streams_listed && stream.enabled)
            device.config.streams.push_back(stream.name);
    }
    if (streams_listed && device.config.streams.empty()) {
        return fail(*find(*fields, "streams"),
                    "every listed stream is disabled; enable one or remove the device");
    }
    if (const Item* calibration = find(*fields, "calibration")) {
        auto file = calibrationFile(*calibration, device.config.name, "");
        if (!file)
            return file.status();
        rig.calibration.push_back(std::move(*file));
    }
    rig.devices.push_back(std::move(device));
    return Status::ok();
}

Status RigParser::parseStreams(const Item& item, RigDevice& device, RigDescription& rig) {
    static constexpr std::array<std::string_view, 10> kStreamKeys = {
        "name",   "enabled", "mode",  "format",   "width",
        "height", "fps",     "queue", "capacity", "calibration"};
    std::span<const std::string_view> settings_keys(kStreamKeys.begin() + 1, kStreamKeys.end());
    auto add = [&](const Item& where, const std::string& stream_name) -> Result<RigStream*> {
        if (device.findStream(stream_name)) {
            return corrupt(where.where, where.path, "stream " + stream_name + " is listed twice");
        }
        RigStream& stream = device.streams.emplace_back();
        stream.name = stream_name;
        stream.where = where.where;
        return &stream;
    };

    if (item.node.IsSequence()) {
        // [depth, color] or [{name: depth, ...}, ...]
        size_t index = 0;
        for (const auto& node : item.node) {
            const Item entry = element(item, node, index++);
            if (entry.node.IsMap()) {
                auto fields = readMap(entry, kStreamKeys, "a stream");
                if (!fields)
                    return fields.status();
                MIXRAY_RETURN_IF_ERROR(require(*fields, entry, "name"));
                auto stream_name = name(*find(*fields, "name"));
                if (!stream_name)
                    return stream_name.status();
                auto stream = add(entry, *stream_name);
                if (!stream)
                    return stream.status();
                MIXRAY_RETURN_IF_ERROR(
                    parseStreamSettings(*fields, entry, **stream, device.config.name, rig));
            } else {
                auto stream_name = name(entry);
                if (!stream_name)
                    return stream_name.status();
                auto stream = add(entry, *stream_name);
                if (!stream)
                    return stream.status();
            }
        }
        if (index == 0)
            return expected(item, "at least one stream");
        return Status::ok();
    }
    // {depth: , color: 640x480@30, ir: {enabled: false}}
    auto entries = readMap(item, {}, "a list of streams or a mapping of stream settings");
    if (!entries)
        return entries.status();
    if (entries->empty())
        return expected(item, "at least one stream");
    for (const auto& [key, key_where, value] : *entries) {
        if (!isValidName(key)) {
            return corrupt(key_where, value.path,
                           "a stream name has up to " + std::to_string(kMaxNameLength) +
                               " letters, digits, '_' or '-'");
        }
        auto stream = add({value.node, key_where, value.path}, key);
        if (!stream)
            return stream.status();
        if (value.node.IsMap()) {
            auto fields = readMap(value, settings_keys, "stream settings");
            if (!fields)
                return fields.status();
            MIXRAY_RETURN_IF_ERROR(
                parseStreamSettings(*fields, value, **stream, device.config.name, rig));
        } else if (value.node.IsScalar()) {
            // Shorthand: "color: 640x480@30".
            const Fields shorthand = {{"mode", key_where, value}};
            MIXRAY_RETURN_IF_ERROR(
                parseStreamSettings(shorthand, value, **stream, device.config.name, rig));
        } else if (!value.node.IsNull()) {
            return expected(value, "stream settings or a mode like 640x480@30");
        }
    }
    return Status::ok();
}

Status RigParser::parseStreamSettings(const Fields& fields, const Item& item, RigStream& stream,
                                      const std::string& device, RigDescription& rig) {
    if (const Item* enabled = find(fields, "enabled")) {
        auto value = boolean(*enabled);
        if (!value)
            return value.status();
        stream.enabled = *value;
    }
    const Item* mode_item = find(fields, "mode");
    if (mode_item) {
        if (!mode_item->node.IsScalar())
            return expected(*mode_item, kModeSyntax);
        auto mode = parseStreamMode(mode_item->node.Scalar());
        if (auto* message = std::get_if<std::string>(&mode))
            return fail(*mode_item, *message);
        const auto& m = std::get<StreamMode>(mode);
        stream.width = m.width;
        stream.height = m.height;
        stream.fps = m.fps;
        stream.format = m.format;
    }
    for (std::string_view key : {"width", "height", "fps"}) {
        const Item* given = find(fields, key);
        if (!given)
            continue;
        if (mode_item) {
            return fail(*given, "give either mode or width, height and fps, not both");
        }
        if (key == "fps") {
            auto fps = number(*given, 0, kMaxFps, true);
            if (!fps)
                return fps.status();
            stream.fps = *fps;
        } else {
            auto side = integer(*given, 1, kMaxImageSide);
            if (!side)
                return side.status();
            (key == "width" ? stream.width : stream.height) = static_cast<int>(*side);
        }
    }
    if (stream.width.has_value() != stream.height.has_value()) {
        return corrupt(item.where, item.path, "give both width and height, or neither");
    }
    if (const Item* format = find(fields, "format")) {
        if (stream.format)
            return fail(*format, "the mode already gives a pixel format");
        if (!format->node.IsScalar())
            return expected(*format, "a pixel format name");
        stream.format = pixelFormatFromString(format->node.Scalar());
        if (!stream.format)
            return fail(*format, unknownFormatMessage(format->node.Scalar()));
    }
    if (const Item* queue = find(fields, "queue")) {
        const std::string policy = queue->node.IsScalar() ? queue->node.Scalar() : "";
        if (policy == toString(QueuePolicy::kLive)) {
            stream.queue = QueuePolicy::kLive;
        } else if (policy == toString(QueuePolicy::kLossless)) {
            stream.queue = QueuePolicy::kLossless;
        } else {
            return expected(*queue, "live or lossless");
        }
    }
    if (const Item* capacity = find(fields, "capacity")) {
        auto value = integer(*capacity, 1, kMaxCapacity);
        if (!value)
            return value.status();
        stream.capacity = static_cast<size_t>(*value);
    }
    if (const Item* calibration = find(fields, "calibration")) {
        auto file = calibrationFile(*calibration, device, stream.name);
        if (!file)
            return file.status();
        rig.calibration.push_back(std::move(*file));
    }
    return Status::ok();
}

// Stream names that `mode:` treats as streams even when the device lists none.
bool isImageStreamWord(std::string_view key) {
    if (key == "ir")
        return true;
    auto kind = streamKindFromString(key);
    return kind && (*kind == StreamKind::kColor || *kind == StreamKind::kDepth ||
                    *kind == StreamKind::kInfrared || *kind == StreamKind::kMono);
}

Status RigParser::parseMode(const Item& item, RigDevice& device, bool streams_listed,
                            std::map<std::string, SourceLocation>& option_where) {
    auto entries = readMap(item, {}, "a mapping of stream modes and device settings");
    if (!entries)
        return entries.status();
    for (const auto& [key, key_where, value] : *entries) {
        RigStream* stream = nullptr;
        for (auto& s : device.streams) {
            if (s.name == key)
                stream = &s;
        }
        if (stream || isImageStreamWord(key)) {
            // A stream's mode: "depth: 640x480@30".
            if (!value.node.IsScalar())
                return expected(value, kModeSyntax);
            if (!stream) {
                if (streams_listed) {
                    return corrupt(key_where, value.path,
                                   "stream " + key + " is not listed under streams");
                }
                stream = &device.streams.emplace_back();
                stream->name = key;
                stream->where = key_where;
            }
            if (stream->width || stream->fps || stream->format) {
                return corrupt(key_where, value.path,
                               "the mode of stream " + key + " is also given under streams (line " +
                                   std::to_string(stream->where.line) + ")");
            }
            auto mode = parseStreamMode(value.node.Scalar());
            if (auto* message = std::get_if<std::string>(&mode))
                return fail(value, *message);
            const auto& m = std::get<StreamMode>(mode);
            stream->width = m.width;
            stream->height = m.height;
            stream->fps = m.fps;
            stream->format = m.format;
            continue;
        }
        // A device-wide setting: "registration: true".
        if (!isValidOptionKey(key)) {
            return corrupt(key_where, value.path,
                           "a setting name has letters, digits, '_', '-' and '.'");
        }
        if (!value.node.IsScalar())
            return expected(value, "a single value");
        if (auto it = option_where.find(key); it != option_where.end()) {
            return corrupt(key_where, value.path,
                           "also set under options (line " + std::to_string(it->second.line) + ")");
        }
        device.config.options[key] = value.node.Scalar();
        option_where[key] = key_where;
    }
    return Status::ok();
}

Status RigParser::parseSync(const Item& item, RigDescription& rig) {
    static constexpr std::array<std::string_view, 2> kSyncKeys = {"streams", "max_skew_ms"};
    auto fields = readMap(item, kSyncKeys, "a mapping with streams: and max_skew_ms:");
    if (!fields)
        return fields.status();
    MIXRAY_RETURN_IF_ERROR(require(*fields, item, "streams"));
    rig.sync.where = item.where;
    const Item& streams = *find(*fields, "streams");
    if (!streams.node.IsSequence() || streams.node.size() < 2) {
        return expected(streams, "a list of at least two streams like [kinect/depth, env/color]");
    }
    size_t index = 0;
    for (const auto& node : streams.node) {
        const Item entry = element(streams, node, index++);
        const std::string value = entry.node.IsScalar() ? entry.node.Scalar() : "";
        const size_t slash = value.find('/');
        if (slash == std::string::npos || !isValidName(value.substr(0, slash)) ||
            !isValidName(value.substr(slash + 1))) {
            return expected(entry, "DEVICE/STREAM like kinect/depth");
        }
        rig.sync.streams.push_back({value.substr(0, slash), value.substr(slash + 1), entry.where});
    }
    if (const Item* skew = find(*fields, "max_skew_ms")) {
        auto value = number(*skew, 0, kMaxSkewMs, true);
        if (!value)
            return value.status();
        rig.sync.max_skew_ms = *value;
    }
    return Status::ok();
}

Status RigParser::parseSite(const Item& item, RigDescription& rig) {
    static constexpr std::array<std::string_view, 5> kSiteKeys = {
        "latitude_deg", "longitude_deg", "heading_deg", "altitude_m", "orientation"};
    auto fields = readMap(item, kSiteKeys, "a mapping with latitude_deg: and longitude_deg:");
    if (!fields)
        return fields.status();
    MIXRAY_RETURN_IF_ERROR(require(*fields, item, "latitude_deg"));
    MIXRAY_RETURN_IF_ERROR(require(*fields, item, "longitude_deg"));
    RigSite site;
    site.where = item.where;
    struct Range {
        std::string_view key;
        double min, max;
        double RigSite::*field;
    };
    for (const Range& r : {Range{"latitude_deg", -90, 90, &RigSite::latitude_deg},
                           Range{"longitude_deg", -180, 180, &RigSite::longitude_deg},
                           Range{"heading_deg", 0, 360, &RigSite::heading_deg},
                           Range{"altitude_m", -11000, 9000, &RigSite::altitude_m}}) {
        if (const Item* given = find(*fields, r.key)) {
            auto value = number(*given, r.min, r.max, false);
            if (!value)
                return value.status();
            site.*r.field = *value;
        }
    }
    if (const Item* orientation = find(*fields, "orientation")) {
        if (const Item* heading = find(*fields, "heading_deg"))
            return fail(*heading, "give either heading_deg or orientation, not both");
        static constexpr std::array<std::string_view, 1> kOrientationKeys = {"quaternion"};
        auto entries = readMap(*orientation, kOrientationKeys, "a mapping with quaternion:");
        if (!entries)
            return entries.status();
        MIXRAY_RETURN_IF_ERROR(require(*entries, *orientation, "quaternion"));
        const Item& quaternion = *find(*entries, "quaternion");
        auto elements = readList(quaternion, 4, 4, "a list of 4 numbers [w, x, y, z]");
        if (!elements)
            return elements.status();
        std::array<double, 4> wxyz{};
        for (size_t i = 0; i < wxyz.size(); ++i) {
            auto value = number((*elements)[i], -1, 1, false);
            if (!value)
                return value.status();
            wxyz[i] = *value;
        }
        const double norm = std::sqrt(wxyz[0] * wxyz[0] + wxyz[1] * wxyz[1] + wxyz[2] * wxyz[2] +
                                      wxyz[3] * wxyz[3]);
        if (!isUnitNorm(norm)) {
            return fail(quaternion, "expected a unit quaternion (norm within " +
                                        formatNumber(kUnitQuaternionTolerance) +
                                        " of 1), got norm " + formatNumber(norm));
        }
        site.orientation_wxyz = wxyz;
    }
    rig.site = site;
    return Status::ok();
}

Result<RigDescription> parseRigAt(std::string_view text, std::string source_name,
                                  std::filesystem::path base) {
    RigDescription rig;
    RigParser parser(source_name, std::move(base));
    try {
        MIXRAY_RETURN_IF_ERROR(parser.parse(text, rig));
    } catch (const YAML::Exception& e) {
        SourceLocation where{source_name, 0, 0};
        if (!e.mark.is_null() && e.mark.line >= 0) {
            where.line = e.mark.line + 1;
            where.column = e.mark.column + 1;
        }
        return corrupt(where, "", "YAML syntax error: " + e.msg);
    } catch (const std::exception& e) {
        return Status(ErrorCode::kInternal, source_name + ": parsing failed: " + e.what());
    }
    MIXRAY_RETURN_IF_ERROR(rig.validate());
    rig.source_path = std::move(source_name);
    rig.source_text = std::string(text);
    return rig;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public API

std::string SourceLocation::toString() const {
    std::string out = file;
    if (line > 0) {
        out += (out.empty() ? "line " : ":") + std::to_string(line);
        if (column > 0)
            out += ":" + std::to_string(column);
    }
    return out;
}

std::string_view toString(DeviceIdKind kind) {
    switch (kind) {
        case DeviceIdKind::kAny:
            return "any";
        case DeviceIdKind::kId:
            return "id";
        case DeviceIdKind::kSerial:
            return "serial";
        case DeviceIdKind::kUri:
            return "uri";
    }
    return "any";
}

const RigStream* RigDevice::findStream(std::string_view stream) const {
    for (const auto& s : streams) {
        if (s.name == stream)
            return &s;
    }
    return nullptr;
}

const RigDevice* RigDescription::findDevice(std::string_view device) const {
    for (const auto& d : devices) {
        if (d.config.name == device)
            return &d;
    }
    return nullptr;
}

const RigCalibrationFile* RigDescription::findCalibration(std::string_view device,
                                                          std::string_view stream) const {
    const RigCalibrationFile* best = nullptr;
    int best_rank = 0;
    for (const auto& file : calibration) {
        int rank = 0;
        if (file.device.empty()) {
            rank = 1;
        } else if (file.device == device && file.stream.empty()) {
            rank = 2;
        } else if (file.device == device && !stream.empty() && file.stream == stream) {
            rank = 3;
        }
        if (rank > best_rank) {
            best = &file;
            best_rank = rank;
        }
    }
    return best;
}

std::vector<DeviceConfig> RigDescription::deviceConfigs() const {
    std::vector<DeviceConfig> configs;
    configs.reserve(devices.size());
    for (const auto& d : devices)
        configs.push_back(d.config);
    return configs;
}

Status RigDescription::validate() const {
    const SourceLocation file_where{source_path, 0, 0};
    if (version != 1) {
        return corrupt(file_where, "version",
                       "unsupported rig format version " + std::to_string(version));
    }
    if (devices.empty())
        return corrupt(file_where, "devices", "at least one device is needed");
    std::map<std::string_view, const RigDevice*> by_name;
    for (size_t i = 0; i < devices.size(); ++i) {
        const RigDevice& d = devices[i];
        const std::string path = indexPath("devices", i);
        if (!isValidName(d.name())) {
            return corrupt(d.where, path + ".name", "invalid device name " + quote(d.name()));
        }
        if (auto [it, inserted] = by_name.emplace(d.name(), &d); !inserted) {
            return corrupt(d.where, path + ".name",
                           "duplicate device name " + quote(d.name()) + firstAt(it->second->where));
        }
        if (!isValidName(d.config.driver)) {
            return corrupt(d.where, path + ".driver",
                           "invalid driver name " + quote(d.config.driver));
        }
        if (d.id_kind != DeviceIdKind::kAny && d.config.id.empty()) {
            return corrupt(d.where, path + "." + std::string(toString(d.id_kind)), "empty");
        }
        std::set<std::string_view> stream_names;
        for (const RigStream& s : d.streams) {
            const std::string stream_path = path + ".streams." + s.name;
            if (!isValidName(s.name)) {
                return corrupt(s.where, stream_path, "invalid stream name " + quote(s.name));
            }
            if (!stream_names.insert(s.name).second) {
                return corrupt(s.where, stream_path, "stream listed twice");
            }
            if ((s.width && (*s.width < 1 || *s.width > kMaxImageSide)) ||
                (s.height && (*s.height < 1 || *s.height > kMaxImageSide))) {
                return corrupt(s.where, stream_path, "image size out of range");
            }
            if (s.fps && !(*s.fps > 0 && *s.fps <= kMaxFps)) {
                return corrupt(s.where, stream_path + ".fps", "frame rate out of range");
            }
            if (s.capacity < 1 || s.capacity > kMaxCapacity) {
                return corrupt(s.where, stream_path + ".capacity", "queue capacity out of range");
            }
        }
    }

    if (!sync.streams.empty()) {
        if (sync.streams.size() < 2) {
            return corrupt(sync.where, "sync.streams", "at least two streams are needed");
        }
        if (!(sync.max_skew_ms > 0 && sync.max_skew_ms <= kMaxSkewMs)) {
            return corrupt(sync.where, "sync.max_skew_ms", "out of range");
        }
        std::set<std::string> seen;
        for (size_t i = 0; i < sync.streams.size(); ++i) {
            const RigStreamRef& ref = sync.streams[i];
            const std::string path = indexPath("sync.streams", i);
            const RigDevice* d = findDevice(ref.device);
            if (!d) {
                std::vector<std::string_view> names;
                for (const auto& device : devices)
                    names.push_back(device.name());
                return corrupt(ref.where, path,
                               "no device named " + quote(ref.device) +
                                   " (devices: " + joinNames(names) + ")");
            }
            const RigStream* s = d->findStream(ref.stream);
            if (s && !s->enabled) {
                return corrupt(ref.where, path, "stream " + ref.name() + " is disabled");
            }
            const auto& enabled = d->config.streams;
            if (!enabled.empty() &&
                std::find(enabled.begin(), enabled.end(), ref.stream) == enabled.end()) {
                std::vector<std::string_view> names(enabled.begin(), enabled.end());
                return corrupt(ref.where, path,
                               "device " + ref.device + " has no stream " + quote(ref.stream) +
                                   " (streams: " + joinNames(names) + ")");
            }
            if (!seen.insert(ref.name()).second) {
                return corrupt(ref.where, path, "stream " + ref.name() + " is listed twice");
            }
        }
    }

    std::set<std::pair<std::string_view, std::string_view>> calibrated;
    for (const RigCalibrationFile& file : calibration) {
        const std::string path = file.device.empty()
                                     ? "calibration"
                                     : "devices." + file.device +
                                           (file.stream.empty() ? "" : ".streams." + file.stream) +
                                           ".calibration";
        if (file.path.empty())
            return corrupt(file.where, path, "empty path");
        if (!file.device.empty()) {
            const RigDevice* d = findDevice(file.device);
            if (!d)
                return corrupt(file.where, path, "no device named " + quote(file.device));
            if (!file.stream.empty() && !d->findStream(file.stream)) {
                return corrupt(file.where, path, "no stream named " + quote(file.stream));
            }
        }
        if (!calibrated.emplace(file.device, file.stream).second) {
            return corrupt(file.where, path, "a second calibration file for the same camera");
        }
    }

    if (site) {
        if (!(site->latitude_deg >= -90 && site->latitude_deg <= 90) ||
            !(site->longitude_deg >= -180 && site->longitude_deg <= 180) ||
            !(site->heading_deg >= 0 && site->heading_deg <= 360) ||
            !std::isfinite(site->altitude_m)) {
            return corrupt(site->where, "site", "coordinates out of range");
        }
        if (const auto& q = site->orientation_wxyz) {
            const double norm = std::sqrt(q->at(0) * q->at(0) + q->at(1) * q->at(1) +
                                          q->at(2) * q->at(2) + q->at(3) * q->at(3));
            if (!isUnitNorm(norm)) {
                return corrupt(site->where, "site.orientation",
                               "not a finite unit quaternion (w, x, y, z)");
            }
        }
    }
    return Status::ok();
}

Result<RigDescription> parseRig(std::string_view text, std::string_view source_name) {
    std::string name(source_name);
    std::filesystem::path base = std::filesystem::path(name).parent_path();
    return parseRigAt(text, std::move(name), std::move(base));
}

Result<RigDescription> loadRig(const std::filesystem::path& path) {
    const std::string name = path.string();
    std::error_code ec;
    const auto status = std::filesystem::status(path, ec);
    if (ec && ec != std::errc::no_such_file_or_directory) {
        return Status(ErrorCode::kIoError, name + ": " + ec.message());
    }
    if (!std::filesystem::exists(status)) {
        return Status(ErrorCode::kNotFound, name + ": no such rig file");
    }
    if (std::filesystem::is_directory(status)) {
        return Status(ErrorCode::kInvalidArgument, name + ": is a directory, not a rig file");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in)
        return Status(ErrorCode::kIoError, name + ": cannot open for reading");
    // Read at most one byte past the limit: enough to tell a file is too large, whatever it is.
    std::string text;
    std::array<char, 64 * 1024> chunk{};
    while (text.size() <= kMaxRigFileBytes && in) {
        in.read(chunk.data(), chunk.size());
        text.append(chunk.data(), static_cast<size_t>(in.gcount()));
    }
    if (in.bad())
        return Status(ErrorCode::kIoError, name + ": read failed");
    std::filesystem::path absolute = std::filesystem::absolute(path, ec);
    std::filesystem::path base = (ec ? path : absolute).parent_path().lexically_normal();
    return parseRigAt(text, name, std::move(base));
}

}  // namespace mixray
