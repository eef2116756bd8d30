// The in-process job of a run: the run pipeline (run_pipeline.hpp) with the store as its
// output. See jobs.hpp for what is written when.
#include <spdlog/spdlog.h>

#include <cerrno>
#include <cstdlib>
#include <limits>
#include <system_error>
#include <thread>
#include <vector>

#include "job.hpp"
#include "run_pipeline.hpp"
#include "table_source.hpp"

namespace lgpd {

using lgp::Expected;
using lgp::Status;
using nlohmann::json;

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

// The search's threads: capped at the cores lgpd may use (lgp::Search does so), and started
// once here, so that a machine that cannot give them fails the run with a message rather than
// in the OpenMP runtime, which ends the process.
Status checkThreads(const std::string& id, const lgp::RunConfig& cfg) {
  const int cores = lgp::Search::maxThreads();
  if (cfg.search.threads > cores)
    spdlog::warn("run {}: search.threads {} capped at the {} cores lgpd may use", id,
                 cfg.search.threads, cores);
  const int threads = cfg.search.threads > 0 ? std::min(cfg.search.threads, cores) : cores;
  return probeThreads(threads);
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

// The search restored from the run's stored checkpoint when there is one (*resumed); one that
// cannot be read or that the search rejects means a fresh start.
std::unique_ptr<lgp::Search> restoredSearch(Store& store, const std::string& id,
                                            const lgp::RunConfig& cfg, const lgp::Table& table,
                                            bool* resumed) {
  auto search = std::make_unique<lgp::Search>(cfg, table);
  *resumed = false;
  auto ckpt = store.loadCheckpoint(id);
  if (!ckpt) {
    spdlog::warn("run {}: {}; starting from scratch", id, ckpt.error());
  } else if (*ckpt) {
    auto s = search->restore(**ckpt);
    if (s) {
      *resumed = true;
    } else {
      spdlog::warn("run {}: checkpoint rejected ({}); starting from scratch", id, s.message());
      search = std::make_unique<lgp::Search>(cfg, table);
    }
  }
  return search;
}

}  // namespace

// A local job's search and the fronts it stores: the pipeline's front with the run's extras,
// and the best of each objective for the counters.
struct JobManager::LocalRun {
  Job& job;
  lgp::Search& search;
  const lgp::cli::FrontExtras& extras;
  json exhaustive;  // the enumeration's certificate (never, while lgpd rejects it)
  json best = json::object();

  json front() {
    json f = lgp::cli::frontJson(search, exhaustive);
    extras.addTo(f);
    best = bestPerObjective(f);
    return f;
  }
  // After front(): its bests are the counters'.
  RunCounters counters() const { return countersOf(search.progress(), best); }
};

Status JobManager::runLocalJob(Job& job, const lgp::RunConfig& cfg,
                               std::unique_ptr<lgp::Search>& search,
                               const std::function<void()>& started) {
  const std::string& id = job.id;
  spdlog::info("run {}: loading its table", id);
  lgp::cli::TableLoadOptions load;
  load.stop = [&job] { return job.stopRequested(); };
  auto loaded = lgp::cli::loadRunTable(cfg, load);
  if (!loaded && job.stopRequested()) return stoppedBeforeStart(job);
  if (!loaded) return loaded.status();
  auto table = std::make_shared<const lgp::Table>(std::move(*loaded));
  publishTable(id, table);
  // The references, scored once on the run's table and stored with every front.
  if (cfg.references.is_array() && !cfg.references.empty())
    spdlog::info("run {}: scoring {} reference(s)", id, cfg.references.size());
  const lgp::cli::FrontExtras extras(cfg, *table);
  if (auto s = checkThreads(id, cfg); !s) return s;

  bool resumed = false;
  search = restoredSearch(store_, id, cfg, *table, &resumed);
  auto seeds = lgp::cli::prepareRun(cfg, *table, resumed, false);
  if (!seeds) return seeds.status();
  if (!seeds->empty()) spdlog::info("run {}: seeding from its references", id);
  auto start = lgp::cli::startSearch(*search, *seeds, !resumed);
  if (!start) return start.status();
  for (const auto& why : start->not_seeded) spdlog::warn("run {}: not seeded: {}", id, why);
  if (!resumed) search->initialize();
  job.attach(search.get());
  if (job.cancel.load() || job.deleted.load()) search->requestStop();
  if (auto s = store_.markStarted(id, resumed, search->progress().generation); !s) return s;
  spdlog::info("run {} {} at generation {}", id, resumed ? "resumed" : "started",
               search->progress().generation);

  LocalRun run{job, *search, extras, std::move(start->exhaustive)};
  if (auto s = stepLocalJob(run, started); !s) return s;
  return endLocalJob(run);
}

Status JobManager::stoppedBeforeStart(Job& job) {
  const std::string& id = job.id;
  if (job.deleted.load()) {  // its rows are gone: nothing to write
    spdlog::info("run {} deleted before its search started", id);
    return Status::ok();
  }
  if (job.cancel.load()) {
    spdlog::info("run {} cancelled before its search started", id);
    return store_.cancelQueued(id);
  }
  spdlog::info("run {} stays queued for the next lgpd (stopped before its search)", id);
  return Status::ok();  // shutdown: still queued, the next start takes it
}

Status JobManager::stepLocalJob(LocalRun& run, const std::function<void()>& started) {
  using clock = std::chrono::steady_clock;
  const std::string& id = run.job.id;
  auto last_ckpt = clock::now(), last_progress = clock::now(), last_front = clock::now();
  while (!run.search.done() && !run.job.shutdown.load()) {
    run.search.step();
    started();  // the start is through: table, references, seeds and a first generation
    if (run.job.deleted.load()) break;
    auto now = clock::now();
    if (seconds(now - last_ckpt) >= cfg_.checkpoint_interval_s) {
      json front = run.front();
      auto s = store_.writeCheckpoint(id, run.search.checkpoint(), &front, run.counters());
      if (!s) return Status::error("cannot store the run's checkpoint: " + s.message());
      last_ckpt = last_progress = last_front = now;
    } else if (seconds(now - last_front) >= cfg_.front_interval_s) {
      json front = run.front();
      auto s = store_.writeFrontSnapshot(id, front, run.counters());
      if (!s) return Status::error("cannot store the run's front: " + s.message());
      last_front = last_progress = now;
    } else if (seconds(now - last_progress) >= cfg_.progress_interval_s) {
      auto s = store_.updateProgress(id, countersOf(run.search.progress(), run.best));
      if (!s) return Status::error("cannot store the run's progress: " + s.message());
      last_progress = now;
    }
  }
  return Status::ok();
}

Status JobManager::endLocalJob(LocalRun& run) {
  Job& job = run.job;
  const std::string& id = job.id;
  if (job.deleted.load()) return Status::ok();
  if (job.shutdown.load() && !run.search.done()) {
    // Daemon stopping: keep the run "running" with a fresh checkpoint; the next start
    // resumes it.
    json front = run.front();
    auto s = store_.writeCheckpoint(id, run.search.checkpoint(), &front, run.counters());
    if (!s) spdlog::error("run {}: checkpoint at shutdown: {}", id, s.message());
    spdlog::info("run {} checkpointed at generation {} for shutdown", id,
                 run.search.progress().generation);
    return Status::ok();
  }
  json front = run.front();
  auto p = run.search.progress();
  RunStatus status = job.cancel.load() ? RunStatus::Cancelled : RunStatus::Finished;
  job.attach(nullptr);
  // An empty front is not a result (as for `lgp run`): every program scored NaN or infinity,
  // which the archive never keeps. A cancelled run may end empty.
  if (status == RunStatus::Finished && front["members"].empty())
    return Status::error(lgp::cli::emptyFrontMessage(run.search));
  // The run's front size is its final front's (measured costs can drop archive members).
  RunCounters counters = countersOf(p, run.best);
  counters.front_size = static_cast<int64_t>(front["members"].size());
  auto s = store_.finishRun(id, status, &front, counters, "");
  if (!s) return Status::error("cannot store the run's final front: " + s.message());
  spdlog::info("run {} {}: generation {}, {} evaluations, front of {}", id, toString(status),
               p.generation, p.evaluations, counters.front_size);
  return Status::ok();
}

}  // namespace lgpd
