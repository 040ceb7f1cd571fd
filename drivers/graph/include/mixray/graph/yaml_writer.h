// Writing YAML that mixray's readers (mixray/graph/yaml_reader.h) take back unchanged.
#pragma once

#include <string>
#include <string_view>

namespace mixray::yaml {

// `text` as a YAML double-quoted scalar: '"' and '\' escaped, and control characters as \xHH
// (a raw line break inside quotes would read back as a space), so any bytes read back the same.
// For names and paths a user chose, which may hold ':', '#', '[' or leading spaces.
std::string doubleQuoted(std::string_view text);

}  // namespace mixray::yaml
