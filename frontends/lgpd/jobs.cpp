#include "jobs.hpp"
#ifdef LGP_HAVE_EMIT
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/score.hpp"
#endif

#include <spdlog/spdlog.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <random>
#include <system_error>
#include <thread>

#include <sys/wait.h>
#include <unistd.h>

#include "lgp/core/text_check.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "submit_checks.hpp"
#include "table_source.hpp"

namespace lgpd {

using lgp::Expected;
using lgp::Status;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// Every member and reference compiled to AMD ISA (emit/gpu_cost.hpp), as `lgp run` does; cached,
// so a live snapshot measures only the members that are new since the last one.
void addMeasuredCost([[maybe_unused]] const lgp::RunConfig& cfg, [[maybe_unused]] json& front) {
#ifdef LGP_HAVE_EMIT
  if (cfg.objectives.measured_cost.families.empty()) return;
  lgp::emit::MeasureOptions mo;
  mo.families = cfg.objectives.measured_cost.families;
  lgp::emit::addMeasuredCost(front, mo);
#endif
}

constexpr size_t kMaxNameLength = 120;
constexpr size_t kTableCacheSize = 4;
constexpr size_t kMaxScoredReferenceRuns = 256;  // runs whose scored references are kept

double seconds(std::chrono::steady_clock::duration d) {
  return std::chrono::duration<double>(d).count();
}

// Resolves a data path of a submission against the daemon's base dir.
std::string absolutePath(const std::string& p, const fs::path& base) {
  fs::path path(p);
  if (path.is_relative()) path = base / path;
  return path.lexically_normal().string();
}

}  // namespace

std::string newRunId() {
  static std::mutex m;
  static std::mt19937_64 rng{[] {
    std::random_device rd;
    return (static_cast<uint64_t>(rd()) << 32) ^ rd() ^
           static_cast<uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
  }()};
  std::lock_guard lock(m);
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(rng()));
  return buf;
}

json bestPerObjective(const json& front) {
  json best = json::object();
  if (!front.is_object() || !front.contains("members") || !front["members"].is_array()) return best;
  for (const char* key : {"error", "cost", "discontinuity"}) {
    double v = std::numeric_limits<double>::infinity();
    int at = -1;
    for (const auto& m : front["members"]) {
      auto it = m.find(key);
      if (it == m.end() || !it->is_number()) continue;
      double x = it->get<double>();
      if (x < v) {
        v = x;
        at = m.value("index", at);
      }
    }
    if (std::isfinite(v)) best[key] = {{"value", v}, {"member", at}};
  }
  return best;
}

struct JobManager::Job {
  std::string id;
  std::thread thread;
  std::atomic<bool> cancel{false};
  std::atomic<bool> deleted{false};
  std::atomic<bool> shutdown{false};
  std::atomic<bool> finished{false};
  std::mutex search_mutex;
  lgp::Search* search = nullptr;  // valid while the job thread runs its search

  void requestStop() {
    std::lock_guard lock(search_mutex);
    if (search) search->requestStop();
  }
};

JobManager::JobManager(Store& store, DaemonConfig cfg) : store_(store), cfg_(std::move(cfg)) {
  if (cfg_.data_base_dir.empty()) cfg_.data_base_dir = fs::current_path();
  cfg_.data_base_dir = fs::absolute(cfg_.data_base_dir).lexically_normal();
  cfg_.data_dir = fs::absolute(cfg_.data_dir).lexically_normal();  // the child runs elsewhere
  mpi_ = resolveMpiTools(cfg_.mpi);
}

JobManager::~JobManager() {
  shutdown();
}

fs::path JobManager::inlineTablePath(const std::string& id) const {
  return cfg_.data_dir / "tables" / (id + ".json");
}

fs::path JobManager::mpiWorkDir(const std::string& id) const {
  return cfg_.data_dir / "mpi" / id;
}

Status JobManager::checkDataPath(const fs::path& p) const {
  if (cfg_.allowed_data_dirs.empty()) return Status::ok();
  std::error_code ec;
  fs::path canon = fs::weakly_canonical(p, ec);
  if (ec) canon = p.lexically_normal();
  for (const auto& dir : cfg_.allowed_data_dirs) {
    fs::path d = fs::weakly_canonical(fs::absolute(dir), ec);
    auto rel = canon.lexically_relative(d);
    if (!rel.empty() && *rel.begin() != "..") return Status::ok();
  }
  return Status::error("is outside the daemon's allowed_data_dirs");
}

Status JobManager::checkDataPaths(const lgp::RunConfig& cfg) const {
  for (auto [key, p] : {std::pair{"path", &cfg.data.path}, std::pair{"scene", &cfg.data.scene}}) {
    if (p->empty()) continue;
    fs::path abs = fs::path(*p).is_relative() ? cfg.base_dir / *p : fs::path(*p);
    if (auto s = checkDataPath(abs); !s)
      return Status::error(std::string("/data/") + key + ": " + abs.string() + " " + s.message());
  }
  return Status::ok();
}

Expected<PreparedRun> JobManager::prepare(const json& submission) const {
  if (!submission.is_object()) return Status::error("/: the run config must be a JSON object");
  json j = submission;
  PreparedRun out;
  out.record.id = newRunId();
  out.record.created_at = unixNow();
  if (auto it = j.find("name"); it != j.end()) {
    if (!it->is_string()) return Status::error("/name: must be a string");
    std::string name = it->get<std::string>();
    if (name.size() > kMaxNameLength)
      return Status::error("/name: at most " + std::to_string(kMaxNameLength) + " characters");
    for (unsigned char c : name)
      if (c < 0x20 || c == 0x7f) return Status::error("/name: control characters not allowed");
    out.record.name = name;
    j.erase("name");
  }
  auto data = j.find("data");
  if (data != j.end() && data->is_object()) {
    if (auto t = data->find("table"); t != data->end()) {
      if (data->contains("path") || data->contains("scene"))
        return Status::error("/data/table: give either an inline table or data.path/scene");
      auto raw = lgp::parseJsonTable(*t, "/data/table");
      if (!raw) return raw.status();
      out.record.inline_table = *t;
      data->erase("table");
      (*data)["path"] = inlineTablePath(out.record.id).string();
    } else {
      for (const char* key : {"path", "scene", "cache_dir"}) {
        auto p = data->find(key);
        if (p == data->end() || !p->is_string() || p->get<std::string>().empty()) continue;
        if (auto why = lgp::controlCharacterReason(p->get<std::string>()); !why.empty())
          return Status::error(std::string("/data/") + key + ": " + why);
        std::string abs = absolutePath(p->get<std::string>(), cfg_.data_base_dir);
        if (std::string(key) != "cache_dir") {
          if (auto s = checkDataPath(abs); !s)
            return Status::error(std::string("/data/") + key + ": " + s.message());
        }
        *p = abs;
      }
    }
  }
  auto cfg = lgp::parseRunConfig(j, cfg_.data_base_dir);
  if (!cfg) return cfg.status();
  if (auto s = checkSearchMemory(*cfg, cfg_.runMemoryBytes()); !s) return s;
  if (auto s = checkServedByLgpd(*cfg); !s) return s;
  if (cfg->mpi.np > 0) {
    if (cfg->mpi.np > cfg_.mpi.max_np)
      return Status::error("/mpi/np: must be in [1, " + std::to_string(cfg_.mpi.max_np) +
                           "] on this lgpd (its mpi.max_np) (got " + std::to_string(cfg->mpi.np) +
                           ")");
    if (cfg->search.multi_output.mode == lgp::MultiOutputMode::TwoStep)
      return Status::error(
          "/search/multi_output/mode: two_step runs are not available over MPI; use joint, "
          "or run without mpi.np");
    if (!mpi_.usable())
      return Status::error("/mpi/np: this lgpd cannot launch MPI runs (" + mpi_.unavailable + ")");
  }
  if (cfg->search.multi_output.mode == lgp::MultiOutputMode::TwoStep)
    return Status::error(
        "/search/multi_output/mode: two_step runs are not served by lgpd yet "
        "(no checkpointing across steps); run them with `lgp run`");
  // Check the table now so that a missing, unreadable or blocking file or an unknown column
  // is a 400, not a failed run; but do not generate a scene or read a large file in the
  // HTTP handler (submit_checks.hpp).
  TableColumns columns;
  if (out.record.inline_table) {
    auto raw = lgp::parseJsonTable(*out.record.inline_table, "/data/table");
    if (!raw) return raw.status();
    auto table = lgp::selectColumns(*raw, cfg->data.inputs, cfg->data.outputs, cfg->data.weights,
                                    "/data/table");
    if (!table) return table.status();
    columns = {table->input_names, table->output_names, true};
  } else {
    auto c = checkTableAtSubmit(*cfg);
    if (!c) return c.status();
    columns = std::move(*c);
  }
  if (auto s = checkReferencesAtSubmit(*cfg, columns); !s) return s;
  out.record.config = j;
  out.record.status = RunStatus::Queued;
  out.config = std::move(*cfg);
  return out;
}

Expected<lgp::RunConfig> JobManager::config(const RunRecord& run) const {
  json j = run.config;
  if (run.inline_table) j["data"]["path"] = inlineTablePath(run.id).string();
  return lgp::parseRunConfig(j, cfg_.data_base_dir);
}

Status JobManager::resolveInlineTable(const RunRecord& run) const {
  if (!run.inline_table) return Status::ok();
  fs::path p = inlineTablePath(run.id);
  std::error_code ec;
  if (fs::exists(p, ec)) return Status::ok();
  fs::create_directories(p.parent_path(), ec);
  // Write-then-rename so a crash never leaves a truncated table behind.
  fs::path tmp = p;
  tmp += ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f << run.inline_table->dump();
    if (!f) return Status::error("cannot write " + tmp.string());
  }
  fs::rename(tmp, p, ec);
  if (ec) return Status::error("cannot rename " + tmp.string() + ": " + ec.message());
  return Status::ok();
}

Expected<std::string> JobManager::submit(PreparedRun run, bool* queue_full) {
  if (queue_full) *queue_full = false;
  {
    // Counted and inserted under one lock, so that concurrent submissions cannot overshoot.
    std::lock_guard lock(submit_mutex_);
    auto queued = store_.queuedRuns();
    if (!queued) return queued.status();
    if (static_cast<int>(queued->size()) >= cfg_.max_queued_runs) {
      if (queue_full) *queue_full = true;
      return Status::error("the queue is full: " + std::to_string(queued->size()) +
                           " runs are waiting (this lgpd's max_queued_runs is " +
                           std::to_string(cfg_.max_queued_runs) + "); submit again later");
    }
    if (auto s = store_.insertRun(run.record); !s) return s;
  }
  if (auto s = resolveInlineTable(run.record); !s)
    spdlog::warn("run {}: {}", run.record.id, s.message());
  { std::lock_guard lock(mutex_); }
  cv_.notify_all();
  spdlog::info("run {} queued{}", run.record.id,
               run.record.name.empty() ? "" : " (" + run.record.name + ")");
  return run.record.id;
}

Expected<JobManager::TablePtr> JobManager::loadTable(const RunRecord& run) const {
  auto cfg = config(run);
  if (!cfg) return cfg.status();
  if (auto s = resolveInlineTable(run); !s) return s;
  if (!run.inline_table) {
    // The file may have been replaced (by a link to a file outside) since submit.
    if (auto s = checkDataPaths(*cfg); !s) return s;
    if (auto s = checkDataFiles(*cfg); !s) return s;
  }
  auto t = lgp::cli::loadRunTable(*cfg);
  if (!t) return t.status();
  return TablePtr(std::make_shared<const lgp::Table>(std::move(*t)));
}

void JobManager::publishTable(const std::string& id, TablePtr table) {
  std::lock_guard lock(table_mutex_);
  tables_[id] = std::move(table);
  std::erase(table_order_, id);
  table_order_.push_back(id);
  while (table_order_.size() > kTableCacheSize) {
    tables_.erase(table_order_.front());
    table_order_.erase(table_order_.begin());
  }
}

std::optional<Expected<JobManager::TablePtr>> JobManager::tableFor(const RunRecord& run,
                                                                   std::chrono::milliseconds wait) {
  std::shared_future<Expected<TablePtr>> pending;
  {
    std::lock_guard lock(table_mutex_);
    if (auto it = tables_.find(run.id); it != tables_.end()) return Expected<TablePtr>(it->second);
    if (auto it = table_loads_.find(run.id); it != table_loads_.end()) {
      pending = it->second;
    } else {
      auto promise = std::make_shared<std::promise<Expected<TablePtr>>>();
      pending = promise->get_future().share();
      table_loads_[run.id] = pending;
      background([this, run, promise] {
        Expected<TablePtr> t = Status::error("lgpd is stopping");
        try {
          t = loadTable(run);
        } catch (const std::exception& e) {
          t = Status::error(std::string("cannot load the table: ") + e.what());
        } catch (...) {
          t = Status::error("cannot load the table: an unknown exception");
        }
        {
          std::lock_guard done_lock(table_mutex_);
          table_loads_.erase(run.id);  // an error is not kept: the file may come back
        }
        if (t) publishTable(run.id, *t);
        promise->set_value(std::move(t));
      });
    }
  }
  if (pending.wait_for(wait) != std::future_status::ready) return std::nullopt;
  return pending.get();
}

std::optional<json> JobManager::scoredReferences(const RunRecord& run,
                                                 std::chrono::milliseconds wait) {
  std::shared_future<json> pending;
  {
    std::lock_guard lock(table_mutex_);
    if (auto it = ref_scores_.find(run.id); it != ref_scores_.end()) {
      pending = it->second;
    } else {
      if (ref_scores_.size() >= kMaxScoredReferenceRuns) ref_scores_.clear();
      auto promise = std::make_shared<std::promise<json>>();
      pending = promise->get_future().share();
      ref_scores_[run.id] = pending;
      background([this, run, promise] {
        json out = json::array();
        std::string why;
        try {
          auto cfg = config(run);
          if (!cfg) {
            why = "the stored config no longer parses: " + cfg.error();
          } else {
            // On the background thread already: take the cached table or load it here.
            Expected<TablePtr> table = Status::error("not loaded");
            {
              std::lock_guard cache_lock(table_mutex_);
              if (auto c = tables_.find(run.id); c != tables_.end()) table = c->second;
            }
            if (!table) {
              table = loadTable(run);
              if (table) publishTable(run.id, *table);
            }
            if (!table) {
              why = "cannot load the run's table: " + table.error();
            } else {
#ifdef LGP_HAVE_EMIT
              out = lgp::emit::scoreReferences(*cfg, **table);
#else
              why = "references are not scored: this lgpd was built without lgp::emit";
#endif
            }
          }
        } catch (const std::exception& e) {
          why = std::string("scoring failed: ") + e.what();
        } catch (...) {
          why = "scoring failed: an unknown exception";
        }
        if (!why.empty()) {
          for (const auto& r : run.config.value("references", json::array())) {
            json e = r.is_object() ? r : json{{"name", "(reference)"}};
            e["invalid"] = why;
            out.push_back(std::move(e));
          }
          std::lock_guard done_lock(table_mutex_);
          ref_scores_.erase(run.id);  // not kept: the table may come back
        }
        promise->set_value(std::move(out));
      });
    }
  }
  if (pending.wait_for(wait) != std::future_status::ready) return std::nullopt;
  return pending.get();
}

void JobManager::background(std::function<void()> task) {
  std::lock_guard lock(bg_mutex_);
  if (bg_stopping_) return;  // the promise is dropped: its waiters see a broken promise
  bg_tasks_.push_back(std::move(task));
  if (!bg_thread_.joinable()) bg_thread_ = std::thread([this] { backgroundLoop(); });
  bg_cv_.notify_one();
}

void JobManager::backgroundLoop() {
  std::unique_lock lock(bg_mutex_);
  for (;;) {
    bg_cv_.wait(lock, [&] { return bg_stopping_ || !bg_tasks_.empty(); });
    if (bg_stopping_) break;
    auto task = std::move(bg_tasks_.front());
    bg_tasks_.pop_front();
    lock.unlock();
    task();
    lock.lock();
  }
}

Status JobManager::start() {
  auto running = store_.runningRuns();
  if (!running) return running.status();
  std::error_code ec;
  fs::create_directories(cfg_.data_dir / "tables", ec);
  if (mpi_.usable())
    spdlog::info("MPI runs: {} with {}{}", mpi_.launcher.string(), mpi_.lgp.string(),
                 mpi_.hostfile.empty() ? "" : ", hostfile " + mpi_.hostfile.string());
  else
    spdlog::info("MPI runs unavailable: {}", mpi_.unavailable);
  // Work dirs of runs deleted while lgpd was down.
  for (const auto& e : fs::directory_iterator(cfg_.data_dir / "mpi", ec)) {
    const std::string name = e.path().filename().string();
    if (!isValidRunId(name)) continue;
    auto rec = store_.getRun(name);
    if (rec && !*rec) fs::remove_all(e.path(), ec);
  }
  int resumed = 0;
  for (const auto& id : *running) {
    auto rec = store_.getRun(id);
    if (!rec || !*rec) continue;
    const RunRecord& r = **rec;
    if (r.cancel_requested) {
      // Cancelled, then the daemon died before the job wrote its end: keep the last snapshot.
      auto s = store_.finishRun(id, RunStatus::Cancelled, nullptr, r.counters, "");
      if (!s) spdlog::error("run {}: {}", id, s.message());
      continue;
    }
    if (resumed < cfg_.max_jobs) {
      spdlog::info("run {}: resuming (checkpoint at generation {})", id, r.checkpoint_generation);
      launch(id, true);
      ++resumed;
    } else {
      // More interrupted runs than slots: they wait in the queue, keeping their checkpoint.
      auto s = store_.requeue(id);
      if (!s) spdlog::error("run {}: {}", id, s.message());
    }
  }
  {
    std::lock_guard lock(mutex_);
    started_ = true;
  }
  scheduler_ = std::thread([this] { schedulerLoop(); });
  return Status::ok();
}

void JobManager::launch(const std::string& id, bool resume) {
  std::lock_guard lock(mutex_);
  if (jobs_.count(id)) return;
  auto job = std::make_unique<Job>();
  job->id = id;
  Job* raw = job.get();
  jobs_[id] = std::move(job);
  (void)resume;  // a checkpoint, when present, is always used
  if (!startJobThread(*raw)) jobs_.erase(id);
}

void JobManager::schedulerLoop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    cv_.wait_for(lock, std::chrono::milliseconds(500));
    if (stopping_) break;
    // Reap finished jobs.
    for (auto it = jobs_.begin(); it != jobs_.end();) {
      if (it->second->finished.load()) {
        auto job = std::move(it->second);
        it = jobs_.erase(it);
        lock.unlock();
        job->thread.join();
        lock.lock();
      } else {
        ++it;
      }
    }
    int active = static_cast<int>(jobs_.size());
    if (active >= cfg_.max_jobs) continue;
    lock.unlock();
    auto queued = store_.queuedRuns();
    lock.lock();
    if (!queued) {
      spdlog::error("{}", queued.error());
      continue;
    }
    for (const auto& id : *queued) {
      if (stopping_ || static_cast<int>(jobs_.size()) >= cfg_.max_jobs) break;
      if (jobs_.count(id)) continue;
      auto job = std::make_unique<Job>();
      job->id = id;
      Job* raw = job.get();
      jobs_[id] = std::move(job);
      if (!startJobThread(*raw)) jobs_.erase(id);
    }
  }
}

bool JobManager::startJobThread(Job& job) {
  try {
    job.thread = std::thread([this, &job] { runJob(job); });
    return true;
  } catch (const std::system_error& e) {
    // No thread for the job: the run fails, the daemon goes on.
    const std::string msg = std::string("cannot start the job's thread: ") + e.what();
    spdlog::error("run {} failed: {}", job.id, msg);
    if (auto s = store_.failRun(job.id, msg); !s) spdlog::error("run {}: {}", job.id, s.message());
    return false;
  }
}

namespace {

// Starts `n` - 1 threads (the job thread is the n-th) and joins them: a machine at its
// thread or memory limit says so here, as a std::system_error, and the run fails with a
// message. LGPD_TEST_THREAD_LIMIT=K (for tests) makes the K+1-th start fail the same way,
// as a machine whose limit is K threads would.
Status probeThreads(int n) {
  int limit = -1;
  if (const char* v = std::getenv("LGPD_TEST_THREAD_LIMIT")) limit = std::atoi(v);
  std::vector<std::thread> started;
  std::string why;
  try {
    for (int i = 1; i < n; ++i) {
      if (limit >= 0 && i > limit)
        throw std::system_error(EAGAIN, std::generic_category(), "thread limit reached");
      started.emplace_back([] {});
    }
  } catch (const std::system_error& e) {
    why = e.what();
  }
  for (auto& t : started) t.join();
  if (why.empty()) return Status::ok();
  return Status::error("cannot start the search's " + std::to_string(n) + " threads (started " +
                       std::to_string(started.size() + 1) + "): " + why + "; lower search.threads");
}

RunCounters countersOf(const lgp::SearchProgress& p, const json& best) {
  RunCounters c;
  c.generation = p.generation;
  c.evaluations = p.evaluations;
  c.elapsed_s = p.elapsed_s;
  c.evals_per_s = p.evals_per_s;
  c.front_size = static_cast<int64_t>(p.front_size);
  c.best_error = p.front_size ? p.best_error : std::numeric_limits<double>::quiet_NaN();
  c.best = best;
  c.stop_reason = p.stop_reason;
  return c;
}

}  // namespace

void JobManager::runJob(Job& job) {
  const std::string id = job.id;
  // The run's start (loading, references, seeds, the first generation) is counted in the
  // store before it begins and cleared once it is through or the job ends in an orderly way,
  // so that a run whose start takes the daemon down is failed instead of being retried at
  // every restart (see kMaxStartAttempts).
  bool counting_start = false;
  auto endStart = [&] {
    if (!counting_start) return;
    counting_start = false;
    if (job.deleted.load()) return;
    if (auto s = store_.endStart(id); !s) spdlog::error("run {}: {}", id, s.message());
  };
  auto finish = [&] {
    endStart();
    job.finished.store(true), cv_.notify_all();
  };
  // The search outlives the try block, so that a cancel never reaches a destroyed search.
  std::unique_ptr<lgp::Search> search;
  auto detach = [&] {
    std::lock_guard lock(job.search_mutex);
    job.search = nullptr;
  };
  auto fail = [&](const std::string& msg) {
    detach();
    spdlog::error("run {} failed: {}", id, msg);
    if (!job.deleted.load()) {
      auto s = store_.failRun(id, msg);
      if (!s) spdlog::error("run {}: {}", id, s.message());
    }
    counting_start = false;
    finish();
  };
  // Everything a job does is inside: no error of a run, thrown or returned, reaches the
  // daemon. (A crash that no handler can catch is what the start count is for.)
  try {
    auto rec = store_.getRun(id);
    if (!rec) return fail(rec.error());
    if (!*rec) return finish();  // deleted meanwhile
    const RunRecord run = **rec;
    if (run.status != RunStatus::Queued && run.status != RunStatus::Running) return finish();
    if (run.start_attempts >= kMaxStartAttempts)
      return fail("lgpd stopped " + std::to_string(run.start_attempts) +
                  " times in a row while this run was starting (a crash, or a kill), so it is "
                  "not started again; lgpd's log of those starts says how far each got");
    if (auto n = store_.beginStart(id); !n)
      return fail(n.error());
    else
      counting_start = true;
    if (run.cancel_requested) job.cancel.store(true);

    auto cfg = config(run);
    if (!cfg) return fail(cfg.error());
    if (auto s = checkServedByLgpd(*cfg); !s) return fail(s.message());
    if (auto s = resolveInlineTable(run); !s) return fail(s.message());
    // Submit checked the files; they may have changed since (a FIFO must never be opened in
    // a way that blocks), and a file inside allowed_data_dirs may have been replaced by a
    // link to one outside.
    if (!run.inline_table) {
      if (auto s = checkDataPaths(*cfg); !s) return fail(s.message());
      if (auto s = checkDataFiles(*cfg); !s) return fail(s.message());
    }
    if (cfg->mpi.np > 0) {
      auto s = runMpiJob(job, run, *cfg, [&] { endStart(); });
      if (!s) return fail(s.message());
      return finish();
    }
    spdlog::info("run {}: loading its table", id);
    auto loaded = lgp::cli::loadRunTable(*cfg);
    if (!loaded) return fail(loaded.error());
    auto table = std::make_shared<const lgp::Table>(std::move(*loaded));
    publishTable(id, table);

    // The references, scored once on the run's table and stored with every front.
    json scored_refs;
#ifdef LGP_HAVE_EMIT
    if (cfg->references.is_array() && !cfg->references.empty()) {
      spdlog::info("run {}: scoring {} reference(s)", id, cfg->references.size());
      scored_refs = lgp::emit::scoreReferences(*cfg, *table);
    }
#endif
    // The search's threads: capped at the cores lgpd may use (lgp::Search does so), and
    // started once here, so that a machine that cannot give them fails the run with a
    // message rather than in the OpenMP runtime, which ends the process.
    const int cores = lgp::Search::maxThreads();
    if (cfg->search.threads > cores)
      spdlog::warn("run {}: search.threads {} capped at the {} cores lgpd may use", id,
                   cfg->search.threads, cores);
    const int threads = cfg->search.threads > 0 ? std::min(cfg->search.threads, cores) : cores;
    if (auto s = probeThreads(threads); !s) return fail(s.message());
    search = std::make_unique<lgp::Search>(*cfg, *table);
    bool resumed = false;
    auto ckpt = store_.loadCheckpoint(id);
    if (!ckpt) {
      spdlog::warn("run {}: {}; starting from scratch", id, ckpt.error());
    } else if (*ckpt) {
      auto s = search->restore(**ckpt);
      if (s) {
        resumed = true;
      } else {
        spdlog::warn("run {}: checkpoint rejected ({}); starting from scratch", id, s.message());
        search = std::make_unique<lgp::Search>(*cfg, *table);
      }
    }
#ifdef LGP_HAVE_EMIT
    if (auto st = lgp::emit::enableMeasuredCostInSearch(*search); !st) return fail(st.message());
#else
    if (cfg->objectives.measured_cost.in_search)
      return fail("/objectives/measured_cost/in_search: this lgpd was built without lgp::emit");
#endif
    if (!resumed) {
#ifdef LGP_HAVE_EMIT
      if (cfg->search.seed_references) {
        spdlog::info("run {}: seeding from its references", id);
        auto progs = lgp::emit::referencePrograms(*cfg, *table);
        if (!progs) return fail(progs.error());
        for (const auto& why : search->addSeeds(*progs))
          spdlog::warn("run {}: not seeded: {}", id, why);
      }
#endif
      search->initialize();
    }
    {
      std::lock_guard lock(job.search_mutex);
      job.search = search.get();
    }
    if (job.cancel.load() || job.deleted.load()) search->requestStop();
    if (auto s = store_.markStarted(id, resumed, search->progress().generation); !s)
      return fail(s.message());
    spdlog::info("run {} {} at generation {}", id, resumed ? "resumed" : "started",
                 search->progress().generation);

    using clock = std::chrono::steady_clock;
    auto last_ckpt = clock::now(), last_progress = clock::now(), last_front = clock::now();
    json best = json::object();
    auto snapshot = [&]() {
      json front = lgp::frontToJson(*search, search->front());
      if (!scored_refs.is_null()) front["references"] = scored_refs;
      addMeasuredCost(*cfg, front);
      best = bestPerObjective(front);
      return front;
    };
    while (!search->done() && !job.shutdown.load()) {
      search->step();
      endStart();  // the start is through: table, references, seeds and a first generation
      if (job.deleted.load()) break;
      auto now = clock::now();
      if (seconds(now - last_ckpt) >= cfg_.checkpoint_interval_s) {
        json front = snapshot();
        auto s = store_.writeCheckpoint(id, search->checkpoint(), &front,
                                        countersOf(search->progress(), best));
        if (!s) return fail("cannot store the run's checkpoint: " + s.message());
        last_ckpt = last_progress = last_front = now;
      } else if (seconds(now - last_front) >= cfg_.front_interval_s) {
        json front = snapshot();
        auto s = store_.writeFrontSnapshot(id, front, countersOf(search->progress(), best));
        if (!s) return fail("cannot store the run's front: " + s.message());
        last_front = last_progress = now;
      } else if (seconds(now - last_progress) >= cfg_.progress_interval_s) {
        auto s = store_.updateProgress(id, countersOf(search->progress(), best));
        if (!s) return fail("cannot store the run's progress: " + s.message());
        last_progress = now;
      }
    }

    if (job.deleted.load()) {
      std::lock_guard lock(job.search_mutex);
      job.search = nullptr;
      return finish();
    }
    if (job.shutdown.load() && !search->done()) {
      // Daemon stopping: keep the run "running" with a fresh checkpoint; the next start
      // resumes it.
      json front = snapshot();
      auto s = store_.writeCheckpoint(id, search->checkpoint(), &front,
                                      countersOf(search->progress(), best));
      if (!s) spdlog::error("run {}: checkpoint at shutdown: {}", id, s.message());
      spdlog::info("run {} checkpointed at generation {} for shutdown", id,
                   search->progress().generation);
      std::lock_guard lock(job.search_mutex);
      job.search = nullptr;
      return finish();
    }
    json front = snapshot();
    auto p = search->progress();
    RunStatus status = job.cancel.load() ? RunStatus::Cancelled : RunStatus::Finished;
    {
      std::lock_guard lock(job.search_mutex);
      job.search = nullptr;
    }
    // An empty front is not a result (as for `lgp run`): every program scored NaN or infinity,
    // which the archive never keeps. A cancelled run may end empty.
    if (status == RunStatus::Finished && search->front().empty())
      return fail("the search ended with an empty front: none of the " +
                  std::to_string(p.evaluations) +
                  " programs evaluated had a finite error, cost and discontinuity (the targets, "
                  "weights or target transforms overflow the float32 evaluation or its sums)");
    auto s = store_.finishRun(id, status, &front, countersOf(p, best), "");
    if (!s) return fail("cannot store the run's final front: " + s.message());
    spdlog::info("run {} {}: generation {}, {} evaluations, front of {}", id, toString(status),
                 p.generation, p.evaluations, p.front_size);
    return finish();
  } catch (const std::bad_alloc&) {
    detach();
    return fail("out of memory (the table or the search is too large for this machine)");
  } catch (const std::exception& e) {
    detach();
    return fail(std::string("internal error: ") + e.what());
  } catch (...) {
    detach();
    return fail("internal error: an unknown exception");
  }
}

namespace {

// Status file of `lgp run --status` (lgp-status/1) into the counters; other keys are kept.
void applyStatus(const json& st, RunCounters& c) {
  try {
    if (!st.is_object() || st.value("format", "") != "lgp-status/1") return;
    c.generation = st.value("generation", c.generation);
    c.evaluations = st.value("evaluations", c.evaluations);
    c.elapsed_s = st.value("elapsed_s", c.elapsed_s);
    if (auto it = st.find("evals_per_s"); it != st.end() && it->is_number())
      c.evals_per_s = it->get<double>();
    c.front_size = st.value("front_size", c.front_size);
    if (auto it = st.find("best_error"); it != st.end())
      c.best_error = it->is_number() ? it->get<double>() : std::numeric_limits<double>::quiet_NaN();
    if (auto it = st.find("stop_reason"); it != st.end() && it->is_string())
      c.stop_reason = it->get<std::string>();
  } catch (const json::exception&) {
    // A status of the wrong shape only costs a progress update.
  }
}

bool isCheckpoint(const std::optional<json>& j) {
  return j && j->is_object() && j->value("format", "") == "lgp-checkpoint/2" &&
         j->contains("generation") && (*j)["generation"].is_number_integer();
}

// The counters of a front document: size and bests (the error best becomes best_error).
void applyFront(const json& front, RunCounters& c) {
  c.best = bestPerObjective(front);
  if (auto m = front.find("members"); m != front.end() && m->is_array())
    c.front_size = static_cast<int64_t>(m->size());
  if (auto e = c.best.find("error"); e != c.best.end()) c.best_error = (*e)["value"].get<double>();
}

std::string hintFor(int wait_status) {
  if (!WIFEXITED(wait_status)) return "";
  switch (WEXITSTATUS(wait_status)) {
    case 1:
      return " (lgp run: I/O error)";
    case 2:
      return " (lgp run rejected its config or arguments)";
    case 126:
    case 127:
      return " (the launcher could not be executed)";
    case 130:
      return " (lgp run was stopped by a signal that lgpd did not send)";
    default:
      return "";
  }
}

}  // namespace

Status JobManager::runMpiJob(Job& job, const RunRecord& run, const lgp::RunConfig& cfg,
                             const std::function<void()>& launched) {
  using clock = std::chrono::steady_clock;
  const std::string& id = run.id;
  if (!mpi_.usable())
    return Status::error("this lgpd cannot launch MPI runs (" + mpi_.unavailable + ")");
  if (cfg.mpi.np > cfg_.mpi.max_np)
    return Status::error("/mpi/np: " + std::to_string(cfg.mpi.np) + " exceeds this lgpd's " +
                         "mpi.max_np (" + std::to_string(cfg_.mpi.max_np) + ")");
  const MpiWorkDir work{mpiWorkDir(id)};
  std::error_code ec;
  fs::create_directories(work.dir, ec);
  if (ec) return Status::error("cannot create " + work.dir.string() + ": " + ec.message());
  // Results of an earlier launch must not be taken for this one's.
  for (const fs::path& p : {work.front(), work.status(), work.pidFile()}) {
    fs::remove(p, ec);
    fs::remove(fs::path(p) += ".tmp", ec);
  }

  // Resume from the newer of the work dir's checkpoint (the launch before a crash may have
  // written one after the last one lgpd stored) and the store's.
  std::optional<json> resume_from = readJsonFile(work.checkpoint());
  if (!isCheckpoint(resume_from)) resume_from.reset();
  if (auto stored = store_.loadCheckpoint(id); !stored) {
    spdlog::warn("run {}: {}", id, stored.error());
  } else if (isCheckpoint(*stored) &&
             (!resume_from ||
              (**stored)["generation"].get<int>() > (*resume_from)["generation"].get<int>())) {
    resume_from = std::move(*stored);
    if (auto s = lgp::writeTextAtomic(resume_from->dump(), work.checkpoint()); !s) return s;
  }
  if (!resume_from) fs::remove(work.checkpoint(), ec);
  const bool resume = resume_from.has_value();
  const int resume_generation = resume ? (*resume_from)["generation"].get<int>() : 0;
  resume_from.reset();

  // The config the child reads: the stored one (absolute data paths), with every output path
  // pointing into the work dir. A request's own output section never reaches the child.
  json rc = run.config;
  if (run.inline_table) rc["data"]["path"] = inlineTablePath(id).string();
  json output = {{"front_json", work.front().string()},
                 {"front_csv", ""},
                 {"progress_interval_s", cfg_.progress_interval_s},
                 {"checkpoint", work.checkpoint().string()},
                 {"checkpoint_interval_s", cfg_.checkpoint_interval_s}};
  if (auto o = rc.find("output");
      o != rc.end() && o->is_object() && o->contains("progress_cost_levels"))
    output["progress_cost_levels"] = (*o)["progress_cost_levels"];
  rc["output"] = std::move(output);
  if (auto s = lgp::writeTextAtomic(rc.dump(2) + "\n", work.config()); !s) return s;

  if (job.deleted.load()) return Status::ok();
  if (job.cancel.load()) {
    auto s = store_.finishRun(id, RunStatus::Cancelled, nullptr, run.counters, "");
    return s;
  }
  if (job.shutdown.load()) return Status::ok();

  const auto argv = mpiArgv(mpi_, cfg_.mpi, cfg.mpi.np, work, cfg_.checkpoint_interval_s, resume);
  std::vector<std::string> env;
  if (::geteuid() == 0) env = {"OMPI_ALLOW_RUN_AS_ROOT=1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1"};
  {
    // The log keeps every launch of the run; a fresh start begins a new one.
    std::ofstream log(work.log(), resume ? std::ios::app : std::ios::trunc);
    log << "lgpd: launch at " << static_cast<int64_t>(unixNow()) << ":";
    for (const auto& a : argv) log << " '" << a << "'";
    log << "\n";
  }
  if (auto s = store_.markStarted(id, resume, resume_generation); !s) return s;
  auto child = ChildProcess::spawn(argv, env, work.log());
  if (!child) return Status::error("cannot start " + argv[0] + ": " + child.error());
  lgp::writeTextAtomic(std::to_string(child->pid()) + "\n", work.pidFile());
  launched();
  spdlog::info("run {} {} over MPI: {} -np {} (pid {}){}", id, resume ? "resumed" : "started",
               argv[0], cfg.mpi.np, child->pid(),
               resume ? " from generation " + std::to_string(resume_generation) : "");

  RunCounters counters = run.counters;
  counters.generation = resume_generation;
  FileVersion seen_status, seen_ckpt = FileVersion::of(work.checkpoint());
  // A front for the store from each checkpoint, by restoring it into an in-process Search
  // (built on first use: the daemon then holds the table too).
  std::unique_ptr<lgp::Search> viewer;
  bool viewer_failed = false;
  json viewer_refs;  // the references scored on the viewer's table, once
  auto frontOf = [&](const json& state) -> std::optional<json> {
    if (viewer_failed) return std::nullopt;
    if (!viewer) {
      auto table = lgp::cli::loadRunTable(cfg);
      if (!table) {
        spdlog::warn("run {}: no live front ({})", id, table.error());
        viewer_failed = true;
        return std::nullopt;
      }
      // A run over more ranks than its islands raised the count: take it from the state.
      lgp::RunConfig view_cfg = cfg;
      lgp::Search::adoptCheckpointIslands(view_cfg, state);
      viewer = std::make_unique<lgp::Search>(view_cfg, std::move(*table));
#ifdef LGP_HAVE_EMIT
      if (cfg.references.is_array() && !cfg.references.empty())
        viewer_refs = lgp::emit::scoreReferences(viewer->config(), viewer->table());
#endif
    }
    if (auto s = viewer->restore(state); !s) {
      spdlog::warn("run {}: checkpoint kept without a front ({})", id, s.message());
      viewer_failed = true;  // the same would happen with every later checkpoint
      return std::nullopt;
    }
    json front = lgp::frontToJson(*viewer, viewer->front());
    if (!viewer_refs.is_null()) front["references"] = viewer_refs;
    addMeasuredCost(cfg, front);
    return front;
  };
  // The first write to the store that failed (a full disk): the ranks are stopped as for a
  // cancel and the run fails with this reason, as an in-process run does.
  std::string store_failure;
  auto pollStatus = [&] {
    auto v = FileVersion::of(work.status());
    if (!v.exists || v == seen_status) return;
    seen_status = v;
    auto st = readJsonFile(work.status());
    if (!st) return;
    applyStatus(*st, counters);
    if (auto s = store_.updateProgress(id, counters); !s) {
      spdlog::error("run {}: progress: {}", id, s.message());
      if (store_failure.empty()) store_failure = "cannot store the run's progress: " + s.message();
    }
  };
  auto pollCheckpoint = [&] {
    auto v = FileVersion::of(work.checkpoint());
    if (!v.exists || v == seen_ckpt) return;
    seen_ckpt = v;
    auto state = readJsonFile(work.checkpoint());
    if (!isCheckpoint(state)) return;
    RunCounters c = counters;
    c.generation = (*state)["generation"].get<int>();
    c.evaluations = state->value("evaluations", c.evaluations);
    c.elapsed_s = state->value("elapsed_s", c.elapsed_s);
    auto front = frontOf(*state);
    if (front) applyFront(*front, c);
    if (auto s = store_.writeCheckpoint(id, *state, front ? &*front : nullptr, c); !s) {
      spdlog::error("run {}: checkpoint: {}", id, s.message());
      if (store_failure.empty())
        store_failure = "cannot store the run's checkpoint: " + s.message();
    } else {
      counters.best = c.best;
    }
  };

  // Wait for the child; a stop request is SIGUSR1 (mpirun forwards it to every rank, which
  // finish their generation and write the front and a checkpoint), then SIGTERM after the
  // grace period (mpirun kills the ranks a second later), then SIGKILL to the whole process
  // group after another min(grace, 10 s).
  const auto grace = std::chrono::duration<double>(cfg_.mpi.stop_grace_s);
  const auto kill_after =
      grace + std::min<std::chrono::duration<double>>(grace, std::chrono::seconds(10));
  std::optional<clock::time_point> stop_at;
  int stage = 0;  // signals sent: 1 = USR1, 2 = TERM, 3 = KILL
  int wait_status = 0;
  for (;;) {
    if (auto st = child->poll()) {
      wait_status = *st;
      break;
    }
    if (job.cancel.load() || job.deleted.load() || job.shutdown.load() || !store_failure.empty()) {
      const auto now = clock::now();
      if (!stop_at) stop_at = now;
      if (stage == 0) {
        child->signal(SIGUSR1);
        stage = 1;
      } else if (stage == 1 && now - *stop_at >= grace) {
        spdlog::warn("run {}: launcher still running {} s after SIGUSR1; sending SIGTERM", id,
                     cfg_.mpi.stop_grace_s);
        child->signal(SIGTERM);
        stage = 2;
      } else if (stage == 2 && now - *stop_at >= kill_after) {
        spdlog::warn("run {}: killing the launcher's process group", id);
        child->signalGroup(SIGKILL);
        child->signal(SIGKILL);
        stage = 3;
      }
    }
    if (!job.deleted.load()) {
      pollStatus();
      pollCheckpoint();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  // Ranks the launcher left behind in its group (it normally reaps them itself).
  child->signalGroup(SIGKILL);
  const std::string how =
      fs::path(argv[0]).filename().string() + " " + describeWaitStatus(wait_status);
  spdlog::info("run {}: {}", id, how);

  if (job.deleted.load()) {
    fs::remove_all(work.dir, ec);
    return Status::ok();
  }
  if (!store_failure.empty() && !job.cancel.load() && !job.shutdown.load())
    return Status::error(store_failure + " (the launch was stopped; its work dir " +
                         work.dir.string() + " is kept)");
  const bool exited = WIFEXITED(wait_status);
  const int code = exited ? WEXITSTATUS(wait_status) : -1;
  // lgpd may be stopping by a signal that also reached the child first (a service manager
  // signals the whole cgroup): give the shutdown a moment to show before calling it a failure.
  if (!(exited && code == 0) && !job.cancel.load())
    for (int i = 0; i < 40 && !job.shutdown.load(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  pollStatus();
  if (auto st = readJsonFile(work.status())) applyStatus(*st, counters);

  if (job.shutdown.load() && !(exited && code == 0) && !job.cancel.load()) {
    // Stays "running": the next lgpd relaunches it with --resume.
    pollCheckpoint();
    spdlog::info("run {} stopped for shutdown at generation {}", id, counters.generation);
    return Status::ok();
  }
  std::optional<json> front;
  if (exited && (code == 0 || code == 130)) {
    front = readJsonFile(work.front());
    if (front && (!front->is_object() || front->value("format", "") != "lgp-front/1"))
      front.reset();
  }
  if (job.cancel.load()) {
    // With no front file (the launch died instead of stopping) the last snapshot is final.
    if (front) applyFront(*front, counters);
    auto s = store_.finishRun(id, RunStatus::Cancelled, front ? &*front : nullptr, counters, "");
    if (!s) return s;
    spdlog::info("run {} cancelled at generation {}{}", id, counters.generation,
                 front ? "" : " (no final front from the launch: " + how + ")");
    fs::remove_all(work.dir, ec);
    return Status::ok();
  }
  if (exited && code == 0 && front) {
    applyFront(*front, counters);
    auto s = store_.finishRun(id, RunStatus::Finished, &*front, counters, "");
    if (!s) return s;
    spdlog::info("run {} finished: generation {}, {} evaluations, front of {}", id,
                 counters.generation, counters.evaluations, counters.front_size);
    fs::remove_all(work.dir, ec);
    return Status::ok();
  }
  // Failed: the newest checkpoint goes to the store (it stays there), the work dir with its
  // log stays for a post-mortem.
  pollCheckpoint();
  std::string msg = "MPI launch failed: " + how + hintFor(wait_status);
  if (exited && code == 0) msg += ", but wrote no valid front to " + work.front().string();
  const std::string tail = fileTail(work.log(), 15, 3000);
  if (!tail.empty()) msg += "; last output:\n" + tail;
  return Status::error(msg);
}

bool JobManager::isActive(const std::string& id) const {
  std::lock_guard lock(mutex_);
  auto it = jobs_.find(id);
  return it != jobs_.end() && !it->second->finished.load();
}

Expected<bool> JobManager::cancel(const std::string& id) {
  std::lock_guard lock(mutex_);
  auto it = jobs_.find(id);
  if (it == jobs_.end() || it->second->finished.load()) {
    // Not active: a queued run is cancelled in the store (the job thread re-checks status
    // before starting, so a concurrent launch sees the cancel).
    if (auto s = store_.cancelQueued(id); !s) {
      spdlog::error("run {}: {}", id, s.message());
      return s;
    }
    return false;
  }
  it->second->cancel.store(true);
  // The job stops either way; the flag in the store only matters if lgpd dies before the job
  // writes its end.
  auto s = store_.requestCancel(id);
  if (!s) spdlog::error("run {}: {}", id, s.message());
  it->second->requestStop();
  return true;
}

Expected<bool> JobManager::remove(const std::string& id) {
  {
    std::lock_guard lock(mutex_);
    auto it = jobs_.find(id);
    if (it != jobs_.end()) {
      it->second->deleted.store(true);
      it->second->requestStop();
    }
  }
  {
    std::lock_guard lock(table_mutex_);
    tables_.erase(id);
    std::erase(table_order_, id);
    ref_scores_.erase(id);
  }
  // Rows go now; a job still finishing its generation skips every write once it sees the
  // flag, and foreign keys reject any write that races with this.
  auto r = store_.deleteRun(id);
  std::error_code ec;
  if (isValidRunId(id)) {
    fs::remove(inlineTablePath(id), ec);
    // An active MPI job removes its work dir itself once its launcher is gone.
    if (!isActive(id)) fs::remove_all(mpiWorkDir(id), ec);
  }
  return r;
}

void JobManager::shutdown() {
  std::vector<std::unique_ptr<Job>> jobs;
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return;
    stopping_ = true;
    for (auto& [id, job] : jobs_) job->shutdown.store(true);
  }
  cv_.notify_all();
  if (scheduler_.joinable()) scheduler_.join();
  {
    std::lock_guard lock(mutex_);
    for (auto& [id, job] : jobs_) jobs.push_back(std::move(job));
    jobs_.clear();
  }
  for (auto& job : jobs)
    if (job->thread.joinable()) job->thread.join();
  {
    std::lock_guard lock(bg_mutex_);
    bg_stopping_ = true;
    bg_tasks_.clear();
  }
  bg_cv_.notify_all();
  if (bg_thread_.joinable()) bg_thread_.join();
}

}  // namespace lgpd
