#include "jobs.hpp"

#include "job.hpp"
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

constexpr size_t kMaxNameLength = 120;
constexpr size_t kTableCacheSize = 4;
constexpr size_t kMaxScoredReferenceRuns = 256;  // runs whose scored references are kept

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

fs::path JobManager::tableCacheDir() const {
  return cfg_.data_dir / "cache";
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
      if (data->contains("cache_dir"))
        return Status::error(
            "/data/cache_dir: lgpd keeps the tables it generates in its own cache (<data_dir>/"
            "cache) and writes no file a request names; remove the field");
      for (const char* key : {"path", "scene"}) {
        auto p = data->find(key);
        if (p == data->end() || !p->is_string() || p->get<std::string>().empty()) continue;
        if (auto why = lgp::controlCharacterReason(p->get<std::string>()); !why.empty())
          return Status::error(std::string("/data/") + key + ": " + why);
        std::string abs = absolutePath(p->get<std::string>(), cfg_.data_base_dir);
        if (auto s = checkDataPath(abs); !s)
          return Status::error(std::string("/data/") + key + ": " + s.message());
        *p = abs;
      }
    }
  }
  auto cfg = lgp::parseRunConfig(j, cfg_.data_base_dir);
  if (!cfg) return cfg.status();
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
  // The shape's bounds and the memory of its longest programs need the output count: known
  // for every table but a large JSON file whose columns the config does not name (priced at
  // the 255-opcode bound then, and the job checks the shape).
  std::optional<size_t> outputs;
  if (columns.known) {
    outputs = columns.outputs.size();
    if (auto s = cfg->validateShape(*outputs); !s) return s;
  }
  if (auto s = checkSearchMemory(*cfg, outputs, cfg_.runMemoryBytes()); !s) return s;
  if (auto s = checkReferencesAtSubmit(*cfg, columns); !s) return s;
  out.record.config = j;
  out.record.status = RunStatus::Queued;
  out.config = std::move(*cfg);
  return out;
}

Expected<lgp::RunConfig> JobManager::config(const RunRecord& run) const {
  json j = run.config;
  if (run.inline_table) j["data"]["path"] = inlineTablePath(run.id).string();
  // lgpd's own cache, whatever the stored config says (a run stored by an older lgpd may
  // name one).
  if (j.contains("data") && j["data"].is_object() && j["data"].contains("scene"))
    j["data"]["cache_dir"] = tableCacheDir().string();
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

Expected<JobManager::TablePtr> JobManager::loadTable(const RunRecord& run,
                                                     const std::atomic<bool>& halt) const {
  auto cfg = config(run);
  if (!cfg) return cfg.status();
  if (auto s = resolveInlineTable(run); !s) return s;
  if (!run.inline_table) {
    // The file may have been replaced (by a link to a file outside) since submit.
    if (auto s = checkDataPaths(*cfg); !s) return s;
    if (auto s = checkDataFiles(*cfg); !s) return s;
  }
  lgp::cli::TableLoadOptions opt;
  opt.stop = [&halt] { return halt.load(std::memory_order_relaxed); };
  auto t = lgp::cli::loadRunTable(*cfg, opt);
  if (!t) return t.status();
  return TablePtr(std::make_shared<const lgp::Table>(std::move(*t)));
}

std::shared_ptr<std::atomic<bool>> JobManager::loadHaltLocked(const std::string& id) {
  auto& flag = load_halts_[id];
  if (!flag) flag = std::make_shared<std::atomic<bool>>(loads_halted_);
  return flag;
}

void JobManager::releaseLoadHaltLocked(const std::string& id,
                                       const std::shared_ptr<std::atomic<bool>>& halt) {
  // Copies are made under table_mutex_ only: the map's and the caller's are the last two.
  if (auto it = load_halts_.find(id); it != load_halts_.end() && it->second == halt &&
                                      halt.use_count() <= 2)
    load_halts_.erase(it);
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
      background([this, run, promise, halt = loadHaltLocked(run.id)] {
        Expected<TablePtr> t = Status::error("lgpd is stopping");
        try {
          t = loadTable(run, *halt);
        } catch (const std::exception& e) {
          t = Status::error(std::string("cannot load the table: ") + e.what());
        } catch (...) {
          t = Status::error("cannot load the table: an unknown exception");
        }
        {
          std::lock_guard done_lock(table_mutex_);
          table_loads_.erase(run.id);  // an error is not kept: the file may come back
          releaseLoadHaltLocked(run.id, halt);
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
      background([this, run, promise, halt = loadHaltLocked(run.id)] {
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
              table = loadTable(run, *halt);
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
        {
          std::lock_guard done_lock(table_mutex_);
          releaseLoadHaltLocked(run.id, halt);
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
  // Owner-only: the generated tables are trusted only where no other user can write
  // (lgp::datasets::generateCached checks it).
  fs::create_directories(tableCacheDir(), ec);
  fs::permissions(tableCacheDir(), fs::perms::owner_all, fs::perm_options::replace, ec);
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
  auto fail = [&](const std::string& msg) {
    job.attach(nullptr);
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
    const Status s = cfg->mpi.np > 0 ? runMpiJob(job, run, *cfg, endStart)
                                     : runLocalJob(job, *cfg, search, endStart);
    job.attach(nullptr);
    if (!s) return fail(s.message());
    return finish();
  } catch (const std::bad_alloc&) {
    return fail("out of memory (the table or the search is too large for this machine)");
  } catch (const std::exception& e) {
    return fail(std::string("internal error: ") + e.what());
  } catch (...) {
    return fail("internal error: an unknown exception");
  }
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
    if (auto it = load_halts_.find(id); it != load_halts_.end()) {
      it->second->store(true);  // a background load of its table stops
      load_halts_.erase(it);
    }
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
  {
    std::lock_guard lock(table_mutex_);
    loads_halted_ = true;
    for (auto& [id, halt] : load_halts_) halt->store(true);
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
