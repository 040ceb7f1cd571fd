#include "ptp_watch.h"

#include <chrono>
#include <filesystem>
#include <map>

#include "mixray/graph/ptp.h"

namespace mixray::dds::detail {

std::shared_ptr<PtpWatch> PtpWatch::shared(const std::string& socket) {
    static std::mutex mutex;
    static std::map<std::string, std::weak_ptr<PtpWatch>> watches;
    std::lock_guard lock(mutex);
    std::weak_ptr<PtpWatch>& slot = watches[socket];
    std::shared_ptr<PtpWatch> watch = slot.lock();
    if (!watch) {
        watch = std::make_shared<PtpWatch>(socket);
        slot = watch;
    }
    return watch;
}

PtpWatch::PtpWatch(std::string socket) : socket_(std::move(socket)) {
    thread_ = std::thread([this] { run(); });
}

PtpWatch::~PtpWatch() {
    {
        std::lock_guard lock(mutex_);
        stopping_ = true;
    }
    stop_changed_.notify_all();
    thread_.join();
}

WallClockState PtpWatch::latest() const {
    std::lock_guard lock(mutex_);
    return latest_;
}

void PtpWatch::run() {
    std::unique_lock lock(mutex_);
    while (!stopping_) {
        lock.unlock();
        WallClockState state;
        std::error_code error;
        if (std::filesystem::exists(socket_, error)) {
            const Result<PtpState> ptp =
                queryPtp4l({.socket = socket_, .pmc = "pmc", .timeout_ms = 2000});
            if (ptp && ptp->locked()) {
                state.ptp_locked = true;
                state.ptp_grandmaster = ptp->grandmaster_identity;
            }
        }
        lock.lock();
        latest_ = state;
        stop_changed_.wait_for(lock, std::chrono::milliseconds(kPeriodMs),
                               [this] { return stopping_; });
    }
}

}  // namespace mixray::dds::detail
