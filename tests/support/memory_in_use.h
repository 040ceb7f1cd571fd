// The process's memory in use, for tests that bound memory growth: resident memory, or under
// AddressSanitizer or ThreadSanitizer their allocator's live heap bytes (ASan's quarantine keeps
// freed blocks resident, and TSan's shadow and history grow with every access, so RSS grows
// there whatever the code under test does).
#pragma once

#include <unistd.h>

#include <cstdint>
#include <fstream>

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define MIXRAY_TEST_SANITIZER_HEAP 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MIXRAY_TEST_SANITIZER_HEAP 1
#endif
#endif
#if MIXRAY_TEST_SANITIZER_HEAP
// The sanitizer runtime's own function (GCC ships no header declaring it).
extern "C" size_t __sanitizer_get_current_allocated_bytes();
#endif

namespace mixray::test {

inline uint64_t memoryInUse() {
#if MIXRAY_TEST_SANITIZER_HEAP
    return __sanitizer_get_current_allocated_bytes();
#else
    std::ifstream statm("/proc/self/statm");
    uint64_t pages = 0, resident = 0;
    statm >> pages >> resident;
    return resident * static_cast<uint64_t>(sysconf(_SC_PAGESIZE));
#endif
}

}  // namespace mixray::test
