// Console output helpers shared by the subcommands: units, a live status line, Ctrl-C.
#pragma once

#include <signal.h>

#include <atomic>
#include <cstdint>
#include <stop_token>
#include <string>
#include <thread>

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

// Turns SIGINT/SIGTERM into a flag long-running commands poll (raised()) and a stop request
// they hand to the libraries (token(): a frame in progress stops within a tile), so they stop
// cleanly and finish their files instead of dying mid-write. A second signal exits at once with
// 128 + its number (the files are left as they are). The handler only stores the signal and
// writes a byte to a pipe; a watcher thread turns that into the stop request, since
// std::stop_source is not async-signal-safe. Installed for the lifetime of the object; one at a
// time. Thread-safe.
class InterruptFlag {
public:
    InterruptFlag();
    ~InterruptFlag();
    InterruptFlag(const InterruptFlag&) = delete;
    InterruptFlag& operator=(const InterruptFlag&) = delete;

    bool raised() const;
    // Requested shortly after the first signal (when the watcher thread wakes).
    std::stop_token token() const { return source_.get_token(); }
    // "SIGINT", "SIGTERM" ("a signal" for others, "" when not raised).
    std::string signalName() const;
    // What a shell expects from a process a signal stopped: 128 + the signal (130 for SIGINT,
    // 143 for SIGTERM); 130 when not raised (a command that stops for another reason).
    int exitCode() const;

private:
    std::stop_source source_;
    int pipe_[2] = {-1, -1};  // the handler writes [1]; the watcher reads [0]
    std::thread watcher_;
    struct sigaction previous_[2] = {};  // SIGINT's and SIGTERM's actions before, restored
};

// Help text (a subcommand's footer) for a command that renders under an InterruptFlag: what
// SIGINT/SIGTERM do; `output` names what is closed with the frames done ("the video").
std::string signalHelp(const std::string& output);

// CPU time of the whole process (every thread) so far, for benchmarks' CPU per frame.
int64_t processCpuNs();

}  // namespace mixray::cli
