// LiveView: subscribes to image streams, encodes JPEG tiles at a bounded rate and sends them,
// with overlays and figures, to every connected browser through its own one-slot mailboxes.
#include "mixray/liveview/live_view.h"

#include <arpa/inet.h>
#include <civetweb.h>
#include <dirent.h>
#include <dlfcn.h>
#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <pthread.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "image_to_jpeg.h"
#include "mixray/graph/host_time.h"
#include "mixray/graph/thread_priority.h"
#include "page.h"
#include "request_check.h"

// civetweb as Debian builds it (1.15) starts its threads with a fixed 100 kB stack. In a process
// that also loads libquadmath (the mixray binary does: mrcal and Ceres pull in libgfortran),
// glibc's printf family takes its positional path (libquadmath registers printf modifiers), which
// needs more stack than that: the WebSocket handshake's mg_printf overflowed a worker's stack and
// crashed `mixray run --view` as soon as a browser connected. civetweb has no run-time setting
// for it, so the stack size a thread asks for is raised to at least kMinThreadStackBytes here;
// the linker exports this definition from the executable, ahead of glibc's, to every library.
namespace {
constexpr size_t kMinThreadStackBytes = size_t{1} << 20;
}  // namespace

extern "C" int pthread_attr_setstacksize(pthread_attr_t* attr, size_t size) {
    using Real = int (*)(pthread_attr_t*, size_t);
    static const Real real = reinterpret_cast<Real>(dlsym(RTLD_NEXT, "pthread_attr_setstacksize"));
    return real(attr, std::max(size, kMinThreadStackBytes));
}

namespace mixray::liveview {
namespace {

using Clock = std::chrono::steady_clock;
using Bytes = std::shared_ptr<const std::string>;

// True when `text` is one JSON object (syntax checked without exceptions).
bool isJsonObject(std::string_view text) {
    const size_t first = text.find_first_not_of(" \t\r\n");
    return first != std::string_view::npos && text[first] == '{' &&
           nlohmann::json::accept(text.begin(), text.end());
}

std::string jsonString(std::string_view text) {
    return nlohmann::json(std::string(text)).dump();
}

std::string endpoint(const std::string& address, int port) {
    return address + ":" + std::to_string(port);
}

// The socket of an accepted connection, found by its two ends: civetweb does not expose it,
// and the view must be able to shut a stalled connection down from another thread (civetweb's
// websocket write blocks while the browser does not read). -1 when not found.
//
// The kernel's table of TCP sockets (/proc/self/net/tcp) gives the connection's inode, and
// /proc/self/fd's links name each descriptor's inode. Nothing here touches a descriptor other
// than the one returned: civetweb's threads open and close theirs meanwhile, and probing them
// (fstat, getpeername) raced with those closes (ThreadSanitizer saw it).
int findConnectionSocket(const std::string& remote_addr, int remote_port, int local_port) {
    in_addr remote{};
    if (inet_pton(AF_INET, remote_addr.c_str(), &remote) != 1)
        return -1;
    std::ifstream tcp("/proc/self/net/tcp");
    std::string line;
    std::getline(tcp, line);  // the header
    std::string inode;
    while (inode.empty() && std::getline(tcp, line)) {
        std::istringstream fields(line);
        std::string slot, local, peer, state, queues, timer, retransmits, uid, timeout, node;
        fields >> slot >> local >> peer >> state >> queues >> timer >> retransmits >> uid >>
            timeout >> node;
        // "0100007F:1F90": the address as the kernel holds it (network order) printed as a
        // native word, then the port.
        const size_t colon = peer.find(':');
        if (colon != 8 || local.size() < 10)
            continue;
        const auto hex = [](const std::string& text) {
            return static_cast<uint32_t>(std::strtoul(text.c_str(), nullptr, 16));
        };
        if (hex(peer.substr(0, 8)) == remote.s_addr &&
            static_cast<int>(hex(peer.substr(9))) == remote_port &&
            static_cast<int>(hex(local.substr(9))) == local_port)
            inode = node;
    }
    if (inode.empty() || inode == "0")
        return -1;
    const std::string target = "socket:[" + inode + "]";
    DIR* dir = opendir("/proc/self/fd");
    if (dir == nullptr)
        return -1;
    int found = -1;
    char link[64];
    while (dirent* entry = readdir(dir)) {
        const std::string path = std::string("/proc/self/fd/") + entry->d_name;
        const ssize_t n = readlink(path.c_str(), link, sizeof(link) - 1);
        if (n > 0 && std::string_view(link, static_cast<size_t>(n)) == target) {
            found = std::atoi(entry->d_name);
            break;
        }
    }
    closedir(dir);
    return found;
}

// A port nobody listens on now, for port 0 (civetweb needs a number): the kernel's choice for
// a socket bound to `address`, released again. -1 when binding fails.
int pickFreePort(const std::string& address) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0)
        return -1;
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = 0;
    int port = -1;
    if (inet_pton(AF_INET, address.c_str(), &addr.sin_addr) == 1 &&
        bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0) {
        socklen_t len = sizeof(addr);
        if (getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
            port = ntohs(addr.sin_port);
        }
    }
    close(fd);
    return port;
}

// A dotted-quad IPv4 address (checked on the whole string: no NUL or anything after it).
bool isIpv4(const std::string& text) {
    in_addr parsed{};
    return !text.empty() && text.size() <= 15 &&
           text.find_first_not_of("0123456789.") == std::string::npos &&
           inet_pton(AF_INET, text.c_str(), &parsed) == 1;
}

// A token from the kernel's CSPRNG: 32 bytes as 64 hex digits. Never a weaker fallback: when
// getrandom fails the view does not start.
Status makeToken(std::string* token) {
    unsigned char bytes[32];
    size_t got = 0;
    while (got < sizeof(bytes)) {
        const ssize_t n = getrandom(bytes + got, sizeof(bytes) - got, 0);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            return {ErrorCode::kUnavailable,
                    std::string("live view: no random token (getrandom: ") + std::strerror(errno) +
                        ")"};
        }
        got += static_cast<size_t>(n);
    }
    static constexpr char kHex[] = "0123456789abcdef";
    token->clear();
    for (const unsigned char b : bytes) {
        token->push_back(kHex[b >> 4]);
        token->push_back(kHex[b & 0xF]);
    }
    return Status::ok();
}

// This host's IPv4 addresses on interfaces that are up, loopback last; empty when unknown.
std::vector<std::string> interfaceAddresses() {
    std::vector<std::string> out;
    std::vector<std::string> loopback;
    ifaddrs* list = nullptr;
    if (getifaddrs(&list) != 0)
        return out;
    for (const ifaddrs* i = list; i != nullptr; i = i->ifa_next) {
        if (i->ifa_addr == nullptr || i->ifa_addr->sa_family != AF_INET || !(i->ifa_flags & IFF_UP))
            continue;
        char text[INET_ADDRSTRLEN] = {};
        inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(i->ifa_addr)->sin_addr, text,
                  sizeof(text));
        std::vector<std::string>& into = isLoopbackAddress(text) ? loopback : out;
        if (std::find(into.begin(), into.end(), text) == into.end())
            into.emplace_back(text);
    }
    freeifaddrs(list);
    out.insert(out.end(), loopback.begin(), loopback.end());
    return out;
}

// Opens and closes a TCP connection to host:port (without waiting for it to be served).
void knock(const std::string& host, int port) {
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
    if (fd < 0)
        return;
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port));
    if (inet_pton(AF_INET, host.c_str(), &addr.sin_addr) == 1) {
        (void)::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr));
    }
    close(fd);
}

}  // namespace

Status LiveViewOptions::validate() const {
    auto bad = [](const std::string& field, const std::string& why) {
        return Status(ErrorCode::kInvalidArgument, "live view option " + field + ": " + why);
    };
    if (!isIpv4(address)) {
        return bad("address", "'" + address + "' is not an IPv4 address (e.g. 127.0.0.1)");
    }
    if (port < 0 || port > 65535)
        return bad("port", std::to_string(port) + " is not 0..65535");
    if (!(max_tile_fps > 0 && max_tile_fps <= 240))
        return bad("max_tile_fps", "must be in (0, 240]");
    if (jpeg_quality < 1 || jpeg_quality > 100)
        return bad("jpeg_quality", "must be 1..100");
    if (max_tile_width < 16 || max_tile_width > 16384) {
        return bad("max_tile_width", "must be 16..16384");
    }
    if (!(depth_min_m >= 0 && depth_max_m > depth_min_m && std::isfinite(depth_max_m))) {
        return bad("depth_min_m/depth_max_m", "need 0 <= min < max");
    }
    if (!token.empty() && !isValidToken(token)) {
        return bad("token", "must be 16..256 characters of A-Z a-z 0-9 - . _ ~ (got " +
                                std::to_string(token.size()) + " characters)");
    }
    if (max_clients < 1 || max_clients > 64)
        return bad("max_clients", "must be 1..64");
    if (max_requests < 1 || max_requests > 64)
        return bad("max_requests", "must be 1..64");
    if (max_request_bytes < 1024 || max_request_bytes > 65536)
        return bad("max_request_bytes", "must be 1024..65536");
    // civetweb keeps at most MG_MAX_HEADERS (64) lines and drops the rest unseen; a request
    // that reaches the limit is refused rather than judged without all its headers.
    if (max_headers < 1 || max_headers >= MG_MAX_HEADERS)
        return bad("max_headers", "must be 1.." + std::to_string(MG_MAX_HEADERS - 1));
    if (request_timeout_ms < 100 || request_timeout_ms > 600000)
        return bad("request_timeout_ms", "must be 100..600000");
    if (!(stalled_client_timeout_s > 0))
        return bad("stalled_client_timeout_s", "must be > 0");
    if (!(status_period_s > 0 && status_period_s <= 60)) {
        return bad("status_period_s", "must be in (0, 60]");
    }
    for (const std::string& s : streams) {
        if (s.empty())
            return bad("streams", "an empty stream name");
    }
    return Status::ok();
}

Status parseViewAddress(std::string_view text, LiveViewOptions* options) {
    const auto bad = [&](const std::string& why) {
        return Status(ErrorCode::kInvalidArgument,
                      "--view '" + std::string(text) + "': " + why + " (expected [ADDR:]PORT)");
    };
    const size_t colon = text.rfind(':');
    const std::string_view port_text =
        colon == std::string_view::npos ? text : text.substr(colon + 1);
    if (port_text.empty() || port_text.size() > 5 ||
        !std::all_of(port_text.begin(), port_text.end(),
                     [](char c) { return c >= '0' && c <= '9'; })) {
        return bad("the port is not a number");
    }
    const int port = std::stoi(std::string(port_text));
    if (port > 65535)
        return bad("the port is over 65535");
    std::string address = options->address;
    if (colon != std::string_view::npos) {
        address = std::string(text.substr(0, colon));
        if (!isIpv4(address))
            return bad("'" + address + "' is not an IPv4 address");
    }
    options->address = std::move(address);
    options->port = port;
    return Status::ok();
}

// One connected browser: a mailbox of one slot per message kind and tile (the newest message
// wins), and the sender thread that writes it to the socket.
struct Client {
    uint64_t id = 0;
    std::string remote;
    mg_connection* conn = nullptr;
    int fd = -1;

    std::mutex mutex;
    std::condition_variable wake;
    // Slots: 0 the tile list, 1 the status, then one overlay per tile, then one image per tile.
    std::vector<Bytes> slots;
    size_t first_image_slot = 0;
    size_t next_slot = 0;  // round-robin start among overlays and images
    size_t queued_bytes = 0;
    size_t queued_bytes_high = 0;
    bool closing = false;
    bool failed = false;
    int64_t write_started_ns = 0;  // 0: not writing
    uint64_t frames_sent = 0;
    uint64_t frames_skipped = 0;
    uint64_t messages_sent = 0;
    std::thread sender;

    // Puts `message` into `slot`, replacing what waited there. Never blocks on the socket.
    void post(size_t slot, Bytes message) {
        std::lock_guard lock(mutex);
        if (closing)
            return;
        if (slots[slot]) {
            queued_bytes -= slots[slot]->size();
            if (slot >= first_image_slot)
                ++frames_skipped;
        }
        queued_bytes += message->size();
        queued_bytes_high = std::max(queued_bytes_high, queued_bytes);
        slots[slot] = std::move(message);
        wake.notify_one();
    }

    void run() {
        std::unique_lock lock(mutex);
        while (true) {
            wake.wait(lock, [&] {
                return closing || std::any_of(slots.begin(), slots.end(),
                                              [](const Bytes& b) { return b != nullptr; });
            });
            if (closing)
                return;
            // The tile list and the status first, then overlays and images in turn.
            size_t slot = slots[0] ? 0 : 1;
            if (!slots[slot]) {
                const size_t n = slots.size() - 2;
                for (size_t k = 0; k < n; ++k) {
                    const size_t s = 2 + (next_slot + k) % n;
                    if (slots[s]) {
                        slot = s;
                        next_slot = (s - 2 + 1) % n;
                        break;
                    }
                }
            }
            Bytes message = std::move(slots[slot]);
            const bool binary = slot >= first_image_slot;
            write_started_ns = monotonicNowNs();
            lock.unlock();
            const int rc = mg_websocket_write(
                conn, binary ? MG_WEBSOCKET_OPCODE_BINARY : MG_WEBSOCKET_OPCODE_TEXT,
                message->data(), message->size());
            lock.lock();
            write_started_ns = 0;
            queued_bytes -= message->size();
            if (rc <= 0) {
                // The connection is gone or broke mid-message: a half-written frame cannot be
                // resumed, so end it; civetweb's reader then calls the close handler.
                failed = true;
                closing = true;
                shutdown(fd, SHUT_RDWR);
                return;
            }
            ++messages_sent;
            if (binary)
                ++frames_sent;
        }
    }
};

struct Tile {
    std::string stream;
    StreamInfo info;
    std::shared_ptr<FrameQueue> queue;
    int tile_width = 0;
    int tile_height = 0;
    int64_t next_due_ns = 0;
    uint64_t encoded = 0;
    uint64_t encode_errors = 0;
    std::string last_error;
    uint64_t fps_base_encoded = 0;
    int64_t fps_base_ns = 0;
    double fps = 0;
};

struct LiveView::Impl {
    LiveViewOptions options;
    Graph* graph = nullptr;
    std::vector<Tile> tiles;
    std::function<std::string()> status_provider;

    mg_context* ctx = nullptr;
    bool library_initialised = false;
    RequestPolicy policy;  // set at start()
    std::atomic<int> port{0};
    std::atomic<bool> stopping{false};
    std::string last_log;  // civetweb's last message, for bind errors
    std::mutex log_mutex;

    std::thread thread;
    std::mutex thread_mutex;
    std::condition_variable thread_wake;
    bool thread_stop = false;

    mutable std::mutex clients_mutex;
    std::vector<std::shared_ptr<Client>> clients;
    std::atomic<size_t> connected{0};  // clients.size(), read by the view's thread without a lock
    uint64_t next_client_id = 1;
    uint64_t clients_ever = 0;
    uint64_t clients_refused = 0;
    uint64_t clients_dropped = 0;
    uint64_t requests_unauthorized = 0;
    uint64_t requests_refused = 0;
    uint64_t messages_refused = 0;
    int requests_in_flight = 0;  // pages being written, at most options.max_requests
    // The newest message of each kind, for browsers that connect later.
    Bytes config_message;
    Bytes status_message;
    std::vector<Bytes> overlay_messages;
    std::vector<Bytes> image_messages;
    mutable std::mutex tiles_mutex;  // the tiles' figures, read by stats()

    size_t slotCount() const { return 2 + 2 * tiles.size(); }

    // Hands `message` to every browser's `slot`, and keeps it for later ones.
    void broadcast(size_t slot, Bytes message) {
        std::lock_guard lock(clients_mutex);
        if (slot == 1) {
            status_message = message;
        } else if (slot >= 2 && slot < 2 + tiles.size()) {
            overlay_messages[slot - 2] = message;
        } else if (slot >= 2 + tiles.size()) {
            image_messages[slot - 2 - tiles.size()] = message;
        }
        for (const auto& client : clients)
            client->post(slot, message);
    }

    std::string configJson() const {
        nlohmann::json tiles_json = nlohmann::json::array();
        for (size_t i = 0; i < tiles.size(); ++i) {
            const Tile& t = tiles[i];
            tiles_json.push_back({{"index", i},
                                  {"stream", t.stream},
                                  {"device", t.info.device},
                                  {"kind", std::string(toString(t.info.kind))},
                                  {"format", std::string(toString(t.info.format.format))},
                                  {"width", t.info.format.width},
                                  {"height", t.info.format.height},
                                  {"tile_width", t.tile_width},
                                  {"tile_height", t.tile_height},
                                  {"nominal_fps", t.info.nominal_fps}});
        }
        const nlohmann::json j = {{"type", "config"},
                                  {"title", options.title},
                                  {"max_tile_fps", options.max_tile_fps},
                                  {"depth_auto_range", options.depth_auto_range},
                                  {"depth_min_m", options.depth_min_m},
                                  {"depth_max_m", options.depth_max_m},
                                  {"tiles", tiles_json}};
        return j.dump();
    }

    std::string statusJson() {
        nlohmann::json view_tiles = nlohmann::json::array();
        {
            std::lock_guard lock(tiles_mutex);
            for (const Tile& t : tiles) {
                const QueueStats q = t.queue ? t.queue->stats() : QueueStats{};
                nlohmann::json tile = {{"stream", t.stream},
                                       {"fps", std::round(t.fps * 10) / 10},
                                       {"frames_in", q.pushed},
                                       {"encoded", t.encoded},
                                       {"skipped", q.skipped}};
                if (!t.last_error.empty())
                    tile["error"] = t.last_error;
                view_tiles.push_back(std::move(tile));
            }
        }
        size_t client_count = 0;
        {
            std::lock_guard lock(clients_mutex);
            client_count = clients.size();
        }
        std::string pipeline = "null";
        std::string error;
        if (status_provider) {
            std::string reply = status_provider();
            if (reply.size() > kMaxJsonBytes) {
                error = "the pipeline's status is over " + std::to_string(kMaxJsonBytes) + " bytes";
            } else if (!isJsonObject(reply)) {
                error = "the pipeline's status is not a JSON object";
            } else {
                pipeline = std::move(reply);
            }
        }
        const nlohmann::json view = {{"tiles", view_tiles}, {"clients", client_count}};
        std::string out =
            R"({"type":"status","view":)" + view.dump() + R"(,"pipeline":)" + pipeline;
        if (!error.empty())
            out += R"(,"error":)" + jsonString(error);
        out += "}";
        return out;
    }

    // Encodes the tile's newest frame when its turn has come.
    void serviceTile(size_t index, JpegEncoder& encoder, int64_t now) {
        Tile& tile = tiles[index];
        // Nobody watching: no work; the edge keeps replacing its one frame (counted skipped).
        if (now < tile.next_due_ns || connected.load() == 0)
            return;
        std::optional<FrameRef> frame = tile.queue->tryPop();
        if (!frame)
            return;
        const auto period_ns = static_cast<int64_t>(1e9 / options.max_tile_fps);
        // Never more than max_tile_fps, and no burst to catch up after a pause.
        tile.next_due_ns = std::max(tile.next_due_ns + period_ns, now + period_ns / 2);
        TileRenderOptions render{options.max_tile_width, options.jpeg_quality, options.depth_min_m,
                                 options.depth_max_m, options.depth_auto_range};
        EncodedTile encoded;
        const Status status = encoder.encode(frame->image(), render, &encoded);
        const FrameMetadata meta = frame->meta();
        frame.reset();  // the buffer goes back to its device's pool before sending
        if (!status.isOk()) {
            std::lock_guard lock(tiles_mutex);
            ++tile.encode_errors;
            tile.last_error = tile.stream + ": " + status.message();
            return;
        }
        const nlohmann::json header = {{"tile", index},
                                       {"seq", meta.sequence},
                                       {"host_stamp_ns", meta.host_stamp_ns},
                                       {"width", encoded.width},
                                       {"height", encoded.height},
                                       {"lo", encoded.range_lo},
                                       {"hi", encoded.range_hi},
                                       {"status", std::string(toString(meta.status))}};
        const std::string header_text = header.dump();
        auto message = std::make_shared<std::string>();
        message->reserve(4 + header_text.size() + encoded.jpeg.size());
        const auto n = static_cast<uint32_t>(header_text.size());
        const char len[4] = {static_cast<char>(n & 0xFF), static_cast<char>((n >> 8) & 0xFF),
                             static_cast<char>((n >> 16) & 0xFF), static_cast<char>(n >> 24)};
        message->append(len, 4);
        message->append(header_text);
        message->append(encoded.jpeg);
        {
            std::lock_guard lock(tiles_mutex);
            ++tile.encoded;
            tile.last_error.clear();
        }
        broadcast(2 + tiles.size() + index, std::move(message));
    }

    void updateFps(int64_t now) {
        std::lock_guard lock(tiles_mutex);
        for (Tile& t : tiles) {
            const int64_t dt = now - t.fps_base_ns;
            if (dt >= 1'000'000'000) {
                t.fps = static_cast<double>(t.encoded - t.fps_base_encoded) * 1e9 /
                        static_cast<double>(dt);
                t.fps_base_encoded = t.encoded;
                t.fps_base_ns = now;
            }
        }
    }

    // Shuts down connections whose write has made no progress for too long.
    void dropStalledClients(int64_t now) {
        const auto limit_ns = static_cast<int64_t>(options.stalled_client_timeout_s * 1e9);
        std::lock_guard lock(clients_mutex);
        for (const auto& client : clients) {
            std::lock_guard client_lock(client->mutex);
            if (!client->closing && client->write_started_ns != 0 &&
                now - client->write_started_ns > limit_ns) {
                client->closing = true;
                client->failed = true;  // counted as dropped when its close handler runs
                shutdown(client->fd, SHUT_RDWR);
                client->wake.notify_one();
            }
        }
    }

    void run() {
        JpegEncoder encoder;
        const auto status_period_ns = static_cast<int64_t>(options.status_period_s * 1e9);
        int64_t next_status_ns = 0;
        const auto pass = std::chrono::microseconds(std::clamp(
            static_cast<int64_t>(250'000 / options.max_tile_fps), int64_t{1000}, int64_t{10'000}));
        std::unique_lock lock(thread_mutex);
        while (!thread_stop) {
            lock.unlock();
            const int64_t now = monotonicNowNs();
            for (size_t i = 0; i < tiles.size(); ++i)
                serviceTile(i, encoder, now);
            if (now >= next_status_ns) {
                next_status_ns = now + status_period_ns;
                updateFps(now);
                broadcast(1, std::make_shared<const std::string>(statusJson()));
                dropStalledClients(now);
            }
            lock.lock();
            thread_wake.wait_for(lock, pass, [&] { return thread_stop; });
        }
    }

    // civetweb callbacks. cbdata (and the context's user data) is the Impl.

    // Every request comes here first, before civetweb looks at it any further: refused
    // requests are answered here, pages are served here, and WebSocket upgrades go on to
    // civetweb's handshake and wsConnect.
    static int beginRequest(mg_connection* conn) {
        auto* self = static_cast<Impl*>(mg_get_user_data(mg_get_context(conn)));
        const mg_request_info* info = mg_get_request_info(conn);
        const auto text = [](const char* p) { return std::string_view(p != nullptr ? p : ""); };
        HttpRequest request;
        request.method = text(info->request_method);
        request.path = text(info->local_uri);
        request.query = text(info->query_string);
        for (int i = 0; i < info->num_headers; ++i)
            request.headers.push_back(
                {text(info->http_headers[i].name), text(info->http_headers[i].value)});
        const RequestVerdict verdict = checkRequest(self->policy, request);
        if (verdict.status != 0) {
            {
                std::lock_guard lock(self->clients_mutex);
                const bool unauthorized = verdict.status == 401 || verdict.status == 403;
                ++(unauthorized ? self->requests_unauthorized : self->requests_refused);
            }
            return refuseRequest(conn, verdict.status, verdict.reason);
        }
        if (verdict.kind == RequestKind::kWebSocket)
            return 0;
        return self->servePage(conn);
    }

    // Writes a whole response. Written here rather than with civetweb's response functions:
    // civetweb 1.15 sends nothing through those on a connection that asked for a WebSocket,
    // so a refused upgrade would get no answer at all.
    static int respond(mg_connection* conn, int status, const char* content_type,
                       std::string_view body) {
        std::string head = "HTTP/1.1 " + std::to_string(status) + " " +
                           mg_get_response_code_text(conn, status) +
                           "\r\nContent-Type: " + content_type +
                           "\r\nContent-Length: " + std::to_string(body.size()) +
                           "\r\nConnection: close\r\n"
                           // The page's URL may carry the token: no cache keeps it, no other
                           // site gets it as a referrer, and no other site frames the page.
                           "Cache-Control: no-store\r\nReferrer-Policy: no-referrer\r\n"
                           "X-Content-Type-Options: nosniff\r\n"
                           "Content-Security-Policy: frame-ancestors 'none'\r\n\r\n";
        mg_write(conn, head.data(), head.size());
        mg_write(conn, body.data(), body.size());
        return status;
    }

    static int refuseRequest(mg_connection* conn, int status, const std::string& reason) {
        return respond(conn, status, "text/plain; charset=utf-8",
                       "mixray live view: " + reason + "\n");
    }

    int servePage(mg_connection* conn) {
        {
            std::lock_guard lock(clients_mutex);
            if (stopping.load() || requests_in_flight >= options.max_requests) {
                ++clients_refused;
                return refuseRequest(conn, 503, "busy: too many requests at once, try again");
            }
            ++requests_in_flight;
        }
        respond(conn, 200, "text/html; charset=utf-8", pageHtml());
        std::lock_guard lock(clients_mutex);
        --requests_in_flight;
        return 200;
    }

    // After beginRequest let the upgrade through: a browser's place is taken here, under the
    // same lock as the count, so simultaneous upgrades never exceed max_clients.
    static int wsConnect(const mg_connection* conn, void* cbdata) {
        auto* self = static_cast<Impl*>(cbdata);
        auto* writable = const_cast<mg_connection*>(conn);  // civetweb's own answers need it
        const mg_request_info* request = mg_get_request_info(conn);
        auto client = std::make_shared<Client>();
        client->conn = writable;
        client->remote = endpoint(request->remote_addr, request->remote_port);
        // Without its socket the view could not end a stalled write: refuse rather than risk a
        // stop() that hangs.
        client->fd =
            findConnectionSocket(request->remote_addr, request->remote_port, self->port.load());
        client->slots.resize(self->slotCount());
        client->first_image_slot = 2 + self->tiles.size();
        {
            std::lock_guard lock(self->clients_mutex);
            if (self->stopping.load() || client->fd < 0 ||
                self->clients.size() >= static_cast<size_t>(self->options.max_clients)) {
                ++self->clients_refused;
                refuseRequest(writable, 503,
                              "busy: " + std::to_string(self->options.max_clients) +
                                  " browsers are watching already");
                return 1;
            }
            client->id = self->next_client_id++;
            ++self->clients_ever;
            client->post(0, self->config_message);
            if (self->status_message)
                client->post(1, self->status_message);
            for (size_t i = 0; i < self->tiles.size(); ++i) {
                if (self->overlay_messages[i])
                    client->post(2 + i, self->overlay_messages[i]);
                if (self->image_messages[i]) {
                    client->post(client->first_image_slot + i, self->image_messages[i]);
                }
            }
            self->clients.push_back(client);
            self->connected = self->clients.size();
        }
        mg_set_user_connection_data(conn, client.get());
        return 0;
    }

    // The handshake is sent: the browser's sender starts.
    static void wsReady(mg_connection* conn, void* /*cbdata*/) {
        auto* client = static_cast<Client*>(mg_get_user_connection_data(conn));
        if (client != nullptr)
            client->sender = std::thread([client] {
                runAs(ThreadRole::kPublisher);  // below capture and the recorder
                client->run();
            });
    }

    static int wsData(mg_connection* conn, int bits, char* /*data*/, size_t size, void* cbdata) {
        const MessageVerdict verdict = checkClientMessage(static_cast<uint8_t>(bits), size);
        if (verdict.action == MessageAction::kIgnore)
            return 1;
        if (verdict.action == MessageAction::kRefuse) {
            auto* self = static_cast<Impl*>(cbdata);
            {
                std::lock_guard lock(self->clients_mutex);
                ++self->messages_refused;
            }
            // The close code and why, then the connection ends (civetweb calls wsClose).
            std::string payload = {static_cast<char>(verdict.close_code >> 8),
                                   static_cast<char>(verdict.close_code & 0xFF)};
            payload += verdict.reason.substr(0, 123);
            mg_websocket_write(conn, MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE, payload.data(),
                               payload.size());
        }
        return 0;
    }

    // Takes the client out of the list (counted as dropped when its connection failed);
    // returns it, or null when it was not (or no longer) listed.
    std::shared_ptr<Client> unlist(const Client* raw) {
        std::lock_guard lock(clients_mutex);
        auto it = std::find_if(clients.begin(), clients.end(),
                               [&](const auto& c) { return c.get() == raw; });
        if (it == clients.end())
            return nullptr;
        std::shared_ptr<Client> client = *it;
        clients.erase(it);
        connected = clients.size();
        std::lock_guard client_lock(client->mutex);
        if (client->failed && !stopping.load())
            ++clients_dropped;
        return client;
    }

    static void wsClose(const mg_connection* conn, void* cbdata) {
        auto* self = static_cast<Impl*>(cbdata);
        auto* raw = static_cast<Client*>(mg_get_user_connection_data(conn));
        if (raw == nullptr)
            return;
        const std::shared_ptr<Client> client = self->unlist(raw);
        if (!client)
            return;
        {
            std::lock_guard lock(client->mutex);
            client->closing = true;
            // A write in progress would block until the browser reads; the connection ends now
            // anyway, so end the write too.
            if (client->write_started_ns != 0)
                shutdown(client->fd, SHUT_RDWR);
            client->wake.notify_one();
        }
        if (client->sender.joinable())
            client->sender.join();
        mg_set_user_connection_data(conn, nullptr);
    }

    // Every connection's end. A browser whose handshake failed after wsConnect took its place
    // had no wsClose (and no sender): its place is given back here.
    static void connectionClose(const mg_connection* conn) {
        auto* self = static_cast<Impl*>(mg_get_user_data(mg_get_context(conn)));
        auto* raw = static_cast<Client*>(mg_get_user_connection_data(conn));
        if (self != nullptr && raw != nullptr)
            self->unlist(raw);
    }

    static int logMessage(const mg_connection* conn, const char* message) {
        auto* self = static_cast<Impl*>(mg_get_user_data(mg_get_context(conn)));
        if (self != nullptr && message != nullptr) {
            std::lock_guard lock(self->log_mutex);
            self->last_log = message;
        }
        return 1;  // the view reports errors as Status; civetweb prints nothing
    }
};

LiveView::LiveView(LiveViewOptions options) : impl_(std::make_unique<Impl>()) {
    impl_->options = std::move(options);
}

LiveView::~LiveView() {
    stop();
}

Result<std::unique_ptr<LiveView>> LiveView::create(LiveViewOptions options) {
    MIXRAY_RETURN_IF_ERROR(options.validate());
    return std::unique_ptr<LiveView>(new LiveView(std::move(options)));
}

Status LiveView::connect(Graph& graph) {
    Impl& d = *impl_;
    d.graph = &graph;
    std::vector<StreamInfo> chosen;
    if (d.options.streams.empty()) {
        for (const StreamInfo& info : graph.streams()) {
            if (isTileFormat(info.format.format))
                chosen.push_back(info);
        }
    } else {
        for (const std::string& name : d.options.streams) {
            const std::optional<StreamId> id = graph.findStream(name);
            if (!id) {
                return {ErrorCode::kNotFound, "live view: no stream '" + name + "' in the graph"};
            }
            StreamInfo info = graph.stream(*id);
            if (!isTileFormat(info.format.format)) {
                return {ErrorCode::kInvalidArgument, "live view: stream '" + name + "' is " +
                                                         std::string(toString(info.format.format)) +
                                                         ", not an image"};
            }
            chosen.push_back(std::move(info));
        }
    }
    for (const StreamInfo& info : chosen) {
        Tile tile;
        tile.stream = info.name;
        tile.info = info;
        tileSize(info.format, d.options.max_tile_width, &tile.tile_width, &tile.tile_height);
        // Capacity 1, live, newest only: the newest frame waits for the view's next turn, older
        // ones are replaced (QueueStats::skipped, not drops: the view's rate is its choice),
        // and the view holds at most one buffer of the pool.
        Result<std::shared_ptr<FrameQueue>> queue = graph.subscribe(
            *graph.findStream(info.name), QueueOptions{.capacity = 1,
                                                       .policy = QueuePolicy::kLive,
                                                       .name = "liveview:" + info.name,
                                                       .newest_only = true});
        if (!queue)
            return queue.status().withContext("live view");
        tile.queue = std::move(queue.value());
        d.tiles.push_back(std::move(tile));
    }
    d.overlay_messages.assign(d.tiles.size(), nullptr);
    d.image_messages.assign(d.tiles.size(), nullptr);
    d.config_message = std::make_shared<const std::string>(d.configJson());
    return Status::ok();
}

Status LiveView::start() {
    Impl& d = *impl_;
    if (d.ctx != nullptr)
        return Status::ok();
    if (!d.config_message)
        d.config_message = std::make_shared<const std::string>(d.configJson());
    const bool loopback = isLoopbackAddress(d.options.address);
    // Made once: a view started again keeps the URL it printed.
    if (d.policy.token.empty())
        d.policy.token = d.options.token;
    if (d.policy.token.empty() && (!loopback || d.options.require_token))
        MIXRAY_RETURN_IF_ERROR(makeToken(&d.policy.token));
    // With a token, the view may be reached by any name (a rig's host name); without one it
    // answers to loopback names only.
    d.policy.loopback_host_only = d.policy.token.empty();
    d.policy.max_headers = d.options.max_headers;
    int port = d.options.port;
    if (port == 0) {
        port = pickFreePort(d.options.address);
        if (port < 0) {
            return {ErrorCode::kUnavailable, "live view: cannot bind " +
                                                 endpoint(d.options.address, 0) + ": " +
                                                 std::strerror(errno)};
        }
    }
    const std::string where = endpoint(d.options.address, port);
    // One thread per connection: the browsers' WebSockets and max_requests others. Connections
    // beyond them wait in civetweb's queue (as long) and the kernel's backlog until a thread is
    // free; one that sends no whole request within request_timeout_ms is closed.
    const std::string threads = std::to_string(d.options.max_clients + d.options.max_requests);
    const std::string request_bytes = std::to_string(d.options.max_request_bytes);
    const std::string request_timeout = std::to_string(d.options.request_timeout_ms);
    const char* config[] = {"listening_ports",
                            where.c_str(),
                            "num_threads",
                            threads.c_str(),
                            "connection_queue",
                            threads.c_str(),
                            "listen_backlog",
                            threads.c_str(),
                            "max_request_size",
                            request_bytes.c_str(),
                            "enable_keep_alive",
                            "no",
                            "request_timeout_ms",
                            request_timeout.c_str(),
                            "websocket_timeout_ms",
                            "3600000",
                            nullptr};
    mg_callbacks callbacks{};
    callbacks.log_message = &Impl::logMessage;
    callbacks.begin_request = &Impl::beginRequest;
    callbacks.connection_close = &Impl::connectionClose;
    mg_init_library(0);
    d.library_initialised = true;
    char error_text[256] = {};
    unsigned error_code = 0;
    mg_error_data error{};
    error.code = &error_code;
    error.text = error_text;
    error.text_buffer_size = sizeof(error_text);
    mg_init_data init{};
    init.callbacks = &callbacks;
    init.user_data = &d;
    init.configuration_options = config;
    d.stopping = false;
    d.ctx = mg_start2(&init, &error);
    if (d.ctx == nullptr) {
        mg_exit_library();
        d.library_initialised = false;
        std::string why = error_text;
        if (why.empty()) {
            std::lock_guard lock(d.log_mutex);
            why = d.last_log;
        }
        return {ErrorCode::kUnavailable, "live view: cannot listen on " + where + ": " +
                                             (why.empty() ? "bind failed" : why)};
    }
    d.port = port;
    mg_set_websocket_handler(d.ctx, "/ws", &Impl::wsConnect, &Impl::wsReady, &Impl::wsData,
                             &Impl::wsClose, &d);
    {
        std::lock_guard lock(d.thread_mutex);
        d.thread_stop = false;
    }
    const int64_t now = monotonicNowNs();
    for (Tile& t : d.tiles)
        t.fps_base_ns = now;
    d.thread = std::thread([&d] {
        runAs(ThreadRole::kPublisher);
        d.run();
    });
    return Status::ok();
}

void LiveView::stop() {
    Impl& d = *impl_;
    if (d.ctx == nullptr)
        return;
    d.stopping = true;
    {
        std::lock_guard lock(d.thread_mutex);
        d.thread_stop = true;
        d.thread_wake.notify_all();
    }
    if (d.thread.joinable())
        d.thread.join();
    {
        // Ends every connection at the socket: a sender blocked on a browser that does not read
        // returns, and civetweb's reader sees the end and calls the close handler.
        std::lock_guard lock(d.clients_mutex);
        for (const auto& client : d.clients) {
            std::lock_guard client_lock(client->mutex);
            client->closing = true;
            shutdown(client->fd, SHUT_RDWR);
            client->wake.notify_one();
        }
    }
    // civetweb's listening thread polls for 2 s at a time before it sees the stop flag; a
    // connection wakes it at once, so knock until mg_stop() returns.
    std::atomic<bool> stopped{false};
    std::thread knocker([&] {
        const std::string host = d.options.address == "0.0.0.0" ? "127.0.0.1" : d.options.address;
        while (!stopped.load()) {
            knock(host, d.port.load());
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
    });
    mg_stop(d.ctx);
    stopped = true;
    knocker.join();
    d.ctx = nullptr;
    // Close handlers have run for every connection civetweb served; anything left never got one.
    std::vector<std::shared_ptr<Client>> left;
    {
        std::lock_guard lock(d.clients_mutex);
        left.swap(d.clients);
        d.connected = 0;
    }
    for (const auto& client : left) {
        if (client->sender.joinable())
            client->sender.join();
    }
    if (d.library_initialised) {
        mg_exit_library();
        d.library_initialised = false;
    }
    d.port = 0;
}

void LiveView::setStatusProvider(std::function<std::string()> provider) {
    impl_->status_provider = std::move(provider);
}

Status LiveView::setOverlay(std::string_view stream, std::string overlay_json) {
    Impl& d = *impl_;
    const auto it = std::find_if(d.tiles.begin(), d.tiles.end(),
                                 [&](const Tile& t) { return t.stream == stream; });
    if (it == d.tiles.end()) {
        return {ErrorCode::kNotFound,
                "live view overlay: '" + std::string(stream) + "' is not a tile"};
    }
    if (overlay_json.size() > kMaxJsonBytes) {
        return {ErrorCode::kInvalidArgument, "live view overlay for '" + std::string(stream) +
                                                 "': over " + std::to_string(kMaxJsonBytes) +
                                                 " bytes"};
    }
    if (!isJsonObject(overlay_json)) {
        return {ErrorCode::kInvalidArgument,
                "live view overlay for '" + std::string(stream) + "': not a JSON object"};
    }
    const auto index = static_cast<size_t>(it - d.tiles.begin());
    auto message =
        std::make_shared<const std::string>(R"({"type":"overlay","tile":)" + std::to_string(index) +
                                            R"(,"overlay":)" + overlay_json + "}");
    d.broadcast(2 + index, std::move(message));
    return Status::ok();
}

int LiveView::port() const {
    return impl_->port.load();
}

namespace {

std::string viewUrl(const std::string& host, int port, const std::string& token) {
    return "http://" + endpoint(host, port) + "/" + (token.empty() ? "" : "?token=" + token);
}

}  // namespace

std::string LiveView::url() const {
    const int p = port();
    if (p == 0)
        return "";
    const std::string host =
        impl_->options.address == "0.0.0.0" ? "127.0.0.1" : impl_->options.address;
    return viewUrl(host, p, impl_->policy.token);
}

std::vector<std::string> LiveView::urls() const {
    const int p = port();
    if (p == 0)
        return {};
    if (impl_->options.address != "0.0.0.0")
        return {url()};
    std::vector<std::string> out;
    for (const std::string& address : interfaceAddresses())
        out.push_back(viewUrl(address, p, impl_->policy.token));
    if (out.empty())
        out.push_back(url());
    return out;
}

std::string LiveView::exposureWarning() const {
    return port() == 0 ? "" : liveview::exposureWarning(impl_->options.address, port());
}

std::string LiveView::token() const {
    return impl_->policy.token;
}

LiveViewStats LiveView::stats() const {
    const Impl& d = *impl_;
    LiveViewStats s;
    {
        std::lock_guard lock(d.tiles_mutex);
        for (const Tile& t : d.tiles) {
            const QueueStats q = t.queue ? t.queue->stats() : QueueStats{};
            s.tiles.push_back({t.stream, q.pushed, t.encoded, q.skipped, t.encode_errors, t.fps});
        }
    }
    // Bound: every slot full at its largest (header and length prefix included).
    size_t bound = d.config_message ? d.config_message->size() : 0;
    bound += kMaxJsonBytes + 4096;  // status: the pipeline's JSON and the view's figures
    for (const Tile& t : d.tiles) {
        const size_t image = t.info.format.format == PixelFormat::kMJPEG
                                 ? t.info.format.bufferBytes()
                                 : JpegEncoder::maxJpegBytes(t.tile_width, t.tile_height);
        bound += image + 1024 + kMaxJsonBytes + 64;
    }
    s.queue_bound_bytes = bound;
    std::lock_guard lock(d.clients_mutex);
    s.clients_ever = d.clients_ever;
    s.clients_refused = d.clients_refused;
    s.clients_dropped = d.clients_dropped;
    s.requests_unauthorized = d.requests_unauthorized;
    s.requests_refused = d.requests_refused;
    s.messages_refused = d.messages_refused;
    const int64_t now = monotonicNowNs();
    for (const auto& c : d.clients) {
        std::lock_guard client_lock(c->mutex);
        s.clients.push_back(
            {c->id, c->remote, c->frames_sent, c->frames_skipped, c->messages_sent, c->queued_bytes,
             c->queued_bytes_high,
             c->write_started_ns != 0 && now - c->write_started_ns > 1'000'000'000});
    }
    return s;
}

}  // namespace mixray::liveview
