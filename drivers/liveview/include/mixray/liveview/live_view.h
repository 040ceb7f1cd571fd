// The rig's live view in the browser: a graph sink serving a page of image tiles, overlays and
// figures over HTTP + WebSocket.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "mixray/graph/graph.h"
#include "mixray/graph/result.h"

namespace mixray::liveview {

// How a LiveView serves and what it shows.
struct LiveViewOptions {
    // Address to listen on: loopback unless the user names one (docs/live-view.md, Security).
    // IPv4 dotted quad or "0.0.0.0" for every interface. Any address outside 127.0.0.0/8
    // requires a token.
    std::string address = "127.0.0.1";
    int port = 8080;  // 0: any free port (port() says which after start())
    // The secret every request must carry as ?token=... (the page passes it on to its
    // WebSocket), compared in constant time: 16..256 characters of A-Z a-z 0-9 - . _ ~. Empty:
    // none on loopback; on any other address (or with require_token) start() makes one from the
    // kernel's CSPRNG (getrandom: 32 bytes as 64 hex digits), which token() and url() give.
    std::string token;
    bool require_token = false;  // a token on loopback too (a given token is always required)
    // Graph streams shown as tiles, in order; empty: every image stream in the graph at
    // connect(). Naming a stream that is absent or not an image is an error.
    std::vector<std::string> streams;
    double max_tile_fps = 15;  // JPEGs per tile per second at most, (0, 240]
    int jpeg_quality = 80;     // 1..100
    int max_tile_width = 640;  // larger images are downscaled (integer factor) before encoding
    std::string title = "mixray";
    // Depth tiles in false colour (turbo) over this fixed range, in metres; depth_auto_range:
    // over each frame's own nearest..farthest measurement instead.
    double depth_min_m = 0.3;
    double depth_max_m = 5.0;
    bool depth_auto_range = false;
    int max_clients = 8;  // browsers (WebSockets) connected at once, 1..64; more: HTTP 503
    // Other requests served at once (page loads, refusals), 1..64; more: HTTP 503. The server
    // has max_clients + max_requests threads, so connections beyond those wait in a queue of
    // that many and the kernel's backlog, never in memory of the view's.
    int max_requests = 4;
    int max_request_bytes = 8192;  // request line and headers, 1024..65536; more: HTTP 413
    int max_headers = 32;          // header lines, 1..63; more: HTTP 431
    // A connection that has not sent its whole request by then is closed (its thread is free
    // again). civetweb uses the same value as the longest a write to any client may make no
    // progress, so a browser stalled this long is dropped even before
    // stalled_client_timeout_s. 100..600000.
    int request_timeout_ms = 10000;
    // A browser that takes no bytes of a message for this long is disconnected, so a dead
    // connection does not hold a sender thread forever.
    double stalled_client_timeout_s = 10;
    double status_period_s = 0.25;  // how often the status provider is asked, > 0

    // kInvalidArgument naming the field for values out of range.
    Status validate() const;
};

// Reads "[ADDR:]PORT" as a command line's --view takes it ("8080", "0.0.0.0:8080",
// "127.0.0.1:0") into options->address (left as it is when the text has none) and options->port.
// kInvalidArgument quoting the text when it is not an IPv4 address and a port 0..65535.
Status parseViewAddress(std::string_view text, LiveViewOptions* options);

// One tile's figures.
struct TileStats {
    std::string stream;
    uint64_t frames_in = 0;      // frames the graph handed to the view's edge
    uint64_t encoded = 0;        // JPEGs made (or MJPEG frames passed through)
    uint64_t skipped_rate = 0;   // frames replaced on the edge before their turn (rate limit)
    uint64_t encode_errors = 0;  // frames that could not be converted or encoded
    double fps = 0;              // JPEGs per second over the last second or so
};

// One browser connection's figures.
struct ClientStats {
    uint64_t id = 0;
    std::string remote;            // "127.0.0.1:54321"
    uint64_t frames_sent = 0;      // image messages written to the socket
    uint64_t frames_skipped = 0;   // image messages replaced by a newer one before sending
    uint64_t messages_sent = 0;    // every message, images included
    size_t queued_bytes = 0;       // bytes waiting in its mailbox plus the one being written
    size_t queued_bytes_high = 0;  // most ever
    bool stalled = false;          // a write has been in progress for over a second
};

// What a LiveView has done; plain value.
struct LiveViewStats {
    std::vector<TileStats> tiles;
    std::vector<ClientStats> clients;  // connected now
    uint64_t clients_ever = 0;
    uint64_t clients_refused = 0;  // over max_clients or max_requests (HTTP 503)
    uint64_t clients_dropped = 0;  // disconnected for stalling or a failed write
    // Requests refused before they were served: no or a wrong token (401, 403), a Host or
    // Origin of another site (403); and the rest (a method, path or header count the view
    // does not serve: 404, 405, 431, 400).
    uint64_t requests_unauthorized = 0;
    uint64_t requests_refused = 0;
    uint64_t messages_refused = 0;  // WebSocket messages that ended their connection
    // The most bytes any client's mailbox can ever hold: one message per tile (its largest
    // possible JPEG), one overlay per tile and one status at their size limits, and the tile
    // list. ClientStats::queued_bytes never exceeds it.
    size_t queue_bound_bytes = 0;
};

// Largest overlay or status JSON accepted, in bytes.
inline constexpr size_t kMaxJsonBytes = 256 * 1024;

// A graph sink that shows streams in the browser. connect() subscribes to the tile streams over
// live edges of capacity 1 (the newest frame wins; the pipeline never waits for the view);
// start() binds the HTTP server and starts the view's thread, which encodes at most
// max_tile_fps JPEGs per tile and hands each to every browser's one-slot-per-tile mailbox; each
// browser has its own sender thread, so a slow or stalled browser gets fewer frames, never more
// memory, and never slows the pipeline or the other browsers. The page is embedded in the
// binary and sends nothing the server reads. Every request passes one gate (a token where
// required, the Host and Origin, the header count, the number of clients; docs/live-view.md).
// Thread-safety: create/connect/start/stop by the graph's owner; setOverlay, setStatusProvider
// (before start), port, url and stats from any thread.
class LiveView : public Node {
public:
    // kInvalidArgument from options.validate().
    static Result<std::unique_ptr<LiveView>> create(LiveViewOptions options);
    ~LiveView() override;
    LiveView(const LiveView&) = delete;
    LiveView& operator=(const LiveView&) = delete;

    std::string name() const override { return "liveview"; }
    // Subscribes to the tile streams. kNotFound for a named stream the graph lacks,
    // kInvalidArgument for a named stream that is not an image; an empty list with no image
    // stream in the graph is allowed (the page then shows figures only).
    Status connect(Graph& graph) override;
    // Binds address:port. kUnavailable naming address:port when it is taken or cannot be bound.
    Status start() override;
    // Disconnects every browser and joins every thread; returns promptly even when a browser
    // has stalled. Idempotent.
    void stop() override;

    // Called on the view's thread (the one that encodes, so it must return quickly) every
    // status_period_s: a JSON object with the pipeline's
    // figures (docs/live-view.md has the schema), sent to every browser. Set before start().
    // A reply that is not a JSON object (or over kMaxJsonBytes) is shown as a message instead.
    void setStatusProvider(std::function<std::string()> provider);

    // The latest overlay for the tile of `stream` (JSON, image pixel coordinates; schema in
    // docs/live-view.md), drawn over its image by the page. Cheap; callable from any thread at
    // any rate: only the newest overlay per tile is kept and sent. kNotFound when `stream` is
    // not a tile; kInvalidArgument when the text is not a JSON object or over kMaxJsonBytes.
    Status setOverlay(std::string_view stream, std::string overlay_json);

    int port() const;  // the bound port; 0 before start()
    // A URL that opens the view from this machine, token included ("http://127.0.0.1:8080/",
    // "http://10.0.0.5:8080/?token=..."; 127.0.0.1 when bound to 0.0.0.0); empty before start().
    std::string url() const;
    // Every URL the view is served at, token included: the bound address's, or for 0.0.0.0 one
    // per IPv4 address of this host's interfaces. Empty before start().
    std::vector<std::string> urls() const;
    // For a command to print on stderr after start(): empty on loopback; else that every camera
    // is served to the network, where, and how it is protected.
    std::string exposureWarning() const;
    std::string token() const;  // the token requests must carry; empty when none
    LiveViewStats stats() const;

private:
    struct Impl;
    explicit LiveView(LiveViewOptions options);
    std::unique_ptr<Impl> impl_;
};

}  // namespace mixray::liveview
