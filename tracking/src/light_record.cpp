// Light and environment-map records: encoding, decoding and validation of their stream payloads.
#include "mixray/tracking/light_record.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>

#include "mixray/graph/pose.h"
#include "mixray/graph/record_codec.h"

namespace mixray::tracking {
namespace {

using record::getF32;
using record::getF64;
using record::getLe;
using record::putF32;
using record::putF64;
using record::putLe;

// "MXLI" and "MXEM" read as little-endian u32s.
constexpr uint32_t kLightMagic = 0x494c584d;
constexpr uint32_t kMapMagic = 0x4d45584d;

// Light record header.
constexpr size_t kOffGroupCount = 6, kOffReserved0 = 7, kOffRecordBytes = 8, kOffReserved1 = 12,
                 kOffSequence = 16, kOffStamp = 24;
// Group header, from the group's start.
constexpr size_t kGroupNameLength = 0, kGroupReasonLength = 1, kGroupLightCount = 2,
                 kGroupFlags = 3, kGroupReserved = 4, kGroupStamp = 8, kGroupGoodStamp = 16;
// One light, from its start.
constexpr size_t kLightSource = 0, kLightFlags = 1, kLightReserved = 2, kLightDirection = 8,
                 kLightIntensity = 32, kLightRadius = 56, kLightPosition = 64, kLightWeight = 88;
constexpr uint8_t kStale = 0x01;
constexpr uint8_t kHasPosition = 0x01;
static_assert(kLightWeight + 8 == kLightBytes);

// Environment-map header.
constexpr size_t kMapFlags = 6, kMapChannels = 7, kMapWidth = 8, kMapHeight = 12, kMapSequence = 16,
                 kMapFrameStamp = 24, kMapStamp = 32, kMapGoodStamp = 40, kMapReason = 48;
constexpr size_t kMapReasonField = kEnvironmentMapHeaderBytes - kMapReason;  // 128, NUL-padded
static_assert(kMapReasonField == kLightReasonMaxBytes + 1);

constexpr size_t pad8(size_t n) {
    return (n + 7) / 8 * 8;
}

Status invalid(const std::string& kind, const std::string& what) {
    return Status(ErrorCode::kInvalidArgument, kind + " record: " + what);
}

// The checks every Estimate<T> header passes: a reason fits, is printable, and only a stale
// estimate has one.
Status validateReason(bool stale, const std::string& reason, const std::string& where,
                      const std::string& kind) {
    if (reason.size() > kLightReasonMaxBytes)
        return invalid(kind, where + "reason must have at most " +
                                 std::to_string(kLightReasonMaxBytes) + " bytes, got " +
                                 std::to_string(reason.size()));
    if (!record::isPrintableUtf8(reason))
        return invalid(kind, where + "reason holds bytes that are not printable UTF-8");
    if (!stale && !reason.empty())
        return invalid(kind, where + "a fresh estimate has no reason, got '" + reason + "'");
    return Status::ok();
}

Status validateLight(const EstimatedLight& l, const std::string& where) {
    const auto bad = [&](const std::string& what) { return invalid("light", where + what); };
    if (static_cast<uint8_t>(l.source) > static_cast<uint8_t>(LightSource::kSun))
        return bad("source " + std::to_string(static_cast<int>(l.source)) + " is out of range");
    if (!l.to_light_world.allFinite())
        return bad("to_light_world is not finite");
    if (std::abs(l.to_light_world.norm() - 1.0) > 1e-6)
        return bad("to_light_world is not a unit vector (norm " +
                   std::to_string(l.to_light_world.norm()) + ")");
    if (!l.intensity.allFinite() || (l.intensity.array() < 0).any())
        return bad("intensity must be finite and >= 0");
    if (!std::isfinite(l.angular_radius_rad) || l.angular_radius_rad < 0)
        return bad("angular_radius_rad must be finite and >= 0");
    if (l.position_world && !l.position_world->allFinite())
        return bad("position_world is not finite");
    if (!std::isfinite(l.weight) || l.weight < 0)
        return bad("weight must be finite and >= 0");
    return Status::ok();
}

void putVector(uint8_t* out, const Eigen::Vector3d& v) {
    for (int i = 0; i < 3; ++i)
        putF64(out + 8 * i, v[i]);
}
Eigen::Vector3d getVector(const uint8_t* in) {
    return {getF64(in), getF64(in + 8), getF64(in + 16)};
}

size_t groupBytes(const LightGroup& g) {
    return kLightGroupHeaderBytes + pad8(g.name.size() + g.reason.size()) +
           g.lights.size() * kLightBytes;
}

// Decodes the group at `data + *offset`, bounds-checked against `end` (the CRC's offset).
Result<LightGroup> decodeGroup(const uint8_t* data, size_t* offset, size_t end, size_t index) {
    const std::string where = "group " + std::to_string(index) + ": ";
    const auto corrupt = [&](const std::string& what) {
        return record::corrupt("light", where + what);
    };
    const uint8_t* g = data + *offset;
    if (end - *offset < kLightGroupHeaderBytes)
        return corrupt("header runs past the end of the record");
    const size_t name_length = g[kGroupNameLength];
    const size_t reason_length = g[kGroupReasonLength];
    const size_t light_count = g[kGroupLightCount];
    if (name_length == 0 || name_length > kLightGroupNameMaxChars)
        return corrupt("name length " + std::to_string(name_length) + " is not 1 to " +
                       std::to_string(kLightGroupNameMaxChars));
    if (reason_length > kLightReasonMaxBytes)
        return corrupt("reason length " + std::to_string(reason_length) + " is over " +
                       std::to_string(kLightReasonMaxBytes));
    if (light_count > kLightGroupMaxLights)
        return corrupt("light count " + std::to_string(light_count) + " is over " +
                       std::to_string(kLightGroupMaxLights));
    if ((g[kGroupFlags] & ~kStale) != 0 || getLe(g + kGroupReserved, 4) != 0)
        return corrupt("reserved bits are not zero");
    const size_t text = pad8(name_length + reason_length);
    const size_t bytes = kLightGroupHeaderBytes + text + light_count * kLightBytes;
    if (end - *offset < bytes)
        return corrupt("its " + std::to_string(light_count) + " lights run past the end of the " +
                       "record");
    LightGroup group;
    group.stale = (g[kGroupFlags] & kStale) != 0;
    group.stamp_ns = static_cast<int64_t>(getLe(g + kGroupStamp, 8));
    group.good_stamp_ns = static_cast<int64_t>(getLe(g + kGroupGoodStamp, 8));
    const auto* chars = reinterpret_cast<const char*>(g + kLightGroupHeaderBytes);
    group.name.assign(chars, name_length);
    group.reason.assign(chars + name_length, reason_length);
    if (!record::allZero(g + kLightGroupHeaderBytes + name_length + reason_length,
                         text - name_length - reason_length))
        return corrupt("text padding is not zero");
    const uint8_t* l = g + kLightGroupHeaderBytes + text;
    for (size_t i = 0; i < light_count; ++i, l += kLightBytes) {
        if (l[kLightSource] > static_cast<uint8_t>(LightSource::kSun))
            return corrupt("light " + std::to_string(i) + ": source " +
                           std::to_string(l[kLightSource]) + " is out of range");
        if ((l[kLightFlags] & ~kHasPosition) != 0 ||
            !record::allZero(l + kLightReserved, kLightDirection - kLightReserved))
            return corrupt("light " + std::to_string(i) + ": reserved bits are not zero");
        EstimatedLight light;
        light.source = static_cast<LightSource>(l[kLightSource]);
        light.to_light_world = getVector(l + kLightDirection);
        light.intensity = getVector(l + kLightIntensity);
        light.angular_radius_rad = getF64(l + kLightRadius);
        if (l[kLightFlags] & kHasPosition)
            light.position_world = getVector(l + kLightPosition);
        else if (!record::allZero(l + kLightPosition, 24))
            return corrupt("light " + std::to_string(i) + ": absent position is not zero");
        light.weight = getF64(l + kLightWeight);
        group.lights.push_back(std::move(light));
    }
    *offset += bytes;
    return group;
}

template <typename T>
LightGroup groupOf(std::string name, const Estimate<T>& e) {
    LightGroup group;
    group.name = std::move(name);
    group.stale = e.stale;
    group.reason = e.stale ? record::printableText(e.reason, kLightReasonMaxBytes) : "";
    group.stamp_ns = e.stamp_ns;
    group.good_stamp_ns = e.good_stamp_ns;
    return group;
}

void addLights(LightGroup* group, const std::vector<EstimatedLight>& lights) {
    const size_t n = std::min(lights.size(), kLightGroupMaxLights);
    group->lights.assign(lights.begin(), lights.begin() + static_cast<std::ptrdiff_t>(n));
}

}  // namespace

Status validate(const LightRecord& r) {
    if (r.groups.size() > kLightRecordMaxGroups)
        return invalid("light", "at most " + std::to_string(kLightRecordMaxGroups) +
                                    " groups, got " + std::to_string(r.groups.size()));
    std::set<std::string> names;
    for (size_t i = 0; i < r.groups.size(); ++i) {
        const LightGroup& g = r.groups[i];
        const std::string where = "group " + std::to_string(i) + " '" + g.name + "': ";
        if (g.name.empty() || g.name.size() > kLightGroupNameMaxChars)
            return invalid("light", where + "name must have 1 to " +
                                        std::to_string(kLightGroupNameMaxChars) +
                                        " characters, got " + std::to_string(g.name.size()));
        for (char c : g.name)
            if (c < 0x21 || c > 0x7e)
                return invalid("light",
                               where + "name holds a character that is not printable ASCII");
        if (!names.insert(g.name).second)
            return invalid("light", where + "name is used by an earlier group");
        MIXRAY_RETURN_IF_ERROR(validateReason(g.stale, g.reason, where, "light"));
        if (g.lights.size() > kLightGroupMaxLights)
            return invalid("light", where + "at most " + std::to_string(kLightGroupMaxLights) +
                                        " lights, got " + std::to_string(g.lights.size()));
        for (size_t k = 0; k < g.lights.size(); ++k)
            MIXRAY_RETURN_IF_ERROR(
                validateLight(g.lights[k], where + "light " + std::to_string(k) + ": "));
    }
    return Status::ok();
}

Result<std::vector<uint8_t>> encodeLightRecord(const LightRecord& r) {
    MIXRAY_RETURN_IF_ERROR(validate(r));
    size_t size = kLightRecordHeaderBytes + 4;
    for (const LightGroup& g : r.groups)
        size += groupBytes(g);
    std::vector<uint8_t> out(size, 0);
    record::putHeader(out.data(), kLightMagic, kLightRecordVersion);
    out[kOffGroupCount] = static_cast<uint8_t>(r.groups.size());
    putLe(out.data() + kOffRecordBytes, size, 4);
    putLe(out.data() + kOffSequence, r.frame_sequence, 8);
    putLe(out.data() + kOffStamp, static_cast<uint64_t>(r.frame_device_stamp_ns), 8);
    uint8_t* g = out.data() + kLightRecordHeaderBytes;
    for (const LightGroup& group : r.groups) {
        g[kGroupNameLength] = static_cast<uint8_t>(group.name.size());
        g[kGroupReasonLength] = static_cast<uint8_t>(group.reason.size());
        g[kGroupLightCount] = static_cast<uint8_t>(group.lights.size());
        g[kGroupFlags] = group.stale ? kStale : 0;
        putLe(g + kGroupStamp, static_cast<uint64_t>(group.stamp_ns), 8);
        putLe(g + kGroupGoodStamp, static_cast<uint64_t>(group.good_stamp_ns), 8);
        uint8_t* text = g + kLightGroupHeaderBytes;
        std::memcpy(text, group.name.data(), group.name.size());
        std::memcpy(text + group.name.size(), group.reason.data(), group.reason.size());
        uint8_t* l = text + pad8(group.name.size() + group.reason.size());
        for (const EstimatedLight& light : group.lights) {
            l[kLightSource] = static_cast<uint8_t>(light.source);
            l[kLightFlags] = light.position_world ? kHasPosition : 0;
            putVector(l + kLightDirection, light.to_light_world);
            putVector(l + kLightIntensity, light.intensity);
            putF64(l + kLightRadius, light.angular_radius_rad);
            if (light.position_world)
                putVector(l + kLightPosition, *light.position_world);
            putF64(l + kLightWeight, light.weight);
            l += kLightBytes;
        }
        g += groupBytes(group);
    }
    record::putCrc(out.data(), out.size());
    return out;
}

Result<LightRecord> decodeLightRecord(const uint8_t* data, size_t size) {
    const auto corrupt = [](const std::string& what) { return record::corrupt("light", what); };
    constexpr size_t kSmallest = kLightRecordHeaderBytes + 4;
    if (data == nullptr || size < kSmallest || size > kLightRecordMaxBytes)
        return corrupt("expected " + std::to_string(kSmallest) + " to " +
                       std::to_string(kLightRecordMaxBytes) + " bytes, got " +
                       std::to_string(data == nullptr ? 0 : size));
    const size_t declared = getLe(data + kOffRecordBytes, 4);
    // The size field before the CRC: a record cut short says so rather than "CRC mismatch".
    if (getLe(data, 4) == kLightMagic && declared != size)
        return corrupt("the record says it has " + std::to_string(declared) +
                       " bytes, the payload has " + std::to_string(size));
    MIXRAY_RETURN_IF_ERROR(
        record::checkFrame(data, size, size, kLightMagic, kLightRecordVersion, "light"));
    if (data[kOffReserved0] != 0 || getLe(data + kOffReserved1, 4) != 0)
        return corrupt("reserved bytes are not zero");
    const size_t group_count = data[kOffGroupCount];
    if (group_count > kLightRecordMaxGroups)
        return corrupt("group count " + std::to_string(group_count) + " is over " +
                       std::to_string(kLightRecordMaxGroups));
    LightRecord r;
    r.frame_sequence = getLe(data + kOffSequence, 8);
    r.frame_device_stamp_ns = static_cast<int64_t>(getLe(data + kOffStamp, 8));
    const size_t end = size - 4;
    size_t offset = kLightRecordHeaderBytes;
    for (size_t i = 0; i < group_count; ++i) {
        auto group = decodeGroup(data, &offset, end, i);
        if (!group)
            return group.status();
        r.groups.push_back(std::move(*group));
    }
    if (offset != end)
        return corrupt(std::to_string(end - offset) + " bytes after the last group");
    if (Status s = validate(r); !s)
        return Status(ErrorCode::kCorruptData, s.message());
    return r;
}

StreamInfo makeLightStreamInfo(const std::string& name, const std::string& light_of, double fps) {
    StreamInfo info;
    info.name = name;
    info.device = name.substr(0, name.find('/'));
    info.kind = StreamKind::kData;
    info.format =
        ImageDesc::packed(PixelFormat::kBinary, static_cast<int>(kLightRecordMaxBytes), 1);
    info.nominal_fps = fps;
    info.tags["light_of"] = light_of;
    info.tags["light_record"] = "mixray-lights-1";
    return info;
}

LightGroup toLightGroup(std::string name, const Estimate<std::vector<EstimatedLight>>& e) {
    LightGroup group = groupOf(std::move(name), e);
    if (e.value)
        addLights(&group, *e.value);
    return group;
}

LightGroup toLightGroup(std::string name, const Estimate<ProbeResult>& e) {
    LightGroup group = groupOf(std::move(name), e);
    if (e.value)
        addLights(&group, e.value->lights);
    return group;
}

LightGroup toLightGroup(std::string name, const Estimate<EnvironmentEstimate>& e) {
    LightGroup group = groupOf(std::move(name), e);
    if (e.value)
        addLights(&group, e.value->lights);
    return group;
}

LightGroup toLightGroup(std::string name, const Estimate<EstimatedLight>& e) {
    LightGroup group = groupOf(std::move(name), e);
    if (e.value)
        group.lights.push_back(*e.value);
    return group;
}

EnvironmentMapHeader toEnvironmentMapHeader(uint64_t frame_sequence, int64_t frame_device_stamp_ns,
                                            const Estimate<EnvironmentEstimate>& e) {
    const LightGroup group = groupOf(std::string(), e);
    EnvironmentMapHeader header;
    header.frame_sequence = frame_sequence;
    header.frame_device_stamp_ns = frame_device_stamp_ns;
    header.stale = group.stale;
    header.reason = group.reason;
    header.stamp_ns = group.stamp_ns;
    header.good_stamp_ns = group.good_stamp_ns;
    return header;
}

size_t environmentMapRecordBytes(int width, int height) {
    if (width < 1 || height < 1 || width > kEnvironmentMapMaxSide ||
        height > kEnvironmentMapMaxSide ||
        static_cast<size_t>(width) * static_cast<size_t>(height) > kEnvironmentMapMaxPixels)
        return 0;
    return kEnvironmentMapHeaderBytes +
           static_cast<size_t>(width) * static_cast<size_t>(height) * 3 * sizeof(float) + 4;
}

Result<size_t> encodeEnvironmentMapRecord(const FloatImage& map, const EnvironmentMapHeader& header,
                                          uint8_t* out, size_t capacity) {
    const size_t bytes = environmentMapRecordBytes(map.width, map.height);
    if (bytes == 0)
        return invalid("environment map",
                       "size " + std::to_string(map.width) + "x" + std::to_string(map.height) +
                           " is out of bounds (1 to " + std::to_string(kEnvironmentMapMaxSide) +
                           " per side, at most " + std::to_string(kEnvironmentMapMaxPixels) +
                           " pixels)");
    const size_t values = static_cast<size_t>(map.width) * static_cast<size_t>(map.height) * 3;
    if (map.channels != 3 || map.pixels.size() != values)
        return invalid("environment map", "the map must have 3 channels and " +
                                              std::to_string(values) + " values, got " +
                                              std::to_string(map.channels) + " channels and " +
                                              std::to_string(map.pixels.size()) + " values");
    MIXRAY_RETURN_IF_ERROR(validateReason(header.stale, header.reason, "", "environment map"));
    if (out == nullptr || capacity < bytes)
        return invalid("environment map", "the buffer holds " + std::to_string(capacity) +
                                              " bytes, the record needs " + std::to_string(bytes));
    for (size_t i = 0; i < values; ++i)
        if (!std::isfinite(map.pixels[i]))
            return invalid("environment map", "value " + std::to_string(i) + " is not finite");
    std::memset(out, 0, kEnvironmentMapHeaderBytes);
    record::putHeader(out, kMapMagic, kEnvironmentMapRecordVersion);
    out[kMapFlags] = header.stale ? kStale : 0;
    out[kMapChannels] = 3;
    putLe(out + kMapWidth, static_cast<uint32_t>(map.width), 4);
    putLe(out + kMapHeight, static_cast<uint32_t>(map.height), 4);
    putLe(out + kMapSequence, header.frame_sequence, 8);
    putLe(out + kMapFrameStamp, static_cast<uint64_t>(header.frame_device_stamp_ns), 8);
    putLe(out + kMapStamp, static_cast<uint64_t>(header.stamp_ns), 8);
    putLe(out + kMapGoodStamp, static_cast<uint64_t>(header.good_stamp_ns), 8);
    record::putPaddedText(out + kMapReason, kMapReasonField, header.reason);
    uint8_t* p = out + kEnvironmentMapHeaderBytes;
    for (size_t i = 0; i < values; ++i, p += 4)
        putF32(p, map.pixels[i]);
    record::putCrc(out, bytes);
    return bytes;
}

Result<EnvironmentMapRecord> decodeEnvironmentMapRecord(const uint8_t* data, size_t size) {
    const auto corrupt = [](const std::string& what) {
        return record::corrupt("environment map", what);
    };
    constexpr size_t kSmallest = kEnvironmentMapHeaderBytes + 4;
    if (data == nullptr || size < kSmallest)
        return corrupt("expected at least " + std::to_string(kSmallest) + " bytes, got " +
                       std::to_string(data == nullptr ? 0 : size));
    if (getLe(data, 4) != kMapMagic)
        return corrupt("bad magic (not a mixray environment map record)");
    const auto width = static_cast<uint32_t>(getLe(data + kMapWidth, 4));
    const auto height = static_cast<uint32_t>(getLe(data + kMapHeight, 4));
    const size_t bytes =
        width > static_cast<uint32_t>(kEnvironmentMapMaxSide) ||
                height > static_cast<uint32_t>(kEnvironmentMapMaxSide)
            ? 0
            : environmentMapRecordBytes(static_cast<int>(width), static_cast<int>(height));
    if (bytes == 0)
        return corrupt("size " + std::to_string(width) + "x" + std::to_string(height) +
                       " is out of bounds");
    if (bytes != size)
        return corrupt("a " + std::to_string(width) + "x" + std::to_string(height) + " map needs " +
                       std::to_string(bytes) + " bytes, the payload has " + std::to_string(size));
    MIXRAY_RETURN_IF_ERROR(record::checkFrame(data, size, size, kMapMagic,
                                              kEnvironmentMapRecordVersion, "environment map"));
    if ((data[kMapFlags] & ~kStale) != 0)
        return corrupt("reserved flag bits are not zero");
    if (data[kMapChannels] != 3)
        return corrupt("channels " + std::to_string(data[kMapChannels]) + " is not 3");
    EnvironmentMapRecord r;
    EnvironmentMapHeader& h = r.header;
    h.stale = (data[kMapFlags] & kStale) != 0;
    h.frame_sequence = getLe(data + kMapSequence, 8);
    h.frame_device_stamp_ns = static_cast<int64_t>(getLe(data + kMapFrameStamp, 8));
    h.stamp_ns = static_cast<int64_t>(getLe(data + kMapStamp, 8));
    h.good_stamp_ns = static_cast<int64_t>(getLe(data + kMapGoodStamp, 8));
    MIXRAY_RETURN_IF_ERROR(record::getPaddedText(data + kMapReason, kMapReasonField,
                                                 "environment map", "reason", &h.reason));
    if (Status s = validateReason(h.stale, h.reason, "", "environment map"); !s)
        return Status(ErrorCode::kCorruptData, s.message());
    r.map.width = static_cast<int>(width);
    r.map.height = static_cast<int>(height);
    r.map.channels = 3;
    const size_t values = static_cast<size_t>(width) * height * 3;
    r.map.pixels.resize(values);
    const uint8_t* p = data + kEnvironmentMapHeaderBytes;
    for (size_t i = 0; i < values; ++i, p += 4) {
        r.map.pixels[i] = getF32(p);
        if (!std::isfinite(r.map.pixels[i]))
            return corrupt("value " + std::to_string(i) + " is not finite");
    }
    return r;
}

StreamInfo makeEnvironmentMapStreamInfo(const std::string& name, const std::string& map_of,
                                        int width, int height) {
    StreamInfo info;
    info.name = name;
    info.device = name.substr(0, name.find('/'));
    info.kind = StreamKind::kData;
    info.format = ImageDesc::packed(PixelFormat::kBinary,
                                    static_cast<int>(environmentMapRecordBytes(width, height)), 1);
    info.nominal_fps = 0;
    info.tags["map_of"] = map_of;
    info.tags["environment_map_record"] = "mixray-envmap-1";
    info.tags["map_width"] = std::to_string(width);
    info.tags["map_height"] = std::to_string(height);
    return info;
}

RecordStreamKind recordStreamKind(const StreamInfo& info) {
    if (info.tags.count("light_record"))
        return RecordStreamKind::kLight;
    if (info.tags.count("environment_map_record"))
        return RecordStreamKind::kEnvironmentMap;
    if (info.kind == StreamKind::kPose || info.tags.count("pose_record"))
        return RecordStreamKind::kPose;
    return RecordStreamKind::kNone;
}

Result<RecordDigest> digestRecord(RecordStreamKind kind, const ImageView& payload) {
    RecordDigest digest;
    switch (kind) {
        case RecordStreamKind::kNone:
            break;
        case RecordStreamKind::kPose: {
            auto pose = decodePoseRecord(payload);
            if (!pose)
                return pose.status();
            digest.stale = pose->status == PoseStatus::kStale;
            digest.lost = pose->status == PoseStatus::kLost;
            digest.reason = pose->reason;
            return digest;
        }
        case RecordStreamKind::kLight: {
            auto lights = decodeLightRecord(payload);
            if (!lights)
                return lights.status();
            for (const LightGroup& group : lights->groups) {
                if (!group.stale)
                    continue;
                if (digest.reason.empty() && !group.reason.empty())
                    digest.reason = group.name + ": " + group.reason;
                digest.stale = true;
            }
            return digest;
        }
        case RecordStreamKind::kEnvironmentMap: {
            auto map = decodeEnvironmentMapRecord(payload);
            if (!map)
                return map.status();
            digest.stale = map->header.stale;
            digest.reason = map->header.reason;
            return digest;
        }
    }
    return Status(ErrorCode::kInvalidArgument, "not a pose, light or environment-map stream");
}

}  // namespace mixray::tracking
