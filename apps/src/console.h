// Console output helpers shared by the subcommands: units, a live status line, Ctrl-C.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>

namespace mixray::cli {

// "12.3 MB", "512 B": decimal units, as disks are sold.
std::string formatBytes(uint64_t bytes);
// "1.234 s", "12.5 ms", "830 µs".
std::string formatDuration(int64_t ns);

// A status line redrawn in place on a terminal (carriage return), printed as ordinary lines
// at most every few seconds when stderr is a file or pipe, so logs stay readable.
// Thread-bound.
class StatusLine {
public:
    StatusLine();
    ~StatusLine();
    void update(const std::string& text);
    // Leaves the last status on its own line (also printed when output is not a terminal).
    void finish();

private:
    bool tty_;
    int64_t last_print_ns_ = 0;
    size_t last_width_ = 0;
    bool dirty_ = false;
    std::string pending_;  // not yet printed (non-terminal output)
};

// Turns SIGINT/SIGTERM into a flag long-running commands poll, so they stop cleanly and
// finish their files instead of dying mid-write. Installed for the lifetime of the object.
class InterruptFlag {
public:
    InterruptFlag();
    ~InterruptFlag();
    bool raised() const;
};

int64_t monotonicNowNs();

}  // namespace mixray::cli
