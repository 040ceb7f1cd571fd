// PTP state from linuxptp's pmc (mixray/graph/ptp.h): its answers parsed, pmc run with a
// timeout.
#include "mixray/graph/ptp.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "mixray/graph/host_time.h"

extern char** environ;

namespace mixray {

namespace {

std::string_view trim(std::string_view s) {
    const size_t first = s.find_first_not_of(" \t\r");
    if (first == std::string_view::npos)
        return {};
    const size_t last = s.find_last_not_of(" \t\r");
    return s.substr(first, last - first + 1);
}

bool parseInt64(std::string_view text, int64_t& out) {
    if (!text.empty() && text.front() == '+')
        text.remove_prefix(1);
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc() && end == text.data() + text.size();
}

bool parseDouble(std::string_view text, double& out) {
    if (!text.empty() && text.front() == '+')
        text.remove_prefix(1);
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc() && end == text.data() + text.size() && std::isfinite(out);
}

// What a PTP identity prints as: hex digits and dots (clock), then "-port" for a port.
bool isIdentity(std::string_view text) {
    return !text.empty() && text.size() <= 64 && std::all_of(text.begin(), text.end(), [](char c) {
        return std::isxdigit(static_cast<unsigned char>(c)) || c == '.' || c == '-';
    });
}

std::string signedNs(int64_t ns) {
    char text[32];
    std::snprintf(text, sizeof(text), "%+lld ns", static_cast<long long>(ns));
    return text;
}

}  // namespace

bool PtpState::following() const {
    return grandmaster_present &&
           std::find(port_states.begin(), port_states.end(), "SLAVE") != port_states.end();
}

bool PtpState::grandmaster() const {
    return !clock_identity.empty() && grandmaster_identity == clock_identity &&
           std::find(port_states.begin(), port_states.end(), "MASTER") != port_states.end();
}

std::string PtpState::describe() const {
    std::string path;
    if (steps_removed)
        path += " (" + std::to_string(*steps_removed) + (*steps_removed == 1 ? " step" : " steps") +
                ")";
    std::string offset = ", offset " + signedNs(master_offset_ns);
    if (path_delay_ns)
        offset += ", path delay " + std::to_string(std::llround(*path_delay_ns)) + " ns";
    if (following())
        return "PTP-locked: following grandmaster " + grandmaster_identity + path + offset;
    if (grandmaster())
        return "PTP-locked: this host's clock " + clock_identity +
               " is the grandmaster the others follow";
    std::string states;
    for (const std::string& s : port_states)
        states += (states.empty() ? "" : ", ") + s;
    if (states.empty())
        states = "no port";
    if (grandmaster_present && grandmaster_identity != clock_identity)
        return "not PTP-locked: ptp4l's port is " + states + ", grandmaster " +
               grandmaster_identity + path + offset;
    return "not PTP-locked: ptp4l's port is " + states + " and hears no other grandmaster";
}

Result<PtpState> parsePmcOutput(std::string_view text) {
    PtpState state;
    std::string tlv;  // the management TLV whose fields follow
    int answers = 0;
    while (!text.empty()) {
        const size_t eol = text.find('\n');
        const std::string_view line = trim(text.substr(0, eol));
        text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
        if (line.empty() || line.rfind("sending:", 0) == 0)
            continue;
        // "<port identity> seq <n> RESPONSE MANAGEMENT <TLV>" starts an answer.
        if (const size_t response = line.find(" RESPONSE "); response != std::string_view::npos) {
            const std::string_view identity = line.substr(0, line.find(' '));
            std::string_view rest = trim(line.substr(response + 10));
            if (rest.rfind("MANAGEMENT_ERROR_STATUS", 0) == 0)
                return Result<PtpState>(
                    ErrorCode::kUnavailable,
                    "ptp4l refused a management request: " + std::string(line.substr(0, 200)));
            if (rest.rfind("MANAGEMENT ", 0) != 0 || !isIdentity(identity)) {
                tlv.clear();
                continue;
            }
            tlv = std::string(trim(rest.substr(11)));
            ++answers;
            if (state.clock_identity.empty())
                state.clock_identity = std::string(identity.substr(0, identity.find('-')));
            continue;
        }
        const size_t space = line.find_first_of(" \t");
        if (space == std::string_view::npos)
            continue;
        const std::string_view key = line.substr(0, space);
        const std::string_view value = trim(line.substr(space));
        const auto bad = [&] {
            return Result<PtpState>(ErrorCode::kCorruptData,
                                    "pmc's " + tlv + " " + std::string(key) +
                                        " is not a number: '" + std::string(value.substr(0, 64)) +
                                        "'");
        };
        if (tlv == "TIME_STATUS_NP") {
            if (key == "master_offset") {
                if (!parseInt64(value, state.master_offset_ns))
                    return bad();
            } else if (key == "gmPresent") {
                state.grandmaster_present = value == "true";
            } else if (key == "gmIdentity" && isIdentity(value)) {
                state.grandmaster_identity = std::string(value);
            }
        } else if (tlv == "PORT_DATA_SET") {
            if (key == "portState" && !value.empty() && value.size() <= 32)
                state.port_states.emplace_back(value);
        } else if (tlv == "CURRENT_DATA_SET") {
            double number = 0;
            if (key == "meanPathDelay") {
                if (!parseDouble(value, number))
                    return bad();
                state.path_delay_ns = number;
            } else if (key == "stepsRemoved") {
                int64_t steps = 0;
                if (!parseInt64(value, steps) || steps < 0 || steps > 65535)
                    return bad();
                state.steps_removed = static_cast<int>(steps);
            }
        }
    }
    if (answers == 0)
        return Result<PtpState>(ErrorCode::kUnavailable, "ptp4l gave no management answer");
    return state;
}

Result<PtpState> queryPtp4l(const PtpQueryOptions& options) {
    // pmc's own socket goes to the temporary folder: its default, /var/run/pmc.<pid>, needs root.
    const std::string client =
        (std::filesystem::temp_directory_path() / ("mixray-pmc." + std::to_string(getpid())))
            .string();
    std::vector<std::string> args = {options.pmc,
                                     "-u",
                                     "-b",
                                     "0",
                                     "-s",
                                     options.socket,
                                     "-i",
                                     client,
                                     "GET TIME_STATUS_NP",
                                     "GET PORT_DATA_SET",
                                     "GET CURRENT_DATA_SET"};
    std::vector<char*> argv;
    for (std::string& a : args)
        argv.push_back(a.data());
    argv.push_back(nullptr);

    int out[2];
    if (pipe2(out, O_CLOEXEC) != 0)
        return Result<PtpState>(ErrorCode::kIoError,
                                std::string("pmc: cannot make a pipe: ") + std::strerror(errno));
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, out[1], STDOUT_FILENO);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
    pid_t pid = -1;
    const int spawned =
        posix_spawnp(&pid, options.pmc.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(out[1]);
    if (spawned != 0) {
        close(out[0]);
        return Result<PtpState>(
            ErrorCode::kNotFound,
            "cannot run " + options.pmc + " (" + std::strerror(spawned) +
                "): install linuxptp (sudo apt-get install linuxptp) to read ptp4l's state");
    }
    std::string text;
    const int64_t deadline = monotonicNowNs() + int64_t{options.timeout_ms} * 1'000'000;
    bool timed_out = false;
    bool ended = false;
    while (text.size() < (1 << 20)) {
        const int64_t left_ms = (deadline - monotonicNowNs()) / 1'000'000;
        if (left_ms <= 0) {
            timed_out = true;
            break;
        }
        pollfd p{.fd = out[0], .events = POLLIN, .revents = 0};
        if (poll(&p, 1, static_cast<int>(left_ms)) <= 0)
            continue;
        char buffer[4096];
        const ssize_t n = read(out[0], buffer, sizeof(buffer));
        if (n <= 0) {
            ended = true;
            break;
        }
        text.append(buffer, static_cast<size_t>(n));
    }
    close(out[0]);
    if (!ended)
        kill(pid, SIGKILL);
    int wait_status = 0;
    while (waitpid(pid, &wait_status, 0) < 0 && errno == EINTR) {
    }
    std::error_code ignored;
    std::filesystem::remove(client, ignored);
    if (timed_out)
        return Result<PtpState>(
            ErrorCode::kUnavailable,
            options.pmc + " did not finish in " + std::to_string(options.timeout_ms) + " ms");
    Result<PtpState> state = parsePmcOutput(text);
    if (!state && state.status().code() == ErrorCode::kUnavailable &&
        text.find(" RESPONSE ") == std::string::npos)
        return Result<PtpState>(ErrorCode::kUnavailable,
                                "ptp4l does not answer at " + options.socket +
                                    " (not running, another uds_address, or not allowed: its "
                                    "socket is root's)");
    return state;
}

}  // namespace mixray
