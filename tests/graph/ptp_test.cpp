// This host's PTP state (mixray/graph/ptp.h): pmc's answers as linuxptp prints them
// (fixtures/ptp), bad answers refused, pmc and ptp4l missing said plainly, and two ptp4l
// instances in two network namespaces read live: a grandmaster, and a port following it.
#include "mixray/graph/ptp.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "network_namespaces.h"
#include "test_data.h"

extern char** environ;

namespace mixray {
namespace {

namespace fs = std::filesystem;
using hosts::shell;

std::string fixture(const std::string& name) {
    std::ifstream in(test::fixturesDir() / "ptp" / name);
    EXPECT_TRUE(in) << name;
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

bool contains(const std::string& text, const std::string& part) {
    return text.find(part) != std::string::npos;
}

TEST(Ptp, TheGrandmastersAnswersSayItIsTheClockTheOthersFollow) {
    const Result<PtpState> state = parsePmcOutput(fixture("pmc_grandmaster.txt"));
    ASSERT_TRUE(state) << state.status().toString();
    EXPECT_EQ(state->clock_identity, "9ef2f2.fffe.4fa318");
    EXPECT_EQ(state->grandmaster_identity, "9ef2f2.fffe.4fa318");
    EXPECT_EQ(state->port_states, std::vector<std::string>{"MASTER"});
    EXPECT_TRUE(state->grandmaster());
    EXPECT_FALSE(state->following());
    EXPECT_TRUE(state->locked());
    EXPECT_EQ(state->describe(),
              "PTP-locked: this host's clock 9ef2f2.fffe.4fa318 is the grandmaster the others "
              "follow");
}

TEST(Ptp, APortNotYetLockedIsNotLockedAndSaysWhomItFollows) {
    const Result<PtpState> state = parsePmcOutput(fixture("pmc_uncalibrated.txt"));
    ASSERT_TRUE(state) << state.status().toString();
    EXPECT_EQ(state->clock_identity, "ca3e6e.fffe.8ae66e");
    EXPECT_TRUE(state->grandmaster_present);
    EXPECT_EQ(state->grandmaster_identity, "9ef2f2.fffe.4fa318");
    EXPECT_EQ(state->port_states, std::vector<std::string>{"UNCALIBRATED"});
    EXPECT_EQ(state->master_offset_ns, -158);
    ASSERT_TRUE(state->path_delay_ns.has_value());
    EXPECT_DOUBLE_EQ(*state->path_delay_ns, 2453.0);
    EXPECT_EQ(state->steps_removed, 1);
    EXPECT_FALSE(state->locked());
    EXPECT_EQ(state->describe(),
              "not PTP-locked: ptp4l's port is UNCALIBRATED, grandmaster 9ef2f2.fffe.4fa318 "
              "(1 step), offset -158 ns, path delay 2453 ns");
}

TEST(Ptp, ASlavePortFollowingAPresentGrandmasterIsLocked) {
    const Result<PtpState> state = parsePmcOutput(fixture("pmc_slave.txt"));
    ASSERT_TRUE(state) << state.status().toString();
    EXPECT_TRUE(state->following());
    EXPECT_TRUE(state->locked());
    EXPECT_EQ(state->describe(),
              "PTP-locked: following grandmaster 9ef2f2.fffe.4fa318 (1 step), offset -158 ns, "
              "path delay 2453 ns");
    // A SLAVE port whose grandmaster went away is not locked.
    std::string lost = fixture("pmc_slave.txt");
    lost.replace(lost.find("gmPresent                  true"), 31,
                 "gmPresent                  false");
    const Result<PtpState> alone = parsePmcOutput(lost);
    ASSERT_TRUE(alone);
    EXPECT_FALSE(alone->locked());
}

TEST(Ptp, AnswersThatAreMissingWrongOrRefusedAreErrors) {
    // pmc prints only what it sent when ptp4l does not answer.
    const Result<PtpState> none = parsePmcOutput("sending: GET TIME_STATUS_NP\n");
    ASSERT_FALSE(none);
    EXPECT_EQ(none.status().code(), ErrorCode::kUnavailable);
    EXPECT_FALSE(parsePmcOutput(""));

    const Result<PtpState> refused = parsePmcOutput(
        "\tca3e6e.fffe.8ae66e-0 seq 0 RESPONSE MANAGEMENT_ERROR_STATUS TIME_STATUS_NP\n"
        "\t\tERROR: NOT_SUPPORTED\n");
    ASSERT_FALSE(refused);
    EXPECT_TRUE(contains(refused.status().message(), "refused")) << refused.status().toString();

    std::string garbled = fixture("pmc_uncalibrated.txt");
    garbled.replace(garbled.find("-158\n"), 4, "1e99x");
    const Result<PtpState> bad = parsePmcOutput(garbled);
    ASSERT_FALSE(bad);
    EXPECT_EQ(bad.status().code(), ErrorCode::kCorruptData);
    EXPECT_TRUE(contains(bad.status().message(), "master_offset")) << bad.status().toString();
}

TEST(Ptp, AMissingPmcOrASilentPtp4lIsSaidPlainly) {
    const Result<PtpState> no_pmc =
        queryPtp4l({.socket = "/var/run/ptp4l", .pmc = "mixray-no-such-pmc", .timeout_ms = 1000});
    ASSERT_FALSE(no_pmc);
    EXPECT_EQ(no_pmc.status().code(), ErrorCode::kNotFound);
    EXPECT_TRUE(contains(no_pmc.status().message(), "apt-get install linuxptp"))
        << no_pmc.status().toString();

    if (std::system("command -v pmc >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "pmc (linuxptp) is not installed";
    const std::string socket = (fs::path(::testing::TempDir()) / "no-ptp4l-here").string();
    const Result<PtpState> silent =
        queryPtp4l({.socket = socket, .pmc = "pmc", .timeout_ms = 2000});
    ASSERT_FALSE(silent);
    EXPECT_EQ(silent.status().code(), ErrorCode::kUnavailable);
    EXPECT_TRUE(contains(silent.status().message(), "does not answer at " + socket))
        << silent.status().toString();
}

// ptp4l in network namespace `ns` on `interface`, with `config`; killed with the object.
class Ptp4l {
public:
    Ptp4l(const std::string& ns, const std::string& interface, const fs::path& config) {
        std::vector<std::string> args = {"ip", "netns",         "exec", ns,       "ptp4l",
                                         "-f", config.string(), "-i",   interface};
        std::vector<char*> argv;
        for (std::string& a : args)
            argv.push_back(a.data());
        argv.push_back(nullptr);
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
        posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
        if (posix_spawnp(&pid_, "ip", &actions, nullptr, argv.data(), environ) != 0)
            pid_ = -1;
        posix_spawn_file_actions_destroy(&actions);
    }
    ~Ptp4l() {
        if (pid_ > 0) {
            kill(pid_, SIGTERM);
            waitpid(pid_, nullptr, 0);
        }
    }
    bool started() const { return pid_ > 0; }

private:
    pid_t pid_ = -1;
};

// Two hosts joined by a veth pair, each with its ptp4l: one a grandmaster by priority, the other
// following it without steering any clock (free_running: both share this machine's clock).
TEST(PtpLive, AFollowerAndItsGrandmasterReadThroughPmc) {
    if (geteuid() != 0)
        GTEST_SKIP() << "needs root to make network namespaces (CI runs as root)";
    if (std::system("command -v ptp4l >/dev/null 2>&1 && command -v pmc >/dev/null 2>&1") != 0)
        GTEST_SKIP() << "ptp4l and pmc (linuxptp) are not installed";
    const std::string id = std::to_string(getpid() % 100000);
    const std::string a = "mxpa" + id, b = "mxpb" + id;
    if (shell("ip netns add " + a) != 0)
        GTEST_SKIP() << "ip netns add failed: no network namespaces here";
    ASSERT_EQ(shell("ip netns add " + b), 0);
    struct Cleanup {
        std::string a, b;
        ~Cleanup() {
            shell("ip netns del " + a);
            shell("ip netns del " + b);
        }
    } cleanup{a, b};
    const std::string net = "10." + std::to_string(100 + getpid() % 100) + ".77.";
    ASSERT_TRUE(hosts::linkNamespaces({.ns = a, .name = "pa" + id, .address = net + "1"},
                                      {.ns = b, .name = "pb" + id, .address = net + "2"}));

    const fs::path dir = fs::path(::testing::TempDir()) / ("mixray_ptp_" + id);
    fs::create_directories(dir);
    // Quick announce and sync intervals so the follower hears the grandmaster in about a second.
    const auto config = [&](const std::string& name, const std::string& extra) {
        const fs::path path = dir / (name + ".cfg");
        std::ofstream(path) << "[global]\ntime_stamping software\nfree_running 1\n"
                               "network_transport UDPv4\nlogAnnounceInterval -2\n"
                               "logSyncInterval -3\nannounceReceiptTimeout 3\nuds_address "
                            << (dir / (name + ".sock")).string() << "\n"
                            << extra;
        return path;
    };
    Ptp4l grandmaster(a, "pa" + id, config("gm", "priority1 100\n"));
    Ptp4l follower(b, "pb" + id, config("follower", "slaveOnly 1\n"));
    ASSERT_TRUE(grandmaster.started() && follower.started());

    const PtpQueryOptions gm_query{
        .socket = (dir / "gm.sock").string(), .pmc = "pmc", .timeout_ms = 2000};
    const PtpQueryOptions follower_query{
        .socket = (dir / "follower.sock").string(), .pmc = "pmc", .timeout_ms = 2000};
    Result<PtpState> gm(ErrorCode::kUnavailable, "not asked");
    Result<PtpState> other(ErrorCode::kUnavailable, "not asked");
    for (int i = 0; i < 100; ++i) {
        gm = queryPtp4l(gm_query);
        other = queryPtp4l(follower_query);
        if (gm && gm->grandmaster() && other && other->grandmaster_present &&
            other->grandmaster_identity == gm->clock_identity && other->path_delay_ns &&
            *other->path_delay_ns > 0)
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_TRUE(gm) << gm.status().toString();
    ASSERT_TRUE(other) << other.status().toString();
    std::printf("grandmaster: %s\nfollower:    %s\n", gm->describe().c_str(),
                other->describe().c_str());
    EXPECT_TRUE(gm->grandmaster()) << gm->describe();
    EXPECT_TRUE(gm->locked());
    EXPECT_EQ(other->grandmaster_identity, gm->clock_identity) << other->describe();
    EXPECT_NE(other->clock_identity, gm->clock_identity);
    EXPECT_EQ(other->steps_removed, 1);
    // The follower measured its path delay (0 until its first delay request is answered).
    ASSERT_TRUE(other->path_delay_ns.has_value());
    EXPECT_GT(*other->path_delay_ns, 0) << other->describe();
    // Not steering its clock, the follower never locks; both share one clock, so the offset it
    // measures is the timestamping noise.
    EXPECT_EQ(other->port_states, std::vector<std::string>{"UNCALIBRATED"}) << other->describe();
    EXPECT_FALSE(other->locked());
    EXPECT_LT(std::abs(other->master_offset_ns), 1'000'000) << other->describe();
    fs::remove_all(dir);
}

}  // namespace
}  // namespace mixray
