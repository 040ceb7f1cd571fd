// What the tracking graph nodes share: the end of a node's run, and publishing one record.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>

#include "mixray/graph/graph.h"
#include "mixray/tracking/light_record.h"

namespace mixray::tracking::detail {

// A buffer of `out` to write a record into. Lossless, waits for one until `stop`; live, a full
// pool gives none (the record is dropped).
WritableFrame acquireRecordBuffer(const PooledStream& out, bool lossless,
                                  const std::atomic<bool>& stop);

// Publishes `size` bytes as one frame of `out` with `meta` (its stream set to out's).
// Lossless, waits for a buffer until `stop`; live, a full pool drops the record. False (the
// record counted lost) when it was not published.
bool publishRecord(Graph& graph, const PooledStream& out, const uint8_t* bytes, size_t size,
                   const FrameMetadata& meta, bool lossless, const std::atomic<bool>& stop);

// publishRecord() for an encoder's result: an encoding error counts the record lost.
template <typename Bytes>
bool publishEncoded(Graph& graph, const PooledStream& out, const Result<Bytes>& bytes,
                    const FrameMetadata& meta, bool lossless, const std::atomic<bool>& stop) {
    if (!bytes) {
        graph.countLost(out.id);
        return false;
    }
    return publishRecord(graph, out, bytes->data(), bytes->size(), meta, lossless, stop);
}

// Adds the stream of environment maps built from stream `of` (its clock domain and rate),
// width x width/2, published by `device`. Maps are published rarely and held by the
// compositor until a newer one comes: a pool of a few.
Result<PooledStream> addEnvironmentMapStream(Graph& graph, const std::string& name,
                                             const std::string& device, const StreamInfo& of,
                                             int width);

// Publishes `map` as one environment-map record of `out` with `header` and `meta` (its stream
// set to out's), as publishRecord() does. False (counted lost) when it was not published.
bool publishEnvironmentMap(Graph& graph, const PooledStream& out, const FloatImage& map,
                           const EnvironmentMapHeader& header, FrameMetadata meta, bool lossless,
                           const std::atomic<bool>& stop);

// Live: replaces `frame` by the newest frame waiting in `queue`; how many it skipped.
uint64_t skipToNewest(FrameQueue& queue, FrameRef& frame);

// The graph's stream named `name`, or kNotFound naming what it has and who needs it.
Result<StreamId> findStream(const Graph& graph, const std::string& name, const std::string& use);

// Pops the next frame, polling `queue` every few milliseconds so that `stop` is seen; nullopt
// once stopped, or closed with nothing left.
std::optional<FrameRef> popUnlessStopped(FrameQueue& queue, const std::atomic<bool>& stop);

}  // namespace mixray::tracking::detail
