// Thread roles and their scheduling priorities: when the machine is short of CPU, what gives
// way is the composite, never a captured or recorded frame.
#pragma once

namespace mixray {

// What a thread does, from the work that must never wait to the work that may fall behind.
// Linux gives each thread its own nice value (setpriority on its thread id); every thread of
// a role runs at the role's nice value, so under load the scheduler hands the cores down
// this list. docs/architecture.md ("Threads and priorities") says which thread runs as what.
enum class ThreadRole {
    kCapture,    // device capture and replay threads: a frame late here is a frame lost
    kRecorder,   // the recorder and its encoder: its queue holds driver buffers
    kPublisher,  // the live view's senders and DDS publishers: other hosts and people wait
    kEstimator,  // marker tracking, light estimation, synchronizers: the newest answer wins
    kRenderer,   // the compositor and its render threads: a late composite is skipped
};

const char* toString(ThreadRole role);

// The nice value a role asks for. Capture and the recorder ask for more than a normal
// thread (a negative nice value), which Linux grants only to privileged processes (root,
// CAP_SYS_NICE, or a raised RLIMIT_NICE); elsewhere they run at 0, still above the tracking
// and render threads.
int requestedNice(ThreadRole role);

// Sets the calling thread's nice value to the role's, or the nearest the process may set
// (a privileged nice value falls back to 0). Returns the nice value the thread runs at now.
int runAs(ThreadRole role);

// The calling thread's nice value.
int currentNice();

// Sets the calling thread's nice value; false where the process may not (raising a thread's
// priority needs privilege).
bool setCurrentNice(int nice);

// Runs the calling thread as `role` for its lifetime, then gives it back its own nice value
// where the process may. For a scope that starts threads which inherit its priority: FFmpeg's
// codec threads are made when a decoder or encoder opens, on the thread that opens it, so a
// recording replayed as a device opens under kCapture and the recorder's encoders under
// kRecorder. Thread-bound.
class ScopedThreadRole {
public:
    explicit ScopedThreadRole(ThreadRole role) : before_(currentNice()) { runAs(role); }
    ~ScopedThreadRole() { (void)setCurrentNice(before_); }
    ScopedThreadRole(const ScopedThreadRole&) = delete;
    ScopedThreadRole& operator=(const ScopedThreadRole&) = delete;

private:
    int before_;
};

}  // namespace mixray
