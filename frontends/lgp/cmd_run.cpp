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
#include "run_extras.hpp"
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

int runMain(int argc, char** argv) {
  cxxopts::Options opts(argv[0], "Run a symbolic-regression search from a JSON config.");
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
      cxxopts::value<std::string>())("q,quiet", "no progress output")("h,help", "this help");
  opts.parse_positional({"config"});
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "config", "no config given");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);

  // Under an MPI launcher every rank runs this; rank 0 reads the files, prints and writes.
  if (const int tasks = lgp::mpi::slurmTasksWithoutPmi()) {
    std::fprintf(stderr,
                 "error: srun started %d tasks without MPI (no PMI), so each would run the whole "
                 "search: use `srun --mpi=pmix` (or pmi2)\n",
                 tasks);
    return 2;
  }
#ifdef LGP_HAVE_MPI
  std::optional<lgp::mpi::Session> mpi;
  if (lgp::mpi::launchedByLauncher()) mpi.emplace(&argc, &argv);
  const int rank = mpi ? mpi->rank() : 0;
  const int ranks = mpi ? mpi->size() : 1;
#else
  if (lgp::mpi::launchedByLauncher()) {
    std::fprintf(stderr,
                 "error: an MPI launcher started this lgp, which was built without MPI "
                 "(LGP_WITH_MPI=OFF): every rank would run the whole search on its own. Install "
                 "OpenMPI (libopenmpi-dev) and rebuild, or run lgp without the launcher\n");
    return 2;
  }
  const int rank = 0, ranks = 1;
#endif
  const bool root = rank == 0;
  const bool distributed = ranks > 1;
  // Every rank reaches the same verdict on the same input; rank 0 says it.
  auto fail = [&](const std::string& msg, int code) {
    if (root) std::fprintf(stderr, "error: %s\n", msg.c_str());
    return code;
  };
  const std::string config_path = args["config"].as<std::string>();
  auto cfg = [&]() -> lgp::Expected<lgp::RunConfig> {
#ifdef LGP_HAVE_MPI
    if (distributed) {
      lgp::Expected<std::string> text = lgp::Status::error(config_path + ": not read");
      if (root) text = lgp::readInputFile(config_path, lgp::kMaxConfigBytes);
      auto shared = lgp::mpi::shareBytes(text);
      if (!shared) return shared.status();
      return lgp::parseRunConfigText(*shared, config_path);
    }
#endif
    return lgp::loadRunConfig(config_path);
  }();
  if (!cfg) return fail(cfg.error(), 2);
  if (args.count("seed")) cfg->search.seed = args["seed"].as<uint64_t>();
  if (args.count("threads")) cfg->search.threads = std::max(0, args["threads"].as<int>());
  if (args.count("generations"))
    cfg->search.generations = std::max(0, args["generations"].as<int>());
  if (args.count("wall-time"))
    cfg->search.wall_time_s = std::max(0.0, args["wall-time"].as<double>());
  if (args.count("out")) cfg->output.front_json = args["out"].as<std::string>();
  if (args.count("csv")) cfg->output.front_csv = args["csv"].as<std::string>();
  if (args.count("checkpoint")) cfg->output.checkpoint = args["checkpoint"].as<std::string>();
  if (args.count("checkpoint-interval"))
    cfg->output.checkpoint_interval_s = std::max(0.0, args["checkpoint-interval"].as<double>());
  const bool resume = args.count("resume") > 0;
  const std::string status_path = args.count("status") ? args["status"].as<std::string>() : "";
  if (auto st = cfg->validate(); !st) return fail(st.message(), 2);
  if (resume && cfg->output.checkpoint.empty())
    return fail("--resume: no checkpoint file named (--checkpoint or output.checkpoint)", 2);
  const bool two_step = cfg->search.multi_output.mode == lgp::MultiOutputMode::TwoStep;
  if (two_step && !cfg->output.checkpoint.empty())
    return fail("/output/checkpoint: not available with two_step (no checkpoint across steps)", 2);
  if (two_step && distributed)
    return fail("/search/multi_output: two_step does not run over MPI; run it in one process", 2);
  lgp::Expected<lgp::Table> table = lgp::Status::error("no table");
  if (root) table = lgp::cli::loadRunTable(*cfg);
#ifdef LGP_HAVE_MPI
  if (distributed) table = lgp::mpi::shareTable(table);
#endif
  if (!table) return fail(table.error(), 2);
  // Reference formulas are checked before the night's work starts, not after.
  if (auto st = lgp::cli::checkRunReferences(*cfg, *table); !st) return fail(st.message(), 2);
  const bool quiet = args.count("quiet") > 0 || !root;
  const bool tty = isatty(fileno(stderr));
  if (cfg->search.threads > lgp::Search::maxThreads() && root)
    std::fprintf(stderr,
                 "warning: /search/threads: %d capped at the %d cores this process may use\n",
                 cfg->search.threads, lgp::Search::maxThreads());
  if (!quiet) {
    std::fprintf(stderr, "lgp: %zu rows, inputs [%zu], outputs [%zu], population %d, seed %llu",
                 table->rows(), table->numInputs(), table->numOutputs(), cfg->search.population,
                 static_cast<unsigned long long>(cfg->search.seed));
    if (distributed)
      std::fprintf(stderr, ", %d MPI ranks (%s migration)", ranks,
                   std::string(lgp::toString(cfg->mpi.migration)).c_str());
    std::fprintf(stderr, "\n");
  }

  std::vector<lgp::NamedProgram> seeds;
  if (!resume) {
    auto progs = lgp::cli::referenceSeeds(*cfg, *table);
    if (!progs) return fail(progs.error(), 2);
    seeds = std::move(*progs);
  }
  if (auto st = lgp::cli::checkRunMode(*cfg, !seeds.empty(), distributed); !st)
    return fail(st.message(), 2);
  nlohmann::json exhaustive;  // the enumeration's certificate (search.exhaustive)
  std::unique_ptr<lgp::Search> single;
  std::unique_ptr<lgp::TwoStepSearch> stepped;
  if (two_step) {
    stepped = std::make_unique<lgp::TwoStepSearch>(*cfg, std::move(*table));
    g_two_step.store(stepped.get());
  } else if (!distributed) {
    lgp::Expected<nlohmann::json> ck = nlohmann::json();
    if (resume) {
      ck = lgp::readCheckpointFile(cfg->output.checkpoint);
      if (!ck) return fail(ck.error(), 2);
      if (lgp::Search::adoptCheckpointIslands(*cfg, *ck) && !quiet)
        std::fprintf(stderr, "lgp: %d islands, as in the checkpoint\n", cfg->search.islands.count);
    }
    single = std::make_unique<lgp::Search>(*cfg, std::move(*table));
    if (resume)
      if (auto st = single->restore(*ck); !st)
        return fail(cfg->output.checkpoint + ": " + st.message(), 2);
    if (auto st = lgp::cli::enableArchiveMeasuredCost(*single); !st) return fail(st.message(), 2);
    // A reference that does not fit the program shape is reported, not fatal.
    for (const auto& why : single->addSeeds(seeds))
      std::fprintf(stderr, "warning: /search/seed_references: not seeded: %s\n", why.c_str());
    if (!resume) {
      auto cert = lgp::cli::runExhaustive(*single);
      if (!cert) return fail(cert.error(), 2);
      exhaustive = std::move(*cert);
      if (!exhaustive.is_null() && !quiet)
        std::fprintf(
            stderr,
            "lgp: exhaustive: %s expressions fitted in %.1f s, up to %d operators complete\n",
            exhaustive["fitted"].dump().c_str(), exhaustive["seconds"].get<double>(),
            exhaustive["complete_ops"].get<int>());
    }
    g_search.store(single.get());
  }
  std::signal(SIGINT, onSigint);
  std::signal(SIGTERM, onSigint);
  // Open MPI's mpirun forwards SIGUSR1 to every rank and, unlike SIGTERM, kills no one after it.
  std::signal(SIGUSR1, onSigint);
  int current_step = 0;
  bool status_failed = false;
  // The last write of the status file and of the checkpoint must succeed: a run that ends with
  // either one stale (a full disk) exits 1 after writing its front.
  std::string status_error, checkpoint_error;
  nlohmann::json mpi_stats;  // rank 0 of an MPI run: time in MPI calls per rank
  auto progress = [&](const lgp::SearchProgress& p) {
    if (!status_path.empty() && root) {
      auto st = lgp::writeJsonAtomic(lgp::progressToJson(p), status_path, 2);
      if (!st && !status_failed) std::fprintf(stderr, "warning: %s\n", st.message().c_str());
      status_failed = !st;
      status_error = st ? "" : st.message();
    }
    if (quiet) return;
    std::string levels;
    for (const auto& [c, e] : p.best_at_cost) {
      char b[64];
      std::snprintf(b, sizeof(b), " c<=%g:%s", c, fmtErr(e).c_str());
      levels += b;
    }
    const std::string step = current_step > 0 ? "step " + std::to_string(current_step) + "  " : "";
    std::string mpi_info;
    if (p.ranks > 1)
      mpi_info = " | ranks " + std::to_string(p.ranks) + "  migrants " +
                 std::to_string(p.migrants) + " (" + std::to_string(p.remote_migrants) + " remote)";
    std::fprintf(stderr, "%s%sgen %d  evals %llu  %.3g evals/s  front %zu  best %s |%s%s%s",
                 tty ? "\r\033[K" : "", step.c_str(), p.generation,
                 static_cast<unsigned long long>(p.evaluations), p.evals_per_s, p.front_size,
                 fmtErr(p.best_error).c_str(), levels.c_str(), mpi_info.c_str(), tty ? "" : "\n");
    std::fflush(stderr);
  };
  if (stepped) {
    stepped->run([&](int step, const lgp::SearchProgress& p) {
      if (step != current_step && current_step > 0 && !quiet && tty) std::fprintf(stderr, "\n");
      current_step = step;
      progress(p);
    });
    if (!quiet)
      std::fprintf(stderr, "%slgp: step 1 picked %s = %s\n", tty ? "\n" : "",
                   stepped->pickColumn().c_str(),
                   lgp::toInfix(stepped->pick(), stepped->result().table().input_names)[0].c_str());
  } else if (single) {
    // Search::run with checkpoints: every checkpoint_interval_s and once at the end.
    const std::string& ck_path = cfg->output.checkpoint;
    bool ck_failed = false;
    auto checkpoint = [&]() {
      if (ck_path.empty()) return;
      auto st = lgp::writeCheckpointFile(single->checkpoint(), ck_path);
      if (!st && !ck_failed) std::fprintf(stderr, "\nwarning: %s\n", st.message().c_str());
      ck_failed = !st;
      checkpoint_error = st ? "" : st.message();
    };
    auto last_progress = Clock::now(), last_checkpoint = Clock::now();
    if (!resume) single->initialize();
    progress(single->progress());
    while (!single->done()) {
      single->step();
      if (since(last_progress) >= cfg->output.progress_interval_s) {
        progress(single->progress());
        last_progress = Clock::now();
      }
      if (since(last_checkpoint) >= cfg->output.checkpoint_interval_s) {
        checkpoint();
        last_checkpoint = Clock::now();
      }
    }
    checkpoint();
    progress(single->progress());
    if (!quiet && tty) std::fprintf(stderr, "\n");
  } else {
#ifdef LGP_HAVE_MPI
    lgp::mpi::DistributedOptions opt;
    opt.seeds = std::move(seeds);
    opt.checkpoint_path = cfg->output.checkpoint;
    opt.checkpoint_interval_s = cfg->output.checkpoint_interval_s;
    opt.resume = resume;
    opt.on_progress = progress;
    opt.on_warning = [&](const std::string& w) {
      std::fprintf(stderr, "%swarning: %s\n", tty ? "\r\033[K" : "", w.c_str());
    };
    opt.on_search = [](lgp::Search* s) {
      g_search.store(s);
      if (s && g_interrupts.load() > 0) s->requestStop();  // a signal came during set-up
    };
    auto result = lgp::mpi::runDistributed(*cfg, *table, std::move(opt));
    if (!result) return fail(result.error(), 2);
    if (!root) return g_interrupts.load() > 0 ? 130 : 0;
    single = std::move(result->search);
    mpi_stats = std::move(result->stats);
    if (!quiet && tty) std::fprintf(stderr, "\n");
#endif
  }
  g_search.store(nullptr);
  g_two_step.store(nullptr);
  const lgp::Search& search = stepped ? stepped->result() : *single;

  const auto front = search.front();
  if (front.empty()) {
    // Not a result: every program scored NaN or infinity (which the archive never keeps), or
    // none was scored. No front is written, and the exit status says the run failed.
    return fail(
        lgp::cli::emptyFrontMessage(search) + "; no front written to " + cfg->output.front_json,
        g_interrupts.load() > 0 ? 130 : 1);
  }
  auto j = lgp::frontToJson(search, front);
  if (!mpi_stats.is_null()) j["progress"]["mpi"] = mpi_stats;
  if (!exhaustive.is_null()) j["exhaustive"] = exhaustive;
  // After Ctrl-C a launcher such as mpirun gives the process about a second: the front goes
  // to disk first (atomically), then is rewritten with the references and measured costs.
  if (g_interrupts.load() > 0)
    if (auto st = lgp::writeFrontJson(j, cfg->output.front_json); !st) {
      std::fprintf(stderr, "error: %s\n", st.message().c_str());
      return 1;
    }
  if (const std::string note = lgp::cli::addFrontExtras(j, search); !note.empty() && !quiet)
    std::fprintf(stderr, "lgp: %s\n", note.c_str());
  if (auto st = lgp::writeFrontJson(j, cfg->output.front_json); !st) {
    std::fprintf(stderr, "error: %s\n", st.message().c_str());
    return 1;
  }
  if (!cfg->output.front_csv.empty())
    if (auto st = lgp::writeFrontCsv(j, cfg->output.front_csv); !st) {
      std::fprintf(stderr, "error: %s\n", st.message().c_str());
      return 1;
    }
  const auto p = search.progress();
  if (!quiet)
    std::fprintf(
        stderr,
        "lgp: stopped (%s) after %d generations, %llu evaluations, %.1f s; %zu members -> %s\n",
        p.stop_reason.c_str(), p.generation, static_cast<unsigned long long>(p.evaluations),
        p.elapsed_s, front.size(), cfg->output.front_json.c_str());
  if (!quiet && p.cost_measurements > 0)
    std::fprintf(stderr,
                 "lgp: measured cost in the archive: %llu candidates compiled in %.1f s (%.0f %% "
                 "of the run)\n",
                 static_cast<unsigned long long>(p.cost_measurements), p.cost_measure_s,
                 p.elapsed_s > 0 ? 100 * p.cost_measure_s / p.elapsed_s : 0.0);
  if (!checkpoint_error.empty())
    return fail("the last checkpoint was not written: " + checkpoint_error, 1);
  if (!status_error.empty()) return fail("the last status was not written: " + status_error, 1);
  return g_interrupts.load() > 0 ? 130 : 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kRunCommand, "run", "run a search from a JSON config and write its front",
                     runMain);
