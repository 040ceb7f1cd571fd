# Warnings (errors for project code), sanitizers and the helper that declares a mixray library.

add_library(mixray_warnings INTERFACE)
target_compile_options(mixray_warnings INTERFACE
    -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align -Woverloaded-virtual
    -Wimplicit-fallthrough -Wformat=2
    $<$<BOOL:${MIXRAY_WERROR}>:-Werror>)

# Full debug info makes GCC take 1.5x as long on the Eigen- and OpenCV-heavy files and 1.9x as long
# under the sanitizers (measured on light_probe.cpp and renderer_test.cpp); line tables still give
# file:line in backtraces and sanitizer reports, which is what the test builds need. GCC keeps
# the last -g level, and these options follow CMAKE_CXX_FLAGS_<CONFIG>.
if(NOT MIXRAY_FULL_DEBUG_INFO)
    add_compile_options($<$<CONFIG:Debug,RelWithDebInfo>:-g1>)
endif()

if(MIXRAY_SANITIZE)
    add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer
                        -fno-sanitize-recover=undefined)
    # The sanitizers' instrumentation makes GCC's flow analysis report uninitialised values in
    # library code that is fine (std::regex, std::function); the plain build keeps the check.
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
        add_compile_options(-Wno-maybe-uninitialized)
    endif()
    add_link_options(-fsanitize=address,undefined)
    # Under ASan Eigen switches to its own aligned allocator (offset pointers), while Debian's
    # static libceres keeps plain malloc: Eigen's inline allocation code instantiated in one
    # and freed in the other is a bad free. glibc's (and ASan's) malloc is already 16-byte
    # aligned on x86-64, so Eigen may use it as the libraries do.
    add_compile_definitions(EIGEN_MALLOC_ALREADY_ALIGNED=1)
endif()

# ThreadSanitizer (scripts/tsan builds the threaded components' tests with it). It cannot share
# a process with ASan, and the third-party libraries are not instrumented: tests/tsan.supp
# names what they report, each with its reason.
if(MIXRAY_TSAN)
    if(MIXRAY_SANITIZE)
        message(FATAL_ERROR "MIXRAY_TSAN and MIXRAY_SANITIZE cannot be combined")
    endif()
    add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
    add_link_options(-fsanitize=thread)
    # GCC 12 warns that std::atomic_thread_fence is not supported by TSan (libstdc++'s
    # shared_ptr and TBB use it); reports at fences are what tests/tsan.supp is for.
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
        add_compile_options(-Wno-tsan -Wno-maybe-uninitialized)
    endif()
endif()

# mixray_optimise_under_sanitizers(<target>): the sanitizer build (Debug, -O1) compiles <target>
# at -O2, still instrumented and with its assertions. For the per-pixel code of the renderer and
# the light estimators, which at -O1 spends its time calling the one-line Eigen functions -O1
# does not inline (render::detail::rotate alone was 16% of an AR pipeline test under ASan).
function(mixray_optimise_under_sanitizers target)
    if(MIXRAY_SANITIZE OR MIXRAY_TSAN)
        target_compile_options(${target} PRIVATE -O2)
    endif()
endfunction()

# Fuzzing (clang only): everything is instrumented for libFuzzer's coverage and built with ASan +
# UBSan; tests/fuzz links the fuzzer executables with -fsanitize=fuzzer.
set(MIXRAY_FUZZ_ENABLED OFF)
if(MIXRAY_FUZZ)
    if(CMAKE_CXX_COMPILER_ID MATCHES "Clang")
        set(MIXRAY_FUZZ_ENABLED ON)
        add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer
                            -fno-sanitize-recover=undefined)
        add_link_options(-fsanitize=address,undefined)
    else()
        message(WARNING "MIXRAY_FUZZ needs clang (CXX=clang++); the fuzzers are not built")
    endif()
endif()

# ccache with paths relative to the checkout, so that another clone of the same commit (CI clones
# into a fresh folder) hits the cache made by this one: CCACHE_BASEDIR rewrites the absolute
# -I and source paths, and the working directory is left out of the hash (it only names the
# build folder in the debug info). Absolute paths in -D values would still miss: keep them in
# one small source file each (tests/support/test_data.cpp, apps/src/test_data_paths.cpp).
find_program(CCACHE_PROGRAM ccache)
if(CCACHE_PROGRAM)
    set(MIXRAY_CCACHE_LAUNCHER ${CMAKE_COMMAND} -E env CCACHE_BASEDIR=${PROJECT_SOURCE_DIR}
                               CCACHE_NOHASHDIR=true CCACHE_MAXSIZE=20G
                               ${CCACHE_PROGRAM})
    set(CMAKE_CXX_COMPILER_LAUNCHER ${MIXRAY_CCACHE_LAUNCHER})
    set(CMAKE_C_COMPILER_LAUNCHER ${MIXRAY_CCACHE_LAUNCHER})
endif()

# mixray_library(<target> ALIAS <mixray::name> SOURCES ... ) declares a module library whose
# public headers live in include/ next to the CMakeLists that calls it.
function(mixray_library target)
    cmake_parse_arguments(ARG "" "ALIAS" "SOURCES" ${ARGN})
    add_library(${target} ${ARG_SOURCES})
    target_include_directories(${target} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include
                                         PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/src)
    target_link_libraries(${target} PRIVATE mixray_warnings)
    set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    if(ARG_ALIAS)
        add_library(${ARG_ALIAS} ALIAS ${target})
    endif()
endfunction()
