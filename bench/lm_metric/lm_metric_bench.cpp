// Levenberg-Marquardt on the configured error (search.refine.lm_metric "configured") against
// plain least squares ("least_squares"): the same search, fixed seed, 1 thread and a fixed
// number of generations, run with each setting in turn (interleaved, --reps times). Prints,
// per run, the best error in the archive (the accurate end of the front), the evaluations,
// the LM fits with the share the scorer took (accept rate), the fits that converged without
// improving, and the Nelder-Mead runs and evaluations (Search::refineStats), and the wall time.
//
// Usage: lm_metric_bench CONFIG TABLE [--generations N] [--reps N] [--error METRIC]
//   CONFIG  a run config (examples/scenes/run_dfg.json); its data section selects the columns
//   TABLE   the table file to use instead of data.path or data.scene (`lgp data SCENE -o T`)
//   --error overrides objectives.error (rmse, max_abs, mae, mean_rel)
// References are not seeded (that needs the CLI's parser); everything else is the config's.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "../bench_util.hpp"
#include "lgp/config/config.hpp"
#include "lgp/io/table_file.hpp"
#include "lgp/search/search.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s CONFIG TABLE [--generations N] [--reps N] [--error METRIC]\n",
                 argv[0]);
    return 2;
  }
  int generations = 100, reps = 1;
  std::string error;
  for (int i = 3; i + 1 < argc; i += 2) {
    if (!std::strcmp(argv[i], "--generations"))
      generations = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--reps"))
      reps = std::atoi(argv[i + 1]);
    else if (!std::strcmp(argv[i], "--error"))
      error = argv[i + 1];
    else {
      std::fprintf(stderr, "unknown option %s\n", argv[i]);
      return 2;
    }
  }
  nlohmann::json j = lgp::bench::benchConfigJson(argv[1], argv[2], 1);
  j["search"]["generations"] = generations;
  if (!error.empty()) j["objectives"]["error"] = error;
  std::printf("%-14s %4s %14s %12s %8s %8s %7s %9s %8s %10s %8s\n", "lm_metric", "rep",
              "best_error", "evals", "lm_fits", "lm_acc", "acc%", "lm_conv", "nm_runs", "nm_evals",
              "wall_s");
  for (int rep = 0; rep < reps; ++rep)
    for (const char* mode : {"least_squares", "configured"}) {
      j["search"]["refine"]["lm_metric"] = mode;
      auto cfg = lgp::parseRunConfig(j, std::filesystem::path(argv[1]).parent_path());
      if (!cfg) {
        std::fprintf(stderr, "%s\n", cfg.error().c_str());
        return 1;
      }
      auto table = lgp::loadTableFile(cfg->data, ".");
      if (!table) {
        std::fprintf(stderr, "%s\n", table.error().c_str());
        return 1;
      }
      const auto t0 = std::chrono::steady_clock::now();
      lgp::Search s(*cfg, std::move(*table));
      s.run();
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const lgp::SearchProgress p = s.progress();
      const lgp::RefineStats r = s.refineStats();
      std::printf("%-14s %4d %14.8g %12llu %8llu %8llu %6.1f%% %9llu %8llu %10llu %8.1f\n", mode,
                  rep, p.best_error, static_cast<unsigned long long>(p.evaluations),
                  static_cast<unsigned long long>(r.lm_fits),
                  static_cast<unsigned long long>(r.lm_accepted),
                  r.lm_fits ? 100.0 * r.lm_accepted / r.lm_fits : 0.0,
                  static_cast<unsigned long long>(r.lm_converged),
                  static_cast<unsigned long long>(r.nm_runs),
                  static_cast<unsigned long long>(r.nm_evaluations), wall);
      std::fflush(stdout);
    }
  return 0;
}
