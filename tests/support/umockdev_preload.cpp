// Re-executing a test under umockdev's preload library (umockdev_preload.h).
#include "umockdev_preload.h"

#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

namespace mixray::test {

bool umockdevPreloaded() {
    const char* preload = std::getenv("LD_PRELOAD");
    return preload && std::strstr(preload, kUmockdevPreload);
}

void reexecWithUmockdevPreload(int argc, char** argv) {
    const bool listing = argc > 1 && std::strstr(argv[1], "--gtest_list_tests");
    // The guard variable stops a loop should the loader ignore LD_PRELOAD.
    if (listing || umockdevPreloaded() || std::getenv("MIXRAY_UMOCKDEV_NO_PRELOAD"))
        return;
    for (const char* dir :
         {"/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64", "/usr/lib"}) {
        if (!std::filesystem::exists(std::string(dir) + "/" + kUmockdevPreload))
            continue;
        const char* preload = std::getenv("LD_PRELOAD");
        std::string value = kUmockdevPreload;
        if (preload && *preload)
            value += std::string(":") + preload;
        setenv("LD_PRELOAD", value.c_str(), 1);
        setenv("MIXRAY_UMOCKDEV_NO_PRELOAD", "1", 1);
        // ASan wants to be the first library loaded; umockdev's preload comes first here.
        const char* asan = std::getenv("ASAN_OPTIONS");
        std::string asan_options = "verify_asan_link_order=0";
        if (asan && *asan)
            asan_options = std::string(asan) + ":" + asan_options;
        setenv("ASAN_OPTIONS", asan_options.c_str(), 1);
        execv("/proc/self/exe", argv);
        return;
    }
}

}  // namespace mixray::test
