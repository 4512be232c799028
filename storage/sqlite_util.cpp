#include "storage/sqlite_util.hpp"

namespace fb::sql {

std::string describe(sqlite3* db, int rc, std::string_view doing) {
  const std::string detail = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  std::string what = std::string(doing) + ": " + detail;
  switch (rc & 0xff) {
    case SQLITE_FULL:
      return what + " (the disk is full: free space and retry; the last committed state is intact)";
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB:
      return what +
             " (the database file is damaged or not a facebooth store: move it aside and restore "
             "it from a backup; facebooth did not modify it)";
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      return what + " (another process holds the database; retry when it is done)";
    case SQLITE_READONLY:
      return what + " (the store is open read-only or the file is not writable)";
    case SQLITE_IOERR:
      return what + " (an I/O error: check the disk; the last committed state is intact)";
    case SQLITE_CANTOPEN:
      return what + " (check that the folder exists and is writable)";
    default:
      return what;
  }
}

Statement& Statement::bind(int i, std::int64_t v) {
  if (const int rc = sqlite3_bind_int64(handle_.get(), i, v); rc != SQLITE_OK) bind_error_ = rc;
  return *this;
}
Statement& Statement::bind(int i, double v) {
  if (const int rc = sqlite3_bind_double(handle_.get(), i, v); rc != SQLITE_OK) bind_error_ = rc;
  return *this;
}
Statement& Statement::bind(int i, std::string_view v) {
  if (const int rc = sqlite3_bind_text(handle_.get(), i, v.data(), static_cast<int>(v.size()),
                                       SQLITE_TRANSIENT);
      rc != SQLITE_OK) {
    bind_error_ = rc;
  }
  return *this;
}
Statement& Statement::bind(int i, std::nullopt_t) {
  if (const int rc = sqlite3_bind_null(handle_.get(), i); rc != SQLITE_OK) bind_error_ = rc;
  return *this;
}

Result<bool> Statement::step() {
  if (bind_error_ != SQLITE_OK) {
    return fail(describe(db_, bind_error_, "binding a query parameter"));
  }
  const int rc = sqlite3_step(handle_.get());
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  return fail(describe(db_, rc, std::string("running `") + sqlite3_sql(handle_.get()) + "`"));
}

Result<void> Statement::run() {
  for (;;) {
    auto row = step();
    if (!row) return row.failure();
    if (!*row) return success();
  }
}

std::string Statement::text(int col) const {
  const auto* p = sqlite3_column_text(handle_.get(), col);
  if (p == nullptr) return {};
  return std::string(reinterpret_cast<const char*>(p),
                     static_cast<std::size_t>(sqlite3_column_bytes(handle_.get(), col)));
}

Result<Statement> prepare(sqlite3* db, std::string_view sql) {
  sqlite3_stmt* raw = nullptr;
  const int rc = sqlite3_prepare_v2(db, sql.data(), static_cast<int>(sql.size()), &raw, nullptr);
  StatementHandle handle(raw);  // owns it even on failure
  if (rc != SQLITE_OK) return fail(describe(db, rc, "preparing `" + std::string(sql) + "`"));
  return Statement(std::move(handle), db);
}

Result<void> exec(sqlite3* db, const std::string& sql) {
  char* message = nullptr;
  const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &message);
  const std::unique_ptr<char, decltype(&sqlite3_free)> owned(message, &sqlite3_free);
  if (rc != SQLITE_OK) return fail(describe(db, rc, "running `" + sql.substr(0, 60) + "`"));
  return success();
}

Result<std::string> query_text(sqlite3* db, const std::string& sql) {
  auto stmt = prepare(db, sql);
  if (!stmt) return stmt.failure();
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return std::string();
  return stmt->text(0);
}

Result<std::int64_t> query_int(sqlite3* db, const std::string& sql) {
  auto stmt = prepare(db, sql);
  if (!stmt) return stmt.failure();
  auto row = stmt->step();
  if (!row) return row.failure();
  if (!*row) return std::int64_t{0};
  return stmt->int64(0);
}

Result<Transaction> Transaction::begin(sqlite3* db) {
  if (auto r = exec(db, "BEGIN IMMEDIATE"); !r) return r.failure();
  return Transaction(db);
}

Transaction::~Transaction() {
  if (open_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
}

Result<void> Transaction::commit() {
  auto r = exec(db_, "COMMIT");
  if (r) open_ = false;
  return r;
}

}  // namespace fb::sql
