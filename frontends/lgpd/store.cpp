#include "store.hpp"

#include <sqlite3.h>

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>

#include "lgp/config/json_reader.hpp"
#include "lgp/io/terminal_text.hpp"

namespace lgpd {

using lgp::Expected;
using lgp::Status;
using nlohmann::json;

double unixNow() {
  using namespace std::chrono;
  return duration<double>(system_clock::now().time_since_epoch()).count();
}

std::string_view toString(RunStatus s) {
  switch (s) {
    case RunStatus::Queued:
      return "queued";
    case RunStatus::Running:
      return "running";
    case RunStatus::Finished:
      return "finished";
    case RunStatus::Cancelled:
      return "cancelled";
    case RunStatus::Failed:
      return "failed";
  }
  return "unknown";
}

std::optional<RunStatus> runStatusFromString(std::string_view s) {
  for (auto v : {RunStatus::Queued, RunStatus::Running, RunStatus::Finished, RunStatus::Cancelled,
                 RunStatus::Failed})
    if (toString(v) == s) return v;
  return std::nullopt;
}

bool isValidRunId(const std::string& id) {
  if (id.size() != 16) return false;
  for (char c : id)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

namespace {

constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
INSERT OR IGNORE INTO meta(key, value) VALUES ('schema', 'lgpd/1');
CREATE TABLE IF NOT EXISTS runs (
  seq INTEGER PRIMARY KEY AUTOINCREMENT,
  id TEXT NOT NULL UNIQUE,
  name TEXT NOT NULL DEFAULT '',
  status TEXT NOT NULL,
  config TEXT NOT NULL,
  inline_table BLOB,
  created_at REAL NOT NULL,
  started_at REAL NOT NULL DEFAULT 0,
  finished_at REAL NOT NULL DEFAULT 0,
  error TEXT NOT NULL DEFAULT '',
  cancel_requested INTEGER NOT NULL DEFAULT 0,
  resumes INTEGER NOT NULL DEFAULT 0,
  generation INTEGER NOT NULL DEFAULT 0,
  evaluations INTEGER NOT NULL DEFAULT 0,
  elapsed_s REAL NOT NULL DEFAULT 0,
  evals_per_s REAL NOT NULL DEFAULT 0,
  front_size INTEGER NOT NULL DEFAULT 0,
  best_error REAL,
  best TEXT NOT NULL DEFAULT '{}',
  stop_reason TEXT NOT NULL DEFAULT '',
  start_attempts INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS checkpoints (
  run_id TEXT PRIMARY KEY REFERENCES runs(id) ON DELETE CASCADE,
  generation INTEGER NOT NULL,
  created_at REAL NOT NULL,
  state BLOB NOT NULL
);
CREATE TABLE IF NOT EXISTS fronts (
  run_id TEXT PRIMARY KEY REFERENCES runs(id) ON DELETE CASCADE,
  final INTEGER NOT NULL,
  generation INTEGER NOT NULL,
  created_at REAL NOT NULL,
  front BLOB NOT NULL
);
CREATE TABLE IF NOT EXISTS progress (
  run_id TEXT NOT NULL REFERENCES runs(id) ON DELETE CASCADE,
  t REAL NOT NULL,
  generation INTEGER NOT NULL,
  evaluations INTEGER NOT NULL,
  elapsed_s REAL NOT NULL,
  best_error REAL,
  front_size INTEGER NOT NULL,
  event TEXT NOT NULL DEFAULT ''
);
CREATE INDEX IF NOT EXISTS progress_run ON progress(run_id, t);
)sql";

// A prepared statement with positional binds; finalised on scope exit.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) : db_(db) {
    rc_ = sqlite3_prepare_v2(db, sql, -1, &st_, nullptr);
  }
  ~Stmt() { sqlite3_finalize(st_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  bool ok() const { return rc_ == SQLITE_OK; }
  Stmt& bind(int i, const std::string& v) {
    sqlite3_bind_text(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bind(int i, const char* v) { return bind(i, std::string(v)); }
  Stmt& bind(int i, std::string_view v) { return bind(i, std::string(v)); }
  Stmt& bind(int i, int64_t v) {
    sqlite3_bind_int64(st_, i, v);
    return *this;
  }
  Stmt& bind(int i, int v) { return bind(i, static_cast<int64_t>(v)); }
  Stmt& bind(int i, uint64_t v) { return bind(i, static_cast<int64_t>(v)); }
  Stmt& bind(int i, double v) {
    // SQLite stores NaN as NULL; +-inf round-trip as REAL.
    if (std::isnan(v))
      sqlite3_bind_null(st_, i);
    else
      sqlite3_bind_double(st_, i, v);
    return *this;
  }
  Stmt& bindBlob(int i, const std::vector<uint8_t>& v) {
    sqlite3_bind_blob(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bindNull(int i) {
    sqlite3_bind_null(st_, i);
    return *this;
  }
  // SQLITE_ROW, SQLITE_DONE or an error code.
  int step() { return rc_ = sqlite3_step(st_); }
  int rc() const { return rc_; }

  std::string text(int c) const {
    auto* p = sqlite3_column_text(st_, c);
    return p ? std::string(reinterpret_cast<const char*>(p),
                           static_cast<size_t>(sqlite3_column_bytes(st_, c)))
             : std::string();
  }
  int64_t i64(int c) const { return sqlite3_column_int64(st_, c); }
  double real(int c) const {
    return sqlite3_column_type(st_, c) == SQLITE_NULL ? std::numeric_limits<double>::quiet_NaN()
                                                      : sqlite3_column_double(st_, c);
  }
  bool isNull(int c) const { return sqlite3_column_type(st_, c) == SQLITE_NULL; }
  std::vector<uint8_t> blob(int c) const {
    auto* p = static_cast<const uint8_t*>(sqlite3_column_blob(st_, c));
    return p ? std::vector<uint8_t>(p, p + sqlite3_column_bytes(st_, c)) : std::vector<uint8_t>();
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* st_ = nullptr;
  int rc_ = SQLITE_OK;
};

Status sqlError(sqlite3* db, const std::string& what) {
  return Status::error("sqlite: " + what + ": " + sqlite3_errmsg(db));
}

Status exec(sqlite3* db, const char* sql) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql, nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : "unknown error";
    sqlite3_free(err);
    return Status::error(std::string("sqlite: ") + msg);
  }
  return Status::ok();
}

// Runs a prepared statement to completion.
Status run(sqlite3* db, Stmt& st, const char* what) {
  if (!st.ok()) return sqlError(db, std::string("prepare ") + what);
  int rc = st.step();
  if (rc != SQLITE_DONE && rc != SQLITE_ROW) return sqlError(db, what);
  return Status::ok();
}

// BEGIN IMMEDIATE ... COMMIT, rolled back unless commit() succeeds.
class Transaction {
 public:
  explicit Transaction(sqlite3* db) : db_(db) { began_ = exec(db, "BEGIN IMMEDIATE"); }
  ~Transaction() {
    // A failed ROLLBACK leaves nothing to do here: SQLite rolls the transaction back when the
    // statement or the connection ends.
    if (began_ && !done_) (void)exec(db_, "ROLLBACK");
  }
  const Status& began() const { return began_; }
  Status commit() {
    auto s = exec(db_, "COMMIT");
    done_ = s.isOk();
    return s;
  }

 private:
  sqlite3* db_;
  Status began_;
  bool done_ = false;
};

std::vector<uint8_t> toCbor(const json& j) {
  return json::to_cbor(j);
}

// Rows are read with the limits of a request body: a row written by hand (or by a tool gone
// wrong) nested deeper than lgp::JsonLimits::max_depth would overflow the stack when it is
// parsed (CBOR recurses), copied or dumped.
constexpr size_t kMaxRowDepth = lgp::JsonLimits{}.max_depth;

// A first pass over a CBOR blob that only counts nesting, stopping at the limit before the
// reader recurses further; the tree is built by a second pass.
class DepthCheck : public nlohmann::json_sax<json> {
 public:
  bool too_deep = false;
  bool null() override { return true; }
  bool boolean(bool) override { return true; }
  bool number_integer(number_integer_t) override { return true; }
  bool number_unsigned(number_unsigned_t) override { return true; }
  bool number_float(number_float_t, const string_t&) override { return true; }
  bool string(string_t&) override { return true; }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override { return enter(); }
  bool key(string_t&) override { return true; }
  bool end_object() override { return leave(); }
  bool start_array(std::size_t) override { return enter(); }
  bool end_array() override { return leave(); }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    return false;
  }

 private:
  bool enter() {
    too_deep = ++depth_ > kMaxRowDepth;
    return !too_deep;
  }
  bool leave() {
    --depth_;
    return true;
  }
  size_t depth_ = 0;
};

Expected<json> fromCbor(const std::vector<uint8_t>& b, const std::string& what) {
  try {
    DepthCheck depth;
    const bool ok = json::sax_parse(b, &depth, json::input_format_t::cbor);
    if (depth.too_deep)
      return Status::error(what + ": nested deeper than " + std::to_string(kMaxRowDepth) +
                           " levels");
    if (!ok) return Status::error(what + ": corrupt CBOR");
    return json::from_cbor(b);
  } catch (const std::exception& e) {
    return Status::error(what + ": corrupt CBOR: " + e.what());
  }
}

Expected<json> fromText(const std::string& t, const std::string& what) {
  auto j = lgp::parseJson(t);
  if (!j) return Status::error(what + ": corrupt JSON: " + j.error());
  return j;
}

constexpr const char* kRunColumns =
    "id, name, status, config, inline_table, created_at, started_at, finished_at, error, "
    "cancel_requested, resumes, generation, evaluations, elapsed_s, evals_per_s, front_size, "
    "best_error, best, stop_reason, "
    "(SELECT generation FROM checkpoints c WHERE c.run_id = runs.id), "
    "(SELECT created_at FROM checkpoints c WHERE c.run_id = runs.id), start_attempts";

Expected<RunRecord> readRun(const Stmt& st) {
  RunRecord r;
  r.id = st.text(0);
  r.name = st.text(1);
  if (!isValidRunId(r.id))
    return Status::error("a run row with a bad id '" + lgp::terminalSafe(r.id.substr(0, 40)) + "'");
  auto status = runStatusFromString(st.text(2));
  if (!status)
    return Status::error("run " + r.id + ": bad status '" +
                         lgp::terminalSafe(st.text(2).substr(0, 40)) + "'");
  r.status = *status;
  auto cfg = fromText(st.text(3), "run " + r.id + " config");
  if (!cfg) return cfg.status();
  r.config = std::move(*cfg);
  if (!st.isNull(4)) {
    auto t = fromCbor(st.blob(4), "run " + r.id + " inline table");
    if (!t) return t.status();
    r.inline_table = std::move(*t);
  }
  r.created_at = st.real(5);
  r.started_at = st.real(6);
  r.finished_at = st.real(7);
  r.error = st.text(8);
  r.cancel_requested = st.i64(9) != 0;
  r.resumes = static_cast<int>(st.i64(10));
  r.counters.generation = static_cast<int>(st.i64(11));
  r.counters.evaluations = static_cast<uint64_t>(st.i64(12));
  r.counters.elapsed_s = st.real(13);
  r.counters.evals_per_s = st.real(14);
  r.counters.front_size = st.i64(15);
  r.counters.best_error = st.real(16);
  auto best = fromText(st.text(17), "run " + r.id + " best");
  r.counters.best = best ? *best : json::object();
  r.counters.stop_reason = st.text(18);
  r.checkpoint_generation = st.isNull(19) ? -1 : static_cast<int>(st.i64(19));
  r.checkpoint_at = st.isNull(20) ? 0 : st.real(20);
  r.start_attempts = static_cast<int>(st.i64(21));
  return r;
}

Status updateCounters(sqlite3* db, const std::string& id, const RunCounters& c) {
  Stmt st(db,
          "UPDATE runs SET generation = ?2, evaluations = ?3, elapsed_s = ?4, evals_per_s = ?5, "
          "front_size = ?6, best_error = ?7, best = ?8, stop_reason = ?9 WHERE id = ?1");
  st.bind(1, id)
      .bind(2, c.generation)
      .bind(3, c.evaluations)
      .bind(4, c.elapsed_s)
      .bind(5, c.evals_per_s)
      .bind(6, c.front_size)
      .bind(7, c.best_error)
      .bind(8, c.best.dump())
      .bind(9, c.stop_reason);
  return run(db, st, "update counters");
}

Status addHistory(sqlite3* db, const std::string& id, const RunCounters& c,
                  const std::string& event) {
  Stmt st(db,
          "INSERT INTO progress(run_id, t, generation, evaluations, elapsed_s, best_error, "
          "front_size, event) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
  st.bind(1, id)
      .bind(2, unixNow())
      .bind(3, c.generation)
      .bind(4, c.evaluations)
      .bind(5, c.elapsed_s)
      .bind(6, c.best_error)
      .bind(7, c.front_size)
      .bind(8, event);
  return run(db, st, "insert progress");
}

Status upsertFront(sqlite3* db, const std::string& id, const json& front, bool final,
                   int generation) {
  Stmt st(db,
          "INSERT INTO fronts(run_id, final, generation, created_at, front) "
          "VALUES (?1, ?2, ?3, ?4, ?5) ON CONFLICT(run_id) DO UPDATE SET final = excluded.final, "
          "generation = excluded.generation, created_at = excluded.created_at, "
          "front = excluded.front");
  st.bind(1, id).bind(2, final ? 1 : 0).bind(3, generation).bind(4, unixNow());
  st.bindBlob(5, toCbor(front));
  return run(db, st, "upsert front");
}

}  // namespace

// Borrowed connection, returned to the pool on scope exit.
class Store::Lease {
 public:
  explicit Lease(Store& s) : s_(s) {
    auto db = s.acquire();
    if (db)
      db_ = *db;
    else
      status_ = db.status();
  }
  ~Lease() {
    if (db_) s_.release(db_);
  }
  sqlite3* db() const { return db_; }
  const Status& status() const { return status_; }

 private:
  Store& s_;
  sqlite3* db_ = nullptr;
  Status status_;
};

#define LGPD_LEASE(lease) \
  Lease lease(*this);     \
  if (!lease.db()) return lease.status();

namespace {

namespace fs = std::filesystem;

// What is wrong with an existing database file, before SQLite opens (and maybe rewrites) it:
// not a file, empty, unreadable, or without the SQLite header.
Status checkDatabaseFile(const fs::path& p) {
  const std::string name = p.string();
  std::error_code ec;
  const auto st = fs::symlink_status(p, ec);
  if (fs::is_symlink(st)) return checkDatabaseFile(fs::read_symlink(p, ec));
  if (!fs::is_regular_file(st)) return Status::error(name + " is not a regular file");
  if (::access(name.c_str(), R_OK | W_OK) != 0)
    return Status::error(name + " cannot be read and written by lgpd: " + std::strerror(errno));
  const auto size = fs::file_size(p, ec);
  if (ec) return Status::error(name + ": " + ec.message());
  if (size == 0) return Status::error(name + " is empty (0 bytes)");
  std::ifstream f(p, std::ios::binary);
  char head[16] = {0};
  if (!f.read(head, sizeof head) || std::memcmp(head, "SQLite format 3", 16) != 0)
    return Status::error(name + " is not an SQLite database (its header is " +
                         (f ? "wrong" : "cut short") + ": a corrupt or foreign file)");
  return Status::ok();
}

// The database is lgpd's and intact: its meta row and SQLite's quick_check.
Status checkDatabaseContent(sqlite3* db, const fs::path& p) {
  {
    Stmt st(db, "SELECT value FROM meta WHERE key = 'schema'");
    if (!st.ok())
      return Status::error(p.string() + " is not an lgpd database (" + sqlite3_errmsg(db) + ")");
    if (st.step() != SQLITE_ROW)
      return Status::error(p.string() + " is not an lgpd database (no schema entry)");
    if (st.text(0) != "lgpd/1")
      return Status::error(p.string() + " has schema '" + st.text(0) +
                           "', which this lgpd does not read (lgpd/1)");
  }
  Stmt st(db, "PRAGMA quick_check");
  if (!st.ok()) return Status::error(p.string() + " is corrupt: " + sqlite3_errmsg(db));
  std::string problems;
  while (st.step() == SQLITE_ROW) {
    if (st.text(0) == "ok") continue;
    if (!problems.empty()) problems += "; ";
    problems += st.text(0);
    if (problems.size() > 400) break;
  }
  if (st.rc() != SQLITE_DONE && st.rc() != SQLITE_ROW && problems.empty())
    problems = sqlite3_errmsg(db);
  if (!problems.empty()) return Status::error(p.string() + " is corrupt: " + problems);
  return Status::ok();
}

// Columns added after the first release of the schema.
Status migrate(sqlite3* db) {
  bool has_attempts = false;
  Stmt st(db, "PRAGMA table_info(runs)");
  if (!st.ok()) return sqlError(db, "table_info");
  while (st.step() == SQLITE_ROW)
    if (st.text(1) == "start_attempts") has_attempts = true;
  if (!has_attempts)
    return exec(db, "ALTER TABLE runs ADD COLUMN start_attempts INTEGER NOT NULL DEFAULT 0");
  return Status::ok();
}

// Moves a bad database (and its -wal/-shm) aside as <name>.broken-<unix time>.
Expected<fs::path> moveAside(const fs::path& p) {
  const std::string suffix = ".broken-" + std::to_string(static_cast<int64_t>(unixNow()));
  fs::path to = p;
  to += suffix;
  std::error_code ec;
  fs::rename(p, to, ec);
  if (ec) return Status::error("cannot move " + p.string() + " aside: " + ec.message());
  for (const char* side : {"-wal", "-shm"}) {
    fs::path from = p, dest = to;
    from += side;
    dest += side;
    if (fs::exists(from, ec)) fs::rename(from, dest, ec);
  }
  return to;
}

}  // namespace

Expected<std::unique_ptr<Store>> Store::open(const fs::path& dir, bool init) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Status::error("cannot create data dir " + dir.string() + ": " + ec.message());
  const fs::path path = dir / "lgpd.sqlite3";
  const std::string hint =
      "; start lgpd with --init to keep it aside and begin with an empty "
      "database";
  bool fresh = false;
  if (!fs::exists(fs::symlink_status(path, ec))) {
    // A data dir that lgpd has used (it holds tables/ or mpi/) lost its database: every run
    // would vanish without a word.
    if (!init && (fs::exists(dir / "tables", ec) || fs::exists(dir / "mpi", ec)))
      return Status::error("the data dir " + dir.string() + " has been used by lgpd but " +
                           path.string() + " is missing" + hint);
    fresh = true;
  } else if (auto bad = checkDatabaseFile(path); !bad) {
    if (!init) return Status::error(bad.message() + hint);
    auto moved = moveAside(path);
    if (!moved) return moved.status();
    spdlog::warn("{}; kept as {}, starting with an empty database", bad.message(), moved->string());
    fresh = true;
  }
  std::unique_ptr<Store> s(new Store(path));
  auto db = s->acquire();
  if (!db) return Status::error(db.error() + (fresh ? "" : hint));
  Status st = fresh ? Status::ok() : checkDatabaseContent(*db, path);
  if (!st && init) {
    s->release(*db);
    s.reset();
    auto moved = moveAside(path);
    if (!moved) return moved.status();
    spdlog::warn("{}; kept as {}, starting with an empty database", st.message(), moved->string());
    return open(dir, false);
  }
  if (!st) {
    s->release(*db);
    return Status::error(st.message() + hint);
  }
  st = exec(*db, kSchema);
  if (st) st = migrate(*db);
  s->release(*db);
  if (!st) return st;
  if (fresh) spdlog::info("created a new database {}", path.string());
  s->ensureReserve();
  return s;
}

namespace {

// SQLite's SQLITE_FULL and SQLITE_IOERR texts, and ENOSPC's.
bool isDiskFull(const std::string& msg) {
  return msg.find("database or disk is full") != std::string::npos ||
         msg.find("disk I/O error") != std::string::npos ||
         msg.find("No space left") != std::string::npos;
}

const std::string& errorOf(const Status& s) {
  return s.message();
}
template <class T>
const std::string& errorOf(const Expected<T>& e) {
  return e.error();
}

}  // namespace

void Store::ensureReserve() {
  std::lock_guard lock(reserve_mutex_);
  std::error_code ec;
  if (fs::exists(reserve_path_, ec)) return;
  fs::path tmp = reserve_path_;
  tmp += ".tmp";
  int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0600);
  if (fd < 0) return;
  // posix_fallocate really takes the blocks (a sparse file would free nothing).
  const bool ok = ::posix_fallocate(fd, 0, kReserveBytes) == 0;
  ::close(fd);
  if (ok) fs::rename(tmp, reserve_path_, ec);
  if (!ok || ec) {
    fs::remove(tmp, ec);
    spdlog::warn("no room for the disk-full reserve {} ({} bytes)", reserve_path_.string(),
                 kReserveBytes);
  }
}

bool Store::releaseReserve() {
  std::lock_guard lock(reserve_mutex_);
  std::error_code ec;
  return fs::remove(reserve_path_, ec);
}

template <class F>
auto Store::essential(F write) -> decltype(write()) {
  auto r = write();
  if (!r && isDiskFull(errorOf(r)) && releaseReserve()) {
    spdlog::warn("the data dir's disk is full ({}); released the reserve {} to write anyway",
                 errorOf(r), reserve_path_.string());
    r = write();
  }
  return r;
}

Store::~Store() {
  for (auto* db : pool_) sqlite3_close_v2(db);
}

Expected<sqlite3*> Store::acquire() {
  {
    std::lock_guard lock(pool_mutex_);
    if (!pool_.empty()) {
      auto* db = pool_.back();
      pool_.pop_back();
      return db;
    }
  }
  sqlite3* db = nullptr;
  int rc =
      sqlite3_open_v2(path_.c_str(), &db,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    std::string msg = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close_v2(db);
    return Status::error("cannot open " + path_.string() + ": " + msg);
  }
  sqlite3_busy_timeout(db, 10000);
  // WAL: readers never block the writer; FULL: a committed transaction survives power loss.
  for (const char* pragma :
       {"PRAGMA journal_mode = WAL", "PRAGMA synchronous = FULL", "PRAGMA foreign_keys = ON"}) {
    Status s = exec(db, pragma);
    if (!s) {
      sqlite3_close_v2(db);
      return s;
    }
  }
  return db;
}

void Store::release(sqlite3* db) {
  std::lock_guard lock(pool_mutex_);
  if (pool_.size() < 16)
    pool_.push_back(db);
  else
    sqlite3_close_v2(db);
}

Status Store::insertRun(const RunRecord& r) {
  LGPD_LEASE(l);
  Stmt st(l.db(),
          "INSERT INTO runs(id, name, status, config, inline_table, created_at) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
  st.bind(1, r.id).bind(2, r.name).bind(3, toString(r.status)).bind(4, r.config.dump());
  if (r.inline_table)
    st.bindBlob(5, toCbor(*r.inline_table));
  else
    st.bindNull(5);
  st.bind(6, r.created_at);
  return run(l.db(), st, "insert run");
}

Expected<std::optional<RunRecord>> Store::getRun(const std::string& id) {
  LGPD_LEASE(l);
  std::string sql = std::string("SELECT ") + kRunColumns + " FROM runs WHERE id = ?1";
  Stmt st(l.db(), sql.c_str());
  if (!st.ok()) return sqlError(l.db(), "prepare get run");
  st.bind(1, id);
  int rc = st.step();
  if (rc == SQLITE_DONE) return std::optional<RunRecord>();
  if (rc != SQLITE_ROW) return sqlError(l.db(), "get run");
  auto r = readRun(st);
  if (!r) return r.status();
  return std::optional<RunRecord>(std::move(*r));
}

Expected<std::vector<RunRecord>> Store::listRuns(std::vector<std::string>* unreadable) {
  LGPD_LEASE(l);
  std::string sql = std::string("SELECT ") + kRunColumns + " FROM runs ORDER BY seq DESC";
  Stmt st(l.db(), sql.c_str());
  if (!st.ok()) return sqlError(l.db(), "prepare list runs");
  std::vector<RunRecord> out;
  int rc;
  while ((rc = st.step()) == SQLITE_ROW) {
    auto r = readRun(st);
    if (!r) {
      spdlog::error("store: a run row is skipped: {}", r.error());
      if (unreadable) unreadable->push_back(r.error());
      continue;
    }
    r->inline_table.reset();  // listings never need the data
    out.push_back(std::move(*r));
  }
  if (rc != SQLITE_DONE) return sqlError(l.db(), "list runs");
  return out;
}

namespace {
Expected<std::vector<std::string>> idsWithStatus(sqlite3* db, RunStatus s) {
  Stmt st(db, "SELECT id FROM runs WHERE status = ?1 ORDER BY seq ASC");
  if (!st.ok()) return sqlError(db, "prepare ids");
  st.bind(1, toString(s));
  std::vector<std::string> out;
  int rc;
  while ((rc = st.step()) == SQLITE_ROW) {
    // Ids become file names (the run's inline table, its MPI work dir): an edited row's is
    // never used.
    if (isValidRunId(st.text(0)))
      out.push_back(st.text(0));
    else
      spdlog::error("store: a run row with a bad id '{}' is skipped",
                    lgp::terminalSafe(st.text(0).substr(0, 40)));
  }
  if (rc != SQLITE_DONE) return sqlError(db, "ids");
  return out;
}
}  // namespace

Expected<std::vector<std::string>> Store::queuedRuns() {
  LGPD_LEASE(l);
  return idsWithStatus(l.db(), RunStatus::Queued);
}

Expected<std::vector<std::string>> Store::runningRuns() {
  LGPD_LEASE(l);
  return idsWithStatus(l.db(), RunStatus::Running);
}

Status Store::markStarted(const std::string& id, bool resumed, int generation) {
  LGPD_LEASE(l);
  Transaction tx(l.db());
  if (!tx.began()) return tx.began();
  Stmt st(l.db(), resumed
                      ? "UPDATE runs SET status = 'running', resumes = resumes + 1 WHERE id = ?1"
                      : "UPDATE runs SET status = 'running', started_at = ?2 WHERE id = ?1");
  st.bind(1, id);
  if (!resumed) st.bind(2, unixNow());
  if (auto s = run(l.db(), st, "mark started"); !s) return s;
  RunCounters c;
  c.generation = generation;
  c.best_error = std::numeric_limits<double>::quiet_NaN();
  if (auto s = addHistory(l.db(), id, c, resumed ? "resumed" : "started"); !s) return s;
  return tx.commit();
}

Expected<int> Store::beginStart(const std::string& id) {
  LGPD_LEASE(l);
  Transaction tx(l.db());
  if (!tx.began()) return tx.began();
  Stmt up(l.db(), "UPDATE runs SET start_attempts = start_attempts + 1 WHERE id = ?1");
  up.bind(1, id);
  if (auto s = run(l.db(), up, "begin start"); !s) return s;
  int n = 0;
  {
    Stmt st(l.db(), "SELECT start_attempts FROM runs WHERE id = ?1");
    if (!st.ok()) return sqlError(l.db(), "prepare begin start");
    st.bind(1, id);
    int rc = st.step();
    if (rc == SQLITE_DONE) return Status::error("no run " + id);
    if (rc != SQLITE_ROW) return sqlError(l.db(), "begin start");
    n = static_cast<int>(st.i64(0));
  }
  if (auto s = tx.commit(); !s) return s;
  return n;
}

Status Store::endStart(const std::string& id) {
  LGPD_LEASE(l);
  Stmt st(l.db(), "UPDATE runs SET start_attempts = 0 WHERE id = ?1 AND start_attempts != 0");
  st.bind(1, id);
  return run(l.db(), st, "end start");
}

Status Store::requestCancel(const std::string& id) {
  return essential([&]() -> Status {
    LGPD_LEASE(l);
    Stmt st(l.db(), "UPDATE runs SET cancel_requested = 1 WHERE id = ?1");
    st.bind(1, id);
    return run(l.db(), st, "request cancel");
  });
}

Status Store::requeue(const std::string& id) {
  return essential([&]() -> Status {
    LGPD_LEASE(l);
    Stmt st(l.db(), "UPDATE runs SET status = 'queued' WHERE id = ?1 AND status = 'running'");
    st.bind(1, id);
    return run(l.db(), st, "requeue");
  });
}

Status Store::cancelQueued(const std::string& id) {
  return essential([&]() -> Status {
    LGPD_LEASE(l);
    Stmt st(l.db(),
            "UPDATE runs SET status = 'cancelled', cancel_requested = 1, finished_at = ?2, "
            "stop_reason = 'cancelled' WHERE id = ?1 AND status = 'queued'");
    st.bind(1, id).bind(2, unixNow());
    return run(l.db(), st, "cancel queued");
  });
}

Status Store::updateProgress(const std::string& id, const RunCounters& c) {
  LGPD_LEASE(l);
  Transaction tx(l.db());
  if (!tx.began()) return tx.began();
  if (auto s = updateCounters(l.db(), id, c); !s) return s;
  if (auto s = addHistory(l.db(), id, c, ""); !s) return s;
  return tx.commit();
}

Status Store::writeFrontSnapshot(const std::string& id, const json& front, const RunCounters& c) {
  LGPD_LEASE(l);
  Transaction tx(l.db());
  if (!tx.began()) return tx.began();
  if (auto s = upsertFront(l.db(), id, front, false, c.generation); !s) return s;
  if (auto s = updateCounters(l.db(), id, c); !s) return s;
  return tx.commit();
}

Status Store::writeCheckpoint(const std::string& id, const json& state, const json* front,
                              const RunCounters& c) {
  auto blob = toCbor(state);  // outside the transaction: it can take a while
  LGPD_LEASE(l);
  Transaction tx(l.db());
  if (!tx.began()) return tx.began();
  Stmt st(l.db(),
          "INSERT INTO checkpoints(run_id, generation, created_at, state) VALUES (?1, ?2, ?3, ?4) "
          "ON CONFLICT(run_id) DO UPDATE SET generation = excluded.generation, "
          "created_at = excluded.created_at, state = excluded.state");
  st.bind(1, id).bind(2, c.generation).bind(3, unixNow()).bindBlob(4, blob);
  if (auto s = run(l.db(), st, "write checkpoint"); !s) return s;
  if (front)
    if (auto s = upsertFront(l.db(), id, *front, false, c.generation); !s) return s;
  if (auto s = updateCounters(l.db(), id, c); !s) return s;
  if (auto s = addHistory(l.db(), id, c, "checkpoint"); !s) return s;
  return tx.commit();
}

Status Store::finishRun(const std::string& id, RunStatus status, const json* front,
                        const RunCounters& c, const std::string& error) {
  return essential([&]() -> Status {
    LGPD_LEASE(l);
    Transaction tx(l.db());
    if (!tx.began()) return tx.began();
    if (front) {
      if (auto s = upsertFront(l.db(), id, *front, true, c.generation); !s) return s;
    } else {
      // A snapshot left from a checkpoint becomes the final front (cancel before completion).
      Stmt st(l.db(), "UPDATE fronts SET final = 1 WHERE run_id = ?1");
      st.bind(1, id);
      if (auto s = run(l.db(), st, "finalise front"); !s) return s;
    }
    if (auto s = updateCounters(l.db(), id, c); !s) return s;
    Stmt st(l.db(), "UPDATE runs SET status = ?2, finished_at = ?3, error = ?4 WHERE id = ?1");
    st.bind(1, id).bind(2, toString(status)).bind(3, unixNow()).bind(4, error);
    if (auto s = run(l.db(), st, "finish run"); !s) return s;
    Stmt del(l.db(), "DELETE FROM checkpoints WHERE run_id = ?1");
    del.bind(1, id);
    if (auto s = run(l.db(), del, "drop checkpoint"); !s) return s;
    if (auto s = addHistory(l.db(), id, c, std::string(toString(status))); !s) return s;
    return tx.commit();
  });
}

Status Store::failRun(const std::string& id, const std::string& error) {
  return essential([&]() -> Status {
    LGPD_LEASE(l);
    Stmt st(l.db(),
            "UPDATE runs SET status = 'failed', finished_at = ?2, error = ?3 WHERE id = ?1");
    st.bind(1, id).bind(2, unixNow()).bind(3, error);
    return run(l.db(), st, "fail run");
  });
}

Expected<std::optional<json>> Store::loadCheckpoint(const std::string& id) {
  LGPD_LEASE(l);
  Stmt st(l.db(), "SELECT state FROM checkpoints WHERE run_id = ?1");
  if (!st.ok()) return sqlError(l.db(), "prepare load checkpoint");
  st.bind(1, id);
  int rc = st.step();
  if (rc == SQLITE_DONE) return std::optional<json>();
  if (rc != SQLITE_ROW) return sqlError(l.db(), "load checkpoint");
  auto j = fromCbor(st.blob(0), "run " + id + " checkpoint");
  if (!j) return j.status();
  return std::optional<json>(std::move(*j));
}

Expected<std::optional<StoredFront>> Store::loadFront(const std::string& id) {
  LGPD_LEASE(l);
  Stmt st(l.db(), "SELECT front, final, generation FROM fronts WHERE run_id = ?1");
  if (!st.ok()) return sqlError(l.db(), "prepare load front");
  st.bind(1, id);
  int rc = st.step();
  if (rc == SQLITE_DONE) return std::optional<StoredFront>();
  if (rc != SQLITE_ROW) return sqlError(l.db(), "load front");
  auto j = fromCbor(st.blob(0), "run " + id + " front");
  if (!j) return j.status();
  StoredFront f;
  f.front = std::move(*j);
  f.final = st.i64(1) != 0;
  f.generation = static_cast<int>(st.i64(2));
  return std::optional<StoredFront>(std::move(f));
}

Expected<std::vector<ProgressRow>> Store::history(const std::string& id, size_t max_rows) {
  LGPD_LEASE(l);
  // The newest max_rows rows and every lifecycle event, however old (a run resumed early in a
  // long night keeps its "resumed" row), oldest first.
  Stmt st(l.db(),
          "SELECT t, generation, evaluations, elapsed_s, best_error, front_size, event FROM "
          "progress WHERE run_id = ?1 AND (rowid IN (SELECT rowid FROM progress WHERE run_id = "
          "?1 ORDER BY rowid DESC LIMIT ?2) OR event IN ('started', 'resumed', 'finished', "
          "'cancelled')) ORDER BY rowid ASC");
  if (!st.ok()) return sqlError(l.db(), "prepare history");
  st.bind(1, id).bind(2, static_cast<int64_t>(max_rows));
  std::vector<ProgressRow> out;
  int rc;
  while ((rc = st.step()) == SQLITE_ROW) {
    ProgressRow p;
    p.t = st.real(0);
    p.generation = static_cast<int>(st.i64(1));
    p.evaluations = static_cast<uint64_t>(st.i64(2));
    p.elapsed_s = st.real(3);
    p.best_error = st.real(4);
    p.front_size = st.i64(5);
    p.event = st.text(6);
    out.push_back(std::move(p));
  }
  if (rc != SQLITE_DONE) return sqlError(l.db(), "history");
  return out;
}

Expected<bool> Store::deleteRun(const std::string& id) {
  auto r = essential([&]() -> Expected<bool> {
    LGPD_LEASE(l);
    Transaction tx(l.db());
    if (!tx.began()) return tx.began();
    for (const char* sql :
         {"DELETE FROM progress WHERE run_id = ?1", "DELETE FROM fronts WHERE run_id = ?1",
          "DELETE FROM checkpoints WHERE run_id = ?1"}) {
      Stmt st(l.db(), sql);
      st.bind(1, id);
      if (auto s = run(l.db(), st, "delete run rows"); !s) return s;
    }
    Stmt st(l.db(), "DELETE FROM runs WHERE id = ?1");
    st.bind(1, id);
    if (auto s = run(l.db(), st, "delete run"); !s) return s;
    bool existed = sqlite3_changes(l.db()) > 0;
    if (auto s = tx.commit(); !s) return s;
    return existed;
  });
  // Rows deleted: room, maybe, for the reserve that a full disk took.
  if (r) ensureReserve();
  return r;
}

}  // namespace lgpd
