// libFuzzer target for the text the replay backend's sequence folders are read from: a TUM RGB-D
// list file (parseTumList, rgb.txt / depth.txt), a TUM timestamp (parseTumStamp) and a PCL
// OpenNI TIFF file name's timestamp (parsePclStamp; a PCL folder has no list, its file names are
// the sequence). Every input goes to each. A rejection is kCorruptData (naming the list file and
// line), never a crash or an overflow (UBSan); an accepted list has time-ordered entries inside
// the folder and, written again the way the TUM writer writes it, parses to the same list; an
// accepted stamp formats back to the same nanoseconds (a PCL stamp: to the same text).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "mixray/replay/pcl_tiff.h"
#include "mixray/replay/tum.h"

namespace {

using namespace mixray;

[[noreturn]] void broken(const char* what, const std::string& detail) {
    std::fprintf(stderr, "tum_list_fuzz: %s: %s\n", what, detail.c_str());
    std::abort();
}

void expectCorrupt(const Status& status, std::string_view prefix) {
    if (status.code() != ErrorCode::kCorruptData)
        broken("unexpected code", status.toString());
    if (status.message().rfind(prefix, 0) != 0)
        broken("message without its source", status.message());
}

// Fractional digits of a stamp's text: 0 without a '.'.
int fractionDigits(std::string_view text) {
    const size_t dot = text.find('.');
    return dot == std::string_view::npos ? 0 : static_cast<int>(text.size() - dot - 1);
}

void fuzzList(std::string_view text) {
    auto list = replay::parseTumList(text, "fuzz/rgb.txt");
    if (!list) {
        expectCorrupt(list.status(), "fuzz/rgb.txt:");
        return;
    }
    if (list->stamp_digits < 0 || list->stamp_digits > 9)
        broken("stamp digits out of range", std::to_string(list->stamp_digits));
    std::string again;
    for (const std::string& comment : list->comments) {
        if (comment.empty() || comment.front() != '#')
            broken("a comment without '#'", comment);
        again += comment + "\n";
    }
    for (size_t i = 0; i < list->entries.size(); ++i) {
        const replay::TumListEntry& e = list->entries[i];
        if (i > 0 && e.stamp_ns < list->entries[i - 1].stamp_ns)
            broken("stamps go backwards", e.file);
        if (e.stamp_ns < 0 || e.file.empty() || e.file.front() == '/' ||
            e.file.find_first_of(" \t\n") != std::string::npos)
            broken("an entry the folder cannot hold", e.file);
        again += replay::formatTumStamp(e.stamp_ns, list->stamp_digits) + " " + e.file + "\n";
    }
    auto back = replay::parseTumList(again, "fuzz/again.txt");
    if (!back)
        broken("a list written again does not parse", back.status().toString());
    if (back->comments != list->comments || back->entries.size() != list->entries.size() ||
        back->stamp_digits != list->stamp_digits)
        broken("a list written again parses to another list", again);
    for (size_t i = 0; i < list->entries.size(); ++i) {
        if (back->entries[i].stamp_ns != list->entries[i].stamp_ns ||
            back->entries[i].file != list->entries[i].file)
            broken("an entry written again parses to another", again);
    }
}

void fuzzStamps(std::string_view text) {
    if (auto stamp = replay::parseTumStamp(text); stamp) {
        if (*stamp < 0)
            broken("a negative TUM stamp", std::string(text));
        auto back = replay::parseTumStamp(replay::formatTumStamp(*stamp, 9));
        if (!back || *back != *stamp)
            broken("a TUM stamp does not format back", std::string(text));
    } else {
        expectCorrupt(stamp.status(), "bad timestamp");
    }
    if (auto stamp = replay::parsePclStamp(text); stamp) {
        const std::string back = replay::formatPclStamp(*stamp, fractionDigits(text));
        if (back != text)
            broken("a PCL stamp does not format back", std::string(text) + " -> " + back);
    } else {
        expectCorrupt(stamp.status(), "bad timestamp");
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    fuzzList(text);
    fuzzStamps(text);
    return 0;
}
