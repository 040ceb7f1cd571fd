// Messages for errors in input files: "file:line:col: field.path: what is wrong", quoted values
// and "did you mean" hints. Shared by the rig parser and the other modules' file parsers.
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>

#include "mixray/graph/result.h"
#include "mixray/graph/rig.h"

namespace mixray {

// kCorruptData with "where: path: what" (parts left out when empty).
Status corrupt(const SourceLocation& where, std::string_view path, std::string_view what);

// A value for a message: quoted, escaped, and cut short when long.
std::string quote(std::string_view text);

// "a, b, c".
std::string joinNames(std::span<const std::string_view> names);

// The allowed name `key` is probably a typo of (a few edits away, or `key` cut short); empty
// when none is close.
std::string_view closestName(std::string_view key, std::span<const std::string_view> names);

// "path[index]".
std::string indexPath(const std::string& path, size_t index);

}  // namespace mixray
