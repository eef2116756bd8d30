// The daemon's durable state: one SQLite database (DIR/lgpd.sqlite3, WAL journal,
// synchronous=FULL). Tables:
//   runs        one row per run: the submitted config, status, latest counters and bests
//   checkpoints the latest search checkpoint of a run (CBOR, so +inf/NaN survive)
//   fronts      the latest front of a run (lgp-front/1 as CBOR); final = 1 once finished
//   progress    the progress history (one row per progress interval, plus lifecycle events)
// Every multi-row change (checkpoint + front + counters; final front + status) is one
// transaction, so a crash leaves either the old or the new state, never a mix. Every
// statement is prepared with bound parameters: ids and configs never reach SQL text.
//
// A full disk: lgpd keeps DIR/lgpd.reserve (kReserveBytes, allocated at start) and deletes
// it when a write that must work finds the disk full (a run failed, finished or cancelled, a
// cancel, a delete), then retries that write once in the space it freed. So a run that can
// no longer write is marked failed with the reason, and cancel and DELETE still work. The
// reserve is allocated again at the next start and after a delete, where there is room.
//
// Thread safety: every method may be called from any thread; each call borrows one of a
// small pool of connections, so API reads do not wait for a job's checkpoint write.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

struct sqlite3;

namespace lgpd {

// Run lifecycle. queued -> running -> finished | cancelled | failed. A run found "running"
// when lgpd starts is resumed from its checkpoint.
enum class RunStatus { Queued, Running, Finished, Cancelled, Failed };
std::string_view toString(RunStatus s);
std::optional<RunStatus> runStatusFromString(std::string_view s);

// Run ids are 16 lowercase hex digits (JobManager's newRunId): ids never carry path or SQL
// syntax. The API checks a request's id, the store every id it reads back (a row may have
// been edited, and ids become file names).
bool isValidRunId(const std::string& id);

struct RunCounters {
  int generation = 0;
  uint64_t evaluations = 0;
  double elapsed_s = 0;
  double evals_per_s = 0;
  int64_t front_size = 0;
  double best_error = 0;                           // NaN when unknown
  nlohmann::json best = nlohmann::json::object();  // {"error":..,"cost":..,"discontinuity":..}
  std::string stop_reason;
};

struct RunRecord {
  std::string id;
  std::string name;  // free label from the submission ("name" key), may be empty
  RunStatus status = RunStatus::Queued;
  nlohmann::json config;                       // the run config as stored (resolved paths)
  std::optional<nlohmann::json> inline_table;  // data.table of the submission, if any
  double created_at = 0, started_at = 0, finished_at = 0;  // unix seconds; 0 = not yet
  std::string error;                                       // failure message (status failed)
  bool cancel_requested = false;
  int resumes = 0;                 // times resumed after a daemon restart
  int checkpoint_generation = -1;  // generation of the latest checkpoint; -1 = none
  double checkpoint_at = 0;
  int start_attempts = 0;  // job starts since the last one that got through its first step
  RunCounters counters;
};

struct StoredFront {
  nlohmann::json front;
  bool final = false;
  int generation = 0;
};

struct ProgressRow {
  double t = 0;  // unix seconds
  int generation = 0;
  uint64_t evaluations = 0;
  double elapsed_s = 0;
  double best_error = 0;
  int64_t front_size = 0;
  std::string event;  // "", "started", "resumed", "checkpoint", "finished", "cancelled", ...
};

class Store {
 public:
  // Opens DIR/lgpd.sqlite3 and its schema. A data dir without a database gets a new one,
  // unless lgpd has used it before (it holds tables/ or mpi/). A database file that is empty,
  // unreadable, not SQLite, not lgpd's or fails SQLite's quick_check is an error; with `init`
  // it is moved aside (lgpd.sqlite3.broken-<unix time>) and a new database is created.
  static lgp::Expected<std::unique_ptr<Store>> open(const std::filesystem::path& dir,
                                                    bool init = false);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  const std::filesystem::path& path() const { return path_; }

  lgp::Status insertRun(const RunRecord& r);
  // nullopt: no such run.
  lgp::Expected<std::optional<RunRecord>> getRun(const std::string& id);
  // Newest first. A row that cannot be read (a bad status, a corrupt or too deeply nested
  // config) is left out, logged, and its reason added to *unreadable: one bad row must not
  // hide every other run.
  lgp::Expected<std::vector<RunRecord>> listRuns(std::vector<std::string>* unreadable = nullptr);
  // Queued runs in submission order.
  lgp::Expected<std::vector<std::string>> queuedRuns();
  // Runs with status running (for resume at startup), in submission order.
  lgp::Expected<std::vector<std::string>> runningRuns();

  lgp::Status markStarted(const std::string& id, bool resumed, int generation);
  // A job starts the run: counts the attempt, durably, before anything of the run is loaded.
  // Returns the number of attempts since the last endStart(); a run whose starts keep
  // taking the daemon down shows a growing count.
  lgp::Expected<int> beginStart(const std::string& id);
  // The run got through its start (table, references, seeds, its first generation).
  lgp::Status endStart(const std::string& id);
  lgp::Status requestCancel(const std::string& id);
  // running -> queued, keeping the checkpoint (more interrupted runs than job slots).
  lgp::Status requeue(const std::string& id);
  // queued -> cancelled without a front (no search ever ran).
  lgp::Status cancelQueued(const std::string& id);
  lgp::Status updateProgress(const std::string& id, const RunCounters& c);
  // Live front snapshot (final = 0) plus counters, one transaction.
  lgp::Status writeFrontSnapshot(const std::string& id, const nlohmann::json& front,
                                 const RunCounters& c);
  // Checkpoint + front snapshot + counters + a history row, one transaction. front may be
  // null (an MPI run's checkpoint whose front lgpd could not rebuild): the old snapshot stays.
  lgp::Status writeCheckpoint(const std::string& id, const nlohmann::json& state,
                              const nlohmann::json* front, const RunCounters& c);
  // Final front + terminal status + counters + history row, one transaction; drops the
  // checkpoint (the front is what is kept). front may be null (failed before any front).
  lgp::Status finishRun(const std::string& id, RunStatus status, const nlohmann::json* front,
                        const RunCounters& c, const std::string& error);
  lgp::Status failRun(const std::string& id, const std::string& error);

  lgp::Expected<std::optional<nlohmann::json>> loadCheckpoint(const std::string& id);
  lgp::Expected<std::optional<StoredFront>> loadFront(const std::string& id);
  lgp::Expected<std::vector<ProgressRow>> history(const std::string& id, size_t max_rows);
  // Removes every row of a run, one transaction. False if there was none.
  lgp::Expected<bool> deleteRun(const std::string& id);

 private:
  explicit Store(std::filesystem::path p)
      : path_(std::move(p)), reserve_path_(path_.parent_path() / "lgpd.reserve") {}
  class Lease;
  // Allocates the reserve file if it is missing and there is room; best effort.
  void ensureReserve();
  // Deletes the reserve; false when there was none.
  bool releaseReserve();
  // Runs `write`; when it fails on a full disk and the reserve is there, frees the reserve
  // and runs it once more.
  template <class F>
  auto essential(F write) -> decltype(write());
  lgp::Expected<sqlite3*> acquire();
  void release(sqlite3* db);

  std::filesystem::path path_;
  std::filesystem::path reserve_path_;
  std::mutex reserve_mutex_;
  std::mutex pool_mutex_;
  std::vector<sqlite3*> pool_;
};

// Size of the reserve file (see Store).
inline constexpr long long kReserveBytes = 4ll << 20;

double unixNow();

}  // namespace lgpd
