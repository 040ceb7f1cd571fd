// Strict YAML reading for mixray's input files (rig files, scene files): a size and nesting
// pre-scan, one document only, and typed accessors whose errors read
// "file:line:col: field.path: what is wrong". Include it from parsers' sources only: it brings
// yaml-cpp's headers.
#pragma once

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <charconv>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

#include "mixray/graph/field_errors.h"
#include "mixray/graph/result.h"
#include "mixray/graph/rig.h"

namespace mixray::yaml {

// The shared message helpers (mixray/graph/field_errors.h), under this namespace's names.
using ::mixray::closestName;
using ::mixray::corrupt;
using ::mixray::indexPath;
using ::mixray::joinNames;
using ::mixray::quote;

// A YAML value with where it was written and its field path ("objects[1].pose.translation").
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

// Whole-string decimal numbers only (from_chars alone would also take "inf" and "nan").
template <typename T>
inline bool parseWhole(std::string_view text, T& value) {
    if (text.empty())
        return false;
    if constexpr (std::is_floating_point_v<T>) {
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

const Item* find(const Fields& fields, std::string_view key);

// The shortest text that reads back as the same number (floats as floats, so 0.9f is "0.9"),
// for files written to be read again exactly. Exponents get a mantissa with a point
// ("6.0e-04"), which YAML 1.1 readers need to see a float.
std::string shortest(double value);
std::string shortest(float value);
std::string keyPath(const std::string& path, std::string_view key);

// Typed, located access to one file's YAML. Thread-bound: one reader per parse. Methods may
// throw YAML exceptions for malformed documents; the caller catches them at its API boundary.
class Reader {
public:
    explicit Reader(std::string file) : file_(std::move(file)) {}

    const std::string& file() const { return file_; }

    // Pre-scans `text` (at most `max_bytes`, nesting at most `max_nesting`, no control
    // characters or tab indentation), loads it and refuses a second document. `kind` names the
    // file in messages ("a scene file").
    Result<Item> load(std::string_view text, size_t max_bytes, int max_nesting,
                      std::string_view kind) const;

    SourceLocation locate(const YAML::Node& node, const SourceLocation& fallback) const;

    Status fail(const Item& item, std::string_view what) const {
        return corrupt(item.where, item.path, what);
    }
    Status expected(const Item& item, std::string_view what) const;

    // A mapping's entries; plain, unique keys, each among `allowed` when it is non-empty
    // (else an error with a "did you mean" hint).
    Result<Fields> readMap(const Item& item, std::span<const std::string_view> allowed,
                           std::string_view expectation) const;
    Status require(const Fields& fields, const Item& parent, std::string_view key) const;
    Item element(const Item& list, const YAML::Node& node, size_t index) const {
        return {node, locate(node, list.where), indexPath(list.path, index)};
    }
    // A sequence's elements; `expectation` when it is not one or its length is outside
    // [min_size, max_size].
    Result<std::vector<Item>> readList(const Item& item, size_t min_size, size_t max_size,
                                       std::string_view expectation) const;

    Result<std::string> text(const Item& item) const;
    Result<int64_t> integer(const Item& item, int64_t min, int64_t max) const;
    // A finite decimal number in [min, max] (above min when min_exclusive).
    Result<double> number(const Item& item, double min, double max, bool min_exclusive) const;
    Result<bool> boolean(const Item& item) const;
    // [x, y, z], each finite and within ±limit.
    Result<Eigen::Vector3d> vector3(const Item& item, double limit) const;
    // The rotation of a pose mapping's fields: `rotation_deg: [x, y, z]` (extrinsic x, then y,
    // then z: R = Rz·Ry·Rx) or `quaternion: [w, x, y, z]` (unit), not both; identity when
    // neither is given.
    Result<Eigen::Quaterniond> rotation(const Fields& fields) const;
    // A pose mapping {translation: [x, y, z], rotation_deg: ... | quaternion: ...}; translation
    // within ±max_translation.
    Result<Eigen::Isometry3d> pose(const Item& item, double max_translation) const;

private:
    std::string file_;
};

}  // namespace mixray::yaml
