// A UVC camera emulated behind umockdev: a /dev/video node whose ioctls a handler answers the
// way uvcvideo does, streaming USERPTR buffers filled with a known pattern.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

namespace mixray::v4l2::test {

// What the emulated camera sends as frame `sequence` of a YUYV stream: every byte a function
// of its position and the sequence; the first 8 bytes are the sequence, little-endian.
uint8_t yuyvByte(uint64_t sequence, int x_byte, int y);
// The JPEG the camera sends as frame `sequence` of an MJPEG stream (encoded with OpenCV from
// an RGB gradient that moves with the sequence); `rgb` receives the encoded image.
std::vector<uint8_t> mjpegFrame(uint64_t sequence, int width, int height,
                                std::vector<uint8_t>* rgb = nullptr);

// One emulated camera at /dev/video0 (capture: YUYV 320x240 and 640x480, MJPEG 320x240 and
// 1280x720; 30 and 15 fps; controls brightness, auto exposure, exposure time, auto white balance,
// white balance temperature, with uvcvideo's rule that a manual value of an automatic control is
// refused with EACCES) and its UVC metadata node /dev/video1 (no video capture). Buffers:
// USERPTR only (REQBUFS for MMAP fails with EINVAL: umockdev cannot map a device).
// Frame k is ready at STREAMON + (k + 1) / fps on CLOCK_MONOTONIC and carries that stamp
// (V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, or TIMESTAMP_UNKNOWN with a stamp counted from 0 after
// setUnknownClock()).
// Thread-safe: the handler runs on umockdev's worker thread, tests read from theirs.
class UvcEmulator {
public:
    // Null when umockdev cannot create the testbed (why says so).
    static std::unique_ptr<UvcEmulator> create(std::string* why);
    ~UvcEmulator();

    // Sequences whose buffers are flagged V4L2_BUF_FLAG_ERROR.
    void setErrorFrames(std::set<uint64_t> sequences);
    // Sequences the camera loses (their number is skipped).
    void setSkippedFrames(std::set<uint64_t> sequences);
    void setUnknownClock(bool unknown);
    // From now on every ioctl fails with ENODEV, as after an unplug.
    void unplug();
    // The camera is back, as a camera freshly plugged in: not streaming, no buffers, default
    // format and control values.
    void replug();

    // Stamps (ns) of the frames dequeued, by sequence.
    std::map<uint64_t, int64_t> stamps() const;
    uint32_t streamOnCount() const;
    bool streaming() const;
    int32_t control(uint32_t id) const;

    struct State;

private:
    UvcEmulator() = default;
    std::shared_ptr<State> state_;
    void* testbed_ = nullptr;
    void* handlers_[2] = {nullptr, nullptr};
};

}  // namespace mixray::v4l2::test
