// umockdev emulates devices by preloading a library that redirects /dev, /sys and device
// ioctls; tests that use it re-execute themselves with it preloaded, so ctest and a plain run
// need no wrapper script.
#pragma once

namespace mixray::test {

inline constexpr const char* kUmockdevPreload = "libumockdev-preload.so.0";

// True when this process runs with umockdev's preload library.
bool umockdevPreloaded();

// Call first in main(): re-executes the binary with umockdev's preload library (and ASan told
// not to insist on being loaded first) when the library is installed and not yet preloaded.
// Returns when it did not (already preloaded, library missing, or only listing tests).
void reexecWithUmockdevPreload(int argc, char** argv);

}  // namespace mixray::test
