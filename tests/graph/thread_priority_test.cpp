// Thread roles: each runs at its nice value, in the order the architecture promises (capture
// and the recorder first, the renderer last), and the graph says when a recording falls behind.
#include "mixray/graph/thread_priority.h"

#include <gtest/gtest.h>

#include <thread>

#include "mixray/graph/graph.h"

namespace mixray {
namespace {

int niceOfNewThreadAs(ThreadRole role) {
    int nice = 99;
    std::thread([&] { nice = runAs(role); }).join();
    return nice;
}

TEST(ThreadPriority, RolesAreOrderedFromCaptureToRenderer) {
    const ThreadRole order[] = {ThreadRole::kCapture, ThreadRole::kRecorder, ThreadRole::kPublisher,
                                ThreadRole::kEstimator, ThreadRole::kRenderer};
    for (size_t i = 1; i < std::size(order); ++i)
        EXPECT_LT(requestedNice(order[i - 1]), requestedNice(order[i])) << toString(order[i]);
}

TEST(ThreadPriority, EachThreadRunsAtItsRolesNiceValueOrTheNearestAllowed) {
    if (currentNice() != 0)
        GTEST_SKIP() << "the test runs at nice " << currentNice() << ", not 0";
    // Below normal priority is always allowed.
    EXPECT_EQ(niceOfNewThreadAs(ThreadRole::kRenderer), requestedNice(ThreadRole::kRenderer));
    EXPECT_EQ(niceOfNewThreadAs(ThreadRole::kEstimator), requestedNice(ThreadRole::kEstimator));
    EXPECT_EQ(niceOfNewThreadAs(ThreadRole::kPublisher), 0);
    // Above normal needs privilege (root with CAP_SYS_NICE, or a raised RLIMIT_NICE);
    // without it, normal priority.
    bool privileged = false;
    std::thread([&] { privileged = setCurrentNice(-1); }).join();
    EXPECT_EQ(niceOfNewThreadAs(ThreadRole::kCapture),
              privileged ? requestedNice(ThreadRole::kCapture) : 0);
    EXPECT_LT(niceOfNewThreadAs(ThreadRole::kRecorder), requestedNice(ThreadRole::kEstimator));
}

TEST(ThreadPriority, OneThreadsNiceValueLeavesTheOthersAlone) {
    const int before = currentNice();
    EXPECT_EQ(niceOfNewThreadAs(ThreadRole::kRenderer), requestedNice(ThreadRole::kRenderer));
    EXPECT_EQ(currentNice(), before);
}

TEST(Graph, RecordingBacklogIsTheFullestRecordingEdge) {
    Graph graph;
    StreamInfo info;
    info.name = "cam/depth";
    info.device = "test";
    info.kind = StreamKind::kDepth;
    info.format = ImageDesc::packed(PixelFormat::kDepth16, 16, 8);
    const StreamId id = *graph.addStream(info);
    auto recording = *graph.subscribe(id, {4, QueuePolicy::kLive, "recorder", true});
    auto viewer = *graph.subscribe(id, {1, QueuePolicy::kLive, "view"});
    auto pool = BufferPool::create({info.format, 0, 8, info.name});
    EXPECT_EQ(graph.recordingBacklog(), 0.0);
    for (int i = 0; i < 2; ++i) {
        WritableFrame w = pool->acquire();
        w.meta().stream = id;
        graph.publish(std::move(w).publish());
    }
    // The viewer's one-frame edge is full, but it records nothing.
    EXPECT_DOUBLE_EQ(graph.recordingBacklog(), 0.5);
    recording->tryPop();
    EXPECT_DOUBLE_EQ(graph.recordingBacklog(), 0.25);
}

}  // namespace
}  // namespace mixray
