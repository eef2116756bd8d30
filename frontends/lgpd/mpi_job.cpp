// The out-of-process job of an MPI run: `lgp run` (the run pipeline) under the MPI launcher
// in <data-dir>/mpi/<id>/, its files polled into the store. See jobs.hpp.
#include <spdlog/spdlog.h>

#include <csignal>
#include <fstream>
#include <limits>
#include <optional>

#include <sys/wait.h>
#include <unistd.h>

#include "job.hpp"
#include "lgp/io/result.hpp"
#include "run_pipeline.hpp"
#include "table_source.hpp"

namespace lgpd {

using lgp::Expected;
using lgp::Status;
using nlohmann::json;
namespace fs = std::filesystem;

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

// A front for the store from each checkpoint the child writes, by restoring it into an
// in-process Search (built on first use: the daemon then holds the table too) and adding the
// run's extras, as the child adds them to its final front.
class CheckpointFronts {
 public:
  // `stop`: the job's stop request, which ends a table generation (a scene's) at once.
  CheckpointFronts(const lgp::RunConfig& cfg, const std::string& id, std::function<bool()> stop)
      : cfg_(cfg), id_(id), stop_(std::move(stop)) {}

  std::optional<json> frontOf(const json& state) {
    if (failed_) return std::nullopt;
    if (!viewer_ && !build(state)) return std::nullopt;
    if (auto s = viewer_->restore(state); !s) {
      spdlog::warn("run {}: checkpoint kept without a front ({})", id_, s.message());
      failed_ = true;  // the same would happen with every later checkpoint
      return std::nullopt;
    }
    json front = lgp::cli::frontJson(*viewer_, json());
    extras_->addTo(front);
    return front;
  }

 private:
  bool build(const json& state) {
    lgp::cli::TableLoadOptions load;
    load.stop = stop_;
    auto table = lgp::cli::loadRunTable(cfg_, load);
    if (!table) {
      spdlog::warn("run {}: no live front ({})", id_, table.error());
      failed_ = true;
      return false;
    }
    // A run over more ranks than its islands raised the count: take it from the state.
    lgp::RunConfig view_cfg = cfg_;
    lgp::Search::adoptCheckpointIslands(view_cfg, state);
    viewer_ = std::make_unique<lgp::Search>(view_cfg, std::move(*table));
    extras_.emplace(viewer_->config(), viewer_->table());
    return true;
  }

  const lgp::RunConfig& cfg_;
  const std::string& id_;
  std::function<bool()> stop_;
  std::unique_ptr<lgp::Search> viewer_;
  std::optional<lgp::cli::FrontExtras> extras_;  // the references scored once
  bool failed_ = false;
};

// The checkpoint a launch resumes from: the newer of the work dir's (the launch before a
// crash may have written one after the last one lgpd stored) and the store's, left in the
// work dir. Returns its generation, or nullopt for a fresh start.
Expected<std::optional<int>> pickResume(Store& store, const std::string& id,
                                        const MpiWorkDir& work) {
  std::optional<json> resume_from = readJsonFile(work.checkpoint());
  if (!isCheckpoint(resume_from)) resume_from.reset();
  if (auto stored = store.loadCheckpoint(id); !stored) {
    spdlog::warn("run {}: {}", id, stored.error());
  } else if (isCheckpoint(*stored) &&
             (!resume_from ||
              (**stored)["generation"].get<int>() > (*resume_from)["generation"].get<int>())) {
    resume_from = std::move(*stored);
    if (auto s = lgp::writeTextAtomic(resume_from->dump(), work.checkpoint()); !s) return s;
  }
  std::error_code ec;
  if (!resume_from) fs::remove(work.checkpoint(), ec);
  if (!resume_from) return std::optional<int>();
  return std::optional<int>((*resume_from)["generation"].get<int>());
}

// The config the child reads: the stored one (absolute data paths), with every output path
// pointing into the work dir. A request's own output section never reaches the child.
Status writeChildConfig(const RunRecord& run, const fs::path& inline_table,
                        const fs::path& table_cache, const MpiWorkDir& work,
                        const DaemonConfig& daemon) {
  json rc = run.config;
  if (run.inline_table) rc["data"]["path"] = inline_table.string();
  if (rc.contains("data") && rc["data"].is_object() && rc["data"].contains("scene"))
    rc["data"]["cache_dir"] = table_cache.string();  // lgpd's own (JobManager::config)
  json output = {{"front_json", work.front().string()},
                 {"front_csv", ""},
                 {"progress_interval_s", daemon.progress_interval_s},
                 {"checkpoint", work.checkpoint().string()},
                 {"checkpoint_interval_s", daemon.checkpoint_interval_s}};
  if (auto o = rc.find("output");
      o != rc.end() && o->is_object() && o->contains("progress_cost_levels"))
    output["progress_cost_levels"] = (*o)["progress_cost_levels"];
  rc["output"] = std::move(output);
  return lgp::writeTextAtomic(rc.dump(2) + "\n", work.config());
}

}  // namespace

// A launched child and the files it writes: its status becomes the counters, each new
// checkpoint is stored with a front rebuilt from it.
struct JobManager::MpiChild {
  Store& store;
  const std::string& id;
  MpiWorkDir work;
  ChildProcess process;
  std::string launcher;  // argv[0]'s file name, for the messages
  RunCounters counters;
  CheckpointFronts fronts;
  FileVersion seen_status, seen_ckpt;
  // The first write to the store that failed (a full disk): the ranks are stopped as for a
  // cancel and the run fails with this reason, as an in-process run does.
  std::string store_failure;

  void pollStatus() {
    auto v = FileVersion::of(work.status());
    if (!v.exists || v == seen_status) return;
    seen_status = v;
    auto st = readJsonFile(work.status());
    if (!st) return;
    applyStatus(*st, counters);
    if (auto s = store.updateProgress(id, counters); !s) {
      spdlog::error("run {}: progress: {}", id, s.message());
      if (store_failure.empty()) store_failure = "cannot store the run's progress: " + s.message();
    }
  }
  void pollCheckpoint() {
    auto v = FileVersion::of(work.checkpoint());
    if (!v.exists || v == seen_ckpt) return;
    seen_ckpt = v;
    auto state = readJsonFile(work.checkpoint());
    if (!isCheckpoint(state)) return;
    RunCounters c = counters;
    c.generation = (*state)["generation"].get<int>();
    c.evaluations = state->value("evaluations", c.evaluations);
    c.elapsed_s = state->value("elapsed_s", c.elapsed_s);
    auto front = fronts.frontOf(*state);
    if (front) applyFront(*front, c);
    if (auto s = store.writeCheckpoint(id, *state, front ? &*front : nullptr, c); !s) {
      spdlog::error("run {}: checkpoint: {}", id, s.message());
      if (store_failure.empty())
        store_failure = "cannot store the run's checkpoint: " + s.message();
    } else {
      counters.best = c.best;
    }
  }
};

Status JobManager::runMpiJob(Job& job, const RunRecord& run, const lgp::RunConfig& cfg,
                             const std::function<void()>& launched) {
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
  auto resume_generation = pickResume(store_, id, work);
  if (!resume_generation) return resume_generation.status();
  const bool resume = resume_generation->has_value();
  const int generation = resume_generation->value_or(0);
  if (auto s = writeChildConfig(run, inlineTablePath(id), tableCacheDir(), work, cfg_); !s) return s;

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
  if (auto s = store_.markStarted(id, resume, generation); !s) return s;
  auto process = ChildProcess::spawn(argv, env, work.log());
  if (!process) return Status::error("cannot start " + argv[0] + ": " + process.error());
  // The launcher's pid in its work dir, for whoever inspects a run by hand; nothing in lgpd
  // reads it, so a failed write is a warning, not a failed run.
  if (auto s = lgp::writeTextAtomic(std::to_string(process->pid()) + "\n", work.pidFile()); !s)
    spdlog::warn("run {}: {}", id, s.message());
  launched();
  spdlog::info("run {} {} over MPI: {} -np {} (pid {}){}", id, resume ? "resumed" : "started",
               argv[0], cfg.mpi.np, process->pid(),
               resume ? " from generation " + std::to_string(generation) : "");

  MpiChild child{store_,
                 id,
                 work,
                 std::move(*process),
                 fs::path(argv[0]).filename().string(),
                 run.counters,
                 CheckpointFronts(cfg, id, [&job] { return job.stopRequested(); }),
                 FileVersion(),
                 FileVersion::of(work.checkpoint()),
                 ""};
  child.counters.generation = generation;
  const int wait_status = waitForChild(job, child);
  return endMpiJob(job, child, wait_status);
}

int JobManager::waitForChild(Job& job, MpiChild& child) {
  using clock = std::chrono::steady_clock;
  // A stop request is SIGUSR1 (mpirun forwards it to every rank, which finish their
  // generation and write the front and a checkpoint), then SIGTERM after the grace period
  // (mpirun kills the ranks a second later), then SIGKILL to the whole process group after
  // another min(grace, 10 s).
  const auto grace = std::chrono::duration<double>(cfg_.mpi.stop_grace_s);
  const auto kill_after =
      grace + std::min<std::chrono::duration<double>>(grace, std::chrono::seconds(10));
  std::optional<clock::time_point> stop_at;
  int stage = 0;  // signals sent: 1 = USR1, 2 = TERM, 3 = KILL
  for (;;) {
    if (auto st = child.process.poll()) return *st;
    if (job.stopRequested() || !child.store_failure.empty()) {
      const auto now = clock::now();
      if (!stop_at) stop_at = now;
      if (stage == 0) {
        child.process.signal(SIGUSR1);
        stage = 1;
      } else if (stage == 1 && now - *stop_at >= grace) {
        spdlog::warn("run {}: launcher still running {} s after SIGUSR1; sending SIGTERM", child.id,
                     cfg_.mpi.stop_grace_s);
        child.process.signal(SIGTERM);
        stage = 2;
      } else if (stage == 2 && now - *stop_at >= kill_after) {
        spdlog::warn("run {}: killing the launcher's process group", child.id);
        child.process.signalGroup(SIGKILL);
        child.process.signal(SIGKILL);
        stage = 3;
      }
    }
    if (!job.deleted.load()) {
      child.pollStatus();
      child.pollCheckpoint();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

Status JobManager::endMpiJob(Job& job, MpiChild& child, int wait_status) {
  const std::string& id = child.id;
  const MpiWorkDir& work = child.work;
  std::error_code ec;
  // Ranks the launcher left behind in its group (it normally reaps them itself).
  child.process.signalGroup(SIGKILL);
  const std::string how = child.launcher + " " + describeWaitStatus(wait_status);
  spdlog::info("run {}: {}", id, how);

  if (job.deleted.load()) {
    fs::remove_all(work.dir, ec);
    return Status::ok();
  }
  if (!child.store_failure.empty() && !job.cancel.load() && !job.shutdown.load())
    return Status::error(child.store_failure + " (the launch was stopped; its work dir " +
                         work.dir.string() + " is kept)");
  const bool exited = WIFEXITED(wait_status);
  const int code = exited ? WEXITSTATUS(wait_status) : -1;
  // lgpd may be stopping by a signal that also reached the child first (a service manager
  // signals the whole cgroup): give the shutdown a moment to show before calling it a failure.
  if (!(exited && code == 0) && !job.cancel.load())
    for (int i = 0; i < 40 && !job.shutdown.load(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  child.pollStatus();
  if (auto st = readJsonFile(work.status())) applyStatus(*st, child.counters);
  RunCounters& counters = child.counters;

  if (job.shutdown.load() && !(exited && code == 0) && !job.cancel.load()) {
    // Stays "running": the next lgpd relaunches it with --resume.
    child.pollCheckpoint();
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
  child.pollCheckpoint();
  std::string msg = "MPI launch failed: " + how + hintFor(wait_status);
  if (exited && code == 0) msg += ", but wrote no valid front to " + work.front().string();
  const std::string tail = fileTail(work.log(), 15, 3000);
  if (!tail.empty()) msg += "; last output:\n" + tail;
  return Status::error(msg);
}

}  // namespace lgpd
