// The replay backend: a recording (mkv, TUM folder, PCL TIFF folder) is a device like any other.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "mixray/graph/device.h"
#include "mixray/graph/recording.h"

namespace mixray::replay {

// How a replay device paces and positions its recording. Parsed from DeviceConfig::options:
//   pace         original | fast   (default original)
//   speed        > 0, e.g. 0.5 or 2 (default 1; only with pace=original)
//   loop         true | false      (default false)
//   start        seconds from the recording's first frame, >= 0 (default 0)
//   depth_units  mm | recorded     (default mm)
//   buffers      frames of one stream consumers may hold at once, >= 1 (default 8)
//   names        device | recorded (default device): graph stream names "<device>/<short>",
//                or the recorded names themselves ("kinect/color"), as the rig that made the
//                recording published them: a recording standing in for its rig
//   stamps       recorded | arrival (default recorded; arrival only with pace=original): host
//                stamps as recorded, or the host time each frame is due to arrive by the
//                recording's timing, as a live device stamps its frames (frames captured
//                together keep one stamp however late the replay delivers them; the delivery
//                time is FrameMetadata::graph_stamp_ns)
// A rig file's per-stream mode requests ("depth.width", ".height", ".fps", ".format") are
// accepted when they describe what was recorded (a recording cannot change its mode); they are
// checked by openReplayDevice(), which knows the recording.
struct ReplayOptions {
    enum class Pace {
        kOriginal,  // frames leave at their recorded intervals divided by `speed`
        kFast,      // as fast as consumers allow: lossless edges back-pressure the device,
                    // live edges drop as they would with a fast camera
    };
    Pace pace = Pace::kOriginal;
    double speed = 1.0;
    // At the end go back to `start` and play again. Later passes have every stamp (host and
    // device) shifted by the played length (last - first stamp of the first pass plus one
    // mean frame interval) and sequences shifted by each stream's frame count, so time and
    // sequence stay strictly increasing for consumers.
    bool loop = false;
    double start_s = 0;
    // mm: depth streams recorded in other units (TUM's 5000/m, see depth_units.h) are
    // converted to millimetres, as every graph consumer expects of kDepth16 (a copy per frame
    // for those streams only; their depth_scale_per_m tag is dropped). recorded: the
    // recording's values pass through bit-exactly, tag kept.
    bool depth_in_mm = true;
    size_t buffers_per_stream = 8;
    bool recorded_names = false;
    bool arrival_stamps = false;

    // kInvalidArgument naming the option for unknown keys and bad values.
    static Result<ReplayOptions> fromConfig(const std::map<std::string, std::string>& options);
    Status validate() const;
};

// A replay device: one thread reads the recording and publishes its frames as the streams
// "<config.name>/<recording stream's short name>" (StreamInfo otherwise as recorded, device set
// to config.name). Frames are the reader's own pooled buffers, forwarded without a copy, their
// metadata exact except the stream id (the graph's) and, on loops, the shifted stamps. When the
// recording ends (no loop) every stream is ended with Graph::endStream(). While the reader has
// no free buffer (consumers hold them all) the device waits for one.
// stop() interrupts pacing and buffer waits at once; a publish blocked on a full lossless
// queue ends when the graph closes its queues, which Graph::stop() does before stopping nodes.
// Thread-safety: connect/start/stop are called by the graph's owner thread; status(),
// finished(), publishedFrames() and passes() may be called from any thread.
class ReplayDevice : public Device {
public:
    ~ReplayDevice() override;

    std::string name() const override { return config_name_; }
    DeviceDescriptor descriptor() const override { return descriptor_; }
    Status connect(Graph& graph) override;
    Status start() override;
    void stop() override;

    // ok while playing and after a clean end; the reader's error when it failed midway;
    // kCorruptData naming the first byte offset when it read past damage (RecordingDamage).
    Status status() const;
    // The same, for the graph's owner that knows it only as a Device.
    Status inputStatus() const override { return status(); }
    // True once the playback thread has ended its streams (end of data, error or stop()).
    bool finished() const { return finished_.load(); }
    // kEnded once finished(); until then kUnknown: its streams' activity tells the rest.
    DeviceState state() const override {
        return finished() ? DeviceState::kEnded : DeviceState::kUnknown;
    }
    // Frames published so far, and completed passes over the recording (loop).
    uint64_t publishedFrames() const { return published_.load(); }
    uint64_t passes() const { return passes_.load(); }
    const ReplayOptions& options() const { return options_; }

private:
    friend Result<std::unique_ptr<ReplayDevice>> openReplayDevice(
        std::unique_ptr<RecordingReader> reader, const DeviceConfig& config);
    ReplayDevice() = default;
    struct StreamRoute;
    void run();
    bool waitFor(std::chrono::steady_clock::duration duration);
    void setError(Status status);

    std::unique_ptr<RecordingReader> reader_;
    ReplayOptions options_;
    std::string config_name_;
    DeviceDescriptor descriptor_;
    std::vector<std::string> stream_filter_;
    Graph* graph_ = nullptr;
    std::vector<StreamRoute> routes_;  // indexed like reader_->streams()
    FrameRef first_frame_;             // read at open to position and validate `start`
    int64_t start_stamp_ns_ = 0;       // where each pass begins
    std::thread thread_;
    mutable std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_requested_ = false;
    Status status_;
    std::atomic<bool> finished_{false};
    std::atomic<uint64_t> published_{0};
    std::atomic<uint64_t> passes_{0};
};

// Builds a replay device over an already open reader (takes ownership). `config.id` only
// labels the descriptor; options and stream filter as for ReplayBackend::open(). Positions the
// reader at options.start_s now, so a start beyond the last frame fails here.
Result<std::unique_ptr<ReplayDevice>> openReplayDevice(std::unique_ptr<RecordingReader> reader,
                                                       const DeviceConfig& config);

// The "replay" backend: DeviceConfig::id is the recording's path (anything openRecording()
// understands). enumerate() lists nothing, without error: recordings are opened by path.
// Thread-bound, like every DeviceBackend.
class ReplayBackend : public DeviceBackend {
public:
    std::string_view name() const override { return "replay"; }
    Result<std::vector<DeviceDescriptor>> enumerate() override;
    Result<std::unique_ptr<Device>> open(const DeviceConfig& config) override;
};

}  // namespace mixray::replay
