// Aravis device options: parsing DeviceConfig::options into AravisOptions.
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <limits>
#include <optional>
#include <utility>

#include "mixray/aravis/aravis_backend.h"
#include "mixray/graph/device_options.h"

namespace mixray::aravis {
namespace {

constexpr double kNoLimit = std::numeric_limits<double>::infinity();

constexpr std::array<std::string_view, 7> kPixelFormats = {
    "Mono8", "Mono16", "RGB8", "BayerRG8", "BayerGR8", "BayerGB8", "BayerBG8"};

// GenICam name of a graph pixel format a rig's stream mode may ask for.
std::optional<std::string_view> genicamName(std::string_view graph_format) {
    static const std::array<std::pair<std::string_view, std::string_view>, 7> kNames = {{
        {"mono8", "Mono8"},
        {"mono16", "Mono16"},
        {"rgb8", "RGB8"},
        {"bayer_rggb8", "BayerRG8"},
        {"bayer_grbg8", "BayerGR8"},
        {"bayer_gbrg8", "BayerGB8"},
        {"bayer_bggr8", "BayerBG8"},
    }};
    for (const auto& [graph, genicam] : kNames) {
        if (graph == graph_format)
            return genicam;
    }
    return std::nullopt;
}

// The rig file's way of asking for a mode: the stream list and "<stream>.width", ".height",
// ".fps", ".format" (graph format names) for the camera's one stream, "mono" or "color".
Status readStreamMode(const DeviceConfig& config, DeviceOptionReader& reader, AravisOptions& o) {
    const std::string context = "aravis device '" + config.name + "'";
    if (config.streams.size() > 1) {
        return {ErrorCode::kInvalidArgument, context + ": the camera has one stream; " +
                                                 std::to_string(config.streams.size()) +
                                                 " are listed"};
    }
    if (!config.streams.empty())
        o.stream = config.streams.front();
    for (const std::string prefix : {"mono", "color"}) {
        const std::string keys[] = {prefix + ".width", prefix + ".height", prefix + ".fps",
                                    prefix + ".format"};
        bool any = false;
        for (const std::string& key : keys)
            any = any || config.options.count(key) > 0;
        if (!any)
            continue;
        if (!o.stream.empty() && o.stream != prefix) {
            return {ErrorCode::kInvalidArgument, context + ": a mode for stream '" + prefix +
                                                     "' but stream '" + o.stream +
                                                     "' is asked for"};
        }
        o.stream = prefix;
        auto once = [&](const std::string& key, const std::string& plain, bool given) -> Status {
            if (given && config.options.count(key)) {
                return {ErrorCode::kInvalidArgument,
                        context + ": both '" + plain + "' and '" + key + "' are given"};
            }
            return Status::ok();
        };
        MIXRAY_RETURN_IF_ERROR(once(keys[0], "width", o.width > 0));
        MIXRAY_RETURN_IF_ERROR(once(keys[1], "height", o.height > 0));
        MIXRAY_RETURN_IF_ERROR(once(keys[2], "fps", o.fps > 0));
        MIXRAY_RETURN_IF_ERROR(once(keys[3], "pixel_format", !o.pixel_format.empty()));
        MIXRAY_RETURN_IF_ERROR(reader.integer(keys[0], o.width, 1, 65535, "1..65535"));
        MIXRAY_RETURN_IF_ERROR(reader.integer(keys[1], o.height, 1, 65535, "1..65535"));
        MIXRAY_RETURN_IF_ERROR(reader.real(keys[2], o.fps, 0, kNoLimit, "a rate > 0",
                                           DeviceOptionReader::Bound::kOpen));
        if (const std::string* format = reader.find(keys[3])) {
            const auto name = genicamName(*format);
            if (!name) {
                return reader.error(keys[3], *format,
                                    "mono8, mono16, rgb8 or bayer_rggb8, _grbg8, _gbrg8, _bggr8");
            }
            // Debayered frames are rgb8 whatever mosaic the camera sends.
            if (!(o.debayer && *format == "rgb8"))
                o.pixel_format = std::string(*name);
        }
    }
    if (!o.stream.empty() && o.stream != "mono" && o.stream != "color") {
        return {ErrorCode::kInvalidArgument, context + ": no stream '" + o.stream +
                                                 "' (an Aravis camera has 'mono' or 'color')"};
    }
    return Status::ok();
}

// A TriggerSource entry name as a user may write it: letters, digits and underscores.
bool isLineName(std::string_view text) {
    return !text.empty() && text.size() <= 64 && std::all_of(text.begin(), text.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
    });
}

}  // namespace

std::string triggerActivationName(std::string_view option_value) {
    static const std::array<std::pair<std::string_view, std::string_view>, 5> kNames = {{
        {"rising_edge", "RisingEdge"},
        {"falling_edge", "FallingEdge"},
        {"any_edge", "AnyEdge"},
        {"level_high", "LevelHigh"},
        {"level_low", "LevelLow"},
    }};
    for (const auto& [option, genicam] : kNames) {
        if (option == option_value)
            return std::string(genicam);
    }
    return {};
}

Result<AravisOptions> AravisOptions::fromConfig(const DeviceConfig& config) {
    AravisOptions o;
    DeviceOptionReader reader(config, "aravis");
    if (const std::string* format = reader.find("pixel_format")) {
        if (std::find(kPixelFormats.begin(), kPixelFormats.end(), *format) == kPixelFormats.end()) {
            return reader.error("pixel_format", *format,
                                "Mono8, Mono16, RGB8, BayerRG8, BayerGR8, BayerGB8 or BayerBG8");
        }
        o.pixel_format = *format;
    }
    MIXRAY_RETURN_IF_ERROR(reader.boolean("debayer", o.debayer));
    MIXRAY_RETURN_IF_ERROR(reader.real("exposure_us", o.exposure_us, 0, kNoLimit, "a time > 0",
                                       DeviceOptionReader::Bound::kOpen));
    MIXRAY_RETURN_IF_ERROR(reader.real("gain", o.gain, 0, kNoLimit, "a gain >= 0"));
    MIXRAY_RETURN_IF_ERROR(
        reader.real("fps", o.fps, 0, kNoLimit, "a rate > 0", DeviceOptionReader::Bound::kOpen));
    MIXRAY_RETURN_IF_ERROR(reader.integer("width", o.width, 1, 65535, "1..65535"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("height", o.height, 1, 65535, "1..65535"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("offset_x", o.offset_x, 0, 65535, "0..65535"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("offset_y", o.offset_y, 0, 65535, "0..65535"));
    if (const std::string* trigger = reader.find("trigger")) {
        if (*trigger == "free") {
            o.trigger = TriggerMode::kFreeRun;
        } else if (*trigger == "software") {
            o.trigger = TriggerMode::kSoftware;
        } else if (isLineName(*trigger)) {
            // Which lines exist is the camera's to say: checked at open.
            o.trigger = TriggerMode::kHardware;
            o.trigger_source = *trigger;
        } else {
            return reader.error("trigger", *trigger,
                                "free, software or a hardware line (line0, line1, ...)");
        }
    }
    if (const std::string* activation = reader.find("trigger_activation")) {
        o.trigger_activation = triggerActivationName(*activation);
        if (o.trigger_activation.empty()) {
            return reader.error("trigger_activation", *activation,
                                "rising_edge, falling_edge, any_edge, level_high or level_low");
        }
    }
    MIXRAY_RETURN_IF_ERROR(reader.boolean("ptp", o.ptp));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer("buffers", o.buffers, size_t{2}, size_t{4096}, "2..4096"));
    MIXRAY_RETURN_IF_ERROR(
        reader.integer("packet_size", o.packet_size, 0, 65535, "0 (negotiate) or a size"));
    MIXRAY_RETURN_IF_ERROR(reader.boolean("packet_resend", o.packet_resend));
    MIXRAY_RETURN_IF_ERROR(reader.integer("lost_timeout_ms", o.lost_timeout_ms, int64_t{100},
                                          int64_t{3'600'000}, "100..3600000"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("reconnect_ms", o.reconnect_ms, int64_t{10},
                                          int64_t{3'600'000}, "10..3600000"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("heartbeat_timeout_ms", o.heartbeat_timeout_ms,
                                          int64_t{500}, int64_t{600'000}, "500..600000"));
    MIXRAY_RETURN_IF_ERROR(reader.integer("clock_domain", o.clock_domain, ClockDomainId{1},
                                          ClockDomainId{UINT32_MAX},
                                          "an integer >= 1 (0 is the host clock)"));
    MIXRAY_RETURN_IF_ERROR(readStreamMode(config, reader, o));
    MIXRAY_RETURN_IF_ERROR(reader.leftovers(
        "pixel_format, debayer, exposure_us, gain, fps, width, height, offset_x, offset_y, "
        "trigger, trigger_activation, ptp, buffers, packet_size, packet_resend, lost_timeout_ms, "
        "reconnect_ms, heartbeat_timeout_ms, clock_domain, and the rig's <stream>.width, .height, "
        ".fps, .format for mono or color"));
    MIXRAY_RETURN_IF_ERROR(o.validate().withContext("aravis device '" + config.name + "'"));
    return o;
}

Status AravisOptions::validate() const {
    if (!pixel_format.empty() && std::find(kPixelFormats.begin(), kPixelFormats.end(),
                                           pixel_format) == kPixelFormats.end()) {
        return {ErrorCode::kInvalidArgument, "unsupported pixel_format '" + pixel_format + "'"};
    }
    if (exposure_us < 0 || fps < 0 || !std::isfinite(gain))
        return {ErrorCode::kInvalidArgument, "exposure, fps and gain must be finite and >= 0"};
    if (width < 0 || height < 0)
        return {ErrorCode::kInvalidArgument, "width and height must be >= 0"};
    if (buffers == 1)
        return {ErrorCode::kInvalidArgument, "buffers must be >= 2"};
    if (packet_size < 0)
        return {ErrorCode::kInvalidArgument, "packet_size must be >= 0"};
    if (trigger == TriggerMode::kHardware && trigger_source.empty())
        return {ErrorCode::kInvalidArgument, "a hardware trigger needs a line (trigger=line0)"};
    if (trigger != TriggerMode::kHardware && !trigger_activation.empty()) {
        return {ErrorCode::kInvalidArgument,
                "trigger_activation needs a hardware trigger (trigger=line0, ...)"};
    }
    if (lost_timeout_ms < 100 || reconnect_ms < 10) {
        return {ErrorCode::kInvalidArgument,
                "lost_timeout_ms must be >= 100 and reconnect_ms >= 10"};
    }
    return Status::ok();
}

}  // namespace mixray::aravis
