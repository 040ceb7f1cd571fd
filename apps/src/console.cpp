// Units, the live status line and Ctrl-C handling for the command line.
#include "console.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <ctime>

#include "mixray/graph/host_time.h"

namespace mixray::cli {
namespace {
// Only lock-free atomics and write(2)/_exit(2) in the handler: it may run on any thread, in the
// middle of anything.
std::atomic<int> g_signal{0};
std::atomic<int> g_wake_fd{-1};
static_assert(std::atomic<int>::is_always_lock_free);

extern "C" void onSignal(int number) {
    const int saved_errno = errno;
    int none = 0;
    if (!g_signal.compare_exchange_strong(none, number)) {
        // The user insists: stop now, whatever is half written.
        static const char kMessage[] = "\nmixray: second signal, exiting at once\n";
        (void)!write(STDERR_FILENO, kMessage, sizeof kMessage - 1);
        _exit(128 + number);
    }
    const int fd = g_wake_fd.load();
    if (fd >= 0) {
        const char byte = 1;
        (void)!write(fd, &byte, 1);
    }
    errno = saved_errno;
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

std::string signalHelp(const std::string& output) {
    return "SIGINT (Ctrl-C) or SIGTERM stops within one image tile: the frame in progress is "
           "dropped, " +
           output +
           " is closed with the frames done (it plays), and mixray exits with 130 (SIGINT) or "
           "143 (SIGTERM). A second signal exits at once, leaving it unfinished.";
}

int64_t processCpuNs() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return static_cast<int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
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
    g_signal.store(0);
    // Without a pipe the flag still works; only token() then never fires.
    if (pipe2(pipe_, O_CLOEXEC) == 0) {
        g_wake_fd.store(pipe_[1]);
        watcher_ = std::thread([this] {
            char byte;
            ssize_t n;
            do {
                n = read(pipe_[0], &byte, 1);
            } while (n < 0 && errno == EINTR);
            // One wake-up: the first signal, or the destructor.
            if (g_signal.load() != 0)
                source_.request_stop();
        });
    }
    struct sigaction action {};
    action.sa_handler = onSignal;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;
    sigaction(SIGINT, &action, &previous_[0]);
    sigaction(SIGTERM, &action, &previous_[1]);
}

InterruptFlag::~InterruptFlag() {
    sigaction(SIGINT, &previous_[0], nullptr);
    sigaction(SIGTERM, &previous_[1], nullptr);
    g_wake_fd.store(-1);
    if (watcher_.joinable()) {
        const char byte = 0;
        (void)!write(pipe_[1], &byte, 1);
        watcher_.join();
    }
    for (int fd : pipe_)
        if (fd >= 0)
            close(fd);
}

bool InterruptFlag::raised() const {
    return g_signal.load() != 0;
}

std::string InterruptFlag::signalName() const {
    switch (g_signal.load()) {
        case 0:
            return "";
        case SIGINT:
            return "SIGINT";
        case SIGTERM:
            return "SIGTERM";
        default:
            return "a signal";
    }
}

int InterruptFlag::exitCode() const {
    const int number = g_signal.load();
    return 128 + (number != 0 ? number : SIGINT);
}

}  // namespace mixray::cli
