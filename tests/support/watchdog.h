// Runs a piece of a test under a time limit, so that a call that never returns (a kernel that
// hangs) fails the test in seconds and names itself instead of stalling the whole suite.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace mixray::test {

// What a watched body is doing now, for the message when it overruns. Thread-safe.
class WatchdogStage {
public:
    void set(std::string stage) {
        std::lock_guard lock(mutex_);
        stage_ = std::move(stage);
    }
    std::string get() const {
        std::lock_guard lock(mutex_);
        return stage_;
    }

private:
    mutable std::mutex mutex_;
    std::string stage_ = "starting";
};

// Runs body(stage) on its own thread and waits at most `limit`. When the body overruns, prints
// "<what> did not return within N s (while <stage>)" and ends the process with exit code 1: a
// hung thread cannot be stopped, and ctest then reports the test as failed, by name, at once.
template <class Body>
void runWithin(std::chrono::seconds limit, const std::string& what, Body body) {
    struct Shared {
        std::mutex mutex;
        std::condition_variable done_cv;
        bool done = false;
        WatchdogStage stage;
    };
    auto shared = std::make_shared<Shared>();
    std::thread worker([shared, body]() mutable {
        body(shared->stage);
        std::lock_guard lock(shared->mutex);
        shared->done = true;
        shared->done_cv.notify_all();
    });
    std::unique_lock lock(shared->mutex);
    if (!shared->done_cv.wait_for(lock, limit, [&] { return shared->done; })) {
        std::fprintf(stderr, "FAILED: %s did not return within %lld s (while %s)\n", what.c_str(),
                     static_cast<long long>(limit.count()), shared->stage.get().c_str());
        std::fflush(nullptr);
        std::_Exit(1);
    }
    lock.unlock();
    worker.join();
}

}  // namespace mixray::test
