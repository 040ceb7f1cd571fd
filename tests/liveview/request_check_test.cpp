// The live view's checks of requests and WebSocket messages (request_check.h), without a server:
// tokens, query parameters, Host and Origin, paths, header counts, client frames.
#include "request_check.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "test_data.h"

// The fuzzer's entry point (tests/fuzz/liveview_request_fuzz.cpp, linked into this test too): it
// aborts on any input that breaks its checks.
extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace mixray::liveview {
namespace {

const std::string kToken = "0123456789abcdef0123456789abcdef";

HttpRequest get(std::string_view path, std::string_view query = "",
                std::vector<HttpHeader> headers = {{"Host", "127.0.0.1:8080"}}) {
    return {"GET", path, query, std::move(headers)};
}

TEST(RequestCheck, QueryParametersAreDecodedAndTheFirstWins) {
    EXPECT_EQ(queryParameter("token=abc", "token"), "abc");
    EXPECT_EQ(queryParameter("a=1&token=a%2Db+c&token=other", "token"), "a-b c");
    EXPECT_EQ(queryParameter("tok%65n=x", "token"), "x");
    EXPECT_EQ(queryParameter("token", "token"), "");
    EXPECT_EQ(queryParameter("token=%zz%4", "token"), "%zz%4");  // malformed escapes stay
    EXPECT_EQ(queryParameter("tokens=x&xtoken=y", "token"), std::nullopt);
    EXPECT_EQ(queryParameter("", "token"), std::nullopt);
}

TEST(RequestCheck, TokensCompareWholeAndValidTokensAreUrlSafe) {
    EXPECT_TRUE(constantTimeEquals(kToken, kToken));
    EXPECT_FALSE(constantTimeEquals(kToken, kToken.substr(0, 31)));
    EXPECT_FALSE(constantTimeEquals(kToken, kToken + "0"));
    EXPECT_FALSE(constantTimeEquals(kToken, ""));
    EXPECT_FALSE(constantTimeEquals("", "x"));
    EXPECT_TRUE(constantTimeEquals("", ""));
    EXPECT_TRUE(isValidToken(kToken));
    EXPECT_TRUE(isValidToken("A-b.c_d~0123456789"));
    EXPECT_FALSE(isValidToken("short-token"));
    EXPECT_FALSE(isValidToken("0123456789abcdef&x=1"));
    EXPECT_FALSE(isValidToken(std::string(257, 'a')));
}

TEST(RequestCheck, LoopbackHostsAndAddresses) {
    for (const char* host : {"127.0.0.1:8080", "127.0.0.1", "127.1.2.3:1", "localhost",
                             "LocalHost:9000", "[::1]:80"}) {
        EXPECT_TRUE(isLoopbackHost(host)) << host;
    }
    for (const char* host :
         {"evil.example", "evil.example:8080", "127.0.0.1.evil.example", "0x7f.0.0.1", "127.1",
          "10.0.0.5:8080", "127.0.0.1:abc", "127.0.0.1:80:1", "localhost@evil.example", "[::1",
          "::1", "127.0.0.1 :80", "", "127.0.0.1:"}) {
        EXPECT_FALSE(isLoopbackHost(host)) << host;
    }
    EXPECT_TRUE(isLoopbackAddress("127.0.0.1"));
    EXPECT_TRUE(isLoopbackAddress("127.0.0.2"));
    EXPECT_FALSE(isLoopbackAddress("0.0.0.0"));
    EXPECT_FALSE(isLoopbackAddress("192.168.1.20"));
}

TEST(RequestCheck, OriginsMatchTheHostsSchemeNameAndPort) {
    EXPECT_TRUE(isSameOrigin("http://127.0.0.1:8080", "127.0.0.1:8080"));
    EXPECT_TRUE(isSameOrigin("HTTP://LocalHost:8080", "localhost:8080"));
    EXPECT_TRUE(isSameOrigin("http://rig-host", "rig-host:80"));
    EXPECT_TRUE(isSameOrigin("http://[::1]:9000", "[::1]:9000"));
    for (const auto& [origin, host] : std::vector<std::pair<std::string, std::string>>{
             {"http://evil.example", "127.0.0.1:8080"},
             {"https://127.0.0.1:8080", "127.0.0.1:8080"},
             {"http://127.0.0.1:8081", "127.0.0.1:8080"},
             {"http://127.0.0.1:8080/", "127.0.0.1:8080"},
             {"http://user@127.0.0.1:8080", "127.0.0.1:8080"},
             {"null", "127.0.0.1:8080"},
             {"http://", ""},
             {"http://127.0.0.1:8080", ""}}) {
        EXPECT_FALSE(isSameOrigin(origin, host)) << origin << " vs " << host;
    }
}

TEST(RequestCheck, LoopbackWithoutATokenRefusesOtherSitesHostsAndOrigins) {
    const RequestPolicy policy;  // no token, loopback names only
    EXPECT_EQ(checkRequest(policy, get("/")).status, 0);
    EXPECT_EQ(checkRequest(policy, get("/index.html")).status, 0);
    EXPECT_EQ(checkRequest(policy, get("/", "", {})).status, 0);  // no Host: not a browser
    const RequestVerdict ws = checkRequest(policy, get("/ws"));
    EXPECT_EQ(ws.status, 0);
    EXPECT_EQ(ws.kind, RequestKind::kWebSocket);
    // Its own origin, by any loopback name, and no Origin at all (not a browser).
    EXPECT_EQ(
        checkRequest(policy, get("/ws", "",
                                 {{"Host", "127.0.0.1:8080"}, {"Origin", "http://127.0.0.1:8080"}}))
            .status,
        0);
    EXPECT_EQ(
        checkRequest(policy, get("/ws", "",
                                 {{"host", "localhost:9000"}, {"origin", "http://localhost:9000"}}))
            .status,
        0);
    // Another site's page, on loopback: refused.
    EXPECT_EQ(
        checkRequest(
            policy, get("/ws", "", {{"Host", "127.0.0.1:8080"}, {"Origin", "http://evil.example"}}))
            .status,
        403);
    EXPECT_EQ(checkRequest(policy, get("/ws", "", {{"Origin", "http://127.0.0.1:8080"}})).status,
              403);  // an Origin with no Host to match
    // DNS rebinding: evil.example resolving to 127.0.0.1 sends its own name as Host and Origin.
    EXPECT_EQ(
        checkRequest(
            policy,
            get("/ws", "", {{"Host", "evil.example:8080"}, {"Origin", "http://evil.example:8080"}}))
            .status,
        403);
    EXPECT_EQ(checkRequest(policy, get("/", "", {{"Host", "evil.example:8080"}})).status, 403);
}

TEST(RequestCheck, ATokenIsRequiredOnEveryRequestAndNeverEchoed) {
    RequestPolicy policy;
    policy.token = kToken;
    policy.loopback_host_only = false;
    const std::vector<HttpHeader> rig = {{"Host", "rig-host:8080"}};
    EXPECT_EQ(checkRequest(policy, get("/", "", rig)).status, 401);
    EXPECT_EQ(checkRequest(policy, get("/", "token=", rig)).status, 403);
    EXPECT_EQ(checkRequest(policy, get("/", "token=" + kToken.substr(1), rig)).status, 403);
    EXPECT_EQ(checkRequest(policy, get("/", "token=" + kToken, rig)).status, 0);
    EXPECT_EQ(checkRequest(policy, get("/", "x=1&token=" + kToken, rig)).status, 0);
    EXPECT_EQ(checkRequest(policy, get("/ws", "", rig)).status, 401);
    EXPECT_EQ(checkRequest(policy, get("/ws", "token=" + kToken, rig)).status, 0);
    // The right token does not let another site's page in.
    EXPECT_EQ(
        checkRequest(policy, get("/ws", "token=" + kToken,
                                 {{"Host", "rig-host:8080"}, {"Origin", "http://evil.example"}}))
            .status,
        403);
    for (const std::string& query : {std::string(), "token=wrong" + kToken}) {
        const RequestVerdict v = checkRequest(policy, get("/", query, rig));
        EXPECT_EQ(v.reason.find(kToken), std::string::npos) << v.reason;
    }
}

TEST(RequestCheck, MethodsPathsHeaderCountsAndRepeatedHeaders) {
    const RequestPolicy policy;
    EXPECT_EQ(checkRequest(policy, {"POST", "/", "", {}}).status, 405);
    EXPECT_EQ(checkRequest(policy, {"OPTIONS", "/ws", "", {}}).status, 405);
    // civetweb hands the path over decoded with its dot segments removed: "/../etc/passwd"
    // arrives as "/etc/passwd".
    for (const char* path : {"/etc/passwd", "/secret", "/ws/", "/index.htm", "", "//"})
        EXPECT_EQ(checkRequest(policy, get(path)).status, 404) << path;
    std::vector<HttpHeader> many(33, HttpHeader{"X-Filler", "1"});
    EXPECT_EQ(checkRequest(policy, get("/", "", many)).status, 431);
    many.resize(32);
    EXPECT_EQ(checkRequest(policy, get("/", "", many)).status, 0);
    EXPECT_EQ(
        checkRequest(policy, get("/", "", {{"Host", "127.0.0.1:8080"}, {"Host", "evil.example"}}))
            .status,
        400);
    EXPECT_EQ(checkRequest(policy, get("/ws", "",
                                       {{"Host", "127.0.0.1:8080"},
                                        {"Origin", "http://127.0.0.1:8080"},
                                        {"Origin", "http://evil.example"}}))
                  .status,
              400);
}

TEST(RequestCheck, ClientMessagesAreIgnoredClosedOrRefusedWithTheirCode) {
    struct Case {
        uint8_t first_byte;
        size_t size;
        MessageAction action;
        uint16_t code;
    };
    const std::vector<Case> cases = {
        {0x81, 10, MessageAction::kIgnore, 0},       // short text
        {0x81, 1024, MessageAction::kIgnore, 0},     // at the limit
        {0x81, 1025, MessageAction::kRefuse, 1009},  // over it
        {0x01, 10, MessageAction::kRefuse, 1003},    // fragmented
        {0x82, 10, MessageAction::kRefuse, 1003},    // binary
        {0x80, 10, MessageAction::kRefuse, 1002},    // continuation without a start
        {0x88, 2, MessageAction::kClose, 0},         // close
        {0x89, 125, MessageAction::kIgnore, 0},      // ping
        {0x8A, 0, MessageAction::kIgnore, 0},        // pong
        {0x89, 126, MessageAction::kRefuse, 1002},   // control frame too long
        {0x09, 4, MessageAction::kRefuse, 1002},     // fragmented control frame
        {0xC1, 4, MessageAction::kRefuse, 1002},     // RSV1 (compression) not agreed
        {0x83, 4, MessageAction::kRefuse, 1002},     // reserved opcodes
        {0x8F, 4, MessageAction::kRefuse, 1002},
    };
    for (const Case& c : cases) {
        const MessageVerdict v = checkClientMessage(c.first_byte, c.size);
        EXPECT_EQ(v.action, c.action) << int{c.first_byte} << " " << c.size;
        EXPECT_EQ(v.close_code, c.code) << int{c.first_byte} << " " << c.size;
        EXPECT_LE(v.reason.size(), 123u);
    }
}

TEST(RequestCheck, ANonLoopbackAddressIsAnnouncedAsServingEveryCamera) {
    EXPECT_EQ(exposureWarning("127.0.0.1", 8080), "");
    const std::string any = exposureWarning("0.0.0.0", 8080);
    EXPECT_NE(any.find("every camera to the network"), std::string::npos) << any;
    EXPECT_NE(any.find("every interface of this host (0.0.0.0:8080)"), std::string::npos) << any;
    const std::string one = exposureWarning("192.168.1.20", 9000);
    EXPECT_NE(one.find("on 192.168.1.20:9000"), std::string::npos) << one;
    EXPECT_NE(one.find("token"), std::string::npos) << one;
}

TEST(RequestCheck, TheFuzzersSeedsHoldItsChecks) {
    const auto dir = test::sourceDir() / "tests" / "fuzz" / "corpus" / "liveview";
    int seeds = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        const std::string bytes = test::readText(entry.path());
        ASSERT_FALSE(bytes.empty()) << entry.path();
        LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
        ++seeds;
    }
    EXPECT_GE(seeds, 10);
}

}  // namespace
}  // namespace mixray::liveview
