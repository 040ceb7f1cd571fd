// The live view: tile images, options, bind errors, several WebSocket clients, a stalled one, and
// the page itself in headless Chromium, with pattern cameras as the source.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <turbojpeg.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <thread>

#include "headless_chromium.h"
#include "image_to_jpeg.h"
#include "memory_in_use.h"
#include "mixray/graph/graph.h"
#include "mixray/liveview/live_view.h"
#include "mixray/pattern/pattern_backend.h"
#include "mixray/pattern/pattern_image.h"
#include "proc_net.h"
#include "test_data.h"
#include "watchdog.h"
#include "websocket_client.h"

namespace mixray::liveview {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// ---- JPEG decoding (the test's independent reader) ----

struct Decoded {
    int width = 0;
    int height = 0;
    std::vector<uint8_t> rgb;
};

Decoded decodeJpeg(const std::string& jpeg) {
    Decoded out;
    tjhandle tj = tjInitDecompress();
    int subsamp = 0;
    int colorspace = 0;
    const auto* data = reinterpret_cast<const unsigned char*>(jpeg.data());
    if (tjDecompressHeader3(tj, data, jpeg.size(), &out.width, &out.height, &subsamp,
                            &colorspace) == 0) {
        out.rgb.resize(static_cast<size_t>(out.width) * out.height * 3);
        if (tjDecompress2(tj, data, jpeg.size(), out.rgb.data(), out.width, 0, out.height, TJPF_RGB,
                          TJFLAG_ACCURATEDCT) != 0) {
            out.rgb.clear();
        }
    }
    tjDestroy(tj);
    return out;
}

const uint8_t* pixel(const Decoded& d, int x, int y) {
    return d.rgb.data() + (static_cast<size_t>(y) * d.width + x) * 3;
}

// ---- Frame -> JPEG ----

TEST(TileImage, DepthIsFalseColourOverTheFixedRangeWithHolesBlack) {
    Image depth(ImageDesc::packed(PixelFormat::kDepth16, 64, 32));
    for (int y = 0; y < 32; ++y) {
        auto* row = depth.mutableView().row<uint16_t>(y);
        for (int x = 0; x < 64; ++x)
            row[x] = x < 16 ? 300 : x < 32 ? 5000 : x < 48 ? 0 : 2650;
    }
    JpegEncoder encoder;
    EncodedTile tile;
    ASSERT_TRUE(encoder.encode(depth.view(), TileRenderOptions{}, &tile).isOk());
    EXPECT_DOUBLE_EQ(tile.range_lo, 0.3);
    EXPECT_DOUBLE_EQ(tile.range_hi, 5.0);
    const Decoded d = decodeJpeg(tile.jpeg);
    ASSERT_EQ(d.width, 64);
    ASSERT_FALSE(d.rgb.empty());
    uint8_t near[3], far[3], mid[3];
    turboColor(0.0, near);
    turboColor(1.0, far);
    turboColor(0.5, mid);
    auto close = [](const uint8_t* got, const uint8_t* want) {
        for (int c = 0; c < 3; ++c) {
            if (std::abs(got[c] - want[c]) > 20)
                return false;
        }
        return true;
    };
    EXPECT_TRUE(close(pixel(d, 8, 16), near));
    EXPECT_TRUE(close(pixel(d, 24, 16), far));
    const uint8_t black[3] = {0, 0, 0};
    EXPECT_TRUE(close(pixel(d, 40, 16), black));
    EXPECT_TRUE(close(pixel(d, 56, 16), mid));
}

TEST(TileImage, ColourFormatsAgreeAndLargeImagesAreSubsampled) {
    // The same colours as rgb8, bgr8 and yuyv (grey levels, which YUV carries exactly).
    const int w = 1280, h = 64;
    Image rgb(ImageDesc::packed(PixelFormat::kRGB8, w, h));
    Image bgr(ImageDesc::packed(PixelFormat::kBGR8, w, h));
    Image yuyv(ImageDesc::packed(PixelFormat::kYUYV, w, h));
    for (int y = 0; y < h; ++y) {
        uint8_t* a = rgb.mutableView().row<uint8_t>(y);
        uint8_t* b = bgr.mutableView().row<uint8_t>(y);
        uint8_t* c = yuyv.mutableView().row<uint8_t>(y);
        for (int x = 0; x < w; ++x) {
            const uint8_t r = x < w / 2 ? 200 : 30, g = 100, bl = x < w / 2 ? 20 : 220;
            a[3 * x] = r, a[3 * x + 1] = g, a[3 * x + 2] = bl;
            b[3 * x] = bl, b[3 * x + 1] = g, b[3 * x + 2] = r;
            c[2 * x] = x < w / 2 ? 60 : 200;  // Y
            c[2 * x + 1] = 128;               // U, V: grey
        }
    }
    JpegEncoder encoder;
    TileRenderOptions options;
    options.max_width = 640;
    EncodedTile a, b, c;
    ASSERT_TRUE(encoder.encode(rgb.view(), options, &a).isOk());
    ASSERT_TRUE(encoder.encode(bgr.view(), options, &b).isOk());
    ASSERT_TRUE(encoder.encode(yuyv.view(), options, &c).isOk());
    EXPECT_EQ(a.width, 640);
    EXPECT_EQ(a.height, 32);
    const Decoded da = decodeJpeg(a.jpeg), db = decodeJpeg(b.jpeg), dc = decodeJpeg(c.jpeg);
    ASSERT_EQ(da.width, 640);
    for (int c2 = 0; c2 < 3; ++c2) {
        EXPECT_NEAR(pixel(da, 100, 16)[c2], pixel(db, 100, 16)[c2], 2);
        EXPECT_NEAR(pixel(da, 500, 16)[c2], pixel(db, 500, 16)[c2], 2);
    }
    EXPECT_NEAR(pixel(da, 100, 16)[0], 200, 12);
    EXPECT_NEAR(pixel(da, 500, 16)[2], 220, 12);
    // BT.601 limited range: Y 60 -> 51, Y 200 -> 214.
    EXPECT_NEAR(pixel(dc, 100, 16)[1], 51, 6);
    EXPECT_NEAR(pixel(dc, 500, 16)[1], 214, 6);
}

TEST(TileImage, Infrared16IsNormalisedAndBinaryIsNoTile) {
    Image ir(ImageDesc::packed(PixelFormat::kIR16, 32, 16));
    for (int y = 0; y < 16; ++y) {
        auto* row = ir.mutableView().row<uint16_t>(y);
        for (int x = 0; x < 32; ++x)
            row[x] = x < 16 ? 1000 : 1100;  // a dim image
    }
    JpegEncoder encoder;
    EncodedTile tile;
    ASSERT_TRUE(encoder.encode(ir.view(), TileRenderOptions{}, &tile).isOk());
    const Decoded d = decodeJpeg(tile.jpeg);
    ASSERT_FALSE(d.rgb.empty());
    EXPECT_LT(pixel(d, 4, 8)[0], 10);
    EXPECT_GT(pixel(d, 28, 8)[0], 245);
    EXPECT_FALSE(isTileFormat(PixelFormat::kBinary));
    Image binary(ImageDesc::packed(PixelFormat::kBinary, 16, 1));
    EXPECT_EQ(encoder.encode(binary.view(), TileRenderOptions{}, &tile).code(),
              ErrorCode::kUnsupported);
    // A payload shorter than its layout is an error, not a read past the end.
    ImageView truncated = ir.view();
    truncated.size_bytes = 100;
    EXPECT_EQ(encoder.encode(truncated, TileRenderOptions{}, &tile).code(),
              ErrorCode::kCorruptData);
}

// ---- Options and binding ----

TEST(LiveViewOptions, DefaultsAreLoopbackAndBadValuesNameTheField) {
    const LiveViewOptions defaults;
    EXPECT_EQ(defaults.address, "127.0.0.1");
    EXPECT_TRUE(defaults.validate().isOk());
    struct Case {
        LiveViewOptions options;
        std::string field;
    };
    std::vector<Case> cases(5);
    cases[0].options.address = "localhost:80", cases[0].field = "address";
    cases[1].options.port = 70000, cases[1].field = "port";
    cases[2].options.max_tile_fps = 0, cases[2].field = "max_tile_fps";
    cases[3].options.jpeg_quality = 0, cases[3].field = "jpeg_quality";
    cases[4].options.depth_max_m = 0.1, cases[4].field = "depth_min_m";
    for (const Case& c : cases) {
        const Status s = c.options.validate();
        EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument) << c.field;
        EXPECT_NE(s.message().find(c.field), std::string::npos) << s.message();
        EXPECT_FALSE(LiveView::create(c.options).isOk());
    }
}

TEST(LiveViewOptions, ViewAddressIsPortOrAddressAndPort) {
    LiveViewOptions o;
    ASSERT_TRUE(parseViewAddress("9000", &o).isOk());
    EXPECT_EQ(o.address, "127.0.0.1");  // a bare port keeps the loopback default
    EXPECT_EQ(o.port, 9000);
    ASSERT_TRUE(parseViewAddress("0.0.0.0:0", &o).isOk());
    EXPECT_EQ(o.address, "0.0.0.0");
    EXPECT_EQ(o.port, 0);
    for (const std::string& bad :
         std::vector<std::string>{"", "http", ":80", "localhost:80", "1.2.3.4:", "1.2.3.4:65536",
                                  "1.2.3.4:-1", "1.2.3:80", std::string("1.2.3.4\0x:80", 12)}) {
        LiveViewOptions before;
        const Status s = parseViewAddress(bad, &before);
        EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument) << bad;
        EXPECT_NE(s.message().find("--view"), std::string::npos) << s.message();
        EXPECT_EQ(before.port, 8080) << "left untouched on error: " << bad;
    }
}

// A pattern camera in a graph, with the view as its sink.
struct Rig {
    Graph graph;
    pattern::PatternDevice* device = nullptr;
    LiveView* view = nullptr;

    explicit Rig(LiveViewOptions options,
                 std::vector<pattern::PatternStream> streams = {pattern::PatternStream::kColor,
                                                                pattern::PatternStream::kDepth,
                                                                pattern::PatternStream::kInfrared},
                 int width = 320, int height = 240) {
        pattern::PatternOptions p;
        for (auto s : streams)
            p.streams.push_back({s, width, height});
        p.fps = 30;
        p.realtime = true;
        auto dev = std::make_unique<pattern::PatternDevice>("cam", p);
        device = dev.get();
        EXPECT_TRUE(graph.addNode(std::move(dev)).isOk());
        auto created = LiveView::create(std::move(options));
        EXPECT_TRUE(created.isOk()) << created.status().toString();
        view = created.value().get();
        const Status connected = graph.addNode(std::move(created.value()));
        EXPECT_TRUE(connected.isOk()) << connected.toString();
    }
    ~Rig() { graph.stop(); }
};

LiveViewOptions anyPort() {
    LiveViewOptions o;
    o.port = 0;
    return o;
}

// A listening TCP socket on 127.0.0.1 at any port.
int listenAnywhere(int* port) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
    listen(fd, 4);
    socklen_t len = sizeof(addr);
    getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
    *port = ntohs(addr.sin_port);
    return fd;
}

TEST(LiveView, BindFailuresNameAddressAndPort) {
    int taken = 0;
    const int holder = listenAnywhere(&taken);
    {
        LiveViewOptions o;
        o.port = taken;
        Rig rig(o);
        const Status s = rig.graph.start();
        EXPECT_EQ(s.code(), ErrorCode::kUnavailable) << s.toString();
        EXPECT_NE(s.message().find("127.0.0.1:" + std::to_string(taken)), std::string::npos)
            << s.message();
    }
    close(holder);
    {
        LiveViewOptions o;
        o.address = "192.0.2.7";  // TEST-NET-1: no interface of this machine has it
        o.port = 0;
        Rig rig(o);
        const Status s = rig.graph.start();
        EXPECT_EQ(s.code(), ErrorCode::kUnavailable) << s.toString();
        EXPECT_NE(s.message().find("192.0.2.7:"), std::string::npos) << s.message();
    }
}

// Whether /proc/net/tcp lists a listening socket on `port` bound to 127.0.0.1 only.
bool listensOnLoopbackOnly(int port) {
    bool loopback = false, other = false;
    for (const test::Ipv4Socket& s : test::ipv4Sockets("/proc/net/tcp")) {
        if (s.state == "0A" && s.local_port == port)
            (s.local_address == "127.0.0.1" ? loopback : other) = true;
    }
    return loopback && !other;
}

using test::WsClient;

// An image message: its header and JPEG.
struct ImageMessage {
    nlohmann::json header;
    std::string jpeg;
};
std::optional<ImageMessage> parseImage(const WsClient::Message& m) {
    if (m.opcode != 2 || m.payload.size() < 4)
        return std::nullopt;
    const auto* b = reinterpret_cast<const uint8_t*>(m.payload.data());
    const uint32_t n = b[0] | (b[1] << 8) | (b[2] << 16) | (static_cast<uint32_t>(b[3]) << 24);
    if (4 + n > m.payload.size())
        return std::nullopt;
    ImageMessage out;
    out.header = nlohmann::json::parse(m.payload.substr(4, n));
    out.jpeg = m.payload.substr(4 + n);
    return out;
}

// An HTTP GET on 127.0.0.1:port (Host 127.0.0.1:port unless `headers` has one); the whole
// response.
std::string httpGet(int port, const std::string& path, const std::string& headers = "") {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    std::string response;
    if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0) {
        const std::string host = headers.find("Host:") == std::string::npos
                                     ? "Host: 127.0.0.1:" + std::to_string(port) + "\r\n"
                                     : "";
        const std::string request =
            "GET " + path + " HTTP/1.1\r\n" + host + headers + "Connection: close\r\n\r\n";
        send(fd, request.data(), request.size(), MSG_NOSIGNAL);
        char chunk[65536];
        ssize_t n = 0;
        while ((n = recv(fd, chunk, sizeof(chunk), 0)) > 0)
            response.append(chunk, n);
    }
    close(fd);
    return response;
}

TEST(LiveView, ServesItsPageOnLoopbackAndChoosesImageStreams) {
    Rig rig(anyPort());
    // A stream that is not an image is no tile.
    StreamInfo records;
    records.name = "cam/poses";
    records.device = "cam";
    records.kind = StreamKind::kPose;
    records.format = ImageDesc::packed(PixelFormat::kBinary, 64, 1);
    ASSERT_TRUE(rig.graph.addStream(records).isOk());
    ASSERT_TRUE(rig.graph.start().isOk());
    const int port = rig.view->port();
    ASSERT_GT(port, 0);
    EXPECT_EQ(rig.view->url(), "http://127.0.0.1:" + std::to_string(port) + "/");
    EXPECT_TRUE(listensOnLoopbackOnly(port));
    const std::string page = httpGet(port, "/");
    EXPECT_EQ(page.rfind("HTTP/1.1 200", 0), 0u) << page.substr(0, 200);
    EXPECT_NE(page.find("new WebSocket"), std::string::npos);
    EXPECT_EQ(httpGet(port, "/secret").rfind("HTTP/1.1 404", 0), 0u);
    // No way out of the two paths: dot segments are resolved before the path is judged.
    for (const char* path : {"/../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/ws/../secret"})
        EXPECT_EQ(httpGet(port, path).rfind("HTTP/1.1 404", 0), 0u) << path;
    // Loopback and no token: nothing to warn about, a URL without a token.
    EXPECT_EQ(rig.view->exposureWarning(), "");
    EXPECT_EQ(rig.view->token(), "");
    EXPECT_EQ(rig.view->urls(), std::vector<std::string>{rig.view->url()});
    const LiveViewStats stats = rig.view->stats();
    ASSERT_EQ(stats.tiles.size(), 3u);
    EXPECT_EQ(stats.tiles[0].stream, "cam/color");
    EXPECT_EQ(stats.tiles[1].stream, "cam/depth");
    EXPECT_EQ(stats.tiles[2].stream, "cam/ir");

    // Named streams: absent and non-image ones are errors.
    Graph graph;
    ASSERT_TRUE(graph.addStream(records).isOk());
    LiveViewOptions named;
    named.streams = {"cam/nothing"};
    EXPECT_EQ(graph.addNode(LiveView::create(named).value()).code(), ErrorCode::kNotFound);
    named.streams = {"cam/poses"};
    EXPECT_EQ(graph.addNode(LiveView::create(named).value()).code(), ErrorCode::kInvalidArgument);
}

TEST(LiveView, SeveralClientsGetEveryTileAtTheRateLimitWithStatusAndOverlays) {
    LiveViewOptions o = anyPort();
    o.max_tile_fps = 10;
    o.status_period_s = 0.2;
    Rig rig(o);
    rig.view->setStatusProvider(
        [] { return R"({"devices":[{"name":"cam","state":"streaming"}],"custom":7})"; });
    EXPECT_EQ(rig.view->setOverlay("cam/nothing", "{}").code(), ErrorCode::kNotFound);
    EXPECT_EQ(rig.view->setOverlay("cam/color", "{\"polygons\":[").code(),
              ErrorCode::kInvalidArgument);
    EXPECT_EQ(rig.view->setOverlay("cam/color", "[1,2]").code(), ErrorCode::kInvalidArgument);
    EXPECT_EQ(
        rig.view->setOverlay("cam/color", "{\"texts\":\"" + std::string(kMaxJsonBytes, 'x') + "\"}")
            .code(),
        ErrorCode::kInvalidArgument);
    ASSERT_TRUE(rig.graph.start().isOk());
    const int port = rig.view->port();
    constexpr int kClients = 3;
    std::vector<std::unique_ptr<WsClient>> clients;
    for (int i = 0; i < kClients; ++i) {
        clients.push_back(std::make_unique<WsClient>());
        ASSERT_TRUE(clients.back()->open(port));
    }
    ASSERT_TRUE(rig.view
                    ->setOverlay("cam/color",
                                 R"({"circles":[{"centre":[10,20],"radius":5,"color":"#ff0000"}]})")
                    .isOk());
    struct Seen {
        bool config_first = false;
        int status = 0;
        int overlays = 0;
        std::vector<std::set<uint64_t>> seqs = std::vector<std::set<uint64_t>>(3);
        bool decoded = true;
    };
    std::vector<Seen> seen(kClients);
    std::vector<std::thread> readers;
    const auto start = Clock::now();
    for (int i = 0; i < kClients; ++i) {
        readers.emplace_back([&, i] {
            bool first = true;
            while (Clock::now() - start < 2s) {
                auto m = clients[i]->next();
                if (!m)
                    break;
                if (m->opcode == 1) {
                    const auto j = nlohmann::json::parse(m->payload);
                    if (first)
                        seen[i].config_first = j["type"] == "config";
                    if (j["type"] == "status" && j["pipeline"]["custom"] == 7 &&
                        j["view"]["tiles"].size() == 3) {
                        ++seen[i].status;
                    }
                    if (j["type"] == "overlay" && j["tile"] == 0)
                        ++seen[i].overlays;
                } else if (auto image = parseImage(*m)) {
                    const int tile = image->header["tile"];
                    seen[i].seqs[tile].insert(image->header["seq"].get<uint64_t>());
                    const Decoded d = decodeJpeg(image->jpeg);
                    if (d.rgb.empty() || d.width != image->header["width"])
                        seen[i].decoded = false;
                }
                first = false;
            }
        });
    }
    for (auto& r : readers)
        r.join();
    const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
    const LiveViewStats stats = rig.view->stats();
    for (int i = 0; i < kClients; ++i) {
        SCOPED_TRACE("client " + std::to_string(i));
        EXPECT_TRUE(seen[i].config_first);
        EXPECT_GE(seen[i].status, 3);
        EXPECT_GE(seen[i].overlays, 1);
        EXPECT_TRUE(seen[i].decoded);
        for (int t = 0; t < 3; ++t)
            EXPECT_GE(seen[i].seqs[t].size(), 5u) << "tile " << t;
    }
    EXPECT_EQ(stats.clients.size(), static_cast<size_t>(kClients));
    EXPECT_EQ(stats.clients_ever, static_cast<uint64_t>(kClients));
    for (const TileStats& t : stats.tiles) {
        // At most max_tile_fps (with one period of slack for the start); the camera's 30 fps
        // mostly skipped on the edge.
        EXPECT_LE(t.encoded, static_cast<uint64_t>(10 * (elapsed + 0.5)) + 2) << t.stream;
        EXPECT_GT(t.skipped_rate, 0u) << t.stream;
        EXPECT_EQ(t.encode_errors, 0u) << t.stream;
    }
    // The view's rate limit is its choice, not a loss: the graph counts its edges' replaced
    // frames as skipped, and no drop.
    for (const EdgeStats& e : rig.graph.edgeStats()) {
        if (e.consumer.starts_with("liveview:")) {
            EXPECT_EQ(e.queue.dropped, 0u) << e.consumer;
            EXPECT_GT(e.queue.skipped, 0u) << e.consumer;
        }
    }
}

TEST(LiveView, StalledClientNeitherSlowsThePipelineNorGrowsMemory) {
    test::runWithin(60s, "the stalled-client test", [](test::WatchdogStage& stage) {
        LiveViewOptions o = anyPort();
        o.max_tile_fps = 30;  // as fast as the camera: the stalled client's mailbox is busy
        o.jpeg_quality = 95;
        Rig rig(o, {pattern::PatternStream::kColor, pattern::PatternStream::kDepth}, 640, 480);
        ASSERT_TRUE(rig.graph.start().isOk());
        const int port = rig.view->port();
        stage.set("connecting");
        WsClient stalled;
        ASSERT_TRUE(stalled.open(port, 4096));  // handshake done, then never reads
        WsClient reader;
        ASSERT_TRUE(reader.open(port));
        test::ImageMessageCounter frames(reader);
        stage.set("waiting for the stalled client's buffers to fill");
        std::this_thread::sleep_for(1500ms);
        const uint64_t memory_before = test::memoryInUse();
        const uint64_t published_before = rig.device->publishedFrames();
        const int frames_before = frames.count();
        const auto t0 = Clock::now();
        size_t high = 0;
        bool saw_stalled = false;
        while (Clock::now() - t0 < 3s) {
            std::this_thread::sleep_for(100ms);
            for (const ClientStats& c : rig.view->stats().clients) {
                high = std::max(high, c.queued_bytes);
                saw_stalled = saw_stalled || c.stalled;
            }
        }
        const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        const uint64_t published = rig.device->publishedFrames() - published_before;
        const int received = frames.count() - frames_before;
        const uint64_t memory_after = test::memoryInUse();
        const LiveViewStats stats = rig.view->stats();

        // The camera kept its rate (2 streams at 30 fps) and lost nothing.
        EXPECT_GE(published, static_cast<uint64_t>(0.85 * 2 * 30 * seconds));
        EXPECT_EQ(rig.device->poolExhausted(), 0u);
        for (StreamId id : rig.device->streamIds())
            EXPECT_EQ(rig.graph.lostCount(id), 0u);
        // The stalled client is seen as stalled, its mailbox stays within the bound.
        EXPECT_TRUE(saw_stalled);
        EXPECT_LE(high, stats.queue_bound_bytes);
        for (const ClientStats& c : stats.clients) {
            EXPECT_LE(c.queued_bytes_high, stats.queue_bound_bytes);
        }
        ASSERT_EQ(stats.clients.size(), 2u);
        const ClientStats& slow = stats.clients[0].frames_sent < stats.clients[1].frames_sent
                                      ? stats.clients[0]
                                      : stats.clients[1];
        EXPECT_GT(slow.frames_skipped, 0u);
        // The other browser kept receiving both tiles at about the view's rate.
        EXPECT_GE(received, static_cast<int>(0.5 * 2 * 30 * seconds));
        // Memory flat: a few MB of slack for the allocator, not a frame per frame.
        EXPECT_LT(memory_after, memory_before + 8u * 1024 * 1024)
            << "memory in use grew from " << memory_before << " to " << memory_after;

        stage.set("stopping with the stalled client connected");
        const auto s0 = Clock::now();
        rig.view->stop();
        const double stop_s = std::chrono::duration<double>(Clock::now() - s0).count();
        EXPECT_LT(stop_s, 1.0);
        frames.stop();
    });
}

TEST(LiveView, StatusThatIsNotAJsonObjectIsShownAsAMessage) {
    LiveViewOptions o = anyPort();
    o.status_period_s = 0.05;
    Rig rig(o, {pattern::PatternStream::kColor});
    rig.view->setStatusProvider([] { return std::string("fps: 30"); });
    ASSERT_TRUE(rig.graph.start().isOk());
    WsClient client;
    ASSERT_TRUE(client.open(rig.view->port()));
    std::optional<nlohmann::json> status;
    for (int i = 0; i < 50 && !status; ++i) {
        auto m = client.next();
        ASSERT_TRUE(m.has_value());
        if (m->opcode != 1)
            continue;
        auto j = nlohmann::json::parse(m->payload);
        if (j["type"] == "status")
            status = j;
    }
    ASSERT_TRUE(status.has_value());
    EXPECT_TRUE((*status)["pipeline"].is_null());
    EXPECT_NE((*status)["error"].get<std::string>().find("not a JSON object"), std::string::npos);
    EXPECT_EQ((*status)["view"]["tiles"][0]["stream"],
              "cam/color");  // the view's own figures go on
}

TEST(LiveView, EncodesNothingWhileNoBrowserWatches) {
    Rig rig(anyPort());
    ASSERT_TRUE(rig.graph.start().isOk());
    std::this_thread::sleep_for(500ms);
    for (const TileStats& t : rig.view->stats().tiles) {
        EXPECT_EQ(t.encoded, 0u) << t.stream;
        EXPECT_GT(t.frames_in, 0u) << t.stream;
    }
    WsClient client;
    ASSERT_TRUE(client.open(rig.view->port()));
    int images = 0;
    while (images < 6) {
        auto m = client.next();
        ASSERT_TRUE(m.has_value());
        images += m->opcode == 2;
    }
    for (const TileStats& t : rig.view->stats().tiles)
        EXPECT_GT(t.encoded, 0u) << t.stream;
}

TEST(LiveView, ClientStalledPastTheTimeoutIsDisconnected) {
    LiveViewOptions o = anyPort();
    o.max_tile_fps = 30;
    o.stalled_client_timeout_s = 0.5;
    o.jpeg_quality = 95;
    Rig rig(o, {pattern::PatternStream::kColor}, 640, 480);
    ASSERT_TRUE(rig.graph.start().isOk());
    WsClient stalled;
    ASSERT_TRUE(stalled.open(rig.view->port(), 4096));
    const auto t0 = Clock::now();
    while (rig.view->stats().clients_dropped == 0 && Clock::now() - t0 < 10s) {
        std::this_thread::sleep_for(50ms);
    }
    const LiveViewStats stats = rig.view->stats();
    EXPECT_EQ(stats.clients_dropped, 1u);
    EXPECT_TRUE(stats.clients.empty());
}

TEST(LiveView, MoreBrowsersThanMaxClientsAreRefused) {
    LiveViewOptions o = anyPort();
    o.max_clients = 2;
    Rig rig(o);
    ASSERT_TRUE(rig.graph.start().isOk());
    WsClient a, b, c;
    ASSERT_TRUE(a.open(rig.view->port()));
    ASSERT_TRUE(b.open(rig.view->port()));
    std::this_thread::sleep_for(200ms);
    EXPECT_FALSE(c.open(rig.view->port()));
    EXPECT_EQ(rig.view->stats().clients_refused, 1u);
    EXPECT_EQ(rig.view->stats().clients.size(), 2u);
}

// ---- Who may connect, and how much ----

TEST(LiveViewSecurity, OtherSitesPagesAreRefusedOnLoopback) {
    Rig rig(anyPort(), {pattern::PatternStream::kColor});
    ASSERT_TRUE(rig.graph.start().isOk());
    const int port = rig.view->port();
    const std::string p = std::to_string(port);
    // A page of another site opening a WebSocket to the view.
    WsClient evil;
    EXPECT_FALSE(evil.open(port, 0, {"/ws", "", "Origin: http://evil.example\r\n"}));
    EXPECT_EQ(evil.status(), 403);
    // DNS rebinding: a name of the attacker's resolving to 127.0.0.1 is its Host and Origin.
    WsClient rebound;
    EXPECT_FALSE(rebound.open(
        port, 0, {"/ws", "evil.example:" + p, "Origin: http://evil.example:" + p + "\r\n"}));
    EXPECT_EQ(rebound.status(), 403);
    EXPECT_EQ(httpGet(port, "/", "Host: evil.example:" + p + "\r\n").rfind("HTTP/1.1 403", 0), 0u);
    // The view's own page, by either loopback name, and a client that is not a browser.
    WsClient page, named, tool;
    EXPECT_TRUE(page.open(port, 0, {"/ws", "", "Origin: http://127.0.0.1:" + p + "\r\n"}));
    EXPECT_TRUE(
        named.open(port, 0, {"/ws", "localhost:" + p, "Origin: http://localhost:" + p + "\r\n"}));
    EXPECT_TRUE(tool.open(port));
    const auto first = page.next();
    ASSERT_TRUE(first.has_value());
    EXPECT_EQ(nlohmann::json::parse(first->payload)["type"], "config");
    const LiveViewStats stats = rig.view->stats();
    EXPECT_EQ(stats.requests_unauthorized, 3u);
    EXPECT_EQ(stats.clients.size(), 3u);
}

TEST(LiveViewSecurity, AGivenTokenIsRequiredOnEveryRequest) {
    LiveViewOptions o = anyPort();
    o.token = "s3cret-Token_0123456789";
    Rig rig(o, {pattern::PatternStream::kColor});
    ASSERT_TRUE(rig.graph.start().isOk());
    const int port = rig.view->port();
    EXPECT_EQ(rig.view->url(), "http://127.0.0.1:" + std::to_string(port) + "/?token=" + o.token);
    EXPECT_EQ(rig.view->token(), o.token);
    const std::string missing = httpGet(port, "/");
    EXPECT_EQ(missing.rfind("HTTP/1.1 401", 0), 0u) << missing;
    EXPECT_NE(missing.find("?token="), std::string::npos) << "says how to get in";
    EXPECT_EQ(httpGet(port, "/?token=s3cret-Token_0123456780").rfind("HTTP/1.1 403", 0), 0u);
    const std::string page = httpGet(port, "/?token=" + o.token);
    EXPECT_EQ(page.rfind("HTTP/1.1 200", 0), 0u) << page.substr(0, 300);
    // The token in the page's URL goes to no cache and no other site.
    EXPECT_NE(page.find("Referrer-Policy: no-referrer"), std::string::npos);
    EXPECT_NE(page.find("Cache-Control: no-store"), std::string::npos);
    WsClient none, wrong, right;
    EXPECT_FALSE(none.open(port));
    EXPECT_EQ(none.status(), 401);
    EXPECT_FALSE(wrong.open(port, 0, {"/ws?token=" + o.token + "x", "", ""}));
    EXPECT_EQ(wrong.status(), 403);
    EXPECT_TRUE(right.open(port, 0, {"/ws?token=" + o.token, "", ""}));
    EXPECT_TRUE(right.next().has_value());
    EXPECT_EQ(rig.view->stats().requests_unauthorized, 4u);

    // A token too short to guess at is refused before anything listens.
    LiveViewOptions weak;
    weak.token = "secret";
    const Status s = weak.validate();
    EXPECT_EQ(s.code(), ErrorCode::kInvalidArgument);
    EXPECT_NE(s.message().find("token"), std::string::npos) << s.message();
}

TEST(LiveViewSecurity, RequiredTokensAreMadeFreshFromTheKernelsRandomness) {
    LiveViewOptions o = anyPort();
    o.require_token = true;
    Rig a(o, {pattern::PatternStream::kColor});
    Rig b(o, {pattern::PatternStream::kColor});
    ASSERT_TRUE(a.graph.start().isOk());
    ASSERT_TRUE(b.graph.start().isOk());
    const std::string token = a.view->token();
    EXPECT_EQ(token.size(), 64u);
    EXPECT_EQ(token.find_first_not_of("0123456789abcdef"), std::string::npos) << token;
    EXPECT_NE(token, b.view->token());
    EXPECT_NE(a.view->url().find("/?token=" + token), std::string::npos) << a.view->url();
    EXPECT_EQ(httpGet(a.view->port(), "/").rfind("HTTP/1.1 401", 0), 0u);
    EXPECT_EQ(a.view->exposureWarning(), "");  // loopback: nothing to warn about
}

// A WebSocket frame from a client (masked, as browsers send them).
std::string clientFrame(uint8_t first_byte, const std::string& payload) {
    std::string frame(1, static_cast<char>(first_byte));
    frame.push_back(static_cast<char>(0x80 | payload.size()));  // short payloads only
    const std::string mask = "\x01\x02\x03\x04";
    frame += mask;
    for (size_t i = 0; i < payload.size(); ++i)
        frame.push_back(static_cast<char>(payload[i] ^ mask[i % 4]));
    return frame;
}

// Reads until the server's close frame; its status code, or 0 when the connection ended without.
int closeCode(WsClient& client) {
    for (int i = 0; i < 200; ++i) {
        const auto m = client.next();
        if (!m)
            return 0;
        if (m->opcode == 8 && m->payload.size() >= 2)
            return (static_cast<uint8_t>(m->payload[0]) << 8) | static_cast<uint8_t>(m->payload[1]);
    }
    return -1;
}

TEST(LiveViewSecurity, FloodsOversizedRequestsAndBadFramesLeaveTheWatchingBrowserServed) {
    test::runWithin(60s, "the flood test", [](test::WatchdogStage& stage) {
        LiveViewOptions o = anyPort();
        o.max_clients = 2;
        o.max_requests = 2;
        o.request_timeout_ms = 1000;
        o.max_tile_fps = 15;
        // Small tiles: the flood's admitted client reads nothing until its bad frame, and its
        // socket's buffers hold many seconds of them (it is not a stalled browser).
        Rig rig(o, {pattern::PatternStream::kColor}, 64, 48);
        ASSERT_TRUE(rig.graph.start().isOk());
        const int port = rig.view->port();
        WsClient watching;
        ASSERT_TRUE(watching.open(port));
        test::ImageMessageCounter frames(watching);
        std::this_thread::sleep_for(500ms);
        const uint64_t memory_before = test::memoryInUse();
        const int frames_before = frames.count();
        const auto t0 = Clock::now();

        stage.set("a flood of WebSocket clients at once");
        constexpr int kFlood = 12;
        std::vector<std::unique_ptr<WsClient>> flood(kFlood);
        std::vector<std::thread> openers;
        for (int i = 0; i < kFlood; ++i) {
            flood[i] = std::make_unique<WsClient>();
            openers.emplace_back([&, i] { flood[i]->open(port); });
        }
        for (auto& t : openers)
            t.join();
        WsClient* admitted = nullptr;
        int opened = 0;
        int busy = 0;
        for (const auto& c : flood) {
            if (c->status() == 101)
                admitted = c.get(), ++opened;
            busy += c->status() == 503;
        }
        ASSERT_EQ(opened, 1) << "exactly one more browser fits beside the watching one";
        EXPECT_EQ(busy, kFlood - 1);

        stage.set("connections that never send a request");
        std::vector<int> idle;
        for (int i = 0; i < 4; ++i) {
            const int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
            sockaddr_in addr{};
            addr.sin_family = AF_INET;
            addr.sin_port = htons(static_cast<uint16_t>(port));
            addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
            (void)connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
            idle.push_back(fd);
        }

        stage.set("an oversized request and one with too many header lines");
        // civetweb answers a head that overflows its buffer itself: 413, or in 1.15 "400
        // Malformed message" when the buffer filled mid-line.
        const std::string big = httpGet(port, "/", "X-Big: " + std::string(16384, 'a') + "\r\n");
        EXPECT_TRUE(big.rfind("HTTP/1.0 400", 0) == 0 || big.rfind("HTTP/1.1 413", 0) == 0)
            << big.substr(0, 200);
        std::string lines;
        for (int i = 0; i < 40; ++i)
            lines += "X-Line-" + std::to_string(i) + ": 1\r\n";
        EXPECT_EQ(httpGet(port, "/", lines).rfind("HTTP/1.1 431", 0), 0u);

        stage.set("bad frames from an admitted client");
        ASSERT_TRUE(admitted->sendRaw(clientFrame(0x82, "\x01\x02")));  // binary
        EXPECT_EQ(closeCode(*admitted), 1003);
        WsClient huge;
        for (int i = 0; i < 50 && !huge.open(port); ++i)  // its place comes free
            std::this_thread::sleep_for(50ms);
        ASSERT_EQ(huge.status(), 101);
        // A frame announcing 2^40 bytes: civetweb will not buffer it and ends the connection.
        const std::string announce =
            std::string("\x82\xFF\x00\x00\x01\x00\x00\x00\x00\x00", 10) + "\x01\x02\x03\x04";
        ASSERT_TRUE(huge.sendRaw(announce));
        EXPECT_LE(closeCode(huge), 0);

        const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        const int received = frames.count() - frames_before;
        const uint64_t memory_after = test::memoryInUse();
        for (const int fd : idle)
            close(fd);
        // The watching browser kept receiving at about the tile rate throughout.
        EXPECT_GE(received, static_cast<int>(0.5 * 15 * seconds)) << "in " << seconds << " s";
        EXPECT_LT(memory_after, memory_before + 16u * 1024 * 1024)
            << "memory in use grew from " << memory_before << " to " << memory_after;
        const LiveViewStats stats = rig.view->stats();
        EXPECT_GE(stats.clients_refused, static_cast<uint64_t>(kFlood - 1));
        EXPECT_EQ(stats.messages_refused, 1u);
        EXPECT_GE(stats.requests_refused, 1u);  // the header lines (civetweb's own 400/413 not)
        frames.stop();
    });
}

// ---- The page in a real browser ----

TEST(LiveViewBrowser, TilesChangeFiguresUpdateAndDeviceStatesShow) {
    if (test::chromiumPath().empty()) {
        GTEST_SKIP() << "chromium is not installed (apt-get install chromium); the page is not "
                        "checked in a browser";
    }
    LiveViewOptions o = anyPort();
    o.max_tile_fps = 10;
    o.title = "rig check";
    Rig rig(o);
    std::atomic<int> calls{0};
    rig.view->setStatusProvider([&calls] {
        const int n = ++calls;
        return R"({"devices":[{"name":"cam","state":"streaming"},{"name":"env","state":"lost"}],)"
               R"("streams":[{"name":"cam/color","fps":30.0,"published":)" +
               std::to_string(n) +
               R"(,"dropped":0}],"latency_ms":{"p50":12.5,"p95":20,"p99":31},)"
               R"("ladder":{"rung":2,"rungs":4,"label":"spp 1"},"messages":["marker 23 stale"]})";
    });
    ASSERT_TRUE(rig.view
                    ->setOverlay("cam/color",
                                 R"({"polygons":[{"points":[[10,10],[100,10],[100,80]],)"
                                 R"("color":"#00ff00","label":"23"}]})")
                    .isOk());
    ASSERT_TRUE(rig.graph.start().isOk());

    test::ChromiumOptions chrome;
    chrome.timeout = 40s;
    chrome.until_js =
        "(() => { const t = [...document.querySelectorAll('.tile')];"
        " return t.length === 3 && t.every(x => Number(x.dataset.distinct) >= 4) &&"
        " Number(document.body.dataset.statusCount) >= 5; })()";
    chrome.result_js =
        "JSON.stringify({title: document.title, connected: document.body.dataset.connected,"
        " status: Number(document.body.dataset.statusCount), error: document.body.dataset.error || "
        "'',"
        " tiles: [...document.querySelectorAll('.tile')].map(t => ({stream: t.dataset.stream,"
        "   images: Number(t.dataset.images), distinct: Number(t.dataset.distinct),"
        "   overlays: Number(t.dataset.overlays), legend: !!t.querySelector('.legend')})),"
        " devices: [...document.querySelectorAll('#devices li')].map(d => ({name: d.dataset.name,"
        "   state: d.dataset.state, cls: d.className})),"
        " published: (document.querySelector('#streams tr[data-stream=\"cam/color\"] "
        "td:nth-child(3)')"
        "   || {}).textContent, latency: document.getElementById('latency').textContent,"
        " ladder: document.getElementById('ladder').textContent,"
        " messages: document.getElementById('messages').textContent})";
    // A picture of the page for people (kept beside the test's other outputs).
    chrome.screenshot = test::tempDir() / "live_view.png";
    const int status_before = calls.load();
    const test::ChromiumRun run = test::runHeadlessChromium(rig.view->url(), chrome);
    ASSERT_TRUE(run.started) << run.error;
    std::printf("live view page: %s\n", chrome.screenshot.c_str());
    EXPECT_TRUE(run.until_met) << run.result << "\n" << run.error;
    const auto page = nlohmann::json::parse(run.result, nullptr, false);
    ASSERT_FALSE(page.is_discarded()) << run.result;
    EXPECT_EQ(page["title"], "rig check");
    EXPECT_EQ(page["connected"], "1");
    EXPECT_EQ(page["error"], "");
    ASSERT_EQ(page["tiles"].size(), 3u);
    for (const auto& t : page["tiles"]) {
        EXPECT_GE(t["distinct"].get<int>(), 4) << t.dump();  // the images change
    }
    EXPECT_EQ(page["tiles"][0]["stream"], "cam/color");
    EXPECT_GE(page["tiles"][0]["overlays"].get<int>(), 1);
    EXPECT_TRUE(page["tiles"][1]["legend"].get<bool>());  // depth has its colour legend
    ASSERT_EQ(page["devices"].size(), 2u);
    EXPECT_EQ(page["devices"][1]["name"], "env");
    EXPECT_EQ(page["devices"][1]["state"], "lost");
    EXPECT_NE(page["devices"][1]["cls"].get<std::string>().find("state-lost"), std::string::npos);
    // The figures are the latest: a published count the provider gave after the page opened.
    EXPECT_GT(std::stoi(page["published"].get<std::string>()), status_before);
    EXPECT_NE(page["latency"].get<std::string>().find("p99 31.0 ms"), std::string::npos);
    EXPECT_NE(page["ladder"].get<std::string>().find("rung 2 of 4 (spp 1)"), std::string::npos);
    EXPECT_NE(page["messages"].get<std::string>().find("marker 23 stale"), std::string::npos);
    EXPECT_GE(rig.view->stats().clients_ever, 1u);
}

TEST(LiveViewBrowser, ThePageCarriesItsTokenToItsWebSocket) {
    if (test::chromiumPath().empty())
        GTEST_SKIP() << "chromium is not installed: the page's token is not checked in a browser";
    LiveViewOptions o = anyPort();
    o.require_token = true;
    o.max_tile_fps = 10;
    Rig rig(o, {pattern::PatternStream::kColor});
    ASSERT_TRUE(rig.graph.start().isOk());
    test::ChromiumOptions chrome;
    chrome.timeout = 30s;
    chrome.until_js =
        "(() => { const t = document.querySelector('.tile');"
        " return !!t && Number(t.dataset.images) >= 3; })()";
    chrome.result_js =
        "JSON.stringify({connected: document.body.dataset.connected || '',"
        " images: Number((document.querySelector('.tile') || {dataset: {}}).dataset.images || 0)})";
    const test::ChromiumRun run = test::runHeadlessChromium(rig.view->url(), chrome);
    ASSERT_TRUE(run.started) << run.error;
    EXPECT_TRUE(run.until_met) << run.result << "\n" << run.error;
    EXPECT_EQ(rig.view->stats().requests_unauthorized, 0u);
    EXPECT_GE(rig.view->stats().clients_ever, 1u);
}

}  // namespace
}  // namespace mixray::liveview
