// A umockdev testbed for the usb tests, filled from the device descriptions in tests/usb.
#pragma once

#include <gtest/gtest.h>
#include <umockdev.h>

#include <string>

#include "test_data.h"

namespace mixray::usb::test {

// Owns a umockdev testbed; its devices vanish with it.
class Testbed {
public:
    Testbed() : testbed_(umockdev_testbed_new()) {}
    ~Testbed() { g_object_unref(testbed_); }
    Testbed(const Testbed&) = delete;
    Testbed& operator=(const Testbed&) = delete;

    // Adds the devices of tests/usb/<file>; a test failure when umockdev refuses them.
    bool add(const char* file) {
        const std::string path = (mixray::test::sourceDir() / "tests/usb" / file).string();
        GError* error = nullptr;
        if (!umockdev_testbed_add_from_file(testbed_, path.c_str(), &error)) {
            ADD_FAILURE() << "umockdev: " << path << ": " << error->message;
            g_clear_error(&error);
            return false;
        }
        return true;
    }
    void uevent(const std::string& syspath, const char* action) {
        umockdev_testbed_uevent(testbed_, syspath.c_str(), action);
    }
    void remove(const std::string& syspath) {
        umockdev_testbed_remove_device(testbed_, syspath.c_str());
    }
    UMockdevTestbed* get() const { return testbed_; }

private:
    UMockdevTestbed* testbed_;
};

}  // namespace mixray::usb::test
