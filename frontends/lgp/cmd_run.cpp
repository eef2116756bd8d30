// `lgp run cfg.json`: load the table, search, write the front (JSON + CSV).
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cxxopts.hpp>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/mpi_driver.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/two_step.hpp"
#include "run_pipeline.hpp"
#include "table_source.hpp"

namespace {

std::atomic<lgp::Search*> g_search{nullptr};
std::atomic<lgp::TwoStepSearch*> g_two_step{nullptr};
std::atomic<int> g_interrupts{0};

extern "C" void onSigint(int) {
  // First Ctrl-C: finish the generation and write the front. Second: leave at once.
  if (g_interrupts.fetch_add(1) >= 1) std::_Exit(130);
  if (auto* s = g_search.load()) s->requestStop();
  if (auto* s = g_two_step.load()) s->requestStop();
}

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

std::string fmtErr(double e) {
  if (!std::isfinite(e)) return "-";
  char b[32];
  std::snprintf(b, sizeof(b), "%.3g", e);
  return b;
}

cxxopts::Options runOptions(const char* argv0) {
  cxxopts::Options opts(argv0, "Run a symbolic-regression search from a JSON config.");
  opts.positional_help("config.json");
  opts.add_options()("config", "run config (JSON)", cxxopts::value<std::string>())(
      "o,out", "front JSON path (overrides output.front_json)", cxxopts::value<std::string>())(
      "csv", "front CSV path (overrides output.front_csv; '' disables)",
      cxxopts::value<std::string>())("seed", "override search.seed", cxxopts::value<uint64_t>())(
      "threads", "override search.threads", cxxopts::value<int>())(
      "generations", "override search.generations", cxxopts::value<int>())(
      "wall-time", "override search.wall_time_s", cxxopts::value<double>())(
      "checkpoint", "checkpoint file (overrides output.checkpoint), written atomically",
      cxxopts::value<std::string>())(
      "checkpoint-interval", "seconds between checkpoints (output.checkpoint_interval_s)",
      cxxopts::value<double>())("resume", "start from the checkpoint file")(
      "status", "write the progress counters to this JSON file at every progress tick",
      cxxopts::value<std::string>())(
      "front-every",
      "every this many seconds also write the front so far (no references, no measured costs) "
      "beside the front JSON as <name>.at<seconds>s.json: accuracy over time (one-process runs)",
      cxxopts::value<double>())("q,quiet", "no progress output")("h,help", "this help");
  opts.parse_positional({"config"});
  return opts;
}

// The command line's overrides of the config's search and output sections.
void applyOverrides(const cxxopts::ParseResult& args, lgp::RunConfig& cfg) {
  if (args.count("seed")) cfg.search.seed = args["seed"].as<uint64_t>();
  if (args.count("threads")) cfg.search.threads = std::max(0, args["threads"].as<int>());
  if (args.count("generations"))
    cfg.search.generations = std::max(0, args["generations"].as<int>());
  if (args.count("wall-time"))
    cfg.search.wall_time_s = std::max(0.0, args["wall-time"].as<double>());
  if (args.count("out")) cfg.output.front_json = args["out"].as<std::string>();
  if (args.count("csv")) cfg.output.front_csv = args["csv"].as<std::string>();
  if (args.count("checkpoint")) cfg.output.checkpoint = args["checkpoint"].as<std::string>();
  if (args.count("checkpoint-interval"))
    cfg.output.checkpoint_interval_s = std::max(0.0, args["checkpoint-interval"].as<double>());
}

// This process's place in an MPI run: every rank runs `lgp run`; rank 0 reads the files,
// prints and writes.
struct World {
  int rank = 0;
  int ranks = 1;
  bool root() const { return rank == 0; }
  bool distributed() const { return ranks > 1; }
  // Every rank reaches the same verdict on the same input; rank 0 says it.
  int fail(const std::string& msg, int code) const {
    if (root()) std::fprintf(stderr, "error: %s\n", msg.c_str());
    return code;
  }
};

// The config, read by rank 0 and sent to the others in an MPI run.
lgp::Expected<lgp::RunConfig> readConfig(const std::string& path, const World& world) {
#ifdef LGP_HAVE_MPI
  if (world.distributed()) {
    lgp::Expected<std::string> text = lgp::Status::error(path + ": not read");
    if (world.root()) text = lgp::readInputFile(path, lgp::kMaxConfigBytes);
    auto shared = lgp::mpi::shareBytes(text);
    if (!shared) return shared.status();
    return lgp::parseRunConfigText(*shared, path);
  }
#else
  (void)world;
#endif
  return lgp::loadRunConfig(path);
}

// What the config and the command line cannot ask together.
lgp::Status checkRunConfig(const lgp::RunConfig& cfg, bool resume, bool distributed) {
  if (auto st = cfg.validate(); !st) return st;
  if (resume && cfg.output.checkpoint.empty())
    return lgp::Status::error(
        "--resume: no checkpoint file named (--checkpoint or output.checkpoint)");
  const bool two_step = cfg.search.multi_output.mode == lgp::MultiOutputMode::TwoStep;
  if (two_step && !cfg.output.checkpoint.empty())
    return lgp::Status::error(
        "/output/checkpoint: not available with two_step (no checkpoint across steps)");
  if (two_step && distributed)
    return lgp::Status::error(
        "/search/multi_output: two_step does not run over MPI; run it in one process");
  return lgp::Status::ok();
}

// The table, loaded by rank 0 and sent to the others in an MPI run.
lgp::Expected<lgp::Table> readTable(const lgp::RunConfig& cfg, const World& world) {
  lgp::Expected<lgp::Table> table = lgp::Status::error("no table");
  if (world.root()) table = lgp::cli::loadRunTable(cfg);
#ifdef LGP_HAVE_MPI
  if (world.distributed()) table = lgp::mpi::shareTable(table);
#endif
  return table;
}

void printBanner(const lgp::RunConfig& cfg, const lgp::Table& table, const World& world) {
  std::fprintf(stderr, "lgp: %zu rows, inputs [%zu], outputs [%zu], population %d, seed %llu",
               table.rows(), table.numInputs(), table.numOutputs(), cfg.search.population,
               static_cast<unsigned long long>(cfg.search.seed));
  if (world.distributed())
    std::fprintf(stderr, ", %d MPI ranks (%s migration)", world.ranks,
                 std::string(lgp::toString(cfg.mpi.migration)).c_str());
  std::fprintf(stderr, "\n");
}

// The progress line on stderr and the status file (--status), at every progress tick.
class ProgressReport {
 public:
  ProgressReport(std::string status_path, bool root, bool quiet, bool tty)
      : status_path_(std::move(status_path)), root_(root), quiet_(quiet), tty_(tty) {}

  void operator()(const lgp::SearchProgress& p) {
    writeStatus(p);
    if (!quiet_) printLine(p);
  }
  // two_step's current step (0 otherwise): a new step starts a new line.
  void setStep(int step) {
    if (step != step_ && step_ > 0 && !quiet_ && tty_) std::fprintf(stderr, "\n");
    step_ = step;
  }
  // The last write of the status file must succeed: a run that ends with it stale (a full
  // disk) exits 1 after writing its front.
  const std::string& statusError() const { return status_error_; }

 private:
  void writeStatus(const lgp::SearchProgress& p) {
    if (status_path_.empty() || !root_) return;
    auto st = lgp::writeJsonAtomic(lgp::progressToJson(p), status_path_, 2);
    if (!st && !status_failed_) std::fprintf(stderr, "warning: %s\n", st.message().c_str());
    status_failed_ = !st;
    status_error_ = st ? "" : st.message();
  }
  void printLine(const lgp::SearchProgress& p) const {
    std::string levels;
    for (const auto& [c, e] : p.best_at_cost) {
      char b[64];
      std::snprintf(b, sizeof(b), " c<=%g:%s", c, fmtErr(e).c_str());
      levels += b;
    }
    const std::string step = step_ > 0 ? "step " + std::to_string(step_) + "  " : "";
    std::string mpi_info;
    if (p.ranks > 1)
      mpi_info = " | ranks " + std::to_string(p.ranks) + "  migrants " +
                 std::to_string(p.migrants) + " (" + std::to_string(p.remote_migrants) + " remote)";
    std::fprintf(stderr, "%s%sgen %d  evals %llu  %.3g evals/s  front %zu  best %s |%s%s%s",
                 tty_ ? "\r\033[K" : "", step.c_str(), p.generation,
                 static_cast<unsigned long long>(p.evaluations), p.evals_per_s, p.front_size,
                 fmtErr(p.best_error).c_str(), levels.c_str(), mpi_info.c_str(), tty_ ? "" : "\n");
    std::fflush(stderr);
  }

  std::string status_path_;
  bool root_, quiet_, tty_;
  int step_ = 0;
  bool status_failed_ = false;
  std::string status_error_;
};

// What a run asks of its display and files beyond the config.
struct RunFlags {
  bool resume = false;
  double front_every_s = 0;  // --front-every: 0 = no snapshots
  bool quiet = false;        // --quiet, or not rank 0
  bool tty = false;          // stderr is a terminal: progress rewrites one line
};

// The search of one process with one step (pipeline step 3): restored from the checkpoint
// with --resume, else seeded and, with search.exhaustive, enumerated first.
lgp::Expected<std::unique_ptr<lgp::Search>> buildSearch(lgp::RunConfig& cfg, lgp::Table table,
                                                        const std::vector<lgp::NamedProgram>& seeds,
                                                        const RunFlags& flags,
                                                        nlohmann::json& exhaustive) {
  lgp::Expected<nlohmann::json> ck = nlohmann::json();
  if (flags.resume) {
    ck = lgp::readCheckpointFile(cfg.output.checkpoint);
    if (!ck) return ck.status();
    if (lgp::Search::adoptCheckpointIslands(cfg, *ck) && !flags.quiet)
      std::fprintf(stderr, "lgp: %d islands, as in the checkpoint\n", cfg.search.islands.count);
  }
  auto search = std::make_unique<lgp::Search>(cfg, std::move(table));
  if (flags.resume)
    if (auto st = search->restore(*ck); !st)
      return lgp::Status::error(cfg.output.checkpoint + ": " + st.message());
  auto start = lgp::cli::startSearch(*search, seeds, !flags.resume);
  if (!start) return start.status();
  for (const auto& why : start->not_seeded)
    std::fprintf(stderr, "warning: /search/seed_references: not seeded: %s\n", why.c_str());
  exhaustive = std::move(start->exhaustive);
  if (!exhaustive.is_null() && !flags.quiet)
    std::fprintf(stderr,
                 "lgp: exhaustive: %s expressions fitted in %.1f s, up to %d operators complete\n",
                 exhaustive["fitted"].dump().c_str(), exhaustive["seconds"].get<double>(),
                 exhaustive["complete_ops"].get<int>());
  return search;
}

// --front-every's file for the snapshot due at `t` seconds: front.json -> front.at0030s.json.
std::string snapshotPath(const std::string& front_json, double t) {
  std::string stem = front_json;
  if (stem.size() > 5 && stem.compare(stem.size() - 5, 5, ".json") == 0)
    stem.resize(stem.size() - 5);
  char b[32];
  std::snprintf(b, sizeof(b), ".at%04.0fs.json", t);
  return stem + b;
}

// Search::run with checkpoints: every checkpoint_interval_s and once at the end. Returns the
// error of the last checkpoint write ("" when it succeeded): a run that ends with its
// checkpoint stale exits 1 after writing its front.
std::string runSearch(lgp::Search& search, const lgp::RunConfig& cfg, const RunFlags& flags,
                      ProgressReport& progress) {
  const std::string& ck_path = cfg.output.checkpoint;
  bool ck_failed = false;
  std::string checkpoint_error;
  auto checkpoint = [&]() {
    if (ck_path.empty()) return;
    auto st = lgp::writeCheckpointFile(search.checkpoint(), ck_path);
    if (!st && !ck_failed) std::fprintf(stderr, "\nwarning: %s\n", st.message().c_str());
    ck_failed = !st;
    checkpoint_error = st ? "" : st.message();
  };
  // Snapshots of the front (--front-every) by wall time since the run began, set-up included.
  const auto began = Clock::now();
  double next_snapshot = flags.front_every_s;
  auto snapshot = [&]() {
    if (flags.front_every_s <= 0 || since(began) < next_snapshot) return;
    const std::string path = snapshotPath(cfg.output.front_json, next_snapshot);
    if (auto st = lgp::writeFrontJson(lgp::cli::frontJson(search, nullptr), path); !st)
      std::fprintf(stderr, "\nwarning: %s\n", st.message().c_str());
    while (next_snapshot <= since(began)) next_snapshot += flags.front_every_s;
  };
  auto last_progress = Clock::now(), last_checkpoint = Clock::now();
  if (!flags.resume) search.initialize();
  progress(search.progress());
  while (!search.done()) {
    search.step();
    snapshot();
    if (since(last_progress) >= cfg.output.progress_interval_s) {
      progress(search.progress());
      last_progress = Clock::now();
    }
    if (since(last_checkpoint) >= cfg.output.checkpoint_interval_s) {
      checkpoint();
      last_checkpoint = Clock::now();
    }
  }
  checkpoint();
  progress(search.progress());
  if (!flags.quiet && flags.tty) std::fprintf(stderr, "\n");
  return checkpoint_error;
}

void runTwoStep(lgp::TwoStepSearch& stepped, const RunFlags& flags, ProgressReport& progress) {
  stepped.run([&](int step, const lgp::SearchProgress& p) {
    progress.setStep(step);
    progress(p);
  });
  if (!flags.quiet)
    std::fprintf(stderr, "%slgp: step 1 picked %s = %s\n", flags.tty ? "\n" : "",
                 stepped.pickColumn().c_str(),
                 lgp::toInfix(stepped.pick(), stepped.result().table().input_names)[0].c_str());
}

#ifdef LGP_HAVE_MPI
// Islands over the MPI ranks (lgp/search/mpi_driver.hpp). Rank 0 gets the assembled search
// and the per-rank MPI statistics; the other ranks get nullptr.
lgp::Expected<lgp::mpi::DistributedResult> runMpi(const lgp::RunConfig& cfg,
                                                  const lgp::Table& table,
                                                  std::vector<lgp::NamedProgram> seeds,
                                                  const RunFlags& flags, ProgressReport& progress) {
  lgp::mpi::DistributedOptions opt;
  opt.seeds = std::move(seeds);
  opt.checkpoint_path = cfg.output.checkpoint;
  opt.checkpoint_interval_s = cfg.output.checkpoint_interval_s;
  opt.resume = flags.resume;
  opt.on_progress = [&](const lgp::SearchProgress& p) { progress(p); };
  opt.on_warning = [&](const std::string& w) {
    std::fprintf(stderr, "%swarning: %s\n", flags.tty ? "\r\033[K" : "", w.c_str());
  };
  opt.on_search = [](lgp::Search* s) {
    g_search.store(s);
    if (s && g_interrupts.load() > 0) s->requestStop();  // a signal came during set-up
  };
  return lgp::mpi::runDistributed(cfg, table, std::move(opt));
}
#endif

// Pipeline step 5: the front JSON (and CSV) with its extras, and the closing lines.
int writeResults(const lgp::Search& search, const lgp::RunConfig& cfg,
                 const nlohmann::json& exhaustive, const nlohmann::json& mpi_stats,
                 const World& world, bool quiet) {
  auto j = lgp::cli::frontJson(search, exhaustive);
  const size_t members = j["members"].size();
  if (members == 0) {
    // Not a result: every program scored NaN or infinity (which the archive never keeps), or
    // none was scored. No front is written, and the exit status says the run failed.
    return world.fail(
        lgp::cli::emptyFrontMessage(search) + "; no front written to " + cfg.output.front_json,
        g_interrupts.load() > 0 ? 130 : 1);
  }
  if (!mpi_stats.is_null()) j["progress"]["mpi"] = mpi_stats;
  // After Ctrl-C a launcher such as mpirun gives the process about a second: the front goes
  // to disk first (atomically), then is rewritten with the references and measured costs.
  if (g_interrupts.load() > 0)
    if (auto st = lgp::writeFrontJson(j, cfg.output.front_json); !st) {
      std::fprintf(stderr, "error: %s\n", st.message().c_str());
      return 1;
    }
  const lgp::cli::FrontExtras extras(search.config(), search.table());
  if (const std::string note = extras.addTo(j); !note.empty() && !quiet)
    std::fprintf(stderr, "lgp: %s\n", note.c_str());
  if (auto st = lgp::writeFrontJson(j, cfg.output.front_json); !st) {
    std::fprintf(stderr, "error: %s\n", st.message().c_str());
    return 1;
  }
  if (!cfg.output.front_csv.empty())
    if (auto st = lgp::writeFrontCsv(j, cfg.output.front_csv); !st) {
      std::fprintf(stderr, "error: %s\n", st.message().c_str());
      return 1;
    }
  const auto p = search.progress();
  if (!quiet)
    std::fprintf(
        stderr,
        "lgp: stopped (%s) after %d generations, %llu evaluations, %.1f s; %zu members -> %s\n",
        p.stop_reason.c_str(), p.generation, static_cast<unsigned long long>(p.evaluations),
        p.elapsed_s, members, cfg.output.front_json.c_str());
  if (!quiet && p.cost_measurements > 0)
    std::fprintf(stderr,
                 "lgp: measured cost in the archive: %llu candidates compiled in %.1f s (%.0f %% "
                 "of the run)\n",
                 static_cast<unsigned long long>(p.cost_measurements), p.cost_measure_s,
                 p.elapsed_s > 0 ? 100 * p.cost_measure_s / p.elapsed_s : 0.0);
  return 0;
}

int runMain(int argc, char** argv) {
  cxxopts::Options opts = runOptions(argv[0]);
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "config", "no config given");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);

  if (const int tasks = lgp::mpi::slurmTasksWithoutPmi()) {
    std::fprintf(stderr,
                 "error: srun started %d tasks without MPI (no PMI), so each would run the whole "
                 "search: use `srun --mpi=pmix` (or pmi2)\n",
                 tasks);
    return 2;
  }
  World world;
#ifdef LGP_HAVE_MPI
  std::optional<lgp::mpi::Session> mpi;
  if (lgp::mpi::launchedByLauncher()) mpi.emplace(&argc, &argv);
  if (mpi) world = {mpi->rank(), mpi->size()};
#else
  if (lgp::mpi::launchedByLauncher()) {
    std::fprintf(stderr,
                 "error: an MPI launcher started this lgp, which was built without MPI "
                 "(LGP_WITH_MPI=OFF): every rank would run the whole search on its own. Install "
                 "OpenMPI (libopenmpi-dev) and rebuild, or run lgp without the launcher\n");
    return 2;
  }
#endif
  // Pipeline steps 1 and 2 (run_pipeline.hpp): the config, the table, the seeds.
  auto cfg = readConfig(args["config"].as<std::string>(), world);
  if (!cfg) return world.fail(cfg.error(), 2);
  applyOverrides(args, *cfg);
  RunFlags flags;
  flags.resume = args.count("resume") > 0;
  if (args.count("front-every")) {
    flags.front_every_s = args["front-every"].as<double>();
    if (!(flags.front_every_s > 0))
      return world.fail("--front-every: must be a number of seconds > 0", 2);
    if (world.distributed() || cfg->search.multi_output.mode == lgp::MultiOutputMode::TwoStep)
      return world.fail("--front-every: only for a one-process, one-step run", 2);
  }
  if (auto st = checkRunConfig(*cfg, flags.resume, world.distributed()); !st)
    return world.fail(st.message(), 2);
  auto table = readTable(*cfg, world);
  if (!table) return world.fail(table.error(), 2);
  auto seeds = lgp::cli::prepareRun(*cfg, *table, flags.resume, world.distributed());
  if (!seeds) return world.fail(seeds.error(), 2);
  flags.quiet = args.count("quiet") > 0 || !world.root();
  flags.tty = isatty(fileno(stderr));
  if (cfg->search.threads > lgp::Search::maxThreads() && world.root())
    std::fprintf(stderr,
                 "warning: /search/threads: %d capped at the %d cores this process may use\n",
                 cfg->search.threads, lgp::Search::maxThreads());
  if (!flags.quiet) printBanner(*cfg, *table, world);

  // Step 3: the search, one of three kinds.
  const bool two_step = cfg->search.multi_output.mode == lgp::MultiOutputMode::TwoStep;
  nlohmann::json exhaustive, mpi_stats;
  std::unique_ptr<lgp::Search> single;
  std::unique_ptr<lgp::TwoStepSearch> stepped;
  if (two_step) {
    stepped = std::make_unique<lgp::TwoStepSearch>(*cfg, std::move(*table));
    g_two_step.store(stepped.get());
  } else if (!world.distributed()) {
    auto built = buildSearch(*cfg, std::move(*table), *seeds, flags, exhaustive);
    if (!built) return world.fail(built.error(), 2);
    single = std::move(*built);
    g_search.store(single.get());
  }
  std::signal(SIGINT, onSigint);
  std::signal(SIGTERM, onSigint);
  // Open MPI's mpirun forwards SIGUSR1 to every rank and, unlike SIGTERM, kills no one after it.
  std::signal(SIGUSR1, onSigint);

  // Step 4: the search runs.
  ProgressReport progress(args.count("status") ? args["status"].as<std::string>() : "",
                          world.root(), flags.quiet, flags.tty);
  std::string checkpoint_error;
  if (stepped) {
    runTwoStep(*stepped, flags, progress);
  } else if (single) {
    checkpoint_error = runSearch(*single, *cfg, flags, progress);
  } else {
#ifdef LGP_HAVE_MPI
    auto result = runMpi(*cfg, *table, std::move(*seeds), flags, progress);
    if (!result) return world.fail(result.error(), 2);
    if (!world.root()) return g_interrupts.load() > 0 ? 130 : 0;
    single = std::move(result->search);
    mpi_stats = std::move(result->stats);
    if (!flags.quiet && flags.tty) std::fprintf(stderr, "\n");
#endif
  }
  g_search.store(nullptr);
  g_two_step.store(nullptr);

  // Step 5: the front.
  const lgp::Search& search = stepped ? stepped->result() : *single;
  if (int code = writeResults(search, *cfg, exhaustive, mpi_stats, world, flags.quiet); code)
    return code;
  if (!checkpoint_error.empty())
    return world.fail("the last checkpoint was not written: " + checkpoint_error, 1);
  if (!progress.statusError().empty())
    return world.fail("the last status was not written: " + progress.statusError(), 1);
  return g_interrupts.load() > 0 ? 130 : 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kRunCommand, "run", "run a search from a JSON config and write its front",
                     runMain);
