// Messages for errors in input files (field_errors.h).
#include "mixray/graph/field_errors.h"

#include <algorithm>
#include <vector>

namespace mixray {
namespace {

size_t editDistance(std::string_view a, std::string_view b) {
    std::vector<size_t> row(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j)
        row[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        size_t diagonal = row[0];
        row[0] = i;
        for (size_t j = 1; j <= b.size(); ++j) {
            const size_t above = row[j];
            row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] != b[j - 1])});
            diagonal = above;
        }
    }
    return row[b.size()];
}

}  // namespace

Status corrupt(const SourceLocation& where, std::string_view path, std::string_view what) {
    std::string message = where.toString();
    if (!path.empty()) {
        if (!message.empty())
            message += ": ";
        message += path;
    }
    if (!message.empty())
        message += ": ";
    message += what;
    return Status(ErrorCode::kCorruptData, std::move(message));
}

std::string quote(std::string_view text) {
    constexpr size_t kMaxShown = 40;
    std::string out = "\"";
    size_t shown = 0;
    for (char c : text) {
        if (shown++ == kMaxShown) {
            out += "...";
            break;
        }
        const auto byte = static_cast<unsigned char>(c);
        if (c == '"' || c == '\\') {
            out += '\\';
            out += c;
        } else if (byte < 0x20 || byte == 0x7f) {
            constexpr std::string_view kHex = "0123456789abcdef";
            out += "\\x";
            out += kHex[byte >> 4];
            out += kHex[byte & 0xf];
        } else {
            out += c;
        }
    }
    out += '"';
    return out;
}

std::string joinNames(std::span<const std::string_view> names) {
    std::string out;
    for (auto name : names) {
        if (!out.empty())
            out += ", ";
        out += name;
    }
    return out;
}

std::string_view closestName(std::string_view key, std::span<const std::string_view> names) {
    std::string_view best;
    // A cut-short name ("rotation" for "rotation_deg") is a typo too.
    if (key.size() >= 3) {
        for (auto name : names) {
            if (name.size() > key.size() && name.substr(0, key.size()) == key)
                return name;
        }
    }
    size_t best_distance = std::max<size_t>(2, key.size() / 3) + 1;
    for (auto name : names) {
        const size_t d = editDistance(key, name);
        if (d < best_distance) {
            best = name;
            best_distance = d;
        }
    }
    return best;
}

std::string indexPath(const std::string& path, size_t index) {
    return path + "[" + std::to_string(index) + "]";
}

}  // namespace mixray
