// Ownership of umockdev's ioctl argument buffers, for the tests' device emulators.
//
// umockdev_ioctl_data_resolve() returns a new reference (transfer full in UMockdev-1.0.gir, also
// when the same pointer was resolved before); the parent keeps its own. A handler that drops
// the result without unref keeps every buffer it ever resolved alive: an emulated Kinect's
// isochronous URBs (61 kB each, 36 a frame) grew the test process by 40 MB per 40 frames.
#pragma once

#include <umockdev.h>

#include <cstddef>
#include <memory>

namespace mixray::test {

struct IoctlDataUnref {
    void operator()(UMockdevIoctlData* data) const { g_object_unref(data); }
};
// One reference to an ioctl buffer; the buffer stays valid while its parent or this lives.
using IoctlDataRef = std::unique_ptr<UMockdevIoctlData, IoctlDataUnref>;

// The `length` bytes the pointer at `offset` of `parent` points to in the client, fetched;
// null when the client's pointer is null or umockdev cannot read them.
inline IoctlDataRef resolveIoctlData(UMockdevIoctlData* parent, size_t offset, size_t length) {
    GError* error = nullptr;
    IoctlDataRef out(umockdev_ioctl_data_resolve(parent, offset, length, &error));
    g_clear_error(&error);
    return out;
}

}  // namespace mixray::test
