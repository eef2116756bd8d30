// The job queue: runs up to `max_jobs` searches at once, one thread per running job.
//
// A job thread runs the run pipeline (frontends/common/run_pipeline.hpp), as `lgp run` does:
// it loads the table, builds an lgp::Search, restores the run's checkpoint if there is one
// (else seeds it), then calls step() until done(). Every `checkpoint_interval_s` it writes the
// search checkpoint, a front snapshot and the counters in one transaction; every
// `progress_interval_s` it writes the counters and a history row; every `front_interval_s`
// a live front snapshot. At the end the final front and the terminal status are written in
// one transaction, so a finished front is never half-written.
//
// Cancel: requestStop() on the search; the generation in flight completes and the run ends
// as "cancelled" with the front it had. Delete: as cancel, then every row of the run goes.
// Shutdown (SIGINT/SIGTERM): each job checkpoints and stays "running", so the next lgpd
// resumes it. After kill -9 the same happens from the last checkpoint. A job still generating
// its scene's table stops at the next integral on any of the three: a cancelled run ends
// "cancelled" without a front, a deleted one leaves nothing, and at shutdown the run stays
// queued for the next lgpd.
//
// A run whose config sets mpi.np > 0 runs out of process instead: the job thread writes the
// config into <data-dir>/mpi/<id>/, starts `launcher -np N ... lgp run` there (mpi_launch.hpp)
// and polls the files the child writes: its status becomes the progress counters, each new
// checkpoint is stored (with a front rebuilt from it), and its final front finishes the run.
// Cancel, delete and shutdown send SIGUSR1 to the launcher (it forwards it to every rank),
// then SIGTERM after mpi.stop_grace_s, then SIGKILL to its process group. A relaunch resumes
// with --resume from the newest checkpoint (the work dir's file or the store's); any launch
// that fails marks the run failed, so a broken run is never relaunched in a loop.
//
// A job never takes the daemon down: every error and exception of a run fails that run.
// What no handler can catch (a crash in the engine) is bounded by the start count: the store
// counts each start before the job loads anything and clears it after the first generation,
// and a run whose count reaches kMaxStartAttempts is failed instead of started again.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "daemon_config.hpp"
#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/search.hpp"
#include "mpi_launch.hpp"
#include "store.hpp"

namespace lgpd {

// A submission turned into a stored run: the config is parsed and validated (errors name the
// JSON path), data paths are made absolute, inline data is split off.
struct PreparedRun {
  RunRecord record;
  lgp::RunConfig config;
};

class JobManager {
 public:
  JobManager(Store& store, DaemonConfig cfg);
  ~JobManager();
  JobManager(const JobManager&) = delete;
  JobManager& operator=(const JobManager&) = delete;

  // Resumes runs left "running" (and finalises those whose cancel was requested), purges
  // materialised tables of deleted runs, and starts the scheduler.
  lgp::Status start();
  // Checkpoints and stops every job; they stay "running" in the store. Idempotent.
  void shutdown();

  // Validates a submission (the body of POST /api/v1/runs) and turns it into a run record:
  // the config, the data files (regular, readable, never opened so that it could block), the
  // table's columns, the references and, with seed_references, their fit to the program
  // shape (submit_checks.hpp). Generates no scene and reads no large table. The error names
  // the JSON path.
  lgp::Expected<PreparedRun> prepare(const nlohmann::json& submission) const;
  // Stores a prepared run as queued and wakes the scheduler. Returns the id. With
  // max_queued_runs runs waiting already, stores nothing and sets *queue_full.
  lgp::Expected<std::string> submit(PreparedRun run, bool* queue_full = nullptr);

  // False when the run is not active (then the store is authoritative); an error when the
  // store could not record the cancel.
  lgp::Expected<bool> cancel(const std::string& id);
  // Deletes a run: stops it if active, then removes every row. False if unknown.
  lgp::Expected<bool> remove(const std::string& id);
  bool isActive(const std::string& id) const;

  using TablePtr = std::shared_ptr<const lgp::Table>;
  // The table of a run, for the API (residuals): from the cache (a job puts the table it
  // loaded there), else loaded on the background thread. Waits at most `wait`; nullopt means
  // it is still loading (ask again). Thread-safe.
  std::optional<lgp::Expected<TablePtr>> tableFor(const RunRecord& run,
                                                  std::chrono::milliseconds wait);
  // The config's references scored on the run's table (emit::scoreReferences), for a front
  // stored without scores: computed once on the background thread and kept. Waits at most
  // `wait`; nullopt means not ready yet. Thread-safe.
  std::optional<nlohmann::json> scoredReferences(const RunRecord& run,
                                                 std::chrono::milliseconds wait);
  // The parsed config of a stored run.
  lgp::Expected<lgp::RunConfig> config(const RunRecord& run) const;

  const DaemonConfig& daemonConfig() const { return cfg_; }
  // The MPI launcher and lgp binary as resolved at construction.
  const MpiTools& mpiTools() const { return mpi_; }

 private:
  struct Job;
  void schedulerLoop();
  void launch(const std::string& id, bool resume);
  void runJob(Job& job);
  // Starts the job's thread; when that fails (std::system_error) the run is failed in the
  // store and false returned: the caller drops the job.
  bool startJobThread(Job& job);
  // The in-process job (local_job.cpp): the run pipeline, then step() until done, storing
  // checkpoints, fronts and counters. `search` is the caller's, so that it outlives what a
  // cancel can reach. An error fails the run; started() is called after each generation.
  struct LocalRun;
  lgp::Status runLocalJob(Job& job, const lgp::RunConfig& cfg, std::unique_ptr<lgp::Search>& search,
                          const std::function<void()>& started);
  lgp::Status stepLocalJob(LocalRun& run, const std::function<void()>& started);
  // A job stopped before its search started (while its table was generated): a cancelled run
  // ends "cancelled", a deleted one is left alone, and at shutdown it stays queued.
  lgp::Status stoppedBeforeStart(Job& job);
  // The end of a local job: its final front, or a checkpoint when the daemon is stopping.
  lgp::Status endLocalJob(LocalRun& run);
  // The out-of-process job of an MPI run (mpi_job.cpp). An error fails the run (unless it was
  // deleted). launched() is called once the launcher runs.
  lgp::Status runMpiJob(Job& job, const RunRecord& run, const lgp::RunConfig& cfg,
                        const std::function<void()>& launched);
  // A launched MPI child and the files it writes (mpi_job.cpp).
  struct MpiChild;
  // Waits for the child, polling its files into the store; a stop request (cancel, delete,
  // shutdown, a failed store write) signals it. Returns its wait status.
  int waitForChild(Job& job, MpiChild& child);
  // The run's end after the child's: finished, cancelled, kept running for a shutdown, or an
  // error that fails it.
  lgp::Status endMpiJob(Job& job, MpiChild& child, int wait_status);
  void publishTable(const std::string& id, TablePtr table);
  // The run's table, on the background thread; generating a scene stops when `halt` is set
  // (the run deleted, the daemon stopping).
  lgp::Expected<TablePtr> loadTable(const RunRecord& run, const std::atomic<bool>& halt) const;
  // The flag that halts the background loads of run `id` (set by remove() and shutdown());
  // with table_mutex_ held. A finished load releases it.
  std::shared_ptr<std::atomic<bool>> loadHaltLocked(const std::string& id);
  void releaseLoadHaltLocked(const std::string& id, const std::shared_ptr<std::atomic<bool>>& halt);
  // Runs `task` on the background thread (started on first use, joined by shutdown()).
  void background(std::function<void()> task);
  void backgroundLoop();
  std::filesystem::path mpiWorkDir(const std::string& id) const;
  lgp::Status resolveInlineTable(const RunRecord& run) const;
  std::filesystem::path inlineTablePath(const std::string& id) const;
  lgp::Status checkDataPath(const std::filesystem::path& p) const;
  // checkDataPath for data.path and data.scene of a parsed config (at job start and before a
  // table load: a file may have become a link to one outside since submit).
  lgp::Status checkDataPaths(const lgp::RunConfig& cfg) const;
  // Where lgpd keeps the tables it generates from scenes (<data_dir>/cache, owner-only): a
  // run's config never names it (lgpd never writes files a request names).
  std::filesystem::path tableCacheDir() const;

  Store& store_;
  DaemonConfig cfg_;
  MpiTools mpi_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, std::unique_ptr<Job>> jobs_;  // active jobs
  bool stopping_ = false;
  bool started_ = false;
  std::thread scheduler_;
  std::mutex submit_mutex_;

  std::mutex table_mutex_;
  std::map<std::string, TablePtr> tables_;  // small cache
  std::vector<std::string> table_order_;
  std::map<std::string, std::shared_future<lgp::Expected<TablePtr>>> table_loads_;
  std::map<std::string, std::shared_future<nlohmann::json>> ref_scores_;
  std::map<std::string, std::shared_ptr<std::atomic<bool>>> load_halts_;  // see loadHalt
  bool loads_halted_ = false;  // shutdown(): every load halts, new ones at once

  // Work the HTTP handlers must not do themselves: one thread, first come first served.
  std::mutex bg_mutex_;
  std::condition_variable bg_cv_;
  std::deque<std::function<void()>> bg_tasks_;
  std::thread bg_thread_;
  bool bg_stopping_ = false;
};

// A run whose start was interrupted by the daemon's death this many times in a row (its
// start count, Store::beginStart) is failed instead of being started again.
inline constexpr int kMaxStartAttempts = 2;

// Run ids: 16 lowercase hex digits from a random source (isValidRunId, store.hpp, accepts
// exactly that shape).
std::string newRunId();

// {"error":..,"cost":..,"discontinuity":..}: the best value of each objective over a front.
nlohmann::json bestPerObjective(const nlohmann::json& front);

}  // namespace lgpd
