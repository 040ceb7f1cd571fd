// This host's clocks, read in nanoseconds. Every frame's host stamp is monotonicNowNs().
#pragma once

#include <cstdint>

namespace mixray {

// CLOCK_MONOTONIC (what std::chrono::steady_clock reads on Linux): the time base of host
// stamps, graph stamps and every timeout. Never steps; slewed by NTP and PTP daemons.
int64_t monotonicNowNs();

// CLOCK_REALTIME: the wall clock, UTC since 1970. Steps when it is set; on a host that
// ptp4l/phc2sys or chrony disciplines, the clock those keep in step with other hosts.
int64_t realtimeNowNs();

// CLOCK_REALTIME − CLOCK_MONOTONIC now: adds to a host stamp to give its wall time (ROS stamps,
// the sun's position in a recording). Read back to back, so good to a microsecond or so.
int64_t realtimeMinusMonotonicNs();

}  // namespace mixray
