// The live view's checks of what a client sends: requests (path, method, headers, Host, Origin,
// token) and WebSocket messages. Pure functions: no server, no state.
#include "request_check.h"

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>

namespace mixray::liveview {
namespace {

char lower(char c) {
    return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
}

bool equalsNoCase(std::string_view a, std::string_view b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(),
                                              [](char x, char y) { return lower(x) == lower(y); });
}

bool startsWithNoCase(std::string_view text, std::string_view prefix) {
    return text.size() >= prefix.size() && equalsNoCase(text.substr(0, prefix.size()), prefix);
}

bool isDigits(std::string_view text) {
    return !text.empty() &&
           std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// A host[:port] as HTTP names it, split; false when it is not one (spaces, control characters,
// user info, a path, an empty or non-numeric port, an unbracketed IPv6 address).
bool splitAuthority(std::string_view authority, std::string_view* name, std::string_view* port) {
    if (authority.empty() || authority.size() > 255)
        return false;
    for (const char c : authority) {
        const auto u = static_cast<unsigned char>(c);
        if (u <= 0x20 || u >= 0x7F || c == '/' || c == '@' || c == '?' || c == '#' || c == '\\')
            return false;
    }
    size_t name_end = 0;
    if (authority[0] == '[') {
        name_end = authority.find(']');
        if (name_end == std::string_view::npos)
            return false;
        ++name_end;
    } else {
        name_end = authority.find(':');
        if (name_end == std::string_view::npos)
            name_end = authority.size();
        else if (authority.find(':', name_end + 1) != std::string_view::npos)
            return false;
    }
    *name = authority.substr(0, name_end);
    *port = std::string_view();
    const std::string_view rest = authority.substr(name_end);
    if (!rest.empty()) {
        if (rest[0] != ':' || rest.size() > 6 || !isDigits(rest.substr(1)))
            return false;
        *port = rest.substr(1);
    }
    return !name->empty();
}

// host[:port] in lower case, with the default port 80 left out; empty when not an authority.
std::string normalAuthority(std::string_view authority) {
    std::string_view name;
    std::string_view port;
    if (!splitAuthority(authority, &name, &port))
        return "";
    std::string out;
    out.reserve(authority.size());
    for (const char c : name)
        out.push_back(lower(c));
    if (!port.empty() && port != "80") {
        out.push_back(':');
        out.append(port);
    }
    return out;
}

int hexValue(char c) {
    if (c >= '0' && c <= '9')
        return c - '0';
    if (c >= 'a' && c <= 'f')
        return c - 'a' + 10;
    if (c >= 'A' && c <= 'F')
        return c - 'A' + 10;
    return -1;
}

std::string percentDecode(std::string_view text) {
    std::string out;
    out.reserve(text.size());
    for (size_t i = 0; i < text.size(); ++i) {
        if (text[i] == '+') {
            out.push_back(' ');
        } else if (text[i] == '%' && i + 2 < text.size() && hexValue(text[i + 1]) >= 0 &&
                   hexValue(text[i + 2]) >= 0) {
            out.push_back(static_cast<char>(hexValue(text[i + 1]) * 16 + hexValue(text[i + 2])));
            i += 2;
        } else {
            out.push_back(text[i]);
        }
    }
    return out;
}

RequestVerdict refuse(int status, std::string reason, RequestKind kind = RequestKind::kPage) {
    return {status, kind, std::move(reason)};
}

MessageVerdict refuseMessage(uint16_t code, std::string reason) {
    return {MessageAction::kRefuse, code, std::move(reason)};
}

}  // namespace

std::optional<std::string> queryParameter(std::string_view query, std::string_view name) {
    while (!query.empty()) {
        const size_t amp = query.find('&');
        const std::string_view pair = query.substr(0, amp);
        query = amp == std::string_view::npos ? std::string_view() : query.substr(amp + 1);
        const size_t eq = pair.find('=');
        if (percentDecode(pair.substr(0, eq)) != name)
            continue;
        return eq == std::string_view::npos ? std::string() : percentDecode(pair.substr(eq + 1));
    }
    return std::nullopt;
}

bool constantTimeEquals(std::string_view expected, std::string_view given) {
    // Every byte of `expected` is compared whatever `given` holds, so the time says nothing about
    // how long a prefix matched.
    unsigned difference = expected.size() == given.size() ? 0u : 1u;
    for (size_t i = 0; i < expected.size(); ++i) {
        const auto g = i < given.size() ? static_cast<unsigned char>(given[i]) : 0u;
        difference |= static_cast<unsigned char>(expected[i]) ^ g;
    }
    return difference == 0;
}

bool isLoopbackAddress(std::string_view address) {
    if (address.size() > 15 || address.find_first_not_of("0123456789.") != std::string_view::npos)
        return false;
    in_addr parsed{};
    const std::string text(address);
    return inet_pton(AF_INET, text.c_str(), &parsed) == 1 && (ntohl(parsed.s_addr) >> 24) == 127;
}

std::string exposureWarning(std::string_view address, int port) {
    if (isLoopbackAddress(address))
        return "";
    const std::string where = std::string(address) + ":" + std::to_string(port);
    return "warning: the live view serves every camera to the network on " +
           (address == "0.0.0.0" ? "every interface of this host (" + where + ")" : where) +
           ", over plain HTTP: anyone who can reach the port and has the token in its URL sees "
           "every camera, and the token crosses the network unencrypted. Prefer the default "
           "loopback and ssh -L (docs/live-view.md, Security).";
}

bool isLoopbackHost(std::string_view host) {
    std::string_view name;
    std::string_view port;
    if (!splitAuthority(host, &name, &port))
        return false;
    if (equalsNoCase(name, "localhost") || equalsNoCase(name, "localhost.") || name == "[::1]")
        return true;
    // 127.0.0.0/8, as a dotted quad only (inet_pton reads no octal or short forms).
    return isLoopbackAddress(name);
}

bool isSameOrigin(std::string_view origin, std::string_view host) {
    constexpr std::string_view kScheme = "http://";
    if (!startsWithNoCase(origin, kScheme))
        return false;
    const std::string from = normalAuthority(origin.substr(kScheme.size()));
    return !from.empty() && from == normalAuthority(host);
}

bool isValidToken(std::string_view token) {
    return token.size() >= 16 && token.size() <= 256 &&
           std::all_of(token.begin(), token.end(), [](char c) {
               return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '-' || c == '.' ||
                      c == '_' || c == '~';
           });
}

RequestVerdict checkRequest(const RequestPolicy& policy, const HttpRequest& request) {
    if (request.headers.size() > static_cast<size_t>(policy.max_headers)) {
        return refuse(431, "too many header lines (" + std::to_string(request.headers.size()) +
                               ", at most " + std::to_string(policy.max_headers) + ")");
    }
    if (request.method != "GET")
        return refuse(405, "only GET is served");
    const HttpHeader* host = nullptr;
    const HttpHeader* origin = nullptr;
    for (const HttpHeader& h : request.headers) {
        for (auto [name, seen] : {std::pair{"Host", &host}, std::pair{"Origin", &origin}}) {
            if (!equalsNoCase(h.name, name))
                continue;
            if (*seen != nullptr)
                return refuse(400, std::string("more than one ") + name + " header");
            *seen = &h;
        }
    }
    RequestKind kind = RequestKind::kPage;
    if (request.path == "/ws")
        kind = RequestKind::kWebSocket;
    else if (request.path != "/" && request.path != "/index.html")
        return refuse(404, "only / and /ws are served");
    if (policy.loopback_host_only && host != nullptr && !isLoopbackHost(host->value)) {
        return refuse(403,
                      "the Host header does not name this machine's loopback (127.0.0.1, "
                      "localhost): the view serves loopback only",
                      kind);
    }
    if (kind == RequestKind::kWebSocket && origin != nullptr &&
        (host == nullptr || !isSameOrigin(origin->value, host->value))) {
        return refuse(403, "a WebSocket from a page of another origin than this view's", kind);
    }
    if (!policy.token.empty()) {
        const std::optional<std::string> token = queryParameter(request.query, "token");
        if (!token) {
            return refuse(401,
                          "this view needs its token: open the URL it printed, which ends in "
                          "/?token=...",
                          kind);
        }
        if (!constantTimeEquals(policy.token, *token))
            return refuse(403, "wrong token", kind);
    }
    return {0, kind, ""};
}

MessageVerdict checkClientMessage(uint8_t first_byte, size_t size) {
    const bool fin = (first_byte & 0x80) != 0;
    const int opcode = first_byte & 0x0F;
    if ((first_byte & 0x70) != 0)
        return refuseMessage(1002, "reserved bits set (no extension was agreed)");
    switch (opcode) {
        case 0x8:
            return {MessageAction::kClose, 0, ""};
        case 0x9:
        case 0xA:
            if (!fin || size > 125)
                return refuseMessage(1002, "a control frame fragmented or over 125 bytes");
            return {};
        case 0x1:
            if (size > kMaxClientMessageBytes) {
                return refuseMessage(
                    1009, "a message over " + std::to_string(kMaxClientMessageBytes) + " bytes");
            }
            if (!fin)
                return refuseMessage(1003, "fragmented messages are not taken");
            return {};
        case 0x2:
            return refuseMessage(1003, "binary messages are not taken");
        case 0x0:
            return refuseMessage(1002, "a continuation frame without a message");
        default:
            return refuseMessage(1002, "reserved opcode " + std::to_string(opcode));
    }
}

}  // namespace mixray::liveview
