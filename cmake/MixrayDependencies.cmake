# Finds every third-party library mixray uses; a missing one stops configure naming its apt package.
include(FindPkgConfig)

# Stops configure with the Debian package that provides a missing dependency.
function(mixray_require found what apt_package)
    if(NOT ${found})
        message(FATAL_ERROR
            "mixray needs ${what}, which was not found.\n"
            "Install it with: sudo apt-get install ${apt_package}\n"
            "(or run scripts/setup-deps, which installs everything mixray needs)")
    endif()
endfunction()

macro(mixray_pkg name module apt_package)
    pkg_check_modules(${name} QUIET IMPORTED_TARGET ${module})
    mixray_require(${name}_FOUND "${module} (pkg-config)" ${apt_package})
endmacro()

find_package(PkgConfig QUIET)
mixray_require(PKG_CONFIG_FOUND "pkg-config" pkg-config)

# Recordings.
mixray_pkg(LIBAVFORMAT libavformat libavformat-dev)
mixray_pkg(LIBAVCODEC libavcodec libavcodec-dev)
mixray_pkg(LIBAVUTIL libavutil libavutil-dev)
mixray_pkg(LIBSWSCALE libswscale libswscale-dev)

# Device backends.
mixray_pkg(OPENNI2 libopenni2 libopenni2-dev)
# Kinect v1 for the OpenNI2 driver plug-in (drivers/openni2/freenect).
mixray_pkg(LIBFREENECT libfreenect libfreenect-dev)
mixray_pkg(ARAVIS aravis-0.8 libaravis-dev)
mixray_pkg(LIBV4L2 libv4l2 libv4l-dev)
mixray_pkg(LIBUSB libusb-1.0 libusb-1.0-0-dev)
mixray_pkg(LIBFREENECT libfreenect libfreenect-dev)

# The live view in the browser (drivers/liveview): HTTP + WebSocket, and JPEG.
# Debian's civetweb CMake config needs the civetweb server binary (another package): find the C
# library and header directly.
find_path(CIVETWEB_INCLUDE_DIR civetweb.h)
find_library(CIVETWEB_LIBRARY civetweb)
mixray_require(CIVETWEB_LIBRARY "civetweb" libcivetweb-dev)
if(NOT TARGET civetweb::civetweb)
    add_library(civetweb::civetweb UNKNOWN IMPORTED)
    set_target_properties(civetweb::civetweb PROPERTIES IMPORTED_LOCATION ${CIVETWEB_LIBRARY}
                                                        INTERFACE_INCLUDE_DIRECTORIES ${CIVETWEB_INCLUDE_DIR})
endif()
mixray_pkg(TURBOJPEG libturbojpeg libturbojpeg0-dev)

# Rigs across hosts (drivers/dds): Fast DDS 2.9, and fastddsgen to make its types from the IDL.
find_package(fastrtps 2.9 QUIET)
mixray_require(fastrtps_FOUND "eProsima Fast DDS 2.9" "libfastrtps-dev libfastcdr-dev")
find_program(FASTDDSGEN fastddsgen)
mixray_require(FASTDDSGEN "fastddsgen" fastddsgen)
# SHA-256 for ROS 2's type hashes (RIHS01).
find_package(OpenSSL 3 QUIET COMPONENTS Crypto)
mixray_require(OpenSSL_FOUND "OpenSSL 3 (libcrypto)" libssl-dev)
# CRC-32 for MCAP files.
find_package(ZLIB QUIET)
mixray_require(ZLIB_FOUND "zlib" zlib1g-dev)

# Algorithms.
find_package(Eigen3 3.4 QUIET NO_MODULE)
mixray_require(Eigen3_FOUND "Eigen 3" libeigen3-dev)
find_package(OpenCV 4.6 QUIET COMPONENTS core imgproc imgcodecs calib3d aruco)
mixray_require(OpenCV_FOUND "OpenCV 4.6 with contrib (aruco)" "libopencv-dev libopencv-contrib-dev")
mixray_pkg(APRILTAG apriltag libapriltag-dev)
find_package(Ceres 2.1 QUIET)
mixray_require(Ceres_FOUND "Ceres Solver 2.1" libceres-dev)
find_package(embree 3 QUIET)
mixray_require(embree_FOUND "Embree 3" libembree-dev)
# Highway: the renderer's SIMD batches, one build per instruction set, picked at run time.
mixray_pkg(HWY libhwy libhwy-dev)
find_path(MRCAL_INCLUDE_DIR mrcal.h PATH_SUFFIXES mrcal)
find_library(MRCAL_LIBRARY mrcal)
mixray_require(MRCAL_LIBRARY "mrcal 2.2" libmrcal-dev)
if(NOT TARGET mrcal::mrcal)
    add_library(mrcal::mrcal UNKNOWN IMPORTED)
    set_target_properties(mrcal::mrcal PROPERTIES IMPORTED_LOCATION ${MRCAL_LIBRARY}
                                                  INTERFACE_INCLUDE_DIRECTORIES ${MRCAL_INCLUDE_DIR})
endif()

find_package(assimp QUIET)
mixray_require(assimp_FOUND "assimp" libassimp-dev)
find_package(OpenEXR 3 QUIET)
mixray_require(OpenEXR_FOUND "OpenEXR" libopenexr-dev)
find_package(TBB QUIET)
mixray_require(TBB_FOUND "oneTBB" libtbb-dev)

# Support libraries.
find_package(yaml-cpp QUIET)
mixray_require(yaml-cpp_FOUND "yaml-cpp" libyaml-cpp-dev)
find_package(nlohmann_json 3 QUIET)
mixray_require(nlohmann_json_FOUND "nlohmann-json" nlohmann-json3-dev)
find_package(CLI11 QUIET)
if(NOT CLI11_FOUND)
    find_path(CLI11_INCLUDE_DIR CLI/CLI.hpp)
    set(CLI11_FOUND ${CLI11_INCLUDE_DIR})
endif()
mixray_require(CLI11_FOUND "CLI11" libcli11-dev)
if(NOT TARGET CLI11::CLI11)
    add_library(CLI11::CLI11 INTERFACE IMPORTED)
    target_include_directories(CLI11::CLI11 INTERFACE ${CLI11_INCLUDE_DIR})
endif()
find_package(Threads REQUIRED)

if(MIXRAY_BUILD_TESTS)
    find_package(GTest QUIET)
    mixray_require(GTest_FOUND "GoogleTest" "libgtest-dev libgmock-dev")
    find_package(benchmark QUIET)
    mixray_require(benchmark_FOUND "Google Benchmark" libbenchmark-dev)
    # ERFA (the IAU SOFA routines): an independent reference for the sun's position tests.
    mixray_pkg(ERFA erfa liberfa-dev)
    # umockdev: emulated /dev and /sys for the V4L2 backend's tests (a UVC camera in software).
    mixray_pkg(UMOCKDEV umockdev-1.0 libumockdev-dev)
    # Cyclone DDS: the second, independent DDS implementation the ROS 2 interoperability tests
    # receive mixray's topics with; its idlc makes the test's C types from the same IDL.
    find_package(CycloneDDS QUIET)
    mixray_require(CycloneDDS_FOUND "Cyclone DDS" "cyclonedds-dev cyclonedds-tools")
    find_program(CYCLONEDDS_IDLC idlc)
    mixray_require(CYCLONEDDS_IDLC "Cyclone DDS's idlc" cyclonedds-tools)
endif()
