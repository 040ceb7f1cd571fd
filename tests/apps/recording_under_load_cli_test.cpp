// A live run that records keeps every captured frame when the machine is short of CPU: the
// effects scene at 4 samples per pixel, at real pace, beside a busy process per core. What gives
// way is the composite (skipped, counted), never a raw frame; the bench reads the file back.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <thread>

#include "bench_pipeline_json.h"
#include "test_data.h"

namespace mixray::test {
namespace {

using nlohmann::json;

TEST(RecordingUnderLoad, EveryRawFrameReachesTheFileBesideABusyProcessPerCore) {
#if defined(__SANITIZE_ADDRESS__)
    // A claim about time, checked where the code runs at its speed: under AddressSanitizer
    // mixray's own code (the replay's and the recorder's loops) runs several times slower than
    // FFmpeg's, and one run in three lost a few frames of a stream. The sanitizer build still
    // runs this path without load (BenchPipelineCli).
    GTEST_SKIP() << "timing claim: checked in the optimised build";
#endif
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    const std::string effects =
        (sourceDir() / "fixtures/scenes/sim_tabletop_effects.yaml").string();
    const json j = benchPipelineJson("--pace real --seconds 6 --samples 4 --objects " + effects +
                                     " --load " + std::to_string(cores));
    ASSERT_TRUE(j.contains("real")) << j.dump();
    const json& r = j["real"];
    EXPECT_EQ(r["load_processes"].get<unsigned>(), cores);
    const json& rec = r["recording"];
    ASSERT_TRUE(rec["on"].get<bool>());
    EXPECT_EQ(rec["compression"], "ffvhuff");  // mixray run's default
    // Colour and depth at 30 fps and the fish-eye at 2 fps for 6 s: far more than 100 frames.
    EXPECT_GT(rec["raw_published"].get<uint64_t>(), 100u) << rec.dump();
    EXPECT_EQ(rec["raw_lost"].get<uint64_t>(), 0u) << rec.dump();
    int raw_streams = 0;
    for (const json& s : rec["streams"]) {
        if (!s["raw"].get<bool>())
            continue;
        ++raw_streams;
        EXPECT_EQ(s["in_file"], s["published"]) << s.dump();
    }
    EXPECT_GE(raw_streams, 2) << rec.dump();
    // Every set is accounted for, the ones the recorder's backlog cost included.
    expectEverySetAccountedFor(r);
}

}  // namespace
}  // namespace mixray::test
