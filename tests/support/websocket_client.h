// A minimal WebSocket client for the tests of the live view: the handshake, then server frames
// (unmasked) one by one. A client that never calls next() is a browser that stalled.
// Thread-bound.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <thread>

namespace mixray::test {

// What a handshake asks for beyond the defaults.
struct WsRequest {
    std::string path = "/ws";  // with its query ("/ws?token=...")
    std::string host;          // the Host header; empty: 127.0.0.1:PORT
    std::string headers;       // more header lines, each ending in \r\n ("Origin: ...\r\n")
};

class WsClient {
public:
    // Connects and completes the handshake; receive_buffer > 0 shrinks the socket's buffer.
    // False when the answer is not 101; status() says what it was.
    bool open(int port, int receive_buffer = 0, const WsRequest& ask = {}) {
        fd_ = socket(AF_INET, SOCK_STREAM, 0);
        if (receive_buffer > 0) {
            setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer, sizeof(receive_buffer));
        }
        sockaddr_in addr{};
        addr.sin_family = AF_INET;
        addr.sin_port = htons(static_cast<uint16_t>(port));
        addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        if (connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0)
            return false;
        const std::string host = ask.host.empty() ? "127.0.0.1:" + std::to_string(port) : ask.host;
        const std::string request = "GET " + ask.path + " HTTP/1.1\r\nHost: " + host +
                                    "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                                    "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                                    "Sec-WebSocket-Version: 13\r\n" +
                                    ask.headers + "\r\n";
        if (send(fd_, request.data(), request.size(), MSG_NOSIGNAL) !=
            static_cast<ssize_t>(request.size())) {
            return false;
        }
        std::string response;
        while (response.find("\r\n\r\n") == std::string::npos) {
            char c;
            if (!readExact(&c, 1, 5000))
                return false;
            response.push_back(c);
        }
        status_ = response.size() > 12 && response.rfind("HTTP/1.", 0) == 0
                      ? std::atoi(response.c_str() + 9)
                      : 0;
        return status_ == 101;
    }
    int status() const { return status_; }  // the handshake's answer; 0: none
    // Writes raw bytes (a frame the test makes); false when the socket refused them.
    bool sendRaw(const std::string& bytes) {
        return send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL) ==
               static_cast<ssize_t>(bytes.size());
    }
    ~WsClient() {
        if (fd_ >= 0)
            close(fd_);
    }

    struct Message {
        int opcode = 0;
        std::string payload;
    };
    std::optional<Message> next(int timeout_ms = 3000) {
        uint8_t h[2];
        if (!readExact(h, 2, timeout_ms))
            return std::nullopt;
        uint64_t len = h[1] & 0x7F;
        if (len == 126) {
            uint8_t e[2];
            if (!readExact(e, 2, timeout_ms))
                return std::nullopt;
            len = (e[0] << 8) | e[1];
        } else if (len == 127) {
            uint8_t e[8];
            if (!readExact(e, 8, timeout_ms))
                return std::nullopt;
            len = 0;
            for (uint8_t b : e)
                len = (len << 8) | b;
        }
        Message m;
        m.opcode = h[0] & 0x0F;
        m.payload.resize(len);
        if (len > 0 && !readExact(m.payload.data(), len, timeout_ms))
            return std::nullopt;
        return m;
    }

private:
    bool readExact(void* out, size_t n, int timeout_ms) {
        auto* p = static_cast<char*>(out);
        while (n > 0) {
            pollfd pfd{fd_, POLLIN, 0};
            if (poll(&pfd, 1, timeout_ms) <= 0)
                return false;
            const ssize_t got = recv(fd_, p, n, 0);
            if (got <= 0)
                return false;
            p += got;
            n -= static_cast<size_t>(got);
        }
        return true;
    }
    int fd_ = -1;
    int status_ = 0;
};

// Reads a client's messages on a thread of its own, counting the binary (image) ones, until
// stop() or destruction: a failed assertion between start and stop leaves no thread running.
class ImageMessageCounter {
public:
    explicit ImageMessageCounter(WsClient& client)
        : thread_([this, &client] {
              while (!done_) {
                  auto m = client.next(1000);
                  if (m && m->opcode == 2)
                      ++count_;
              }
          }) {}
    ~ImageMessageCounter() { stop(); }
    ImageMessageCounter(const ImageMessageCounter&) = delete;
    ImageMessageCounter& operator=(const ImageMessageCounter&) = delete;

    int count() const { return count_.load(); }
    void stop() {
        done_ = true;
        if (thread_.joinable())
            thread_.join();
    }

private:
    std::atomic<bool> done_{false};
    std::atomic<int> count_{0};
    std::thread thread_;  // last: it starts once the counters exist
};

}  // namespace mixray::test
