// .oni recordings read frame by frame: the openni2 backend's device in a private graph.
#include "mixray/openni2/oni_recording.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <thread>

#include "mixray/graph/frame_queue.h"
#include "mixray/graph/graph.h"
#include "mixray/openni2/openni2_backend.h"

namespace mixray::openni2 {
namespace {

// How long next() waits for the streams that have no frame queued before it returns the
// earliest frame it has: OpenNI2's player could hold one stream back while another's buffers
// are all queued here, and waiting forever would deadlock.
constexpr auto kMergePatience = std::chrono::milliseconds(500);
// How long next() waits for any frame at all before it says the player stopped.
constexpr auto kStallTimeout = std::chrono::seconds(30);

std::string pinholeFromFov(const StreamInfo& info) {
    auto it = info.tags.find(kFieldOfViewTag);
    if (it == info.tags.end())
        return {};
    double h = 0, v = 0;
    if (std::sscanf(it->second.c_str(), "%lf,%lf", &h, &v) != 2 || !(h > 0) || !(v > 0) ||
        h >= M_PI || v >= M_PI) {
        return {};
    }
    const double w = info.format.width;
    const double hh = info.format.height;
    char text[160];
    std::snprintf(text, sizeof text, "%.17g,%.17g,%.17g,%.17g", (w / 2) / std::tan(h / 2),
                  (hh / 2) / std::tan(v / 2), (w - 1) / 2, (hh - 1) / 2);
    return text;
}

class OniReader : public RecordingReader {
public:
    ~OniReader() override { graph_.stop(); }

    Status init(const std::filesystem::path& file, size_t buffers) {
        OpenNI2Backend backend;
        DeviceConfig config;
        config.name = "oni";
        config.driver = "openni2";
        config.id = file.string();
        config.options = {{"pace", "fast"}, {"buffers", std::to_string(buffers)}};
        auto device = backend.open(config);
        if (!device)
            return device.status();
        device_ = dynamic_cast<OpenNI2Device*>(device->get());
        tags_["oni_device"] = (*device)->descriptor().model;
        std::string modes;
        for (const auto& m : (*device)->descriptor().modes)
            modes += (modes.empty() ? "" : "; ") + m;
        tags_["oni_modes"] = modes;
        MIXRAY_RETURN_IF_ERROR(graph_.addNode(std::move(*device)));
        const auto counts = device_ ? device_->recordedFrameCounts() : std::vector<int>{};
        streams_ = graph_.streams();
        for (size_t i = 0; i < streams_.size(); ++i) {
            StreamInfo& info = streams_[i];
            info.clock_domain = kHostClockDomain;  // host stamps are the recorded time
            if (i < counts.size()) {
                info.tags["oni_recorded_frames"] = std::to_string(counts[i]);
                recorded_.push_back(counts[i]);
            } else {
                recorded_.push_back(0);
            }
            if (info.kind == StreamKind::kDepth) {
                const std::string k = pinholeFromFov(info);
                if (!k.empty())
                    info.tags[kOniIntrinsicsTag] = k;
            }
            QueueOptions q;
            q.capacity = buffers + 1;
            q.policy = QueuePolicy::kLossless;
            q.name = "oni reader";
            auto queue = graph_.subscribe(static_cast<StreamId>(i), q);
            if (!queue)
                return queue.status();
            queues_.push_back(*queue);
        }
        heads_.resize(streams_.size());
        delivered_.assign(streams_.size(), 0);
        ended_.assign(streams_.size(), false);
        return Status::ok();
    }

    std::string format() const override { return "oni"; }
    const std::vector<StreamInfo>& streams() const override { return streams_; }
    const std::vector<Attachment>& attachments() const override { return attachments_; }
    const std::map<std::string, std::string>& tags() const override { return tags_; }

    Result<FrameRef> next() override {
        if (!started_) {
            MIXRAY_RETURN_IF_ERROR(graph_.start());
            started_ = true;
        }
        using Clock = std::chrono::steady_clock;
        const auto t0 = Clock::now();
        while (true) {
            bool missing = false, any = false;
            for (size_t i = 0; i < queues_.size(); ++i) {
                // A stream that delivered all it recorded is done: OpenNI2 ends the streams only
                // when every one of them is, and waiting for it would stall the others.
                if (!heads_[i] && recorded_[i] > 0 && delivered_[i] >= recorded_[i])
                    ended_[i] = true;
                if (!heads_[i] && !ended_[i]) {
                    auto frame = queues_[i]->pop(std::chrono::milliseconds(5));
                    if (frame)
                        heads_[i] = std::move(*frame);
                    else if (queues_[i]->closed())
                        ended_[i] = true;
                    else
                        missing = true;
                }
                any = any || heads_[i].has_value();
            }
            if (!missing)
                break;
            const auto waited = Clock::now() - t0;
            if (any && waited > kMergePatience)
                break;
            Status status = device_ ? device_->status() : Status::ok();
            if (!status)
                return status.withContext("playing the .oni recording");
            if (!any && waited > kStallTimeout) {
                return {ErrorCode::kCorruptData,
                        "the .oni recording stopped delivering frames (OpenNI2 playback)"};
            }
        }
        size_t best = heads_.size();
        for (size_t i = 0; i < heads_.size(); ++i) {
            if (heads_[i] && (best == heads_.size() || heads_[i]->meta().device_stamp_ns <
                                                           heads_[best]->meta().device_stamp_ns)) {
                best = i;
            }
        }
        if (best == heads_.size()) {
            Status status = device_ ? device_->status() : Status::ok();
            if (!status)
                return status.withContext("playing the .oni recording");
            return {ErrorCode::kEndOfStream, "oni: end of recording"};
        }
        FrameRef frame = std::move(*heads_[best]);
        heads_[best].reset();
        ++delivered_[best];
        // The queue handed over its reference; the capture thread drops its own just after
        // publishing, which can be a moment after the frame reached the queue. Then the frame
        // is ours alone and its metadata can be amended in place.
        WritableFrame amend = WritableFrame::reclaim(frame);
        for (int tries = 0; !amend && tries < 10000; ++tries) {
            std::this_thread::sleep_for(std::chrono::microseconds(100));
            amend = WritableFrame::reclaim(frame);
        }
        if (!amend)
            return {ErrorCode::kInternal, "oni reader: a played frame is still shared"};
        amend.meta().stream = static_cast<StreamId>(best);
        amend.meta().host_stamp_ns = amend.meta().device_stamp_ns;
        amend.meta().clock_domain = kHostClockDomain;
        started_reading_ = true;
        return std::move(amend).publish();
    }

    Status seek(int64_t host_stamp_ns) override {
        if (!started_reading_ && host_stamp_ns <= 0)
            return Status::ok();
        return {ErrorCode::kUnsupported,
                "oni: OpenNI2 cannot seek this recording; it is read once from its start"};
    }

private:
    Graph graph_;
    OpenNI2Device* device_ = nullptr;  // owned by graph_
    std::vector<StreamInfo> streams_;
    std::vector<Attachment> attachments_;
    std::map<std::string, std::string> tags_;
    std::vector<std::shared_ptr<FrameQueue>> queues_;
    std::vector<std::optional<FrameRef>> heads_;
    std::vector<bool> ended_;
    std::vector<int> recorded_;  // frames per stream the recording holds (0: not known)
    std::vector<int> delivered_;
    bool started_ = false;
    bool started_reading_ = false;
};

}  // namespace

bool looksLikeOni(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    char magic[4] = {};
    in.read(magic, sizeof magic);
    return in.gcount() == 4 && magic[0] == 'N' && magic[1] == 'I' &&
           ((magic[2] == '1' && magic[3] == '0') || (magic[2] == '2' && magic[3] == '0'));
}

Result<std::unique_ptr<RecordingReader>> openOniRecording(const std::filesystem::path& file,
                                                          size_t buffers_per_stream) {
    if (!looksLikeOni(file)) {
        return {ErrorCode::kCorruptData,
                file.string() + ": not an OpenNI recording (no NI10/NI20 magic)"};
    }
    auto reader = std::make_unique<OniReader>();
    Status status = reader->init(file, std::max<size_t>(buffers_per_stream, 2));
    if (!status)
        return status;
    return std::unique_ptr<RecordingReader>(std::move(reader));
}

}  // namespace mixray::openni2
