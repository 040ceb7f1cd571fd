// Strict YAML reading for mixray's input files (see mixray/graph/yaml_reader.h).
#include "mixray/graph/yaml_reader.h"

#include <yaml-cpp/eventhandler.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <numbers>
#include <sstream>

namespace mixray::yaml {
namespace {

constexpr std::array<std::string_view, 3> kPoseKeys = {"translation", "rotation_deg", "quaternion"};

double degreesToRadians(double degrees) {
    return degrees * std::numbers::pi / 180.0;
}

bool isKeyChar(char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-' || c == '.';
}

bool looksNonFinite(std::string_view s) {
    std::string lower;
    for (char c : s)
        lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    for (std::string_view word : {".nan", "nan", ".inf", "inf", "+.inf", "-.inf", "+inf", "-inf",
                                  "infinity", "-infinity"}) {
        if (lower == word)
            return true;
    }
    return false;
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

std::string show(double v) {
    std::ostringstream out;
    out << v;
    return out.str();
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

// Rejects what yaml-cpp would take badly or slowly before it sees the text: oversized files,
// control characters, tab indentation, a line starting with ',' and deep nesting.
Status prescan(std::string_view text, const std::string& file, size_t max_bytes, int max_nesting,
               std::string_view kind) {
    if (text.size() > max_bytes) {
        return corrupt({file, 0, 0}, "",
                       "file is " + std::to_string(text.size()) + " bytes; " + std::string(kind) +
                           " is at most " + std::to_string(max_bytes));
    }
    std::vector<int> indents;
    int block = 0;
    int flow = 0;
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
                                   " in the file; " + std::string(kind) + " is text");
            }
        }
        size_t indent = 0;
        while (indent < content.size() && (content[indent] == ' ' || content[indent] == '\t')) {
            if (content[indent] == '\t' && quote_char == 0 && flow == 0)
                return corrupt(where(indent), "", "tab in indentation; YAML indents with spaces");
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
            if (content[indent] == ',')
                return corrupt(where(indent), "", "unexpected ',' outside a [list] or {mapping}");
        }
        char previous = 0;
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
                ++block;
            }
            if (block + flow > max_nesting) {
                return corrupt(where(i), "",
                               "nesting deeper than " + std::to_string(max_nesting) + " levels; " +
                                   std::string(kind) + " is much flatter");
            }
            if (c != ' ' && c != '\t')
                previous = c;
        }
        pos = eol + 1;
        ++line;
    }
    return Status::ok();
}

template <typename T>
std::string shortestText(T value) {
    char buf[40];
    const auto r = std::to_chars(buf, buf + sizeof buf, value);
    std::string s(buf, r.ptr);
    const size_t e = s.find('e');
    if (e != std::string::npos && s.find('.') == std::string::npos)
        s.insert(e, ".0");
    return s;
}

}  // namespace

std::string shortest(double value) {
    return shortestText(value);
}

std::string shortest(float value) {
    return shortestText(value);
}

const Item* find(const Fields& fields, std::string_view key) {
    for (const auto& f : fields) {
        if (f.key == key)
            return &f.item;
    }
    return nullptr;
}

std::string keyPath(const std::string& path, std::string_view key) {
    const bool plain =
        !key.empty() && key.size() <= 64 && std::all_of(key.begin(), key.end(), isKeyChar);
    const std::string shown = plain ? std::string(key) : quote(key);
    return path.empty() ? shown : path + "." + shown;
}

Result<Item> Reader::load(std::string_view text, size_t max_bytes, int max_nesting,
                          std::string_view kind) const {
    MIXRAY_RETURN_IF_ERROR(prescan(text, file_, max_bytes, max_nesting, kind));
    const std::string copy(text);
    Item root{YAML::Load(copy), {file_, 1, 1}, ""};
    // A second document is found with the bare parser, called at most twice: YAML::LoadAll
    // (yaml-cpp 0.7) loops forever, allocating, on a document that starts with a stray ','.
    std::istringstream stream(copy);
    YAML::Parser parser(stream);
    DocumentFinder finder;
    parser.HandleNextDocument(finder);
    if (parser.HandleNextDocument(finder)) {
        const YAML::Mark mark = finder.last_start;
        return corrupt({file_, mark.line + 1, mark.column + 1}, "",
                       "a second YAML document; " + std::string(kind) + " holds one");
    }
    return root;
}

SourceLocation Reader::locate(const YAML::Node& node, const SourceLocation& fallback) const {
    const YAML::Mark mark = node.Mark();
    if (node.IsNull() || mark.is_null() || mark.line < 0)
        return fallback;
    return {file_, mark.line + 1, mark.column + 1};
}

Status Reader::expected(const Item& item, std::string_view what) const {
    return fail(item, "expected " + std::string(what) + ", got " + describe(item.node));
}

Result<Fields> Reader::readMap(const Item& item, std::span<const std::string_view> allowed,
                               std::string_view expectation) const {
    if (!item.node.IsMap())
        return expected(item, expectation);
    Fields fields;
    std::map<std::string, SourceLocation> seen;
    for (const auto& entry : item.node) {
        const YAML::Node& key = entry.first;
        const SourceLocation key_where = locate(key, item.where);
        if (!key.IsScalar())
            return corrupt(key_where, item.path, "expected a plain key, got " + describe(key));
        const std::string& name = key.Scalar();
        const std::string path = keyPath(item.path, name);
        if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
            std::string what = "unknown field";
            if (auto guess = closestName(name, allowed); !guess.empty())
                what += " (did you mean " + std::string(guess) + "?)";
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

Status Reader::require(const Fields& fields, const Item& parent, std::string_view key) const {
    if (find(fields, key))
        return Status::ok();
    return corrupt(parent.where, keyPath(parent.path, key), "missing required field");
}

Result<std::vector<Item>> Reader::readList(const Item& item, size_t min_size, size_t max_size,
                                           std::string_view expectation) const {
    if (!item.node.IsSequence() || item.node.size() < min_size || item.node.size() > max_size)
        return expected(item, expectation);
    std::vector<Item> items;
    size_t index = 0;
    for (const auto& node : item.node)
        items.push_back(element(item, node, index++));
    return items;
}

Result<std::string> Reader::text(const Item& item) const {
    if (!item.node.IsScalar() || item.node.Scalar().empty())
        return expected(item, "a value");
    return item.node.Scalar();
}

Result<int64_t> Reader::integer(const Item& item, int64_t min, int64_t max) const {
    int64_t value = 0;
    if (!item.node.IsScalar() || !parseWhole(item.node.Scalar(), value) || value < min ||
        value > max) {
        return expected(item,
                        "an integer from " + std::to_string(min) + " to " + std::to_string(max));
    }
    return value;
}

Result<double> Reader::number(const Item& item, double min, double max, bool min_exclusive) const {
    double value = 0;
    if (item.node.IsScalar() && parseWhole(item.node.Scalar(), value) && std::isfinite(value) &&
        (min_exclusive ? value > min : value >= min) && value <= max) {
        return value;
    }
    if (item.node.IsScalar() && looksNonFinite(item.node.Scalar()))
        return fail(item, "expected a finite number, got " + describe(item.node));
    return expected(item, "a number " + std::string(min_exclusive ? "above " : "from ") +
                              show(min) + (min_exclusive ? " up to " : " to ") + show(max));
}

Result<bool> Reader::boolean(const Item& item) const {
    if (item.node.IsScalar()) {
        const std::string& s = item.node.Scalar();
        if (s == "true" || s == "True" || s == "TRUE")
            return true;
        if (s == "false" || s == "False" || s == "FALSE")
            return false;
    }
    return expected(item, "true or false");
}

Result<Eigen::Vector3d> Reader::vector3(const Item& item, double limit) const {
    auto elements = readList(item, 3, 3, "[x, y, z]");
    if (!elements)
        return elements.status();
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) {
        auto x = number((*elements)[i], -limit, limit, false);
        if (!x)
            return x.status();
        v[i] = *x;
    }
    return v;
}

Result<Eigen::Quaterniond> Reader::rotation(const Fields& fields) const {
    const Item* degrees = find(fields, "rotation_deg");
    const Item* quaternion = find(fields, "quaternion");
    if (degrees && quaternion) {
        return fail(*quaternion, "give one of rotation_deg and quaternion; " + degrees->path +
                                     " is already given");
    }
    if (degrees) {
        auto angles = vector3(*degrees, 1e4);
        if (!angles)
            return angles.status();
        // Extrinsic x, then y, then z (fixed axes): R = Rz * Ry * Rx.
        const Eigen::Quaterniond q =
            Eigen::AngleAxisd(degreesToRadians((*angles)[2]), Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(degreesToRadians((*angles)[1]), Eigen::Vector3d::UnitY()) *
            Eigen::AngleAxisd(degreesToRadians((*angles)[0]), Eigen::Vector3d::UnitX());
        return q;
    }
    if (quaternion) {
        auto elements = readList(*quaternion, 4, 4, "a unit quaternion [w, x, y, z]");
        if (!elements)
            return elements.status();
        std::array<double, 4> wxyz{};
        for (size_t i = 0; i < 4; ++i) {
            auto v = number((*elements)[i], -1.01, 1.01, false);
            if (!v)
                return v.status();
            wxyz[i] = *v;
        }
        Eigen::Quaterniond q(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
        if (std::abs(q.norm() - 1.0) > 1e-3) {
            return fail(*quaternion, "not a unit quaternion (norm " + std::to_string(q.norm()) +
                                         "); expected [w, x, y, z]");
        }
        q.normalize();
        return q;
    }
    return Eigen::Quaterniond::Identity();
}

Result<Eigen::Isometry3d> Reader::pose(const Item& item, double max_translation) const {
    auto fields = readMap(item, kPoseKeys,
                          "a pose mapping with translation: and rotation_deg: or quaternion:");
    if (!fields)
        return fields.status();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    if (const Item* t = find(*fields, "translation")) {
        auto translation = vector3(*t, max_translation);
        if (!translation)
            return translation.status();
        T.translation() = *translation;
    }
    auto q = rotation(*fields);
    if (!q)
        return q.status();
    T.linear() = q->toRotationMatrix();
    return T;
}

}  // namespace mixray::yaml
