// Counts heap allocations made through operator new, so benchmarks can show that a hot path
// allocates nothing per frame.
#pragma once

#include <cstdint>

namespace mixray::cli {

// Allocations made by the whole process so far (every thread).
uint64_t heapAllocations();

}  // namespace mixray::cli
