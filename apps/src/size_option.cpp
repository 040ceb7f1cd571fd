// Image sizes given on the command line (size_option.h).
#include "size_option.h"

#include <cstdio>

namespace mixray::cli {

Result<std::pair<int, int>> parseSize(const std::string& option, const std::string& text) {
    int w = 0, h = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || (x != 'x' && x != 'X'))
        return {ErrorCode::kInvalidArgument,
                option + " " + text + ": expected WIDTHxHEIGHT, e.g. 320x240"};
    return std::pair{w, h};
}

}  // namespace mixray::cli
