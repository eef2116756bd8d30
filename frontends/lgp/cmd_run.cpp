// `lgp run cfg.json`: load the table, search, write the front (JSON + CSV).
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <cxxopts.hpp>
#include <iostream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/two_step.hpp"
#include "table_source.hpp"
#ifdef LGP_HAVE_EMIT
#include "lgp/emit/score.hpp"
#endif

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
      "q,quiet", "no progress output")("h,help", "this help");
  opts.parse_positional({"config"});
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "config", "no config given");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  auto cfg = lgp::loadRunConfig(args["config"].as<std::string>());
  if (!cfg) {
    std::fprintf(stderr, "error: %s\n", cfg.error().c_str());
    return 2;
  }
  if (args.count("seed")) cfg->search.seed = args["seed"].as<uint64_t>();
  if (args.count("threads")) cfg->search.threads = std::max(0, args["threads"].as<int>());
  if (args.count("generations"))
    cfg->search.generations = std::max(0, args["generations"].as<int>());
  if (args.count("wall-time"))
    cfg->search.wall_time_s = std::max(0.0, args["wall-time"].as<double>());
  if (args.count("out")) cfg->output.front_json = args["out"].as<std::string>();
  if (args.count("csv")) cfg->output.front_csv = args["csv"].as<std::string>();
  if (auto st = cfg->validate(); !st) {
    std::fprintf(stderr, "error: %s\n", st.message().c_str());
    return 2;
  }
  auto table = lgp::cli::loadRunTable(*cfg);
  if (!table) {
    std::fprintf(stderr, "error: %s\n", table.error().c_str());
    return 2;
  }
#ifdef LGP_HAVE_EMIT
  // Reference formulas are checked before the night's work starts, not after.
  if (auto st = lgp::emit::checkReferences(*cfg, *table); !st) {
    std::fprintf(stderr, "error: %s\n", st.message().c_str());
    return 2;
  }
#endif
  const bool quiet = args.count("quiet") > 0;
  const bool tty = isatty(fileno(stderr));
  if (!quiet)
    std::fprintf(stderr, "lgp: %zu rows, inputs [%zu], outputs [%zu], population %d, seed %llu\n",
                 table->rows(), table->numInputs(), table->numOutputs(), cfg->search.population,
                 static_cast<unsigned long long>(cfg->search.seed));

  std::vector<lgp::NamedProgram> seeds;
  if (cfg->search.seed_references) {
#ifdef LGP_HAVE_EMIT
    auto progs = lgp::emit::referencePrograms(*cfg, *table);
    if (!progs) {
      std::fprintf(stderr, "error: %s\n", progs.error().c_str());
      return 2;
    }
    seeds = std::move(*progs);
#else
    std::fprintf(stderr, "error: /search/seed_references: needs the emit library (parser)\n");
    return 2;
#endif
  }
  const bool two_step = cfg->search.multi_output.mode == lgp::MultiOutputMode::TwoStep;
  if (two_step && !seeds.empty()) {
    std::fprintf(stderr, "error: /search/seed_references: not available with two_step\n");
    return 2;
  }
  std::unique_ptr<lgp::Search> single;
  std::unique_ptr<lgp::TwoStepSearch> stepped;
  if (two_step) {
    stepped = std::make_unique<lgp::TwoStepSearch>(*cfg, std::move(*table));
    g_two_step.store(stepped.get());
  } else {
    single = std::make_unique<lgp::Search>(*cfg, std::move(*table));
    // A reference that does not fit the program shape is reported, not fatal.
    for (const auto& why : single->addSeeds(seeds))
      std::fprintf(stderr, "warning: /search/seed_references: not seeded: %s\n", why.c_str());
    g_search.store(single.get());
  }
  std::signal(SIGINT, onSigint);
  std::signal(SIGTERM, onSigint);
  int current_step = 0;
  auto progress = [&](const lgp::SearchProgress& p) {
    if (quiet) return;
    std::string levels;
    for (const auto& [c, e] : p.best_at_cost) {
      char b[64];
      std::snprintf(b, sizeof(b), " c<=%g:%s", c, fmtErr(e).c_str());
      levels += b;
    }
    const std::string step = current_step > 0 ? "step " + std::to_string(current_step) + "  " : "";
    std::fprintf(stderr, "%s%sgen %d  evals %llu  %.3g evals/s  front %zu  best %s |%s%s",
                 tty ? "\r\033[K" : "", step.c_str(), p.generation,
                 static_cast<unsigned long long>(p.evaluations), p.evals_per_s, p.front_size,
                 fmtErr(p.best_error).c_str(), levels.c_str(), tty ? "" : "\n");
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
  } else {
    single->run(progress);
    if (!quiet && tty) std::fprintf(stderr, "\n");
  }
  g_search.store(nullptr);
  g_two_step.store(nullptr);
  const lgp::Search& search = stepped ? stepped->result() : *single;

  const auto front = search.front();
  auto j = lgp::frontToJson(search, front);
#ifdef LGP_HAVE_EMIT
  if (!cfg->references.empty())
    j["references"] = lgp::emit::scoreReferences(search.config(), search.table());
#endif
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
  return g_interrupts.load() > 0 ? 130 : 0;
}

}  // namespace

LGP_REGISTER_COMMAND(kRunCommand, "run", "run a search from a JSON config and write its front",
                     runMain);
