// This host's PTP lock, read from ptp4l now and then on a thread of its own, for the clock
// exchanges (time_exchange.h), which must not wait for pmc. Internal to drivers/dds.
#pragma once

#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "mixray/dds/host_clock.h"

namespace mixray::dds::detail {

class PtpWatch {
public:
    // How often ptp4l is asked. A lock is lost or gained over seconds.
    static constexpr int kPeriodMs = 5000;

    // The process's watch of ptp4l at `socket`, made on first use and shared by every clock
    // responder and requester while any holds it: one thread and one pmc per socket, however
    // many remote devices a rig has.
    static std::shared_ptr<PtpWatch> shared(const std::string& socket);

    // Asks ptp4l at `socket` at once, then every kPeriodMs; while the socket does not exist
    // (no ptp4l), pmc is not run and the clock is not locked.
    explicit PtpWatch(std::string socket);
    ~PtpWatch();
    PtpWatch(const PtpWatch&) = delete;
    PtpWatch& operator=(const PtpWatch&) = delete;

    WallClockState latest() const;

private:
    void run();

    const std::string socket_;
    mutable std::mutex mutex_;
    std::condition_variable stop_changed_;
    bool stopping_ = false;
    WallClockState latest_;
    std::thread thread_;
};

}  // namespace mixray::dds::detail
