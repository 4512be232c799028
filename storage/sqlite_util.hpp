// Thin RAII layer over the SQLite C API for the session store: owned connection and statement
// handles, typed binding, Result<T> instead of return codes, and error texts that say what to do.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "algo/core/result.hpp"

namespace fb::sql {

struct ConnectionCloser {
  void operator()(sqlite3* db) const { sqlite3_close_v2(db); }
};
struct StatementFinalizer {
  void operator()(sqlite3_stmt* s) const { sqlite3_finalize(s); }
};
using Connection = std::unique_ptr<sqlite3, ConnectionCloser>;
using StatementHandle = std::unique_ptr<sqlite3_stmt, StatementFinalizer>;

// Turns an SQLite result code into an actionable message (full disk, corruption, busy, ...).
std::string describe(sqlite3* db, int rc, std::string_view doing);

class Statement {
 public:
  Statement(StatementHandle handle, sqlite3* db) : handle_(std::move(handle)), db_(db) {}

  Statement& bind(int i, std::int64_t v);
  Statement& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
  Statement& bind(int i, double v);
  Statement& bind(int i, std::string_view v);
  Statement& bind(int i, const std::string& v) { return bind(i, std::string_view(v)); }
  Statement& bind(int i, const char* v) { return bind(i, std::string_view(v)); }
  Statement& bind(int i, std::nullopt_t);
  template <class T>
  Statement& bind(int i, const std::optional<T>& v) {
    return v ? bind(i, *v) : bind(i, std::nullopt);
  }
  // Binds parameters 1..N in order.
  template <class... Args>
  Statement& bind_all(const Args&... args) {
    int i = 0;
    (bind(++i, args), ...);
    return *this;
  }

  // Makes the statement runnable again with new bindings.
  void reset() {
    sqlite3_reset(handle_.get());
    sqlite3_clear_bindings(handle_.get());
    bind_error_ = SQLITE_OK;
  }
  // true when a row is available, false when done.
  Result<bool> step();
  // Runs to completion (for statements that return no rows).
  Result<void> run();

  std::int64_t int64(int col) const { return sqlite3_column_int64(handle_.get(), col); }
  int int32(int col) const { return sqlite3_column_int(handle_.get(), col); }
  double real(int col) const { return sqlite3_column_double(handle_.get(), col); }
  bool is_null(int col) const { return sqlite3_column_type(handle_.get(), col) == SQLITE_NULL; }
  std::string text(int col) const;
  std::optional<std::int64_t> optional_int64(int col) const {
    if (is_null(col)) return std::nullopt;
    return int64(col);
  }

 private:
  StatementHandle handle_;
  sqlite3* db_;
  int bind_error_ = SQLITE_OK;
};

Result<Statement> prepare(sqlite3* db, std::string_view sql);
Result<void> exec(sqlite3* db, const std::string& sql);
// A single-value query (PRAGMA or SELECT returning one row, one column) as text.
Result<std::string> query_text(sqlite3* db, const std::string& sql);
Result<std::int64_t> query_int(sqlite3* db, const std::string& sql);

// BEGIN IMMEDIATE on construction; rolls back on destruction unless commit() succeeded.
class Transaction {
 public:
  static Result<Transaction> begin(sqlite3* db);
  Transaction(Transaction&& o) noexcept : db_(o.db_), open_(o.open_) { o.open_ = false; }
  Transaction& operator=(Transaction&&) = delete;
  ~Transaction();
  Result<void> commit();

 private:
  explicit Transaction(sqlite3* db) : db_(db), open_(true) {}
  sqlite3* db_;
  bool open_;
};

}  // namespace fb::sql
