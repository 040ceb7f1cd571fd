// Input OpenCV 4.6's FileStorage crashes on, refused before it is handed over (marker
// dictionaries, OpenCV calibration files).
#pragma once

#include <string_view>

namespace mixray::calibration::detail {

// An XML text that ends, but for whitespace, right after an attribute's '=' ("<?xml a="):
// FileStorage's XML parser reads the missing value through a null pointer (found by
// dictionary_parser_fuzz). No complete XML document ends so.
inline bool crashesFileStorage(std::string_view text) {
    const size_t first = text.find_first_not_of(" \t\r\n");
    const size_t last = text.find_last_not_of(" \t\r\n");
    return first != std::string_view::npos && text[first] == '<' && text[last] == '=';
}

}  // namespace mixray::calibration::detail
