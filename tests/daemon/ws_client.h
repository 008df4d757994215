// A synchronous Beast WebSocket client with a receive timeout, for the tests only.
#pragma once

#include <sys/socket.h>
#include <sys/time.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace refract::test {

class WsClient {
public:
    // A read that waits longer than `receive_timeout_s` throws.
    WsClient(uint16_t port, const std::string& target, long receive_timeout_s = 60) {
        namespace net = boost::asio;
        net::ip::tcp::endpoint endpoint(net::ip::make_address("127.0.0.1"), port);
        ws_.next_layer().connect(endpoint);
        timeval timeout{receive_timeout_s, 0};
        ::setsockopt(ws_.next_layer().native_handle(), SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
        ws_.handshake("127.0.0.1:" + std::to_string(port), target);
    }
    void send(const nlohmann::json& message) { send_raw(message.dump()); }
    // A text message as given, valid UTF-8 or not.
    void send_raw(const std::string& text) {
        ws_.text(true);
        ws_.write(boost::asio::buffer(text));
    }
    // (is_text, payload): the next message but the notices about other viewers ("viewers", "edited"),
    // which are kept in notices().
    std::pair<bool, std::string> read() {
        for (;;) {
            auto [text, payload] = read_any();
            if (text) {
                nlohmann::json message = nlohmann::json::parse(payload, nullptr, false);
                if (message.is_object() && (message["type"] == "viewers" || message["type"] == "edited")) {
                    notices_.push_back(std::move(message));
                    continue;
                }
            }
            return {text, std::move(payload)};
        }
    }
    // The next message, whatever it is.
    std::pair<bool, std::string> read_any() {
        boost::beast::flat_buffer buffer;
        ws_.read(buffer);
        return {ws_.got_text(), boost::beast::buffers_to_string(buffer.data())};
    }
    // The notices read() has passed over so far, oldest first.
    const std::vector<nlohmann::json>& notices() const { return notices_; }
    // The next frame: its header and PNG; error messages on the way are collected.
    std::pair<nlohmann::json, std::string> read_frame(std::vector<nlohmann::json>* errors = nullptr) {
        for (;;) {
            auto [text, payload] = read();
            if (!text) throw std::runtime_error("binary message without a header");
            nlohmann::json header = nlohmann::json::parse(payload);
            if (header["type"] == "error") {
                if (errors) errors->push_back(header);
                continue;
            }
            auto [png_is_text, png] = read();
            if (png_is_text) throw std::runtime_error("frame header not followed by the PNG");
            return {header, png};
        }
    }

private:
    boost::asio::io_context ioc_;
    boost::beast::websocket::stream<boost::asio::ip::tcp::socket> ws_{ioc_};
    std::vector<nlohmann::json> notices_;
};

}  // namespace refract::test
