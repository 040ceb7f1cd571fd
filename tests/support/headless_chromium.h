// Runs headless Chromium on a page and reads back what the page's own scripts made of it, over
// the DevTools protocol on a pipe (real time: live WebSockets work, unlike --virtual-time-budget).
#pragma once

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

namespace mixray::test {

// Chromium on PATH ("chromium", then "chromium-browser"); empty when absent.
std::filesystem::path chromiumPath();

struct ChromiumOptions {
    // A JavaScript expression evaluated in the page every `poll` until it is true; empty: wait
    // only for the page to load.
    std::string until_js;
    // Evaluated once at the end (after until_js held or the time ran out); its value as a string
    // (JSON.stringify(...) of whatever the test wants to check).
    std::string result_js = "document.documentElement.outerHTML";
    std::chrono::milliseconds timeout{20000};
    std::chrono::milliseconds poll{200};
    // Where to write a PNG of the page at the end (Page.captureScreenshot); empty: none.
    std::filesystem::path screenshot;
    int window_width = 1280;
    int window_height = 900;
};

struct ChromiumRun {
    bool started = false;    // Chromium ran and the DevTools session worked
    bool until_met = false;  // until_js became true within the timeout
    std::string result;      // the value of result_js
    std::string error;       // why not started, or the tail of Chromium's stderr
};

// Starts Chromium (--headless=new --no-sandbox --disable-gpu --remote-debugging-pipe, a fresh
// profile in a temporary folder) on `url`, waits for options.until_js, evaluates
// options.result_js, closes the browser and waits for it (killed when it does not end).
ChromiumRun runHeadlessChromium(const std::string& url, const ChromiumOptions& options = {});

}  // namespace mixray::test
