// This host's PTP state as linuxptp keeps it: ptp4l disciplines the host's clock to a
// grandmaster, and its management client pmc reports how (IEEE 1588 management TLVs).
//
// mixray stamps frames with CLOCK_MONOTONIC, which PTP does not set; what PTP aligns across
// hosts is CLOCK_REALTIME (ptp4l with software timestamps, or phc2sys from the NIC's clock).
// Hosts whose realtime clocks are PTP-locked share one time base through
// realtimeMinusMonotonicNs() (mixray/graph/host_time.h).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/result.h"

namespace mixray {

// Recording tag: PtpState::describe() of the recording host when it started (or why ptp4l did
// not say), so recordings made on several hosts say whether their clocks were PTP-locked.
inline constexpr std::string_view kHostPtpTag = "host_ptp";

struct PtpState {
    // The identity of the clock ptp4l runs (e.g. 9ef2f2.fffe.4fa318), from its answers.
    std::string clock_identity;
    // Each port's state as ptp4l names it: SLAVE (following a master), MASTER, UNCALIBRATED
    // (following, not yet locked), LISTENING, PASSIVE, FAULTY, ...
    std::vector<std::string> port_states;
    bool grandmaster_present = false;     // TIME_STATUS_NP gmPresent
    std::string grandmaster_identity;     // TIME_STATUS_NP gmIdentity
    int64_t master_offset_ns = 0;         // this clock − its master's, last measured
    std::optional<double> path_delay_ns;  // CURRENT_DATA_SET meanPathDelay
    std::optional<int> steps_removed;     // CURRENT_DATA_SET: boundary clocks to the grandmaster

    // A port follows a present grandmaster in ptp4l's locked state (SLAVE)...
    bool following() const;
    // ...or this clock is the grandmaster the others follow (a MASTER port, gmIdentity its own).
    bool grandmaster() const;
    // Time is PTP-locked: either of the above.
    bool locked() const { return following() || grandmaster(); }
    // One line: "PTP-locked: following grandmaster 9ef2f2.fffe.4fa318 (1 step), offset +330 ns,
    // path delay 2236 ns", or why not.
    std::string describe() const;
};

// Reads the answers of `pmc -u -b 0 'GET TIME_STATUS_NP' 'GET PORT_DATA_SET'
// 'GET CURRENT_DATA_SET'` (other answers are skipped). An error when no management answer is in
// the text (ptp4l did not answer), or when ptp4l answered with an error status.
Result<PtpState> parsePmcOutput(std::string_view text);

struct PtpQueryOptions {
    // ptp4l's management socket (its uds_address).
    std::string socket = "/var/run/ptp4l";
    // The pmc program (linuxptp).
    std::string pmc = "pmc";
    // pmc is killed after this long.
    int timeout_ms = 2000;
};

// Asks this host's ptp4l through pmc. Errors say what to do: pmc missing (install linuxptp),
// ptp4l not answering at the socket (not running, another uds_address, or not allowed to).
Result<PtpState> queryPtp4l(const PtpQueryOptions& options = {});

}  // namespace mixray
