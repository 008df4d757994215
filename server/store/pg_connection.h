// libpq, owned: one connection (RAII), the results it returns, and a bounded pool of connections that
// the shared scene store's request threads borrow. Every failure becomes a StoreError carrying what was
// being done and libpq's reason: unavailable when the database cannot be reached, broken otherwise.
#pragma once

#include <libpq-fe.h>

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "store/store.h"

namespace refract::scene::pg {

// A statement parameter: text, or raw bytes for a bytea column. nullopt-free: every value is given.
struct Param {
    std::string_view value;
    bool binary = false;
};

// One result of a statement; rows and columns as text (bytea columns decoded to their bytes).
class Result {
public:
    explicit Result(PGresult* result) : result_(result, PQclear) {}
    int rows() const { return PQntuples(result_.get()); }
    std::string text(int row, int column) const;
    uint64_t number(int row, int column) const;
    // A bytea column's bytes (the statement must ask for binary results).
    std::string bytes(int row, int column) const;
    // Rows an UPDATE, INSERT or DELETE touched.
    uint64_t affected() const;
    PGresult* raw() const { return result_.get(); }

private:
    std::unique_ptr<PGresult, void (*)(PGresult*)> result_;
};

class Connection {
public:
    // Connects to `url` (a libpq connection string or postgresql:// URI) within a few seconds; throws
    // StoreError(unavailable) naming the server and libpq's reason.
    explicit Connection(const std::string& url);
    Connection(const Connection&) = delete;
    Connection& operator=(const Connection&) = delete;

    // Runs one statement. `binary_results`: bytea columns come back raw (Result::bytes). `doing` says
    // what the statement was for, in the error. Throws StoreError: unavailable when the connection is
    // lost (the statement's outcome is then unknown), taken for a unique violation, broken for anything
    // else.
    Result exec(std::string_view sql, const std::vector<Param>& params, const std::string& doing,
                bool binary_results = false);
    // A statement without parameters (BEGIN, COMMIT).
    Result exec(std::string_view sql, const std::string& doing) { return exec(sql, {}, doing); }
    // Several statements separated by semicolons, none with parameters (a migration).
    void exec_script(std::string_view sql, const std::string& doing);

    // False once the server has gone or a transaction was left open: the pool drops it.
    bool reusable() const;
    // For an idle connection, without waiting: false when the server has sent it anything, which is
    // only ever a goodbye (a restart, a terminated server process); a pool would otherwise learn it
    // only when the next statement fails.
    bool still_open() const;
    PGconn* raw() const { return conn_.get(); }
    // The server process serving this connection and when it started (together they name it even
    // after the process is gone and its pid reused); still known after the connection is lost.
    int backend_pid() const { return PQbackendPID(conn_.get()); }
    const std::string& backend_start() const { return backend_start_; }
    // "database refract on 127.0.0.1:5432", never the password.
    std::string describe() const;

private:
    // `result` when it succeeded, else the StoreError its failure calls for.
    Result checked(Result result, const std::string& doing) const;

    std::unique_ptr<PGconn, void (*)(PGconn*)> conn_;
    std::string backend_start_;
};

// Connections for the request threads: at most `max_size` open, borrowed one per statement sequence.
class Pool {
public:
    Pool(std::string url, size_t max_size);

    // A borrowed connection, returned to the pool when it goes out of scope (dropped if unusable).
    class Lease {
    public:
        Lease(Pool& pool, std::unique_ptr<Connection> connection) : pool_(pool), connection_(std::move(connection)) {}
        ~Lease();
        Lease(const Lease&) = delete;
        Lease& operator=(const Lease&) = delete;
        Connection* operator->() const { return connection_.get(); }
        Connection& operator*() const { return *connection_; }

    private:
        Pool& pool_;
        std::unique_ptr<Connection> connection_;
    };

    // An idle connection that is still open, or a new one; waits while `max_size` are borrowed
    // (StoreError(unavailable) after 10 s).
    Lease acquire();
    const std::string& url() const { return url_; }

private:
    std::string url_;
    size_t max_size_;
    std::mutex mutex_;
    std::condition_variable returned_;
    std::vector<std::unique_ptr<Connection>> idle_;
    size_t open_ = 0;  // idle plus borrowed
};

// Runs `body` in a transaction on `connection`: BEGIN, the body, COMMIT; ROLLBACK when the body throws.
template <typename Body>
auto in_transaction(Connection& connection, const std::string& doing, Body&& body) {
    connection.exec("BEGIN", doing);
    try {
        auto result = body();
        connection.exec("COMMIT", doing + " (commit: if the connection was lost here, the outcome is unknown)");
        return result;
    } catch (...) {
        if (PQstatus(connection.raw()) == CONNECTION_OK) PQclear(PQexec(connection.raw(), "ROLLBACK"));
        throw;
    }
}

}  // namespace refract::scene::pg
