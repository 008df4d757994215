#include "store/pg_connection.h"

#include <poll.h>

#include <charconv>
#include <cstring>

namespace refract::scene::pg {

namespace {

// SQLSTATE classes libpq reports (PostgreSQL manual, appendix A).
constexpr std::string_view kUniqueViolation = "23505";
// Classes that mean the server, not the statement, failed: 08 connection exception, 57 operator
// intervention (a terminated backend, a shutdown), 53 insufficient resources (too many connections).
constexpr std::string_view kUnavailableClasses[] = {"08", "57", "53"};

std::string trimmed(const char* message) {
    std::string text = message ? message : "";
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    return text;
}

}  // namespace

std::string Result::text(int row, int column) const {
    return std::string(PQgetvalue(result_.get(), row, column),
                       static_cast<size_t>(PQgetlength(result_.get(), row, column)));
}

uint64_t Result::number(int row, int column) const {
    std::string value = text(row, column);
    uint64_t number = 0;
    auto [rest, error] = std::from_chars(value.data(), value.data() + value.size(), number);
    if (error != std::errc() || rest != value.data() + value.size())
        throw StoreError(StoreFailure::broken,
                         "the database returned '" + value + "' where a number was expected");
    return number;
}

std::string Result::bytes(int row, int column) const {
    return text(row, column);  // binary results: the value is the bytes themselves
}

uint64_t Result::affected() const {
    const char* count = PQcmdTuples(result_.get());
    return count && *count ? std::strtoull(count, nullptr, 10) : 0;
}

Connection::Connection(const std::string& url) : conn_(nullptr, PQfinish) {
    // connect_timeout first, so that one given in the URL wins; without it libpq waits for the OS's
    // TCP timeout (minutes) on a host that drops packets.
    const char* keywords[] = {"connect_timeout", "application_name", "dbname", nullptr};
    const char* values[] = {"5", "refractd", url.c_str(), nullptr};
    conn_.reset(PQconnectdbParams(keywords, values, 1));
    if (!conn_) throw StoreError(StoreFailure::unavailable, "cannot connect to PostgreSQL: out of memory");
    if (PQstatus(conn_.get()) != CONNECTION_OK)
        throw StoreError(StoreFailure::unavailable,
                         "scene store unavailable: cannot connect to PostgreSQL (" + describe() +
                             "): " + trimmed(PQerrorMessage(conn_.get())));
    backend_start_ = exec("SELECT backend_start::text FROM pg_stat_activity WHERE pid = pg_backend_pid()", {},
                          "identifying the connection's server process")
                         .text(0, 0);
}

std::string Connection::describe() const {
    const char* db = PQdb(conn_.get());
    const char* host = PQhost(conn_.get());
    const char* port = PQport(conn_.get());
    return std::string("database ") + (db ? db : "?") + " on " + (host ? host : "?") + ":" + (port ? port : "?");
}

bool Connection::still_open() const {
    // An idle connection is sent nothing but a goodbye (the FATAL a terminated server process sends
    // before it closes) or the close itself: anything to read means it is going.
    pollfd fd{PQsocket(conn_.get()), POLLIN, 0};
    return PQstatus(conn_.get()) == CONNECTION_OK && ::poll(&fd, 1, 0) == 0;
}

bool Connection::reusable() const {
    return PQstatus(conn_.get()) == CONNECTION_OK && PQtransactionStatus(conn_.get()) == PQTRANS_IDLE;
}

Result Connection::exec(std::string_view sql, const std::vector<Param>& params, const std::string& doing,
                        bool binary_results) {
    std::string statement(sql);
    std::vector<const char*> values;
    std::vector<int> lengths, formats;
    for (const Param& p : params) {
        values.push_back(p.value.data());
        lengths.push_back(static_cast<int>(p.value.size()));
        formats.push_back(p.binary ? 1 : 0);
    }
    // Text parameters must be NUL-terminated for libpq: keep terminated copies alive for the call.
    std::vector<std::string> terminated;
    terminated.reserve(params.size());
    for (size_t i = 0; i < params.size(); ++i) {
        if (params[i].binary) continue;
        terminated.emplace_back(params[i].value);
        values[i] = terminated.back().c_str();
    }
    Result result(PQexecParams(conn_.get(), statement.c_str(), static_cast<int>(params.size()), nullptr,
                               values.data(), lengths.data(), formats.data(), binary_results ? 1 : 0));
    return checked(std::move(result), doing);
}

void Connection::exec_script(std::string_view sql, const std::string& doing) {
    checked(Result(PQexec(conn_.get(), std::string(sql).c_str())), doing);
}

Result Connection::checked(Result result, const std::string& doing) const {
    ExecStatusType status = PQresultStatus(result.raw());
    if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) return result;
    if (PQstatus(conn_.get()) != CONNECTION_OK)
        throw StoreError(StoreFailure::unavailable,
                         "scene store unavailable while " + doing + ": the connection to PostgreSQL (" +
                             describe() + ") was lost: " + trimmed(PQerrorMessage(conn_.get())));
    const char* state = PQresultErrorField(result.raw(), PG_DIAG_SQLSTATE);
    std::string why = trimmed(PQresultErrorMessage(result.raw()));
    if (state && kUniqueViolation == state) throw StoreError(StoreFailure::taken, doing + ": " + why);
    for (std::string_view unavailable : kUnavailableClasses)
        if (state && std::string_view(state).substr(0, 2) == unavailable)
            throw StoreError(StoreFailure::unavailable, "scene store unavailable while " + doing +
                                                            ": PostgreSQL (" + describe() + "): " + why);
    throw StoreError(StoreFailure::broken, "PostgreSQL refused " + doing + ": " + why);
}

Pool::Pool(std::string url, size_t max_size) : url_(std::move(url)), max_size_(max_size) {}

Pool::Lease::~Lease() {
    std::lock_guard lock(pool_.mutex_);
    if (connection_->reusable()) {
        pool_.idle_.push_back(std::move(connection_));
    } else {
        --pool_.open_;
        if (PQstatus(connection_->raw()) != CONNECTION_OK) {
            // The server went away: the idle connections went with it. Dropping them now spares the
            // next requests a 503 each once it is back.
            pool_.open_ -= pool_.idle_.size();
            pool_.idle_.clear();
        }
    }
    pool_.returned_.notify_all();
}

Pool::Lease Pool::acquire() {
    std::unique_lock lock(mutex_);
    if (!returned_.wait_for(lock, std::chrono::seconds(10), [&] { return !idle_.empty() || open_ < max_size_; }))
        throw StoreError(StoreFailure::unavailable, "scene store busy: all " + std::to_string(max_size_) +
                                                        " PostgreSQL connections in use for 10 s");
    while (!idle_.empty()) {
        std::unique_ptr<Connection> connection = std::move(idle_.back());
        idle_.pop_back();
        if (connection->still_open()) return Lease(*this, std::move(connection));
        --open_;
    }
    ++open_;
    lock.unlock();
    try {
        return Lease(*this, std::make_unique<Connection>(url_));
    } catch (...) {
        std::lock_guard relock(mutex_);
        --open_;
        returned_.notify_one();
        throw;
    }
}

}  // namespace refract::scene::pg
