// AddressSanitizer defaults for the test executables that run Fast DDS (a source of each).
//
// Fast DDS 2.9.1 (Debian 12) deletes one of a writer's internals through a pointer of a smaller
// type when the writer is destroyed (RTPSWriter::~RTPSWriter: 88 bytes allocated, 56 freed); ASan
// reports it as new-delete-type-mismatch and aborts. It is inside the library and harmless with
// glibc's allocator; ROS 2 sees the same class of report (ros2/rclcpp#2220). ASan cannot
// suppress that check per module, so these executables turn it off; every other check stays.
#if defined(__SANITIZE_ADDRESS__)
extern "C" const char* __asan_default_options() {
    return "new_delete_type_mismatch=0";
}
#endif
