// What the tracking graph nodes share (node_support.h).
#include "node_support.h"

#include <algorithm>

namespace mixray::tracking::detail {

WritableFrame acquireRecordBuffer(const PooledStream& out, bool lossless,
                                  const std::atomic<bool>& stop) {
    return lossless ? acquireWaiting(*out.pool, [&stop] { return stop.load(); })
                    : out.pool->acquire();
}

bool publishRecord(Graph& graph, const PooledStream& out, const uint8_t* bytes, size_t size,
                   const FrameMetadata& meta, bool lossless, const std::atomic<bool>& stop) {
    WritableFrame frame = acquireRecordBuffer(out, lossless, stop);
    if (!frame || size > frame.capacityBytes()) {
        graph.countLost(out.id);
        return false;
    }
    std::copy(bytes, bytes + size, frame.image().data);
    frame.setPayloadBytes(size);
    frame.meta() = meta;
    frame.meta().stream = out.id;
    graph.publish(std::move(frame).publish());
    return true;
}

Result<PooledStream> addEnvironmentMapStream(Graph& graph, const std::string& name,
                                             const std::string& device, const StreamInfo& of,
                                             int width) {
    StreamInfo map = makeEnvironmentMapStreamInfo(name, of.name, width, width / 2);
    map.device = device;
    map.clock_domain = of.clock_domain;
    map.nominal_fps = of.nominal_fps;
    return addPooledStream(graph, map, 4);
}

bool publishEnvironmentMap(Graph& graph, const PooledStream& out, const FloatImage& map,
                           const EnvironmentMapHeader& header, FrameMetadata meta, bool lossless,
                           const std::atomic<bool>& stop) {
    WritableFrame frame = acquireRecordBuffer(out, lossless, stop);
    Result<size_t> bytes = Status(ErrorCode::kUnavailable, "no buffer");
    if (frame)
        bytes = encodeEnvironmentMapRecord(map, header, frame.image().data, frame.capacityBytes());
    if (!bytes) {
        graph.countLost(out.id);
        return false;
    }
    frame.setPayloadBytes(*bytes);
    meta.stream = out.id;
    frame.meta() = meta;
    graph.publish(std::move(frame).publish());
    return true;
}

uint64_t skipToNewest(FrameQueue& queue, FrameRef& frame) {
    uint64_t skipped = 0;
    while (auto newer = queue.tryPop()) {
        frame = std::move(*newer);
        ++skipped;
    }
    return skipped;
}

Result<StreamId> findStream(const Graph& graph, const std::string& name, const std::string& use) {
    if (auto id = graph.findStream(name))
        return *id;
    std::string names;
    for (const StreamInfo& s : graph.streams())
        names += (names.empty() ? "" : ", ") + s.name;
    return Status(ErrorCode::kNotFound, "no stream " + name + " " + use + " (there are: " +
                                            (names.empty() ? "none" : names) + ")");
}

std::optional<FrameRef> popUnlessStopped(FrameQueue& queue, const std::atomic<bool>& stop) {
    while (!stop) {
        if (auto frame = queue.pop(std::chrono::milliseconds(5)))
            return frame;
        if (queue.closed())
            return queue.tryPop();  // the last frame may have come between the timeout and now
    }
    return std::nullopt;
}

}  // namespace mixray::tracking::detail
