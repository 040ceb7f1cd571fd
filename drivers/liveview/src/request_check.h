// What the live view accepts from a client: an HTTP request (path, token, Host, Origin, header
// count) and a WebSocket message, judged by pure functions the server and the fuzzer both call;
// and what it says about the address it listens on.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace mixray::liveview {

// What the view requires of every request; made from LiveViewOptions at start(). Plain value.
struct RequestPolicy {
    // The secret every request must carry as ?token=...; empty: none is required.
    std::string token;
    // The Host header must name loopback (127.x.x.x, localhost, [::1]; any port, for ssh -L).
    // Set when no token is required: a page on another site whose name resolves to 127.0.0.1
    // (DNS rebinding) then sends its own name as Host and is refused.
    bool loopback_host_only = true;
    int max_headers = 32;  // header lines at most; more: 431
};

struct HttpHeader {
    std::string_view name;
    std::string_view value;
};

// The parts of a request the view reads, as civetweb parsed them. Does not own the text.
struct HttpRequest {
    std::string_view method;
    std::string_view path;   // percent-decoded, dot segments removed (civetweb's local_uri)
    std::string_view query;  // after '?', raw; empty when none
    std::vector<HttpHeader> headers;
};

enum class RequestKind { kPage, kWebSocket };

struct RequestVerdict {
    int status = 0;  // 0: serve it; else the HTTP status to answer with
    RequestKind kind = RequestKind::kPage;
    std::string reason;  // one line for the answer's body; never contains the token
};

// Judges a request: 431 over max_headers; 405 for a method other than GET; 400 for a repeated
// Host or Origin; 404 for a path other than "/", "/index.html" and "/ws"; 403 for a Host that
// does not name loopback when policy.loopback_host_only; for "/ws", 403 when an Origin is given
// that is not http:// + the Host (a page of another site; an absent Origin is a client that is
// not a browser); 401 when a token is required and the query has none, 403 when it is wrong
// (compared in constant time).
RequestVerdict checkRequest(const RequestPolicy& policy, const HttpRequest& request);

// The first value of `name` in a query string ("a=1&token=x"), percent-decoded ('+' is a
// space; a malformed escape is kept as it is); nullopt when absent.
std::optional<std::string> queryParameter(std::string_view query, std::string_view name);

// Whether two strings are equal, in time that depends on the length of `expected` only.
bool constantTimeEquals(std::string_view expected, std::string_view given);

// Whether a Host header ("127.0.0.1:8080", "localhost", "[::1]:80") names this machine's
// loopback interface.
bool isLoopbackHost(std::string_view host);

// Whether an Origin header is the origin of a page served by `host` over http: the same scheme,
// host and port (":80" and no port are the same), compared without case.
bool isSameOrigin(std::string_view origin, std::string_view host);

// Whether a listening address (IPv4 dotted quad) is loopback, 127.0.0.0/8: reachable from
// this machine only.
bool isLoopbackAddress(std::string_view address);

// The warning a command prints on stderr when the view listens on address:port: empty for
// loopback; else that every camera is served to the network, where, and how it is protected.
std::string exposureWarning(std::string_view address, int port);

// Whether `token` may be a view's token: 16..256 characters of A-Z a-z 0-9 - . _ ~ (what a URL
// carries without escaping).
bool isValidToken(std::string_view token);

// A WebSocket message from a browser, judged by its first frame byte (FIN, RSV and opcode, as
// civetweb hands it over) and its payload size. The page sends nothing the view reads: a short
// text message, a ping or a pong is ignored; a close ends the connection; anything else (binary,
// long, fragmented, reserved bits or opcodes) ends it with the close code that says why.
enum class MessageAction { kIgnore, kClose, kRefuse };
struct MessageVerdict {
    MessageAction action = MessageAction::kIgnore;
    uint16_t close_code = 0;  // kRefuse: 1002 protocol error, 1003 unsupported, 1009 too big
    std::string reason;       // kRefuse: why, for the close frame (at most 123 bytes)
};
inline constexpr size_t kMaxClientMessageBytes = 1024;
MessageVerdict checkClientMessage(uint8_t first_byte, size_t size);

}  // namespace mixray::liveview
