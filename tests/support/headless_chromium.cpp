// Headless Chromium driven over the DevTools protocol on a pipe (fds 3 and 4, NUL-separated JSON).
#include "headless_chromium.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>

namespace mixray::test {
namespace {

using Clock = std::chrono::steady_clock;

// One DevTools session over the two pipe ends.
class DevTools {
public:
    DevTools(int to_browser, int from_browser, Clock::time_point deadline)
        : out_(to_browser), in_(from_browser), deadline_(deadline) {}

    // Sends a command and waits for its reply; nullopt on timeout or a closed pipe. A reply
    // carrying "error" comes back as it is.
    std::optional<nlohmann::json> call(const std::string& method, nlohmann::json params,
                                       const std::string& session = "") {
        const int id = ++last_id_;
        nlohmann::json message = {{"id", id}, {"method", method}, {"params", std::move(params)}};
        if (!session.empty())
            message["sessionId"] = session;
        std::string text = message.dump();
        text.push_back('\0');
        size_t sent = 0;
        while (sent < text.size()) {
            const ssize_t n = write(out_, text.data() + sent, text.size() - sent);
            if (n <= 0)
                return std::nullopt;
            sent += static_cast<size_t>(n);
        }
        while (true) {
            const size_t end = buffer_.find('\0');
            if (end != std::string::npos) {
                const std::string one = buffer_.substr(0, end);
                buffer_.erase(0, end + 1);
                nlohmann::json reply = nlohmann::json::parse(one, nullptr, false);
                if (!reply.is_discarded() && reply.contains("id") && reply["id"] == id) {
                    return reply;
                }
                continue;  // an event, or a reply to something else
            }
            const auto left =
                std::chrono::duration_cast<std::chrono::milliseconds>(deadline_ - Clock::now());
            if (left.count() <= 0)
                return std::nullopt;
            pollfd pfd{in_, POLLIN, 0};
            if (poll(&pfd, 1, static_cast<int>(left.count())) <= 0)
                return std::nullopt;
            char chunk[65536];
            const ssize_t n = read(in_, chunk, sizeof(chunk));
            if (n <= 0)
                return std::nullopt;
            buffer_.append(chunk, static_cast<size_t>(n));
        }
    }

    // Evaluates `expression` in the page; its value (by value), or nullopt.
    std::optional<nlohmann::json> evaluate(const std::string& session,
                                           const std::string& expression) {
        auto reply = call("Runtime.evaluate", {{"expression", expression}, {"returnByValue", true}},
                          session);
        if (!reply || !reply->contains("result") || !(*reply)["result"].contains("result")) {
            return std::nullopt;
        }
        const nlohmann::json& result = (*reply)["result"]["result"];
        return result.contains("value") ? result["value"] : nlohmann::json();
    }

private:
    int out_;
    int in_;
    Clock::time_point deadline_;
    int last_id_ = 0;
    std::string buffer_;
};

std::string base64Decode(const std::string& text) {
    std::string out;
    uint32_t bits = 0;
    int count = 0;
    for (const char c : text) {
        int v = -1;
        if (c >= 'A' && c <= 'Z')
            v = c - 'A';
        if (c >= 'a' && c <= 'z')
            v = c - 'a' + 26;
        if (c >= '0' && c <= '9')
            v = c - '0' + 52;
        if (c == '+')
            v = 62;
        if (c == '/')
            v = 63;
        if (v < 0)
            continue;  // padding
        bits = (bits << 6) | static_cast<uint32_t>(v);
        count += 6;
        if (count >= 8) {
            count -= 8;
            out.push_back(static_cast<char>((bits >> count) & 0xFF));
        }
    }
    return out;
}

std::string tail(const std::filesystem::path& path, size_t bytes) {
    FILE* f = std::fopen(path.c_str(), "rb");
    if (f == nullptr)
        return "";
    std::string text;
    char chunk[4096];
    size_t n = 0;
    while ((n = std::fread(chunk, 1, sizeof(chunk), f)) > 0)
        text.append(chunk, n);
    std::fclose(f);
    return text.size() > bytes ? text.substr(text.size() - bytes) : text;
}

}  // namespace

std::filesystem::path chromiumPath() {
    const char* path_env = std::getenv("PATH");
    const std::string path = path_env != nullptr ? path_env : "/usr/bin:/bin";
    for (const char* name : {"chromium", "chromium-browser"}) {
        size_t start = 0;
        while (start <= path.size()) {
            const size_t end = std::min(path.find(':', start), path.size());
            const std::filesystem::path candidate =
                std::filesystem::path(path.substr(start, end - start)) / name;
            if (access(candidate.c_str(), X_OK) == 0)
                return candidate;
            start = end + 1;
        }
    }
    return {};
}

ChromiumRun runHeadlessChromium(const std::string& url, const ChromiumOptions& options) {
    ChromiumRun run;
    const std::filesystem::path binary = chromiumPath();
    if (binary.empty()) {
        run.error = "chromium is not installed (apt-get install chromium)";
        return run;
    }
    char profile_template[] = "/tmp/mixray-chromium-XXXXXX";
    if (mkdtemp(profile_template) == nullptr) {
        run.error = std::string("mkdtemp: ") + std::strerror(errno);
        return run;
    }
    const std::filesystem::path profile = profile_template;
    const std::filesystem::path log = profile / "stderr.txt";
    int to_browser[2];
    int from_browser[2];
    if (pipe(to_browser) != 0 || pipe(from_browser) != 0) {
        run.error = std::string("pipe: ") + std::strerror(errno);
        return run;
    }
    // Everything the child needs is made before fork: after it only async-signal-safe calls.
    std::vector<std::string> args = {binary.string(),
                                     "--headless=new",
                                     "--no-sandbox",
                                     "--disable-gpu",
                                     "--no-first-run",
                                     "--no-default-browser-check",
                                     "--remote-debugging-pipe",
                                     "--user-data-dir=" + profile.string(),
                                     "--window-size=" + std::to_string(options.window_width) + "," +
                                         std::to_string(options.window_height),
                                     url};
    std::vector<char*> argv;
    for (std::string& a : args)
        argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t pid = fork();
    if (pid == 0) {
        // The pipe ends may sit on 3 or 4 themselves: lift them out of the way first.
        const int in = fcntl(to_browser[0], F_DUPFD, 10);
        const int out = fcntl(from_browser[1], F_DUPFD, 10);
        const int err = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (in < 0 || out < 0 || dup2(in, 3) < 0 || dup2(out, 4) < 0)
            _exit(127);
        if (err >= 0) {
            dup2(err, 1);
            dup2(err, 2);
        }
        execv(argv[0], argv.data());
        _exit(127);
    }
    close(to_browser[0]);
    close(from_browser[1]);
    if (pid < 0) {
        run.error = std::string("fork: ") + std::strerror(errno);
        close(to_browser[1]);
        close(from_browser[0]);
        return run;
    }
    const Clock::time_point deadline = Clock::now() + options.timeout;
    DevTools devtools(to_browser[1], from_browser[0], deadline);
    std::string session;
    // The page target of `url`; it may take a moment to appear.
    while (session.empty() && Clock::now() < deadline) {
        auto targets = devtools.call("Target.getTargets", nlohmann::json::object());
        if (!targets)
            break;
        for (const auto& t : (*targets)["result"]["targetInfos"]) {
            if (t.value("type", "") != "page")
                continue;
            auto attached = devtools.call("Target.attachToTarget",
                                          {{"targetId", t["targetId"]}, {"flatten", true}});
            if (attached && (*attached).contains("result")) {
                session = (*attached)["result"].value("sessionId", "");
            }
            break;
        }
        if (session.empty())
            std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    if (!session.empty()) {
        run.started = true;
        const std::string until =
            options.until_js.empty() ? "document.readyState === 'complete'" : options.until_js;
        while (Clock::now() < deadline) {
            auto value = devtools.evaluate(session, "Boolean(" + until + ")");
            if (value && value->is_boolean() && value->get<bool>()) {
                run.until_met = true;
                break;
            }
            std::this_thread::sleep_for(options.poll);
        }
        // A little past the deadline for the result and the close.
        DevTools closing(to_browser[1], from_browser[0], Clock::now() + std::chrono::seconds(5));
        auto value = closing.evaluate(session, options.result_js);
        if (value)
            run.result = value->is_string() ? value->get<std::string>() : value->dump();
        if (!options.screenshot.empty()) {
            auto shot = closing.call("Page.captureScreenshot", {{"format", "png"}}, session);
            if (shot && shot->contains("result")) {
                std::ofstream(options.screenshot, std::ios::binary)
                    << base64Decode((*shot)["result"].value("data", ""));
            }
        }
        closing.call("Browser.close", nlohmann::json::object());
    }
    close(to_browser[1]);
    close(from_browser[0]);
    // Chromium ends on Browser.close or when its pipe closes; killed when it lingers.
    int wstatus = 0;
    const Clock::time_point wait_until = Clock::now() + std::chrono::seconds(5);
    while (waitpid(pid, &wstatus, WNOHANG) == 0) {
        if (Clock::now() > wait_until) {
            kill(pid, SIGKILL);
            waitpid(pid, &wstatus, 0);
            break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (!run.started || !run.until_met)
        run.error = tail(log, 2000);
    std::error_code ec;
    std::filesystem::remove_all(profile, ec);
    return run;
}

}  // namespace mixray::test
