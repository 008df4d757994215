// A WebSocket upgrade that HttpServer read on the HTTP port, handed with its connection to WsServer.
// Included only by the translation units that include Boost.Beast anyway.
#pragma once

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/http/message.hpp>
#include <boost/beast/http/string_body.hpp>

#include "http/http_server.h"

namespace refract::http {

struct UpgradeRequest {
    boost::asio::ip::tcp::socket socket;  // on the HTTP server's I/O context
    boost::beast::http::request<boost::beast::http::string_body> request;
};

}  // namespace refract::http
