#include "time_exchange.h"

#include <atomic>
#include <condition_variable>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

#include "frame_message.h"
#include "mixray/graph/host_time.h"

namespace mixray::dds::detail {
namespace {

using ReturnCode_t = eprosima::fastrtps::types::ReturnCode_t;

// A reader of `read_topic` calling `on_sample(message, arrival_ns)` for each sample, with its
// arrival stamped before anything else is done; a writer of `write_topic`.
struct Endpoints : public fdds::DataReaderListener {
    std::shared_ptr<Participant> participant;
    fdds::DataReader* reader = nullptr;
    fdds::DataWriter* writer = nullptr;
    std::function<void(const TimeExchangeMessage&, int64_t)> on_sample;

    Status create(std::shared_ptr<Participant> p, std::string_view read_topic,
                  std::string_view write_topic) {
        participant = std::move(p);
        auto read = participant->topic(std::string(read_topic), timeExchangeType());
        if (!read)
            return read.status();
        auto write = participant->topic(std::string(write_topic), timeExchangeType());
        if (!write)
            return write.status();
        writer = participant->publisher()->create_datawriter(*write, timeExchangeWriterQos());
        if (!writer)
            return {ErrorCode::kInternal, "dds: cannot write " + std::string(write_topic)};
        reader = participant->subscriber()->create_datareader(*read, timeExchangeReaderQos(), this);
        if (!reader)
            return {ErrorCode::kInternal, "dds: cannot read " + std::string(read_topic)};
        return Status::ok();
    }

    // Readers and writers go before the listener they call does.
    void destroy() {
        if (reader) {
            (void)reader->set_listener(nullptr);
            (void)participant->subscriber()->delete_datareader(reader);
            reader = nullptr;
        }
        if (writer) {
            (void)participant->publisher()->delete_datawriter(writer);
            writer = nullptr;
        }
    }

    void on_data_available(fdds::DataReader* r) override {
        const int64_t arrival_ns = monotonicNowNs();
        TimeExchangeMessage message;
        fdds::SampleInfo info;
        while (r->take_next_sample(&message, &info) == ReturnCode_t::RETCODE_OK) {
            if (info.valid_data && message.protocol() <= kProtocolVersion)
                on_sample(message, arrival_ns);
        }
    }
};

}  // namespace

struct TimeResponder::Impl {
    explicit Impl(const std::string& ptp4l) : ptp(PtpWatch::shared(ptp4l)) {}
    std::string host;
    std::shared_ptr<PtpWatch> ptp;
    Endpoints endpoints;
    std::atomic<uint64_t> answered{0};
};

Result<std::unique_ptr<TimeResponder>> TimeResponder::create(
    std::shared_ptr<Participant> participant, std::string host, std::string ptp4l) {
    auto impl = std::make_unique<Impl>(ptp4l);
    impl->host = std::move(host);
    Impl* raw = impl.get();
    impl->endpoints.on_sample = [raw](const TimeExchangeMessage& request, int64_t arrival_ns) {
        if (request.responder() != raw->host || request.t2_ns() != 0 || request.t3_ns() != 0)
            return;
        TimeExchangeMessage answer = request;
        answer.t2_ns(arrival_ns);
        answer.protocol(kProtocolVersion);
        const WallClockState wall = raw->ptp->latest();
        answer.ptp_locked(wall.ptp_locked);
        answer.ptp_grandmaster(wall.ptp_grandmaster);
        answer.realtime_minus_monotonic_ns(realtimeMinusMonotonicNs());
        answer.t3_ns(monotonicNowNs());
        if (raw->endpoints.writer->write(&answer))
            raw->answered.fetch_add(1, std::memory_order_relaxed);
    };
    auto responder = std::unique_ptr<TimeResponder>(new TimeResponder(std::move(impl)));
    MIXRAY_RETURN_IF_ERROR(responder->impl_->endpoints.create(
        std::move(participant), kTimeRequestTopic, kTimeResponseTopic));
    return responder;
}

TimeResponder::TimeResponder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

TimeResponder::~TimeResponder() {
    impl_->endpoints.destroy();
}

uint64_t TimeResponder::answered() const {
    return impl_->answered.load(std::memory_order_relaxed);
}

struct TimeRequester::Impl {
    explicit Impl(const std::string& ptp4l) : ptp(PtpWatch::shared(ptp4l)) {}
    std::string requester;
    std::string host;
    bool wall_clocks = false;       // clock: wall
    std::shared_ptr<PtpWatch> ptp;  // this host's lock
    Endpoints endpoints;
    std::thread thread;

    mutable std::mutex mutex;
    mutable std::condition_variable changed;
    bool stopping = false;
    std::map<uint64_t, int64_t> outstanding;  // sequence -> t1, the last few requests
    HostClockEstimator estimator;
    std::optional<HostClockEstimate> estimate;
    uint64_t requested = 0;
    uint64_t answered = 0;

    void answer(const TimeExchangeMessage& m, int64_t arrival_ns) {
        if (m.requester() != requester || m.responder() != host)
            return;
        std::lock_guard lock(mutex);
        const auto found = outstanding.find(m.sequence_number());
        if (found == outstanding.end() || found->second != m.t1_ns())
            return;
        outstanding.erase(found);
        if (!estimator.add({m.t1_ns(), m.t2_ns(), m.t3_ns(), arrival_ns}))
            return;
        ++answered;
        // After a jump the last fit stands until the new one has its exchanges.
        if (std::optional<HostClockEstimate> fit = estimator.estimate()) {
            const std::optional<std::string> reason = wallClockReason(
                wall_clocks, ptp->latest(),
                {.ptp_locked = m.ptp_locked(), .ptp_grandmaster = m.ptp_grandmaster()});
            estimate = reason ? fromWallClocks(*fit, realtimeMinusMonotonicNs(),
                                               m.realtime_minus_monotonic_ns(), *reason)
                              : *fit;
        }
        changed.notify_all();
    }

    void run() {
        std::unique_lock lock(mutex);
        for (uint64_t sequence = 1; !stopping; ++sequence) {
            TimeExchangeMessage request;
            request.requester(requester);
            request.responder(host);
            request.sequence_number(sequence);
            request.protocol(kProtocolVersion);
            lock.unlock();
            // Written without the lock: in one process Fast DDS may deliver the answer on this
            // very thread, into answer().
            const int64_t t1 = monotonicNowNs();
            request.t1_ns(t1);
            {
                std::lock_guard relock(mutex);
                outstanding[sequence] = t1;
                while (outstanding.size() > 16)
                    outstanding.erase(outstanding.begin());
            }
            const bool sent = endpoints.writer->write(&request);
            lock.lock();
            if (sent)
                ++requested;
            // Quickly while there is no fit (at the start, after a jump), then gently.
            const bool fitting = estimator.size() < 2 * HostClockEstimator::kMinUsed;
            const auto pause = std::chrono::milliseconds(fitting ? 20 : 200);
            changed.wait_for(lock, pause, [&] { return stopping; });
        }
    }
};

Result<std::unique_ptr<TimeRequester>> TimeRequester::create(
    std::shared_ptr<Participant> participant, std::string requester, std::string host,
    bool wall_clocks, std::string ptp4l) {
    auto impl = std::make_unique<Impl>(ptp4l);
    impl->requester = std::move(requester);
    impl->host = std::move(host);
    impl->wall_clocks = wall_clocks;
    Impl* raw = impl.get();
    impl->endpoints.on_sample = [raw](const TimeExchangeMessage& m, int64_t arrival_ns) {
        raw->answer(m, arrival_ns);
    };
    auto made = std::unique_ptr<TimeRequester>(new TimeRequester(std::move(impl)));
    MIXRAY_RETURN_IF_ERROR(made->impl_->endpoints.create(std::move(participant), kTimeResponseTopic,
                                                         kTimeRequestTopic));
    made->impl_->thread = std::thread([raw] { raw->run(); });
    return made;
}

TimeRequester::TimeRequester(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

TimeRequester::~TimeRequester() {
    {
        std::lock_guard lock(impl_->mutex);
        impl_->stopping = true;
        impl_->changed.notify_all();
    }
    if (impl_->thread.joinable())
        impl_->thread.join();
    impl_->endpoints.destroy();
}

std::optional<HostClockEstimate> TimeRequester::estimate() const {
    std::lock_guard lock(impl_->mutex);
    return impl_->estimate;
}

std::optional<HostClockEstimate> TimeRequester::waitEstimate(
    std::chrono::milliseconds timeout) const {
    std::unique_lock lock(impl_->mutex);
    impl_->changed.wait_for(lock, timeout, [&] { return impl_->estimate.has_value(); });
    return impl_->estimate;
}

uint64_t TimeRequester::requested() const {
    std::lock_guard lock(impl_->mutex);
    return impl_->requested;
}

uint64_t TimeRequester::answered() const {
    std::lock_guard lock(impl_->mutex);
    return impl_->answered;
}

}  // namespace mixray::dds::detail
