// Units, the live status line and Ctrl-C handling for the command line.
#include "console.h"

#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>

namespace mixray::cli {
namespace {
std::atomic<bool> g_interrupted{false};
extern "C" void onSignal(int) {
    g_interrupted.store(true);
}
}  // namespace

std::string formatBytes(uint64_t bytes) {
    char text[32];
    const double b = static_cast<double>(bytes);
    if (bytes < 1000) {
        std::snprintf(text, sizeof text, "%llu B", static_cast<unsigned long long>(bytes));
    } else if (bytes < 1000 * 1000) {
        std::snprintf(text, sizeof text, "%.1f kB", b / 1e3);
    } else if (bytes < 1000ull * 1000 * 1000) {
        std::snprintf(text, sizeof text, "%.1f MB", b / 1e6);
    } else {
        std::snprintf(text, sizeof text, "%.2f GB", b / 1e9);
    }
    return text;
}

std::string formatDuration(int64_t ns) {
    char text[32];
    const double v = static_cast<double>(ns);
    const double mag = v < 0 ? -v : v;
    if (mag >= 1e9) {
        std::snprintf(text, sizeof text, "%.3f s", v / 1e9);
    } else if (mag >= 1e6) {
        std::snprintf(text, sizeof text, "%.1f ms", v / 1e6);
    } else {
        std::snprintf(text, sizeof text, "%.0f µs", v / 1e3);
    }
    return text;
}

int64_t monotonicNowNs() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

StatusLine::StatusLine() : tty_(isatty(STDERR_FILENO) != 0) {}

StatusLine::~StatusLine() {
    finish();
}

void StatusLine::update(const std::string& text) {
    const int64_t now = monotonicNowNs();
    if (tty_) {
        std::fprintf(stderr, "\r%s", text.c_str());
        if (text.size() < last_width_) {
            std::fprintf(stderr, "%*s", static_cast<int>(last_width_ - text.size()), "");
        }
        std::fflush(stderr);
        last_width_ = text.size();
        dirty_ = true;
    } else if (now - last_print_ns_ >= 5'000'000'000) {
        std::fprintf(stderr, "%s\n", text.c_str());
        last_print_ns_ = now;
        pending_.clear();
    } else {
        pending_ = text;
    }
}

void StatusLine::finish() {
    if (tty_ && dirty_)
        std::fprintf(stderr, "\n");
    if (!tty_ && !pending_.empty())
        std::fprintf(stderr, "%s\n", pending_.c_str());
    dirty_ = false;
    pending_.clear();
}

InterruptFlag::InterruptFlag() {
    g_interrupted.store(false);
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
}

InterruptFlag::~InterruptFlag() {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
}

bool InterruptFlag::raised() const {
    return g_interrupted.load();
}

}  // namespace mixray::cli
