// NTP-style clock exchanges between mixray hosts over DDS: every publishing host answers
// requests on its participant, and a receiving device asks the host it reads from and fits its
// clock (HostClockEstimator). Internal to drivers/dds.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "mixray/dds/host_clock.h"
#include "mixray/graph/result.h"
#include "participant.h"
#include "ptp_watch.h"

namespace mixray::dds::detail {

inline constexpr std::string_view kTimeRequestTopic = "mixray/time_request";
inline constexpr std::string_view kTimeResponseTopic = "mixray/time_response";

// Answers the requests addressed to `host`, on Fast DDS's listener thread: the request's
// arrival (t2) is stamped first thing, the answer's departure (t3) last before it is written.
// Best effort both ways: a lost or late exchange is only one fewer to fit.
class TimeResponder {
public:
    // `ptp4l`: this host's ptp4l socket, whose lock state the answers carry (PtpWatch).
    static Result<std::unique_ptr<TimeResponder>> create(std::shared_ptr<Participant> participant,
                                                         std::string host, std::string ptp4l);
    ~TimeResponder();
    uint64_t answered() const;

private:
    struct Impl;
    explicit TimeResponder(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

// Asks `host` for its time from a thread of its own, every 20 ms until eight answers are kept
// (at the start, and again after the host's clock jumped) and every 200 ms after, and fits that
// host's clock to this one from the answers.
class TimeRequester {
public:
    // `requester`: a name no other requester in the domain has (answers are addressed to it).
    // The fit's offset comes from both hosts' wall clocks when wallClockReason() says so:
    // `wall_clocks` (clock: wall), or both PTP-locked to one grandmaster (this host's lock read
    // from `ptp4l`, the other's from its answers).
    static Result<std::unique_ptr<TimeRequester>> create(std::shared_ptr<Participant> participant,
                                                         std::string requester, std::string host,
                                                         bool wall_clocks, std::string ptp4l);
    ~TimeRequester();
    // The current fit; nullopt until HostClockEstimator::kMinUsed answers came.
    std::optional<HostClockEstimate> estimate() const;
    // Waits up to `timeout` for a first fit.
    std::optional<HostClockEstimate> waitEstimate(std::chrono::milliseconds timeout) const;
    uint64_t requested() const;
    uint64_t answered() const;

private:
    struct Impl;
    explicit TimeRequester(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

}  // namespace mixray::dds::detail
