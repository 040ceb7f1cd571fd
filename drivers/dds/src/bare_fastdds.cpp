#include "mixray/dds/bare_fastdds.h"

#include <atomic>
#include <chrono>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <functional>
#include <memory>
#include <thread>

#include "frame_message.h"
#include "mixray/graph/host_time.h"
#include "participant.h"

namespace mixray::dds {
namespace {

namespace fdds = eprosima::fastdds::dds;

}  // namespace

void waitForWindow(uint64_t sent, const std::atomic<uint64_t>& received, int64_t now_ns) {
    const int64_t give_up = now_ns + 2'000'000'000;
    while (sent >= received.load() + kBenchWindow && monotonicNowNs() < give_up)
        std::this_thread::sleep_for(std::chrono::microseconds(20));
}

Result<BareRun> runBareFastDds(const DdsOptions& writer_options, const DdsOptions& reader_options,
                               size_t payload_bytes, uint64_t frames, int64_t period_ns,
                               const HostScope& writer_host, const HostScope& reader_host) {
    const auto in = [](const HostScope& host, const std::function<Status()>& make) {
        return host ? host(make) : make();
    };
    const std::string name = "mixray/bench/bare";
    constexpr int kDepth = 2;  // as DdsPublisherOptions::history_depth
    std::shared_ptr<detail::Participant> a, b;
    fdds::DataWriter* writer = nullptr;
    fdds::DataReader* reader = nullptr;
    MIXRAY_RETURN_IF_ERROR(in(writer_host, [&]() -> Status {
        auto made = detail::Participant::create(writer_options, "mixray bench dds: bare writer");
        if (!made)
            return made.status();
        a = *made;
        auto topic = a->topic(name, detail::frameType());
        if (!topic)
            return topic.status();
        writer = a->publisher()->create_datawriter(*topic,
                                                   detail::frameWriterQos(writer_options, kDepth));
        return writer ? Status::ok()
                      : Status{ErrorCode::kInternal, "bench dds: cannot create the bare writer"};
    }));
    MIXRAY_RETURN_IF_ERROR(in(reader_host, [&]() -> Status {
        auto made = detail::Participant::create(reader_options, "mixray bench dds: bare reader");
        if (!made)
            return made.status();
        b = *made;
        auto topic = b->topic(name, detail::frameType());
        if (!topic)
            return topic.status();
        reader = b->subscriber()->create_datareader(*topic, detail::frameReaderQos(4));
        return reader ? Status::ok()
                      : Status{ErrorCode::kInternal, "bench dds: cannot create the bare reader"};
    }));
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    for (;;) {
        fdds::PublicationMatchedStatus w;
        fdds::SubscriptionMatchedStatus r;
        writer->get_publication_matched_status(w);
        reader->get_subscription_matched_status(r);
        if (w.current_count > 0 && r.current_count > 0)
            break;
        if (std::chrono::steady_clock::now() > until)
            return Status{ErrorCode::kUnavailable, "bench dds: the bare endpoints never matched"};
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }

    BareRun run;
    std::atomic<bool> done{false};
    std::atomic<uint64_t> received{0};
    int64_t first_write = 0;
    int64_t last_take = 0;
    std::thread taker([&] {
        detail::FrameMessage message;
        fdds::SampleInfo info;
        while (!done.load()) {
            (void)reader->wait_for_unread_message(eprosima::fastrtps::Duration_t(0, 20'000'000));
            while (reader->take_next_sample(&message, &info) == ReturnCode_t::RETCODE_OK) {
                if (!info.valid_data)
                    continue;
                last_take = monotonicNowNs();
                run.latency_ms.push_back(
                    static_cast<double>(last_take - message.device_stamp_ns()) / 1e6);
                received.fetch_add(1);
            }
        }
    });
    detail::FrameMessage message;
    message.format("mono8");
    message.data().assign(payload_bytes, 0x5a);
    first_write = monotonicNowNs();
    for (uint64_t i = 0; i < frames; ++i) {
        if (period_ns > 0) {
            const int64_t due = first_write + static_cast<int64_t>(i) * period_ns;
            while (monotonicNowNs() < due)
                std::this_thread::sleep_for(std::chrono::microseconds(200));
        } else {
            waitForWindow(run.sent, received, monotonicNowNs());
        }
        message.sequence_number(i);
        message.device_stamp_ns(monotonicNowNs());
        if (writer->write(&message))
            ++run.sent;
    }
    // Whatever is still on its way has half a second to arrive.
    const int64_t give_up = monotonicNowNs() + 500'000'000;
    while (monotonicNowNs() < give_up && received.load() < run.sent)
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    done = true;
    taker.join();
    run.received = received.load();
    run.wall_s = static_cast<double>(last_take - first_write) / 1e9;
    return run;
}

}  // namespace mixray::dds
