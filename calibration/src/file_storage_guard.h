// Input OpenCV 4.6's FileStorage crashes or hangs on, refused before it is handed over (marker
// dictionaries, OpenCV calibration files).
#pragma once

#include <string_view>

namespace mixray::calibration::detail {

// Why FileStorage's XML reader would crash on `text` (it is not XML unless its first character
// is '<'), or nullptr. Both were found by dictionary_parser_fuzz; no well-formed XML file
// OpenCV writes, with Unix or Windows line ends, has either:
// - the text ends, but for whitespace, right after an attribute's '=' ("<?xml a="): the
//   missing value is read through a null pointer;
// - a carriage return not followed by a line feed (a lone CR, as after "<a b=" in
//   "<a b=\r\"\">"): the reader takes it for the end of its line buffer and reads on
//   through a null pointer.
inline const char* crashesFileStorage(std::string_view text) {
    const size_t first = text.find_first_not_of(" \t\r\n");
    if (first == std::string_view::npos || text[first] != '<')
        return nullptr;
    const size_t last = text.find_last_not_of(" \t\r\n");
    if (text[last] == '=')
        return "ends inside an XML tag, after an attribute's '='";
    for (size_t cr = text.find('\r'); cr != std::string_view::npos; cr = text.find('\r', cr + 1)) {
        if (cr + 1 == text.size() || text[cr + 1] != '\n')
            return "holds a carriage return without a line feed (not a line end OpenCV's XML "
                   "reader survives)";
    }
    return nullptr;
}

// Why FileStorage's YAML reader could loop forever on `text`, or nullptr. Its loop over
// documents (persistence_yml.cpp, YAMLParser::parse) makes no progress on a line starting with
// '-' but not "---" once the first document has ended before the end of the text (found by
// dictionary_parser_fuzz: "%YAML:1.0\n---L:1.0\n-s: --\n"). That first document runs to the
// end of the text when it is one block collection starting in column 0; it ends early after
// a "..." line, a second "---", or when it starts indented, after "---" on the same line, or
// as a flow collection. OpenCV writes none of these, so they are refused rather than
// mirrored. XML and JSON text (first character '<' or '{') is not YAML and passes.
inline const char* hangsFileStorageYaml(std::string_view text) {
    auto blank = [](std::string_view rest) {
        const size_t at = rest.find_first_not_of(" \t\r");
        return at == std::string_view::npos || rest[at] == '#';
    };
    const size_t start = text.find_first_not_of(" \t\r\n");
    if (start == std::string_view::npos || text[start] == '<' || text[start] == '{')
        return nullptr;
    bool content = false;  // the document's first content line has been seen
    bool ended = false;    // a "..." line ended the document
    for (size_t at = 0; at < text.size();) {
        size_t end = text.find('\n', at);
        if (end == std::string_view::npos)
            end = text.size();
        const std::string_view line = text.substr(at, end - at);
        at = end + 1;
        if (blank(line))
            continue;
        if (ended)
            return "text after the end of the YAML document ('...')";
        const size_t column = line.find_first_not_of(" \t\r");
        const std::string_view rest = line.substr(column);
        if (rest.starts_with("---")) {
            if (content)
                return "a second YAML document ('---' after the first)";
            if (!blank(rest.substr(3)))
                return "text after '---' on its line";
            continue;
        }
        if (rest.front() == '%' && !content)
            continue;  // a directive
        if (column == 0 && rest.starts_with("...")) {
            if (!blank(rest.substr(3)))
                return "text after '...' on its line";
            ended = true;
            continue;
        }
        if (!content) {
            if (column != 0)
                return "the YAML document's top level is indented";
            if (rest.front() == '[' || rest.front() == '{')
                return "the YAML document's top level is a flow collection ('[' or '{')";
            content = true;
        }
    }
    return nullptr;
}

}  // namespace mixray::calibration::detail
