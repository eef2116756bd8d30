#include "jobs.hpp"
#ifdef LGP_HAVE_EMIT
#include "lgp/emit/score.hpp"
#endif

#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <random>

#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "table_source.hpp"

namespace lgpd {

using lgp::Expected;
using lgp::Status;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

constexpr size_t kMaxNameLength = 120;
constexpr size_t kTableCacheSize = 4;

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

bool isValidRunId(const std::string& id) {
  if (id.size() != 16) return false;
  for (char c : id)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
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
}

JobManager::~JobManager() {
  shutdown();
}

fs::path JobManager::inlineTablePath(const std::string& id) const {
  return cfg_.data_dir / "tables" / (id + ".json");
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
  if (cfg->search.multi_output.mode == lgp::MultiOutputMode::TwoStep)
    return Status::error(
        "/search/multi_output/mode: two_step runs are not served by lgpd yet "
        "(no checkpointing across steps); run them with `lgp run`");
#ifndef LGP_HAVE_EMIT
  if (cfg->search.seed_references)
    return Status::error("/search/seed_references: this lgpd was built without the parser");
#endif
  // Load the table now so that a missing file or column is a 400, not a failed run.
  if (out.record.inline_table) {
    auto raw = lgp::parseJsonTable(*out.record.inline_table, "/data/table");
    if (!raw) return raw.status();
    auto table = lgp::selectColumns(*raw, cfg->data.inputs, cfg->data.outputs, cfg->data.weights,
                                    "/data/table");
    if (!table) return table.status();
  } else {
    auto table = lgp::cli::loadRunTable(*cfg);
    if (!table) return table.status();
  }
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

Expected<std::string> JobManager::submit(PreparedRun run) {
  if (auto s = store_.insertRun(run.record); !s) return s;
  if (auto s = resolveInlineTable(run.record); !s)
    spdlog::warn("run {}: {}", run.record.id, s.message());
  { std::lock_guard lock(mutex_); }
  cv_.notify_all();
  spdlog::info("run {} queued{}", run.record.id,
               run.record.name.empty() ? "" : " (" + run.record.name + ")");
  return run.record.id;
}

Expected<std::shared_ptr<const lgp::Table>> JobManager::table(const RunRecord& run) {
  {
    std::lock_guard lock(table_mutex_);
    if (auto it = tables_.find(run.id); it != tables_.end()) return it->second;
  }
  auto cfg = config(run);
  if (!cfg) return cfg.status();
  if (auto s = resolveInlineTable(run); !s) return s;
  auto t = lgp::cli::loadRunTable(*cfg);
  if (!t) return t.status();
  auto ptr = std::make_shared<const lgp::Table>(std::move(*t));
  std::lock_guard lock(table_mutex_);
  tables_[run.id] = ptr;
  table_order_.push_back(run.id);
  while (table_order_.size() > kTableCacheSize) {
    tables_.erase(table_order_.front());
    table_order_.erase(table_order_.begin());
  }
  return ptr;
}

Status JobManager::start() {
  auto running = store_.runningRuns();
  if (!running) return running.status();
  std::error_code ec;
  fs::create_directories(cfg_.data_dir / "tables", ec);
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
  raw->thread = std::thread([this, raw] { runJob(*raw); });
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
      raw->thread = std::thread([this, raw] { runJob(*raw); });
    }
  }
}

namespace {

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
  auto finish = [&] { job.finished.store(true), cv_.notify_all(); };
  auto fail = [&](const std::string& msg) {
    spdlog::error("run {} failed: {}", id, msg);
    if (!job.deleted.load()) {
      auto s = store_.failRun(id, msg);
      if (!s) spdlog::error("run {}: {}", id, s.message());
    }
    finish();
  };
  try {
    auto rec = store_.getRun(id);
    if (!rec) return fail(rec.error());
    if (!*rec) return finish();  // deleted meanwhile
    const RunRecord run = **rec;
    if (run.status != RunStatus::Queued && run.status != RunStatus::Running) return finish();
    if (run.cancel_requested) job.cancel.store(true);

    auto cfg = config(run);
    if (!cfg) return fail(cfg.error());
    if (auto s = resolveInlineTable(run); !s) return fail(s.message());
    auto table = lgp::cli::loadRunTable(*cfg);
    if (!table) return fail(table.error());

    auto search = std::make_unique<lgp::Search>(*cfg, *table);
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
    if (!resumed) {
#ifdef LGP_HAVE_EMIT
      if (cfg->search.seed_references) {
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
      best = bestPerObjective(front);
      return front;
    };
    while (!search->done() && !job.shutdown.load()) {
      search->step();
      if (job.deleted.load()) break;
      auto now = clock::now();
      if (seconds(now - last_ckpt) >= cfg_.checkpoint_interval_s) {
        json front = snapshot();
        auto s = store_.writeCheckpoint(id, search->checkpoint(), front,
                                        countersOf(search->progress(), best));
        if (!s) spdlog::error("run {}: checkpoint: {}", id, s.message());
        last_ckpt = last_progress = last_front = now;
      } else if (seconds(now - last_front) >= cfg_.front_interval_s) {
        json front = snapshot();
        auto s = store_.writeFrontSnapshot(id, front, countersOf(search->progress(), best));
        if (!s) spdlog::error("run {}: front snapshot: {}", id, s.message());
        last_front = last_progress = now;
      } else if (seconds(now - last_progress) >= cfg_.progress_interval_s) {
        auto s = store_.updateProgress(id, countersOf(search->progress(), best));
        if (!s) spdlog::error("run {}: progress: {}", id, s.message());
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
      auto s = store_.writeCheckpoint(id, search->checkpoint(), front,
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
    auto s = store_.finishRun(id, status, &front, countersOf(p, best), "");
    if (!s) return fail(s.message());
    spdlog::info("run {} {}: generation {}, {} evaluations, front of {}", id, toString(status),
                 p.generation, p.evaluations, p.front_size);
    return finish();
  } catch (const std::exception& e) {
    {
      std::lock_guard lock(job.search_mutex);
      job.search = nullptr;
    }
    return fail(std::string("internal error: ") + e.what());
  }
}

bool JobManager::isActive(const std::string& id) const {
  std::lock_guard lock(mutex_);
  auto it = jobs_.find(id);
  return it != jobs_.end() && !it->second->finished.load();
}

bool JobManager::cancel(const std::string& id) {
  std::lock_guard lock(mutex_);
  auto it = jobs_.find(id);
  if (it == jobs_.end() || it->second->finished.load()) {
    // Not active: a queued run is cancelled in the store (the job thread re-checks status
    // before starting, so a concurrent launch sees the cancel).
    auto s = store_.cancelQueued(id);
    if (!s) spdlog::error("run {}: {}", id, s.message());
    return false;
  }
  it->second->cancel.store(true);
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
  }
  // Rows go now; a job still finishing its generation skips every write once it sees the
  // flag, and foreign keys reject any write that races with this.
  auto r = store_.deleteRun(id);
  std::error_code ec;
  if (isValidRunId(id)) fs::remove(inlineTablePath(id), ec);
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
}

}  // namespace lgpd
