// mixray bench pipeline on the bundled session: the figures it prints are consistent (the
// renderer alone rendered the same images as the pipeline; every set and every recorded frame
// is accounted for), whatever the machine's speed.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "bench_pipeline_json.h"

namespace mixray::test {
namespace {

using nlohmann::json;

TEST(BenchPipelineCli, FastPaceRendersTheSameImagesAsTheRendererAloneWithAndWithoutEstimation) {
    const json j = benchPipelineJson("--pace fast --passes 1 --threads 2");
    ASSERT_TRUE(j.contains("fast")) << j.dump();
    const json& f = j["fast"];
    EXPECT_EQ(f["composites"].get<int>(), 36);
    EXPECT_GT(f["rendered"].get<int>(), 30);
    EXPECT_EQ(f["identical_composites"], f["rendered"]);
    EXPECT_GT(f["pipeline_composites_per_s"].get<double>(), 0);
    EXPECT_GT(f["renderer_alone_frames_per_s"].get<double>(), 0);
    EXPECT_NEAR(f["overhead"].get<double>(),
                f["pipeline_s"].get<double>() / f["renderer_alone_s"].get<double>() - 1, 1e-9);
    // The graph's own cost: the session's recorded poses and fixed lights instead of tracking
    // and estimation, uncompressed frames instead of FFV1; the same images as the renderer's.
    ASSERT_TRUE(f.contains("graph_only")) << f.dump();
    const json& g = f["graph_only"];
    EXPECT_EQ(g["pose_stream"], "truth/pose");
    EXPECT_EQ(g["composites"].get<int>(), 36);
    EXPECT_GT(g["rendered"].get<int>(), 30);
    EXPECT_EQ(g["identical_composites"], g["rendered"]);
    EXPECT_EQ(g["track_ms"].get<double>(), 0);
    EXPECT_NEAR(g["overhead"].get<double>(),
                g["pipeline_s"].get<double>() / g["renderer_alone_s"].get<double>() - 1, 1e-9);
    EXPECT_FALSE(j.contains("real"));
}

TEST(BenchPipelineCli, RealPaceAccountsForEverySetAndRecordedFrame) {
    const json j = benchPipelineJson("--pace real --seconds 3 --threads 2");
    ASSERT_TRUE(j.contains("real")) << j.dump();
    const json& r = j["real"];
    expectEverySetAccountedFor(r);
    // How many sets are composited is the machine's speed; that the compositor got sets and
    // that a run which composited none says why (the recorder came first) is not. Under
    // AddressSanitizer the recorder's backlog can hold every set of a 3-second run back.
    EXPECT_GT(r["sets"]["total"].get<uint64_t>(), 0u) << r.dump();
    if (r["composites"].get<uint64_t>() == 0) {
        EXPECT_GT(r["sets"]["skipped_for_recording"].get<uint64_t>(), 0u) << r.dump();
    }
    EXPECT_DOUBLE_EQ(r["latency_ms"]["bound"].get<double>(), 2000.0 / 30);
    EXPECT_LE(r["latency_ms"]["p50"].get<double>(), r["latency_ms"]["p99"].get<double>());
    uint64_t ladder_frames = 0;
    for (const json& rung : r["ladder"])
        ladder_frames += rung["composites"].get<uint64_t>();
    EXPECT_EQ(ladder_frames, r["composites"].get<uint64_t>());
    ASSERT_TRUE(r["recording"]["on"].get<bool>());
    uint64_t published = 0, in_file = 0;
    for (const json& s : r["recording"]["streams"]) {
        published += s["published"].get<uint64_t>();
        in_file += s["in_file"].get<uint64_t>();
    }
    EXPECT_GT(in_file, 0u);
    EXPECT_EQ(in_file + r["recording"]["dropped"].get<uint64_t>(), published);
}

TEST(BenchPipelineCli, BadOptionsAreRefused) {
    EXPECT_EQ(mixray("bench pipeline --pace slow").exit_code, 2);
    const CliRun missing = mixray("bench pipeline --session /nonexistent/s.mkv");
    EXPECT_NE(missing.exit_code, 0);
    EXPECT_NE(missing.output.find("/nonexistent/s.mkv"), std::string::npos) << missing.output;
}

}  // namespace
}  // namespace mixray::test
