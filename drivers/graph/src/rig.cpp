// Rig file parsing: a cheap pre-scan, yaml-cpp (exceptions caught here), then a strict walk of
// the schema into plain structs, then cross-entry validation.
#include "mixray/graph/rig.h"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <span>
#include <sstream>
#include <system_error>
#include <type_traits>
#include <variant>

#include "mixray/graph/field_errors.h"

namespace mixray {
namespace {

constexpr size_t kMaxNameLength = 64;
constexpr size_t kMaxCapacity = 4096;
constexpr int kMaxImageSide = 65535;
constexpr double kMaxFps = 10000;
constexpr double kMaxSkewMs = 10000;
constexpr std::string_view kModeSyntax = "WIDTHxHEIGHT@FPS like 640x480@30";

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

template <typename T>
bool parseWhole(std::string_view text, T& value) {
    if (text.empty())
        return false;
    if constexpr (std::is_floating_point_v<T>) {
        // from_chars accepts "inf" and "nan"; rig numbers are plain decimals.
        if (!std::all_of(text.begin(), text.end(), [](char c) {
                return (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '+' || c == 'e' ||
                       c == 'E';
            })) {
            return false;
        }
    }
    const char* first = text.data();
    const char* last = text.data() + text.size();
    if (*first == '+' && ++first != last && *first == '-')
        return false;
    auto [end, ec] = std::from_chars(first, last, value);
    return ec == std::errc() && end == last;
}

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
    if (!parseWhole(width, mode.width) || !parseWhole(height, mode.height))
        return syntax_error;
    if (mode.width < 1 || mode.width > kMaxImageSide || mode.height < 1 ||
        mode.height > kMaxImageSide) {
        return "image size out of range (1 to " + std::to_string(kMaxImageSide) +
               " pixels a side), got " + quote(text);
    }
    if (at != std::string_view::npos) {
        double fps = 0;
        if (!parseWhole(rest.substr(at + 1), fps))
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
// Pre-scan: reject what yaml-cpp would take badly or slowly before it sees the text.

Status prescan(std::string_view text, const std::string& file) {
    if (text.size() > kMaxRigFileBytes) {
        return corrupt({file, 0, 0}, "",
                       "file is " + std::to_string(text.size()) + " bytes; a rig file is at most " +
                           std::to_string(kMaxRigFileBytes));
    }
    // Nesting estimate: block levels from the indentation stack and "- - " runs, plus flow
    // levels from brackets that open a node. Quoted scalars and comments are skipped. Rough,
    // but it only has to be right for text nested deeper than any real rig file.
    std::vector<int> indents;
    int block = 0;  // block nesting of the current line
    int flow = 0;   // open [ and { around the current character
    char quote_char = 0;
    int line = 1;
    size_t pos = 0;
    while (pos < text.size()) {
        const size_t eol = std::min(text.find('\n', pos), text.size());
        const std::string_view content = text.substr(pos, eol - pos);
        auto where = [&](size_t column0) {
            return SourceLocation{file, line, static_cast<int>(column0) + 1};
        };
        for (size_t i = 0; i < content.size(); ++i) {
            const auto byte = static_cast<unsigned char>(content[i]);
            if ((byte < 0x20 && byte != '\t' && byte != '\r') || byte == 0x7f) {
                return corrupt(where(i), "",
                               "control character " + quote(content.substr(i, 1)) +
                                   " in the file; a rig file is text");
            }
        }
        size_t indent = 0;
        while (indent < content.size() && (content[indent] == ' ' || content[indent] == '\t')) {
            if (content[indent] == '\t' && quote_char == 0 && flow == 0) {
                return corrupt(where(indent), "", "tab in indentation; YAML indents with spaces");
            }
            ++indent;
        }
        const bool blank =
            indent == content.size() || content[indent] == '#' || content[indent] == '\r';
        if (!blank && quote_char == 0 && flow == 0) {
            const int column = static_cast<int>(indent);
            while (!indents.empty() && indents.back() > column)
                indents.pop_back();
            if (indents.empty() || indents.back() < column)
                indents.push_back(column);
            block = static_cast<int>(indents.size());
        }
        if (!blank && quote_char == 0 && flow == 0 && content[indent] == ',') {
            return corrupt(where(indent), "", "unexpected ',' outside a [list] or {mapping}");
        }
        char previous = 0;  // last non-space character outside quotes on this line
        for (size_t i = indent; i < content.size(); ++i) {
            const char c = content[i];
            if (quote_char != 0) {
                if (c == '\\' && quote_char == '"') {
                    ++i;
                } else if (c == quote_char) {
                    if (quote_char == '\'' && i + 1 < content.size() && content[i + 1] == '\'') {
                        ++i;
                    } else {
                        quote_char = 0;
                        previous = c;
                    }
                }
                continue;
            }
            const bool starts_node = previous == 0 || previous == ':' || previous == '-' ||
                                     previous == ',' || previous == '[' || previous == '{' ||
                                     previous == '?';
            if (c == '#' && (i == 0 || content[i - 1] == ' ' || content[i - 1] == '\t'))
                break;
            if ((c == '"' || c == '\'') && starts_node) {
                quote_char = c;
            } else if ((c == '[' || c == '{') && (starts_node || flow > 0)) {
                ++flow;
            } else if ((c == ']' || c == '}') && flow > 0) {
                --flow;
            } else if (c == '-' && flow == 0 && (previous == 0 || previous == '-') &&
                       i + 1 < content.size() && content[i + 1] == ' ') {
                ++block;  // "- - x": each dash opens a nested sequence
            }
            if (block + flow > kMaxRigNesting) {
                return corrupt(where(i), "",
                               "nesting deeper than " + std::to_string(kMaxRigNesting) +
                                   " levels; a rig file is much flatter");
            }
            if (c != ' ' && c != '\t')
                previous = c;
        }
        pos = eol + 1;
        ++line;
    }
    return Status::ok();
}

// ---------------------------------------------------------------------------------------------
// Schema walk

// A YAML value with where it was written and its field path ("devices[1].mode.depth").
struct Item {
    YAML::Node node;
    SourceLocation where;
    std::string path;
};

struct Field {
    std::string key;
    SourceLocation key_where;
    Item item;
};

using Fields = std::vector<Field>;

const Item* find(const Fields& fields, std::string_view key) {
    for (const auto& f : fields) {
        if (f.key == key)
            return &f.item;
    }
    return nullptr;
}

std::string describe(const YAML::Node& node) {
    switch (node.Type()) {
        case YAML::NodeType::Scalar:
            return quote(node.Scalar());
        case YAML::NodeType::Sequence:
            return node.size() == 0 ? "an empty list" : "a list";
        case YAML::NodeType::Map:
            return node.size() == 0 ? "an empty mapping" : "a mapping";
        default:
            return "nothing";
    }
}

// " (first at rig.yaml:3:5)", or nothing for entries built in code.
std::string firstAt(const SourceLocation& where) {
    const std::string text = where.toString();
    return text.empty() ? "" : " (first at " + text + ")";
}

// A key as it appears in a field path; odd keys (spaces, very long) are quoted and cut short.
std::string keyPath(const std::string& path, std::string_view key) {
    const std::string shown = isValidOptionKey(key) ? std::string(key) : quote(key);
    return path.empty() ? shown : path + "." + shown;
}

// Notes where documents start and ignores everything else.
class DocumentFinder final : public YAML::EventHandler {
public:
    YAML::Mark last_start;

    void OnDocumentStart(const YAML::Mark& mark) override { last_start = mark; }
    void OnDocumentEnd() override {}
    void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
    void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
    void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  const std::string&) override {}
    void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                         YAML::EmitterStyle::value) override {}
    void OnSequenceEnd() override {}
    void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                    YAML::EmitterStyle::value) override {}
    void OnMapEnd() override {}
};

class RigParser {
public:
    RigParser(std::string file, std::filesystem::path base)
        : file_(std::move(file)), base_(std::move(base)) {}

    Status parse(std::string_view text, RigDescription& rig);

private:
    SourceLocation locate(const YAML::Node& node, const SourceLocation& fallback) const {
        const YAML::Mark mark = node.Mark();
        if (node.IsNull() || mark.is_null() || mark.line < 0)
            return fallback;
        return {file_, mark.line + 1, mark.column + 1};
    }

    Status fail(const Item& item, std::string_view what) const {
        return corrupt(item.where, item.path, what);
    }
    Status expected(const Item& item, std::string_view what) const {
        return fail(item, "expected " + std::string(what) + ", got " + describe(item.node));
    }

    // Reads a mapping's entries. Keys must be plain scalars and unique; with `allowed` non-empty
    // they must be among it.
    Result<Fields> readMap(const Item& item, std::span<const std::string_view> allowed,
                           std::string_view expectation) const;
    Status require(const Fields& fields, const Item& parent, std::string_view key) const;
    Item element(const Item& list, const YAML::Node& node, size_t index) const {
        return {node, locate(node, list.where), indexPath(list.path, index)};
    }

    Result<std::string> text(const Item& item) const;
    Result<std::string> name(const Item& item) const;
    Result<int64_t> integer(const Item& item, int64_t min, int64_t max) const;
    Result<double> number(const Item& item, double min, double max, bool min_exclusive) const;
    Result<bool> boolean(const Item& item) const;

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

    std::string file_;
    std::filesystem::path base_;
};

Result<Fields> RigParser::readMap(const Item& item, std::span<const std::string_view> allowed,
                                  std::string_view expectation) const {
    if (!item.node.IsMap())
        return expected(item, expectation);
    Fields fields;
    std::map<std::string, SourceLocation> seen;
    for (const auto& entry : item.node) {
        const YAML::Node& key = entry.first;
        const SourceLocation key_where = locate(key, item.where);
        if (!key.IsScalar()) {
            return corrupt(key_where, item.path, "expected a plain key, got " + describe(key));
        }
        const std::string& name = key.Scalar();
        const std::string path = keyPath(item.path, name);
        if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
            std::string what = "unknown field";
            if (auto guess = closestName(name, allowed); !guess.empty()) {
                what += " (did you mean " + std::string(guess) + "?)";
            }
            what += "; expected one of: " + joinNames(allowed);
            return corrupt(key_where, path, what);
        }
        if (auto [it, inserted] = seen.emplace(name, key_where); !inserted) {
            return corrupt(
                key_where, path,
                "duplicate key (first given at line " + std::to_string(it->second.line) + ")");
        }
        fields.push_back({name, key_where, {entry.second, locate(entry.second, key_where), path}});
    }
    return fields;
}

Status RigParser::require(const Fields& fields, const Item& parent, std::string_view key) const {
    if (find(fields, key))
        return Status::ok();
    return corrupt(parent.where, keyPath(parent.path, key), "missing required field");
}

Result<std::string> RigParser::text(const Item& item) const {
    if (!item.node.IsScalar() || item.node.Scalar().empty())
        return expected(item, "a value");
    return item.node.Scalar();
}

Result<std::string> RigParser::name(const Item& item) const {
    if (!item.node.IsScalar() || !isValidName(item.node.Scalar())) {
        return expected(item, "a name of up to " + std::to_string(kMaxNameLength) +
                                  " letters, digits, '_' or '-'");
    }
    return item.node.Scalar();
}

Result<int64_t> RigParser::integer(const Item& item, int64_t min, int64_t max) const {
    int64_t value = 0;
    if (!item.node.IsScalar() || !parseWhole(item.node.Scalar(), value) || value < min ||
        value > max) {
        return expected(item,
                        "an integer from " + std::to_string(min) + " to " + std::to_string(max));
    }
    return value;
}

Result<double> RigParser::number(const Item& item, double min, double max,
                                 bool min_exclusive) const {
    double value = 0;
    if (item.node.IsScalar() && parseWhole(item.node.Scalar(), value) && std::isfinite(value) &&
        (min_exclusive ? value > min : value >= min) && value <= max) {
        return value;
    }
    auto show = [](double v) {
        std::string s = std::to_string(v);
        s.erase(s.find_last_not_of('0') + 1);
        if (s.back() == '.')
            s.pop_back();
        return s;
    };
    return expected(item, "a number " + std::string(min_exclusive ? "above " : "from ") +
                              show(min) + (min_exclusive ? " up to " : " to ") + show(max));
}

Result<bool> RigParser::boolean(const Item& item) const {
    if (item.node.IsScalar()) {
        const std::string& s = item.node.Scalar();
        if (s == "true" || s == "True" || s == "TRUE")
            return true;
        if (s == "false" || s == "False" || s == "FALSE")
            return false;
    }
    return expected(item, "true or false");
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
    MIXRAY_RETURN_IF_ERROR(prescan(source, file_));
    const std::string copy(source);
    const Item root{YAML::Load(copy), {file_, 1, 1}, ""};
    // A second document is found with the bare parser, called at most twice: YAML::LoadAll
    // (yaml-cpp 0.7) loops forever, allocating, on a document that starts with a stray ','.
    std::istringstream stream(copy);
    YAML::Parser parser(stream);
    DocumentFinder finder;
    parser.HandleNextDocument(finder);
    if (parser.HandleNextDocument(finder)) {
        const YAML::Mark mark = finder.last_start;
        return corrupt({file_, mark.line + 1, mark.column + 1}, "",
                       "a second YAML document; a rig file holds one");
    }
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
    static constexpr std::array<std::string_view, 4> kSiteKeys = {"latitude_deg", "longitude_deg",
                                                                  "heading_deg", "altitude_m"};
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
