// Deprojecting depth frames to organized clouds, PCD/PLY encoding and parsing, the cloud writer.
#include "mixray/replay/point_cloud.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "image_files.h"
#include "mixray/replay/depth_units.h"
#include "mixray/replay/tum.h"

namespace mixray::replay {
namespace {

// Larger clouds are refused by the parsers: no depth camera comes near, and a corrupt count
// must not make a reader allocate gigabytes.
constexpr uint64_t kMaxPoints = uint64_t{1} << 26;

Status corrupt(std::string_view name, const std::string& what) {
    return {ErrorCode::kCorruptData, std::string(name) + ": " + what};
}

bool parseDouble(std::string_view text, double& out) {
    auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc() && end == text.data() + text.size();
}

template <typename T>
bool parseInt(std::string_view text, T& out) {
    auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc() && end == text.data() + text.size();
}

std::vector<std::string_view> splitWords(std::string_view line) {
    std::vector<std::string_view> words;
    size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r'))
            ++i;
        size_t j = i;
        while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r')
            ++j;
        if (j > i)
            words.push_back(line.substr(i, j - i));
        i = j;
    }
    return words;
}

// The next line of `bytes` from `pos` (without its '\n'); false at the end.
bool nextLine(std::string_view bytes, size_t& pos, std::string_view& line) {
    if (pos >= bytes.size())
        return false;
    const size_t end = bytes.find('\n', pos);
    if (end == std::string_view::npos) {
        line = bytes.substr(pos);
        pos = bytes.size();
    } else {
        line = bytes.substr(pos, end - pos);
        pos = end + 1;
    }
    return true;
}

std::string formatDouble(double v) {
    char text[64];
    auto [end, ec] = std::to_chars(text, text + sizeof text, v);
    return ec == std::errc() ? std::string(text, end) : std::string("nan");
}

std::string formatFloat(float v) {
    if (std::isnan(v))
        return "nan";
    char text[48];
    auto [end, ec] = std::to_chars(text, text + sizeof text, v);
    return ec == std::errc() ? std::string(text, end) : std::string("nan");
}

void appendBytes(std::string& out, const void* data, size_t n) {
    out.append(static_cast<const char*>(data), n);
}

// liblzf's decompressor, as PCL's binary_compressed PCD uses it: a control byte below 32 starts
// a literal run of ctrl + 1 bytes; otherwise a back reference of length (ctrl >> 5) + 2 (7 in
// the top bits: one more length byte follows) at distance ((ctrl & 31) << 8) + next byte + 1.
bool lzfDecompress(std::string_view in, std::vector<uint8_t>& out) {
    size_t ip = 0;
    size_t op = 0;
    while (ip < in.size()) {
        const unsigned ctrl = static_cast<uint8_t>(in[ip++]);
        if (ctrl < 32) {
            const size_t run = ctrl + 1;
            if (ip + run > in.size() || op + run > out.size())
                return false;
            std::memcpy(out.data() + op, in.data() + ip, run);
            ip += run;
            op += run;
            continue;
        }
        size_t len = ctrl >> 5;
        if (len == 7) {
            if (ip >= in.size())
                return false;
            len += static_cast<uint8_t>(in[ip++]);
        }
        if (ip >= in.size())
            return false;
        const size_t distance = ((ctrl & 31u) << 8) + static_cast<uint8_t>(in[ip++]) + 1;
        len += 2;
        if (distance > op || op + len > out.size())
            return false;
        for (size_t i = 0; i < len; ++i, ++op)
            out[op] = out[op - distance];  // byte by byte: the source may overlap the output
    }
    return op == out.size();
}

// Unpacks PCL's packed colour (0x00RRGGBB in a 4-byte field, little endian) into R, G, B.
void unpackRgb(const uint8_t* field, uint8_t* rgb) {
    rgb[0] = field[2];
    rgb[1] = field[1];
    rgb[2] = field[0];
}

}  // namespace

Status PinholeIntrinsics::validate() const {
    if (!std::isfinite(fx) || !std::isfinite(fy) || !std::isfinite(cx) || !std::isfinite(cy)) {
        return {ErrorCode::kInvalidArgument, "intrinsics must be finite numbers"};
    }
    if (fx <= 0 || fy <= 0) {
        return {ErrorCode::kInvalidArgument,
                "intrinsics: focal lengths fx and fy must be positive (got " + formatDouble(fx) +
                    ", " + formatDouble(fy) + ")"};
    }
    return Status::ok();
}

Result<PinholeIntrinsics> parseIntrinsics(std::string_view text) {
    static constexpr const char* kNames[] = {"fx", "fy", "cx", "cy"};
    double values[4] = {};
    size_t count = 0;
    size_t pos = 0;
    while (true) {
        const size_t comma = text.find(',', pos);
        std::string_view part = text.substr(
            pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos);
        while (!part.empty() && part.front() == ' ')
            part.remove_prefix(1);
        while (!part.empty() && part.back() == ' ')
            part.remove_suffix(1);
        if (count == 4) {
            return {ErrorCode::kInvalidArgument,
                    "intrinsics '" + std::string(text) + "': expected 4 values fx,fy,cx,cy"};
        }
        if (!parseDouble(part, values[count])) {
            return {ErrorCode::kInvalidArgument, "intrinsics '" + std::string(text) +
                                                     "': " + kNames[count] + " '" +
                                                     std::string(part) + "' is not a number"};
        }
        ++count;
        if (comma == std::string_view::npos)
            break;
        pos = comma + 1;
    }
    if (count != 4) {
        return {ErrorCode::kInvalidArgument, "intrinsics '" + std::string(text) +
                                                 "': expected 4 values fx,fy,cx,cy, got " +
                                                 std::to_string(count)};
    }
    PinholeIntrinsics k{values[0], values[1], values[2], values[3]};
    MIXRAY_RETURN_IF_ERROR(k.validate());
    return k;
}

std::string formatIntrinsics(const PinholeIntrinsics& k) {
    return formatDouble(k.fx) + "," + formatDouble(k.fy) + "," + formatDouble(k.cx) + "," +
           formatDouble(k.cy);
}

Result<PinholeIntrinsics> parsePclCameraXml(std::string_view text, std::string_view file_name) {
    const size_t begin = text.find("<depth>");
    const size_t end = text.find("</depth>");
    if (begin == std::string_view::npos || end == std::string_view::npos || end < begin) {
        return corrupt(file_name, "no <depth> element with the depth camera's intrinsics");
    }
    const std::string_view depth = text.substr(begin, end - begin);
    const auto element = [&](const char* tag, double& out) -> Status {
        const std::string start = std::string("<") + tag + ">";
        const std::string stop = std::string("</") + tag + ">";
        const size_t a = depth.find(start);
        const size_t b = a == std::string_view::npos ? a : depth.find(stop, a);
        if (b == std::string_view::npos)
            return corrupt(file_name, std::string("<depth> has no <") + tag + ">");
        std::string_view value = depth.substr(a + start.size(), b - a - start.size());
        while (!value.empty() && (value.front() == ' ' || value.front() == '\n'))
            value.remove_prefix(1);
        while (!value.empty() && (value.back() == ' ' || value.back() == '\n'))
            value.remove_suffix(1);
        if (!parseDouble(value, out)) {
            return corrupt(file_name, std::string("<depth><") + tag + "> '" + std::string(value) +
                                          "' is not a number");
        }
        return Status::ok();
    };
    PinholeIntrinsics k;
    MIXRAY_RETURN_IF_ERROR(element("focal_length_x", k.fx));
    MIXRAY_RETURN_IF_ERROR(element("focal_length_y", k.fy));
    MIXRAY_RETURN_IF_ERROR(element("principal_point_x", k.cx));
    MIXRAY_RETURN_IF_ERROR(element("principal_point_y", k.cy));
    Status valid = k.validate();
    if (!valid)
        return corrupt(file_name, valid.message());
    return k;
}

Result<PointCloud> deprojectDepth(const ImageView& depth, int depth_per_m,
                                  const PinholeIntrinsics& k, const ImageView* color) {
    MIXRAY_RETURN_IF_ERROR(k.validate());
    if (depth.desc.format != PixelFormat::kDepth16) {
        return {ErrorCode::kInvalidArgument, "deprojectDepth: the depth image is " +
                                                 std::string(toString(depth.desc.format)) +
                                                 ", expected depth16"};
    }
    if (depth_per_m <= 0)
        return {ErrorCode::kInvalidArgument, "deprojectDepth: depth units must be positive"};
    bool bgr = false;
    if (color) {
        if (color->desc.format != PixelFormat::kRGB8 && color->desc.format != PixelFormat::kBGR8) {
            return {ErrorCode::kInvalidArgument, "deprojectDepth: colour is " +
                                                     std::string(toString(color->desc.format)) +
                                                     ", expected rgb8 or bgr8"};
        }
        if (color->desc.width != depth.desc.width || color->desc.height != depth.desc.height) {
            return {ErrorCode::kInvalidArgument,
                    "deprojectDepth: registered colour must have the depth's size (" +
                        std::to_string(depth.desc.width) + "x" + std::to_string(depth.desc.height) +
                        "), got " + std::to_string(color->desc.width) + "x" +
                        std::to_string(color->desc.height)};
        }
        bgr = color->desc.format == PixelFormat::kBGR8;
    }
    PointCloud cloud;
    cloud.width = depth.desc.width;
    cloud.height = depth.desc.height;
    cloud.xyz.resize(cloud.size() * 3);
    if (color)
        cloud.rgb.resize(cloud.size() * 3);
    // PCL's arithmetic, in its order and precision (see the header).
    const float units = static_cast<float>(1.0 / depth_per_m);
    const float inv_fx = 1.f / static_cast<float>(k.fx);
    const float inv_fy = 1.f / static_cast<float>(k.fy);
    const float cx = static_cast<float>(k.cx);
    const float cy = static_cast<float>(k.cy);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    size_t i = 0;
    for (int v = 0; v < cloud.height; ++v) {
        const uint16_t* row = depth.row<uint16_t>(v);
        const uint8_t* crow = color ? color->row<uint8_t>(v) : nullptr;
        for (int u = 0; u < cloud.width; ++u, ++i) {
            float* p = &cloud.xyz[i * 3];
            const float z = static_cast<float>(row[u]) * units;
            if (z == 0.0f) {
                p[0] = p[1] = p[2] = nan;
            } else {
                p[0] = (static_cast<float>(u) - cx) * inv_fx * z;
                p[1] = (static_cast<float>(v) - cy) * inv_fy * z;
                p[2] = z;
            }
            if (crow) {
                const uint8_t* c = crow + static_cast<size_t>(u) * 3;
                uint8_t* out = &cloud.rgb[i * 3];
                out[0] = bgr ? c[2] : c[0];
                out[1] = c[1];
                out[2] = bgr ? c[0] : c[2];
            }
        }
    }
    return cloud;
}

std::string encodePcd(const PointCloud& cloud, PcdEncoding encoding) {
    const bool rgb = cloud.hasColor();
    std::string out;
    out += "# .PCD v0.7 - Point Cloud Data file format (written by mixray)\n";
    out += "VERSION 0.7\n";
    out += rgb ? "FIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
               : "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
    out += "WIDTH " + std::to_string(cloud.width) + "\n";
    out += "HEIGHT " + std::to_string(cloud.height) + "\n";
    out += "VIEWPOINT 0 0 0 1 0 0 0\n";
    out += "POINTS " + std::to_string(cloud.size()) + "\n";
    const size_t n = cloud.size();
    const auto packed = [&](size_t i) {
        const uint8_t* c = &cloud.rgb[i * 3];
        return (uint32_t{c[0]} << 16) | (uint32_t{c[1]} << 8) | uint32_t{c[2]};
    };
    if (encoding == PcdEncoding::kAscii) {
        out += "DATA ascii\n";
        for (size_t i = 0; i < n; ++i) {
            const float* p = &cloud.xyz[i * 3];
            out += formatFloat(p[0]) + " " + formatFloat(p[1]) + " " + formatFloat(p[2]);
            if (rgb)
                out += " " + std::to_string(packed(i));
            out += "\n";
        }
        return out;
    }
    out += "DATA binary\n";
    out.reserve(out.size() + n * (rgb ? 16 : 12));
    for (size_t i = 0; i < n; ++i) {
        appendBytes(out, &cloud.xyz[i * 3], 12);
        if (rgb) {
            const uint32_t value = packed(i);
            appendBytes(out, &value, 4);
        }
    }
    return out;
}

std::string encodePly(const PointCloud& cloud) {
    const bool rgb = cloud.hasColor();
    std::string out;
    out += "ply\nformat binary_little_endian 1.0\n";
    out += "comment written by mixray: an organized cloud, NaN where there is no depth\n";
    out += "comment width " + std::to_string(cloud.width) + "\n";
    out += "comment height " + std::to_string(cloud.height) + "\n";
    out += "obj_info num_cols " + std::to_string(cloud.width) + "\n";
    out += "obj_info num_rows " + std::to_string(cloud.height) + "\n";
    out += "element vertex " + std::to_string(cloud.size()) + "\n";
    out += "property float x\nproperty float y\nproperty float z\n";
    if (rgb)
        out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    out += "end_header\n";
    const size_t n = cloud.size();
    out.reserve(out.size() + n * (rgb ? 15 : 12));
    for (size_t i = 0; i < n; ++i) {
        appendBytes(out, &cloud.xyz[i * 3], 12);
        if (rgb)
            appendBytes(out, &cloud.rgb[i * 3], 3);
    }
    return out;
}

Status writePointCloud(const std::filesystem::path& file, const PointCloud& cloud,
                       PointCloudFormat format, PcdEncoding pcd_encoding) {
    const std::string bytes =
        format == PointCloudFormat::kPly ? encodePly(cloud) : encodePcd(cloud, pcd_encoding);
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    if (!out)
        return {ErrorCode::kIoError, file.string() + ": write failed"};
    return Status::ok();
}

Result<PointCloud> parsePcd(std::string_view bytes, std::string_view name) {
    struct Field {
        std::string name;
        unsigned size = 0;
        char type = 0;
        unsigned count = 1;
        size_t offset = 0;  // in a binary point record
    };
    std::vector<Field> fields;
    uint64_t width = 0, height = 1, points = 0;
    bool have_width = false, have_points = false;
    std::string data;
    size_t pos = 0;
    std::string_view line;
    int line_no = 0;
    while (data.empty() && nextLine(bytes, pos, line)) {
        ++line_no;
        const auto words = splitWords(line);
        if (words.empty() || words[0][0] == '#')
            continue;
        const std::string where = "line " + std::to_string(line_no) + ": ";
        const std::string_view key = words[0];
        if (key == "VERSION" || key == "VIEWPOINT")
            continue;
        if (key == "FIELDS") {
            fields.clear();
            for (size_t i = 1; i < words.size(); ++i)
                fields.push_back({std::string(words[i])});
        } else if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
            if (words.size() != fields.size() + 1)
                return corrupt(name, where + std::string(key) + " does not match FIELDS");
            for (size_t i = 0; i < fields.size(); ++i) {
                const std::string_view w = words[i + 1];
                if (key == "TYPE") {
                    if (w.size() != 1 || (w[0] != 'F' && w[0] != 'U' && w[0] != 'I'))
                        return corrupt(name, where + "TYPE '" + std::string(w) + "'");
                    fields[i].type = w[0];
                } else {
                    unsigned value = 0;
                    if (!parseInt(w, value) || value == 0 || value > 1024) {
                        return corrupt(name, where + std::string(key) + " '" + std::string(w) +
                                                 "' is not a sensible number");
                    }
                    (key == "SIZE" ? fields[i].size : fields[i].count) = value;
                }
            }
        } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
            uint64_t value = 0;
            if (words.size() != 2 || !parseInt(words[1], value) || value > kMaxPoints)
                return corrupt(name, where + std::string(key) + " is not a count up to 2^26");
            if (key == "WIDTH") {
                width = value;
                have_width = true;
            } else if (key == "HEIGHT") {
                height = value;
            } else {
                points = value;
                have_points = true;
            }
        } else if (key == "DATA") {
            if (words.size() != 2)
                return corrupt(name, where + "DATA needs one word");
            data = std::string(words[1]);
        } else {
            return corrupt(name, where + "unknown header key '" + std::string(key) + "'");
        }
    }
    if (data.empty())
        return corrupt(name, "no DATA line (not a PCD file?)");
    if (!have_width)
        return corrupt(name, "no WIDTH");
    if (!have_points)
        points = width * height;
    if (width * height != points)
        return corrupt(name, "WIDTH x HEIGHT is not POINTS");
    const Field* fx = nullptr;
    const Field* fy = nullptr;
    const Field* fz = nullptr;
    const Field* fc = nullptr;
    size_t record = 0;
    size_t values_per_point = 0;
    for (Field& f : fields) {
        if (f.size == 0 || f.type == 0)
            return corrupt(name, "field '" + f.name + "' lacks SIZE or TYPE");
        f.offset = record;
        record += static_cast<size_t>(f.size) * f.count;
        values_per_point += f.count;
    }
    for (const Field& f : fields) {
        if (f.name == "x")
            fx = &f;
        else if (f.name == "y")
            fy = &f;
        else if (f.name == "z")
            fz = &f;
        else if (f.name == "rgb" || f.name == "rgba")
            fc = &f;
    }
    for (const Field* f : {fx, fy, fz}) {
        if (!f || f->type != 'F' || f->size != 4 || f->count != 1)
            return corrupt(name, "fields x, y and z must be present as 4-byte floats");
    }
    if (fc && (fc->size != 4 || fc->count != 1))
        return corrupt(name, "field '" + fc->name + "' must be one 4-byte value");

    PointCloud cloud;
    cloud.width = static_cast<int>(width);
    cloud.height = static_cast<int>(height);
    const size_t n = static_cast<size_t>(points);
    const std::string_view body = bytes.substr(pos);
    // Gathers x, y, z and colour of point i from a record-major or field-major layout.
    const auto gather = [&](const uint8_t* base, bool field_major) {
        cloud.xyz.resize(n * 3);
        if (fc)
            cloud.rgb.resize(n * 3);
        for (size_t i = 0; i < n; ++i) {
            const auto at = [&](const Field& f) {
                return field_major ? base + f.offset * n + i * f.size
                                   : base + i * record + f.offset;
            };
            std::memcpy(&cloud.xyz[i * 3 + 0], at(*fx), 4);
            std::memcpy(&cloud.xyz[i * 3 + 1], at(*fy), 4);
            std::memcpy(&cloud.xyz[i * 3 + 2], at(*fz), 4);
            if (fc)
                unpackRgb(at(*fc), &cloud.rgb[i * 3]);
        }
    };
    if (data == "binary") {
        if (body.size() < n * record) {
            return corrupt(name, "binary data holds " + std::to_string(body.size()) + " bytes, " +
                                     std::to_string(n * record) + " needed");
        }
        gather(reinterpret_cast<const uint8_t*>(body.data()), false);
        return cloud;
    }
    if (data == "binary_compressed") {
        uint32_t compressed = 0, raw = 0;
        if (body.size() < 8)
            return corrupt(name, "binary_compressed data lacks its sizes");
        std::memcpy(&compressed, body.data(), 4);
        std::memcpy(&raw, body.data() + 4, 4);
        if (compressed > body.size() - 8)
            return corrupt(name, "compressed data is truncated");
        if (raw != n * record)
            return corrupt(name, "uncompressed size does not match the fields and POINTS");
        // LZF expands at most ~132 times: a larger claim is corrupt, not worth allocating.
        if (uint64_t{raw} > uint64_t{compressed} * 140 + 64)
            return corrupt(name, "uncompressed size is impossible for the compressed size");
        std::vector<uint8_t> unpacked(raw);
        if (!lzfDecompress(body.substr(8, compressed), unpacked))
            return corrupt(name, "compressed data does not decompress (LZF)");
        gather(unpacked.data(), true);
        return cloud;
    }
    if (data != "ascii")
        return corrupt(name, "DATA '" + data + "': expected ascii, binary or binary_compressed");
    if (body.size() < n)  // every point takes a line
        return corrupt(name, "ascii data has fewer lines than POINTS");
    cloud.xyz.resize(n * 3);
    if (fc)
        cloud.rgb.resize(n * 3);
    size_t p = 0;
    for (size_t i = 0; i < n; ++i) {
        if (!nextLine(body, p, line))
            return corrupt(name, "ascii data ends at point " + std::to_string(i));
        const auto words = splitWords(line);
        if (words.size() != values_per_point) {
            return corrupt(name, "ascii point " + std::to_string(i) + " has " +
                                     std::to_string(words.size()) + " values, expected " +
                                     std::to_string(values_per_point));
        }
        size_t w = 0;
        for (const Field& f : fields) {
            const std::string_view text = words[w];
            w += f.count;
            float* target = &f == fx   ? &cloud.xyz[i * 3]
                            : &f == fy ? &cloud.xyz[i * 3 + 1]
                            : &f == fz ? &cloud.xyz[i * 3 + 2]
                                       : nullptr;
            if (target) {
                double value = 0;
                if (text == "nan" || text == "NaN" || text == "-nan")
                    value = std::numeric_limits<double>::quiet_NaN();
                else if (!parseDouble(text, value))
                    return corrupt(name, "ascii point " + std::to_string(i) + ": '" +
                                             std::string(text) + "' is not a number");
                *target = static_cast<float>(value);
            } else if (&f == fc) {
                uint8_t packed[4] = {};
                if (f.type == 'F') {
                    float value = 0;
                    double d = 0;
                    if (!parseDouble(text, d))
                        return corrupt(name, "ascii colour '" + std::string(text) + "'");
                    value = static_cast<float>(d);
                    std::memcpy(packed, &value, 4);
                } else {
                    uint32_t value = 0;
                    if (!parseInt(text, value))
                        return corrupt(name, "ascii colour '" + std::string(text) + "'");
                    std::memcpy(packed, &value, 4);
                }
                unpackRgb(packed, &cloud.rgb[i * 3]);
            }
        }
    }
    return cloud;
}

Result<PointCloud> parsePly(std::string_view bytes, std::string_view name) {
    size_t pos = 0;
    std::string_view line;
    if (!nextLine(bytes, pos, line) || splitWords(line) != std::vector<std::string_view>{"ply"})
        return corrupt(name, "does not start with 'ply'");
    enum class Encoding { kNone, kAscii, kBinaryLE } encoding = Encoding::kNone;
    struct Property {
        std::string name;
        std::string type;
        unsigned size = 0;
    };
    std::vector<Property> props;
    uint64_t vertices = 0;
    int64_t cols = -1, rows = -1;
    bool in_vertex = false, seen_vertex = false, ended = false;
    int line_no = 1;
    const std::map<std::string_view, unsigned> sizes = {
        {"char", 1},  {"uchar", 1},   {"int8", 1},   {"uint8", 1},  {"short", 2}, {"ushort", 2},
        {"int16", 2}, {"uint16", 2},  {"int", 4},    {"uint", 4},   {"int32", 4}, {"uint32", 4},
        {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
    while (!ended && nextLine(bytes, pos, line)) {
        ++line_no;
        const auto words = splitWords(line);
        const std::string where = "header line " + std::to_string(line_no) + ": ";
        if (words.empty())
            continue;
        const std::string_view key = words[0];
        if (key == "format") {
            if (words.size() != 3 || words[2] != "1.0")
                return corrupt(name, where + "bad format line");
            if (words[1] == "ascii")
                encoding = Encoding::kAscii;
            else if (words[1] == "binary_little_endian")
                encoding = Encoding::kBinaryLE;
            else
                return corrupt(name, where + "format '" + std::string(words[1]) +
                                         "' (ascii and binary_little_endian are read)");
        } else if (key == "comment" || key == "obj_info") {
            if (words.size() == 3) {
                int64_t value = 0;
                if ((words[1] == "num_cols" || words[1] == "width") && parseInt(words[2], value))
                    cols = value;
                if ((words[1] == "num_rows" || words[1] == "height") && parseInt(words[2], value))
                    rows = value;
            }
        } else if (key == "element") {
            if (words.size() != 3)
                return corrupt(name, where + "bad element line");
            if (seen_vertex) {
                in_vertex = false;  // later elements (faces) are not read
                continue;
            }
            if (words[1] != "vertex") {
                return corrupt(name, where + "element '" + std::string(words[1]) +
                                         "' before the vertices (vertex must come first)");
            }
            if (!parseInt(words[2], vertices) || vertices > kMaxPoints)
                return corrupt(name, where + "vertex count is not a count up to 2^26");
            in_vertex = seen_vertex = true;
        } else if (key == "property") {
            if (!in_vertex)
                continue;
            if (words.size() != 3) {
                return corrupt(name, where +
                                         "vertex properties must be scalars ('property "
                                         "<type> <name>')");
            }
            auto it = sizes.find(words[1]);
            if (it == sizes.end())
                return corrupt(name, where + "unknown type '" + std::string(words[1]) + "'");
            props.push_back({std::string(words[2]), std::string(words[1]), it->second});
        } else if (key == "end_header") {
            ended = true;
        } else {
            return corrupt(name, where + "unknown header line '" + std::string(key) + "'");
        }
    }
    if (!ended)
        return corrupt(name, "no end_header");
    if (encoding == Encoding::kNone)
        return corrupt(name, "no format line");
    if (!seen_vertex)
        return corrupt(name, "no vertex element");
    int ix = -1, iy = -1, iz = -1, ir = -1, ig = -1, ib = -1;
    size_t record = 0;
    std::vector<size_t> offsets;
    for (size_t i = 0; i < props.size(); ++i) {
        offsets.push_back(record);
        record += props[i].size;
        const std::string& n = props[i].name;
        const bool is_float = props[i].type == "float" || props[i].type == "float32" ||
                              props[i].type == "double" || props[i].type == "float64";
        const bool is_uchar = props[i].type == "uchar" || props[i].type == "uint8";
        int* slot = n == "x"       ? &ix
                    : n == "y"     ? &iy
                    : n == "z"     ? &iz
                    : n == "red"   ? &ir
                    : n == "green" ? &ig
                    : n == "blue"  ? &ib
                                   : nullptr;
        if (!slot)
            continue;
        if ((slot == &ix || slot == &iy || slot == &iz) && !is_float)
            return corrupt(name, "property " + n + " must be float or double");
        if ((slot == &ir || slot == &ig || slot == &ib) && !is_uchar)
            return corrupt(name, "property " + n + " must be uchar");
        *slot = static_cast<int>(i);
    }
    if (ix < 0 || iy < 0 || iz < 0)
        return corrupt(name, "vertices lack x, y or z");
    const bool rgb = ir >= 0 && ig >= 0 && ib >= 0;
    PointCloud cloud;
    if (cols > 0 && rows > 0 &&
        static_cast<uint64_t>(cols) * static_cast<uint64_t>(rows) == vertices) {
        cloud.width = static_cast<int>(cols);
        cloud.height = static_cast<int>(rows);
    } else {
        cloud.width = static_cast<int>(vertices);
        cloud.height = 1;
    }
    const size_t n = static_cast<size_t>(vertices);
    const std::string_view body = bytes.substr(pos);
    if (encoding == Encoding::kBinaryLE) {
        if (body.size() < n * record) {
            return corrupt(name, "vertex data holds " + std::to_string(body.size()) + " bytes, " +
                                     std::to_string(n * record) + " needed");
        }
    } else if (body.size() < n) {
        return corrupt(name, "ascii vertex data has fewer lines than vertices");
    }
    cloud.xyz.resize(n * 3);
    if (rgb)
        cloud.rgb.resize(n * 3);
    const int xyz_index[3] = {ix, iy, iz};
    const int rgb_index[3] = {ir, ig, ib};
    size_t p = 0;
    for (size_t i = 0; i < n; ++i) {
        if (encoding == Encoding::kBinaryLE) {
            const char* base = body.data() + i * record;
            for (int c = 0; c < 3; ++c) {
                const size_t k = static_cast<size_t>(xyz_index[c]);
                if (props[k].size == 4) {
                    std::memcpy(&cloud.xyz[i * 3 + c], base + offsets[k], 4);
                } else {
                    double d = 0;
                    std::memcpy(&d, base + offsets[k], 8);
                    cloud.xyz[i * 3 + c] = static_cast<float>(d);
                }
                if (rgb)
                    cloud.rgb[i * 3 + c] =
                        static_cast<uint8_t>(base[offsets[static_cast<size_t>(rgb_index[c])]]);
            }
            continue;
        }
        if (!nextLine(body, p, line))
            return corrupt(name, "ascii vertex data ends at vertex " + std::to_string(i));
        const auto words = splitWords(line);
        if (words.size() != props.size())
            return corrupt(name, "ascii vertex " + std::to_string(i) + " has a wrong value count");
        for (int c = 0; c < 3; ++c) {
            const std::string_view text = words[static_cast<size_t>(xyz_index[c])];
            double value = 0;
            if (text == "nan" || text == "NaN" || text == "-nan")
                value = std::numeric_limits<double>::quiet_NaN();
            else if (!parseDouble(text, value))
                return corrupt(name, "ascii vertex " + std::to_string(i) + ": '" +
                                         std::string(text) + "' is not a number");
            cloud.xyz[i * 3 + c] = static_cast<float>(value);
            if (rgb) {
                unsigned byte = 0;
                if (!parseInt(words[static_cast<size_t>(rgb_index[c])], byte) || byte > 255)
                    return corrupt(name, "ascii vertex " + std::to_string(i) + ": bad colour");
                cloud.rgb[i * 3 + c] = static_cast<uint8_t>(byte);
            }
        }
    }
    return cloud;
}

Result<PointCloud> readPointCloud(const std::filesystem::path& file) {
    auto bytes = detail::readTextFile(file);
    if (!bytes)
        return bytes.status();
    if (bytes->rfind("ply", 0) == 0)
        return parsePly(*bytes, file.string());
    return parsePcd(*bytes, file.string());
}

Status PointCloudWriterOptions::validate() const {
    if (intrinsics)
        return intrinsics->validate();
    return Status::ok();
}

Result<PinholeIntrinsics> depthIntrinsics(const RecordingHeader& header, StreamId depth,
                                          const PointCloudWriterOptions& options) {
    if (options.intrinsics) {
        MIXRAY_RETURN_IF_ERROR(options.intrinsics->validate());
        return *options.intrinsics;
    }
    if (depth >= header.streams.size())
        return {ErrorCode::kInvalidArgument, "no such depth stream"};
    const StreamInfo& stream = header.streams[depth];
    auto tag = stream.tags.find(kIntrinsicsTag);
    if (tag != stream.tags.end()) {
        auto k = parseIntrinsics(tag->second);
        if (!k) {
            return k.status().withContext("stream '" + stream.name + "' tag " + kIntrinsicsTag);
        }
        return k;
    }
    for (const Attachment& a : header.attachments) {
        if (a.name.size() < 4 || a.name.compare(a.name.size() - 4, 4, ".xml") != 0)
            continue;
        const std::string_view text(reinterpret_cast<const char*>(a.data.data()), a.data.size());
        if (text.find("<focal_length_x>") == std::string_view::npos)
            continue;
        return parsePclCameraXml(text, a.name);
    }
    return {ErrorCode::kNotFound,
            "no intrinsics for depth stream '" + stream.name +
                "': the recording carries none (no " + kIntrinsicsTag +
                " tag, no PCL camera sidecar); give them as fx,fy,cx,cy (--intrinsics)"};
}

namespace {

// One cloud file per depth frame, paired with the registered colour frame nearest in time.
class PointCloudWriter : public RecordingWriter {
public:
    PointCloudWriter(std::filesystem::path dir, PointCloudWriterOptions options, StreamId depth,
                     StreamId color, int depth_per_m, PinholeIntrinsics k, std::ofstream list)
        : dir_(std::move(dir)),
          options_(std::move(options)),
          depth_(depth),
          color_(color),
          depth_per_m_(depth_per_m),
          k_(k),
          list_(std::move(list)) {}

    Status write(const FrameRef& frame) override {
        if (closed_)
            return {ErrorCode::kInvalidArgument, "point cloud writer: write after close"};
        const StreamId stream = frame.meta().stream;
        if (color_ != kInvalidStream && stream == color_) {
            if (pending_depth_) {
                // The depth frame waited for this colour frame: take the nearer of the two.
                const int64_t t = pending_depth_.meta().host_stamp_ns;
                const bool take_new =
                    !last_color_ || std::llabs(frame.meta().host_stamp_ns - t) <
                                        std::llabs(last_color_.meta().host_stamp_ns - t);
                MIXRAY_RETURN_IF_ERROR(emit(pending_depth_, take_new ? frame : last_color_));
                pending_depth_.reset();
            }
            last_color_ = frame;
            return Status::ok();
        }
        if (stream != depth_)
            return Status::ok();
        if (color_ == kInvalidStream)
            return emit(frame, FrameRef());
        if (pending_depth_)
            MIXRAY_RETURN_IF_ERROR(emit(pending_depth_, last_color_));
        pending_depth_ = frame;
        return Status::ok();
    }

    Status close() override {
        if (closed_)
            return Status::ok();
        closed_ = true;
        if (pending_depth_) {
            Status status = emit(pending_depth_, last_color_);
            pending_depth_.reset();
            last_color_.reset();
            MIXRAY_RETURN_IF_ERROR(status);
        }
        last_color_.reset();
        list_.close();
        if (!list_)
            return {ErrorCode::kIoError, (dir_ / "clouds.txt").string() + ": write failed"};
        return Status::ok();
    }

    uint64_t bytesWritten() const override { return bytes_; }

private:
    Status emit(const FrameRef& depth, const FrameRef& color) {
        const ImageView color_view = color ? color.image() : ImageView{};
        auto cloud = deprojectDepth(depth.image(), depth_per_m_, k_, color ? &color_view : nullptr);
        if (!cloud)
            return cloud.status().withContext("frame " + std::to_string(count_));
        char name[32];
        std::snprintf(name, sizeof name, "cloud_%06llu.%s", static_cast<unsigned long long>(count_),
                      options_.format == PointCloudFormat::kPly ? "ply" : "pcd");
        const std::filesystem::path file = dir_ / name;
        MIXRAY_RETURN_IF_ERROR(
            writePointCloud(file, *cloud, options_.format, options_.pcd_encoding));
        std::error_code ec;
        bytes_ += std::filesystem::file_size(file, ec);
        const std::string line = formatTumStamp(depth.meta().host_stamp_ns, 9) + " " + name + "\n";
        list_ << line;
        list_.flush();
        if (!list_)
            return {ErrorCode::kIoError, (dir_ / "clouds.txt").string() + ": write failed"};
        bytes_ += line.size();
        ++count_;
        return Status::ok();
    }

    std::filesystem::path dir_;
    PointCloudWriterOptions options_;
    StreamId depth_;
    StreamId color_;
    int depth_per_m_;
    PinholeIntrinsics k_;
    std::ofstream list_;
    FrameRef pending_depth_;
    FrameRef last_color_;
    uint64_t count_ = 0;
    uint64_t bytes_ = 0;
    bool closed_ = false;
};

}  // namespace

namespace {

// The depth stream a writer with `options` deprojects and the colour stream its points take
// colour from (kInvalidStream: none).
struct CloudStreams {
    StreamId depth = kInvalidStream;
    StreamId color = kInvalidStream;
};

Result<CloudStreams> pickCloudStreams(const RecordingHeader& header,
                                      const PointCloudWriterOptions& options) {
    auto depth =
        detail::pickStream(header, options.depth_stream, StreamKind::kDepth, "point clouds");
    if (!depth)
        return depth.status();
    if (*depth == kInvalidStream) {
        return {ErrorCode::kUnsupported,
                "point clouds: the recording has no depth16 stream to deproject"};
    }
    const StreamInfo& depth_info = header.streams[*depth];
    StreamId color = kInvalidStream;
    auto registered = depth_info.tags.find(kRegisteredToTag);
    if (options.color && registered != depth_info.tags.end()) {
        for (size_t i = 0; i < header.streams.size(); ++i) {
            const StreamInfo& s = header.streams[i];
            if (s.name != registered->second)
                continue;
            if (s.format.format != PixelFormat::kRGB8 && s.format.format != PixelFormat::kBGR8) {
                return {ErrorCode::kUnsupported,
                        "point clouds: colour stream '" + s.name + "' is " +
                            std::string(toString(s.format.format)) +
                            "; points take colour from rgb8 or bgr8 (turn colour off)"};
            }
            if (s.format.width != depth_info.format.width ||
                s.format.height != depth_info.format.height) {
                return {ErrorCode::kUnsupported, "point clouds: depth '" + depth_info.name +
                                                     "' is registered to '" + s.name +
                                                     "' but their sizes differ; turn colour off"};
            }
            color = static_cast<StreamId>(i);
        }
    }
    return CloudStreams{*depth, color};
}

}  // namespace

Result<WriteLosses> pointCloudLosses(const RecordingHeader& header,
                                     const PointCloudWriterOptions& options) {
    auto picked = pickCloudStreams(header, options);
    if (!picked)
        return picked.status();
    WriteLosses losses;
    for (size_t i = 0; i < header.streams.size(); ++i) {
        const auto id = static_cast<StreamId>(i);
        if (id == picked->depth || id == picked->color)
            continue;
        losses.dropped_streams.push_back(id);
        losses.dropped.push_back("stream '" + header.streams[i].name +
                                 "': point clouds hold one depth stream and the colour it is "
                                 "registered to");
    }
    for (const auto& attachment : header.attachments)
        losses.dropped.push_back("attachment '" + attachment.name + "'");
    return losses;
}

Result<std::unique_ptr<RecordingWriter>> createPointCloudWriter(
    const std::filesystem::path& dir, const RecordingHeader& header,
    const PointCloudWriterOptions& options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    auto picked = pickCloudStreams(header, options);
    if (!picked)
        return picked.status();
    const StreamId depth = picked->depth, color = picked->color;
    const StreamInfo& depth_info = header.streams[depth];
    auto scale = depthScalePerMetre(depth_info);
    if (!scale)
        return scale.status();
    auto k = depthIntrinsics(header, depth, options);
    if (!k)
        return k.status();
    MIXRAY_RETURN_IF_ERROR(detail::prepareOutputDir(dir));
    std::ofstream list(dir / "clouds.txt", std::ios::binary | std::ios::trunc);
    if (!list)
        return {ErrorCode::kIoError, (dir / "clouds.txt").string() + ": cannot create"};
    list << "# point clouds of depth stream " << depth_info.name
         << " (mixray convert); intrinsics fx,fy,cx,cy " << formatIntrinsics(*k) << "\n"
         << "# timestamp filename\n";
    return std::unique_ptr<RecordingWriter>(
        new PointCloudWriter(dir, options, depth, color, *scale, *k, std::move(list)));
}

}  // namespace mixray::replay
