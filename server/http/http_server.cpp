// One of the two translation units that include Boost.Beast (it compiles slowly).
#include "http/http_server.h"

#include <sys/socket.h>

#include <array>
#include <cerrno>
#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket/rfc6455.hpp>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <regex>
#include <stdexcept>
#include <thread>

#include "http/upgrade.h"

namespace refract::http {

namespace {

namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

int hex_value(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

char lower(char c) {
    return static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
}

// "a=1&b=x%20y" into decoded pairs; a name without '=' has an empty value.
void parse_query(std::string_view query, std::multimap<std::string, std::string>& params) {
    while (!query.empty()) {
        size_t amp = query.find('&');
        std::string_view pair = query.substr(0, amp);
        if (!pair.empty()) {
            size_t eq = pair.find('=');
            std::string_view value = eq == std::string_view::npos ? std::string_view() : pair.substr(eq + 1);
            params.emplace(percent_decode(pair.substr(0, eq), true), percent_decode(value, true));
        }
        if (amp == std::string_view::npos) break;
        query.remove_prefix(amp + 1);
    }
}

// Threads that run route handlers, with a bounded queue of requests waiting for one.
class WorkerPool {
public:
    WorkerPool(unsigned threads, size_t max_pending) : max_pending_(max_pending) {
        for (unsigned i = 0; i < std::max(threads, 1u); ++i) threads_.emplace_back([this] { run(); });
    }
    ~WorkerPool() { stop(); }

    // False when the queue is full or the pool is stopping.
    bool submit(std::function<void()> task) {
        {
            std::lock_guard lock(mutex_);
            if (stopping_ || tasks_.size() >= max_pending_) return false;
            tasks_.push_back(std::move(task));
        }
        wake_.notify_one();
        return true;
    }

    // Runs what is queued, then joins. Idempotent.
    void stop() {
        {
            std::lock_guard lock(mutex_);
            stopping_ = true;
        }
        wake_.notify_all();
        for (auto& thread : threads_)
            if (thread.joinable()) thread.join();
    }

private:
    void run() {
        for (;;) {
            std::unique_lock lock(mutex_);
            wake_.wait(lock, [this] { return stopping_ || !tasks_.empty(); });
            if (tasks_.empty()) return;
            auto task = std::move(tasks_.front());
            tasks_.pop_front();
            lock.unlock();
            task();
        }
    }

    size_t max_pending_;
    std::mutex mutex_;
    std::condition_variable wake_;
    std::deque<std::function<void()>> tasks_;
    bool stopping_ = false;
    std::vector<std::thread> threads_;
};

struct Route {
    std::string method;
    std::regex pattern;
    Handler handler;
};

class Session;

}  // namespace

namespace detail {

struct HttpServerState {
    HttpServerOptions options;
    std::vector<Route> routes;
    std::optional<net::io_context> ioc{std::in_place};
    std::optional<tcp::acceptor> acceptor{std::in_place, *ioc};
    std::optional<net::steady_timer> accept_retry{std::in_place, *ioc};
    WorkerPool pool;
    std::mutex mutex;  // guards `live`
    std::map<Session*, std::weak_ptr<Session>> live;
    std::atomic<bool> stopped{false};

    explicit HttpServerState(HttpServerOptions o)
        : options(std::move(o)), pool(options.workers, options.max_pending) {}
    ~HttpServerState() {
        // Handlers first (they post answers to the I/O context), then the sockets, then the context.
        pool.stop();
        accept_retry.reset();
        acceptor.reset();
        ioc.reset();
    }

    void accept();
};

}  // namespace detail

namespace {

constexpr std::string_view kContinue = "HTTP/1.1 100 Continue\r\n\r\n";

// One client connection: requests read one after another, each answered before the next is read.
class Session : public std::enable_shared_from_this<Session> {
public:
    Session(tcp::socket socket, detail::HttpServerState& server)
        : stream_(std::move(socket)), server_(server) {}
    ~Session() {
        std::lock_guard lock(server_.mutex);
        server_.live.erase(this);
    }

    void start() {
        net::dispatch(stream_.get_executor(), [self = shared_from_this()] { self->read_header(); });
    }

    // Drops the connection (server stop); safe from any thread.
    void close() {
        net::post(stream_.get_executor(), [self = shared_from_this()] {
            beast::error_code ignored;
            self->stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
            self->stream_.close();
        });
    }

private:
    const HttpServerOptions& options() const { return server_.options; }

    void read_header() {
        parser_.emplace();
        parser_->header_limit(static_cast<std::uint32_t>(options().max_header_bytes));
        parser_->body_limit(boost::none);  // checked against --max-body once the header is known
        request_ = {};
        head_ = false;
        // The whole header within the deadline, however slowly its bytes come.
        stream_.expires_after(options().header_timeout);
        bhttp::async_read_header(
            stream_, buffer_, *parser_,
            [self = shared_from_this()](beast::error_code ec, size_t) { self->on_header(ec); });
    }

    void on_header(beast::error_code ec) {
        started_ = Clock::now();
        if (ec) {
            if (ec == bhttp::error::header_limit)
                return refuse(431, "the request header is larger than " +
                                       std::to_string(options().max_header_bytes) + " bytes");
            if (ec.category() == bhttp::make_error_code(bhttp::error::bad_target).category() &&
                ec != bhttp::error::end_of_stream && ec != bhttp::error::partial_message)
                return refuse(400, "bad request: " + ec.message());
            return drop();  // gone, timed out, or reset: nobody to answer
        }
        const auto& header = parser_->get();
        request_.method = std::string(header.method_string());
        request_.target = std::string(header.target());
        std::string_view target = header.target();
        size_t question = target.find('?');
        request_.path = percent_decode(target.substr(0, question), false);
        if (question != std::string_view::npos) parse_query(target.substr(question + 1), request_.params);
        size_t fields = 0;
        for (const auto& field : header) {
            request_.headers.emplace(std::string(field.name_string()), std::string(field.value()));
            ++fields;
        }
        if (fields > options().max_header_fields)
            return refuse(431, "the request has more than " + std::to_string(options().max_header_fields) +
                                   " header fields");
        if (options().on_upgrade && beast::websocket::is_upgrade(header)) {
            // The connection leaves this server: the WebSocket endpoint answers the upgrade itself.
            stream_.expires_never();
            UpgradePtr upgrade(new UpgradeRequest{stream_.release_socket(), parser_->release()},
                               [](UpgradeRequest* gone) { delete gone; });
            return options().on_upgrade(std::move(upgrade));
        }
        if (request_.method == "HEAD") {
            request_.method = "GET";
            head_ = true;
        }
        keep_alive_ = header.keep_alive();

        const auto length = parser_->content_length();
        const bool has_body = parser_->chunked() || (length && *length > 0);
        if (length && *length > options().max_body)
            return refuse(413, "request body is larger than " + std::to_string(options().max_body) +
                                   " bytes (--max-body)");
        route_ = find_route();
        if (!route_) return refuse(404, "not found: " + request_.path);
        if (has_body && options().before_body) {
            Response refused;
            if (!options().before_body(request_, refused)) {
                keep_alive_ = false;
                return write(std::move(refused), true);
            }
        }
        if (!has_body) return run_handler();

        parser_->body_limit(options().max_body);
        const uint64_t expected = length ? *length : options().max_body;
        stream_.expires_after(options().body_grace +
                              std::chrono::seconds(expected / std::max<size_t>(options().min_body_rate, 1)));
        if (beast::iequals(request_.get_header_value("Expect"), "100-continue")) {
            net::async_write(stream_, net::buffer(kContinue.data(), kContinue.size()),
                             [self = shared_from_this()](beast::error_code write_ec, size_t) {
                                 if (write_ec) return self->drop();
                                 self->read_body();
                             });
            return;
        }
        read_body();
    }

    void read_body() {
        bhttp::async_read(stream_, buffer_, *parser_,
                          [self = shared_from_this()](beast::error_code ec, size_t) { self->on_body(ec); });
    }

    void on_body(beast::error_code ec) {
        if (ec == bhttp::error::body_limit)
            return refuse(413, "request body is larger than " + std::to_string(options().max_body) +
                                   " bytes (--max-body)");
        if (ec && ec.category() == bhttp::make_error_code(bhttp::error::bad_target).category() &&
            ec != bhttp::error::partial_message)
            return refuse(400, "bad request body: " + ec.message());
        if (ec) return drop();
        request_.body = std::move(parser_->get().body());
        run_handler();
    }

    const Route* find_route() {
        for (const auto& route : server_.routes) {
            if (route.method != request_.method && route.method != "*") continue;
            std::smatch match;
            if (!std::regex_match(request_.path, match, route.pattern)) continue;
            request_.matches.assign(match.begin(), match.end());
            return &route;
        }
        return nullptr;
    }

    // The handler runs on a worker; its answer comes back to this connection's strand.
    void run_handler() {
        stream_.expires_never();  // a frame may take a while; the handler bounds its own waits
        // Nothing reads the socket while the handler runs: a peek that finds its end (or an error) means
        // the client hung up. Bytes waiting (a pipelined request) mean it is still there.
        request_.client_gone = [fd = stream_.socket().native_handle()] {
            char byte = 0;
            const ssize_t got = ::recv(fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
            return got == 0 || (got < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR);
        };
        auto self = shared_from_this();
        bool queued = server_.pool.submit([self] {
            Response res;
            std::optional<std::string> failure;
            try {
                self->route_->handler(self->request_, res);
            } catch (const std::exception& e) {
                failure = std::string("internal error: ") + e.what();
            } catch (...) {
                failure = "internal error";
            }
            if (failure) {
                res = {};
                res.status = 500;
                res.set_content(self->options().error_body(*failure), "application/json");
            }
            net::post(self->stream_.get_executor(),
                      [self, res = std::move(res)]() mutable { self->write(std::move(res), false); });
        });
        if (!queued) {
            Response busy;
            busy.status = 503;
            busy.set_header("Retry-After", "1");
            busy.set_content(options().error_body("the server is busy; retry shortly"), "application/json");
            write(std::move(busy), false);
        }
    }

    // Answers an error the server finds itself and closes the connection: what follows is not trusted.
    void refuse(int status, const std::string& message) {
        Response res;
        res.status = status;
        res.set_content(options().error_body(message), "application/json");
        keep_alive_ = false;
        write(std::move(res), true);
    }

    void write(Response res, bool unread_body) {
        if (options().on_answer)
            options().on_answer(request_, res.status,
                                std::chrono::duration<double, std::milli>(Clock::now() - started_).count());
        auto message = std::make_shared<bhttp::response<bhttp::string_body>>();
        message->version(11);
        message->result(static_cast<unsigned>(res.status));
        for (auto& [name, value] : res.headers) message->insert(name, value);
        message->keep_alive(keep_alive_);
        const size_t size = res.body.size();
        message->body() = std::move(res.body);
        message->prepare_payload();
        if (head_) {
            message->body().clear();
            message->content_length(size);
        }
        stream_.expires_after(options().body_grace +
                              std::chrono::seconds(size / std::max<size_t>(options().min_body_rate, 1)));
        bhttp::async_write(stream_, *message,
                           [self = shared_from_this(), message, unread_body](beast::error_code ec, size_t) {
                               if (ec) return self->drop();
                               if (unread_body) return self->linger();
                               if (!self->keep_alive_) return self->drop();
                               self->read_header();
                           });
    }

    // After a refusal with a body still coming: stop sending, discard what arrives for a moment (so that
    // the client reads the answer rather than a reset), then close.
    void linger() {
        beast::error_code ignored;
        stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
        stream_.expires_after(std::chrono::seconds(1));
        discard();
    }

    void discard() {
        stream_.async_read_some(net::buffer(discard_),
                                [self = shared_from_this()](beast::error_code ec, size_t) {
                                    if (ec) return self->drop();
                                    self->discard();
                                });
    }

    void drop() {
        beast::error_code ignored;
        stream_.socket().shutdown(tcp::socket::shutdown_both, ignored);
        stream_.close();
    }

    beast::tcp_stream stream_;
    detail::HttpServerState& server_;
    beast::flat_buffer buffer_{64 * 1024};
    std::optional<bhttp::request_parser<bhttp::string_body>> parser_;
    Request request_;
    const Route* route_ = nullptr;
    Clock::time_point started_ = Clock::now();
    bool head_ = false;
    bool keep_alive_ = false;
    std::array<char, 16 * 1024> discard_{};
};

}  // namespace

void detail::HttpServerState::accept() {
    acceptor->async_accept(net::make_strand(*ioc), [this](beast::error_code ec, tcp::socket socket) {
        if (ec) {
            if (ec == net::error::operation_aborted || !acceptor->is_open()) return;
            // Out of descriptors (or another passing failure): wait a little rather than spin.
            accept_retry->expires_after(std::chrono::milliseconds(50));
            accept_retry->async_wait([this](beast::error_code wait_ec) {
                if (!wait_ec) accept();
            });
            return;
        }
        beast::error_code ignored;
        socket.set_option(tcp::no_delay(true), ignored);  // small answers go out at once
        std::shared_ptr<Session> session;
        {
            std::lock_guard lock(mutex);
            if (live.size() < options.max_connections) {
                session = std::make_shared<Session>(std::move(socket), *this);
                live.emplace(session.get(), session);
            }
        }
        if (session) session->start();  // else the socket closes here, unanswered
        accept();
    });
}

bool FieldLess::operator()(std::string_view a, std::string_view b) const {
    return std::lexicographical_compare(a.begin(), a.end(), b.begin(), b.end(),
                                        [](char x, char y) { return lower(x) < lower(y); });
}

std::string Request::get_header_value(const std::string& name) const {
    auto it = headers.find(name);
    return it == headers.end() ? std::string() : it->second;
}

std::string Request::get_param_value(const std::string& name) const {
    auto it = params.find(name);
    return it == params.end() ? std::string() : it->second;
}

void Response::set_header(const std::string& name, const std::string& value) {
    headers.emplace_back(name, value);
}

void Response::set_content(std::string content, const std::string& content_type) {
    body = std::move(content);
    set_header("Content-Type", content_type);
}

void Response::set_content(const char* data, size_t size, const std::string& content_type) {
    set_content(std::string(data, size), content_type);
}

std::string percent_decode(std::string_view text, bool plus_is_space) {
    std::string out;
    out.reserve(text.size());
    for (size_t i = 0; i < text.size(); ++i) {
        if (text[i] == '%' && i + 2 < text.size() && hex_value(text[i + 1]) >= 0 &&
            hex_value(text[i + 2]) >= 0) {
            out += static_cast<char>(hex_value(text[i + 1]) * 16 + hex_value(text[i + 2]));
            i += 2;
        } else {
            out += plus_is_space && text[i] == '+' ? ' ' : text[i];
        }
    }
    return out;
}

HttpServer::HttpServer(HttpServerOptions options)
    : state_(std::make_unique<detail::HttpServerState>(std::move(options))) {}

HttpServer::~HttpServer() = default;

void HttpServer::route(const std::string& method, const std::string& pattern, Handler handler) {
    state_->routes.push_back({method, std::regex(pattern), std::move(handler)});
}

void HttpServer::bind() {
    const HttpServerOptions& o = state_->options;
    const std::string where = o.bind + ":" + std::to_string(o.port);
    beast::error_code ec;
    auto address = net::ip::make_address(o.bind, ec);
    if (ec) throw std::runtime_error("cannot parse --bind address '" + o.bind + "'");
    tcp::endpoint endpoint(address, o.port);
    tcp::acceptor& acceptor = *state_->acceptor;
    acceptor.open(endpoint.protocol(), ec);
    // SO_REUSEADDR lets a restart reuse a port in TIME_WAIT; a daemon still listening there keeps it.
    if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) acceptor.bind(endpoint, ec);
    if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
    if (ec) throw std::runtime_error("cannot listen on " + where + ": " + ec.message());
}

void HttpServer::serve() {
    detail::HttpServerState& s = *state_;
    if (!s.stopped) {
        s.accept();
        std::vector<std::thread> threads;
        for (unsigned i = 1; i < std::max(s.options.io_threads, 1u); ++i)
            threads.emplace_back([&s] { s.ioc->run(); });
        s.ioc->run();
        for (auto& thread : threads) thread.join();
    }
    s.pool.stop();
}

void HttpServer::stop() {
    detail::HttpServerState& s = *state_;
    if (s.stopped.exchange(true)) return;
    net::post(*s.ioc, [&s] {
        beast::error_code ignored;
        s.acceptor->close(ignored);
        std::vector<std::shared_ptr<Session>> open;
        {
            std::lock_guard lock(s.mutex);
            for (auto& [raw, ref] : s.live)
                if (auto session = ref.lock()) open.push_back(std::move(session));
        }
        for (auto& session : open) session->close();
        s.ioc->stop();
    });
}

}  // namespace refract::http
