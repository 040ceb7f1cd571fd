// libFuzzer target for what a client sends the live view (request_check.h): the first byte picks
// an HTTP request head (even: loopback without a token; bit 1 set: a token is required) or a
// WebSocket message (odd: the next byte is its first frame byte, the rest its payload). Any input
// gives a verdict with a status the view answers with, never one that lets a request in without
// the token, from another Host on loopback or another site's Origin, and never a reason that
// contains the token.
#include <algorithm>
#include <cctype>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "request_check.h"

namespace {

using namespace mixray::liveview;

const std::string kToken = "0123456789abcdef0123456789abcdef";

[[noreturn]] void broken(const char* what, std::string_view detail) {
    std::fprintf(stderr, "liveview_request_fuzz: %s: %.*s\n", what, static_cast<int>(detail.size()),
                 detail.data());
    std::abort();
}

std::string_view nextLine(std::string_view* text) {
    const size_t end = text->find('\n');
    std::string_view line = text->substr(0, end);
    *text = end == std::string_view::npos ? std::string_view() : text->substr(end + 1);
    if (!line.empty() && line.back() == '\r')
        line.remove_suffix(1);
    return line;
}

// "METHOD TARGET VERSION" and "Name: value" lines up to an empty one, roughly as civetweb reads
// them (the path is not decoded here: the checks must hold for any path).
HttpRequest parseHead(std::string_view text) {
    HttpRequest request;
    std::string_view line = nextLine(&text);
    const size_t space = line.find(' ');
    request.method = line.substr(0, space);
    if (space != std::string_view::npos) {
        std::string_view target = line.substr(space + 1);
        target = target.substr(0, target.find(' '));
        const size_t question = target.find('?');
        request.path = target.substr(0, question);
        if (question != std::string_view::npos)
            request.query = target.substr(question + 1);
    }
    while (!text.empty()) {
        line = nextLine(&text);
        if (line.empty())
            break;
        const size_t colon = line.find(':');
        std::string_view value =
            colon == std::string_view::npos ? std::string_view() : line.substr(colon + 1);
        while (!value.empty() && (value.front() == ' ' || value.front() == '\t'))
            value.remove_prefix(1);
        request.headers.push_back({line.substr(0, colon), value});
    }
    return request;
}

std::string_view header(const HttpRequest& request, std::string_view name) {
    for (const HttpHeader& h : request.headers) {
        if (h.name.size() == name.size() &&
            std::equal(h.name.begin(), h.name.end(), name.begin(), [](char a, char b) {
                return std::tolower(static_cast<unsigned char>(a)) ==
                       std::tolower(static_cast<unsigned char>(b));
            })) {
            return h.value;
        }
    }
    return {};
}

void checkHead(uint8_t selector, std::string_view text) {
    RequestPolicy policy;
    if (selector & 2) {
        policy.token = kToken;
        policy.loopback_host_only = false;
    }
    const HttpRequest request = parseHead(text);
    const RequestVerdict verdict = checkRequest(policy, request);
    switch (verdict.status) {
        case 0:
        case 400:
        case 401:
        case 403:
        case 404:
        case 405:
        case 431:
            break;
        default:
            broken("a status the view does not answer with", std::to_string(verdict.status));
    }
    if (verdict.reason.find(kToken) != std::string::npos)
        broken("the reason gives the token away", verdict.reason);
    if (verdict.status != 0)
        return;
    if (!policy.token.empty() && queryParameter(request.query, "token") != kToken)
        broken("let in without the token", request.query);
    const std::string_view host = header(request, "Host");
    if (policy.loopback_host_only && !host.empty() && !isLoopbackHost(host))
        broken("let in from a Host that is not loopback", host);
    const std::string_view origin = header(request, "Origin");
    if (verdict.kind == RequestKind::kWebSocket && !origin.empty() && !isSameOrigin(origin, host))
        broken("a WebSocket let in from another origin", origin);
    // A page's own origin always matches the Host it was served from.
    if (isLoopbackHost(host) && !isSameOrigin("http://" + std::string(host), host))
        broken("a loopback Host is not its own origin", host);
}

void checkMessage(uint8_t first_byte, size_t size) {
    const MessageVerdict verdict = checkClientMessage(first_byte, size);
    const int opcode = first_byte & 0x0F;
    const bool fin = (first_byte & 0x80) != 0;
    const bool clean = (first_byte & 0x70) == 0;
    if (verdict.reason.size() > 123)
        broken("a close reason over 123 bytes", verdict.reason);
    switch (verdict.action) {
        case MessageAction::kIgnore:
            if (!clean || !fin ||
                !((opcode == 1 && size <= kMaxClientMessageBytes) ||
                  ((opcode == 9 || opcode == 10) && size <= 125))) {
                broken("an ignored message the view should refuse", std::to_string(first_byte));
            }
            break;
        case MessageAction::kClose:
            if (opcode != 8 || !clean)
                broken("closed on a frame that is not a close", std::to_string(first_byte));
            break;
        case MessageAction::kRefuse:
            if (verdict.close_code != 1002 && verdict.close_code != 1003 &&
                verdict.close_code != 1009) {
                broken("a close code outside 1002, 1003, 1009", std::to_string(verdict.close_code));
            }
            break;
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    if (size == 0)
        return 0;
    const std::string_view rest(reinterpret_cast<const char*>(data) + 1, size - 1);
    if ((data[0] & 1) == 0) {
        checkHead(data[0], rest);
    } else if (!rest.empty()) {
        // The payload's size, scaled by the selector's high bits to reach past the limits.
        checkMessage(static_cast<uint8_t>(rest[0]), (rest.size() - 1) << ((data[0] >> 4) & 0xF));
    }
    // The token comparison agrees with ==, whatever the lengths.
    const size_t half = rest.size() / 2;
    if (constantTimeEquals(rest.substr(0, half), rest.substr(half)) !=
        (rest.substr(0, half) == rest.substr(half))) {
        broken("constantTimeEquals disagrees with ==", rest);
    }
    return 0;
}
