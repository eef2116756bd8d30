// The semantic cache (search.semantic_cache) off and on: the same search, fixed seed and
// evaluation budget, run with each setting in turn (interleaved, --reps times). The cache
// must not change the result, so every run's front is compared with the first run's without
// it; what it changes is time. Prints, per run, wall and CPU time, generations, evaluations,
// the cache's hits (offspring scores, and offspring LM fits replayed from it), the LM
// fits actually run, and whether the front is identical; then the median wall-time ratio.
//
// Usage: semantic_cache_bench CONFIG TABLE [--evaluations N] [--reps N] [--threads N]
//        [--entries N]
//   CONFIG  a run config; its data section selects the columns
//   TABLE   the table file to use instead of data.path or data.scene
//   --evaluations  the budget (default 2,000,000), replacing the config's budgets
//   --entries      the cache size of the "on" runs (default: the config's or the default)
// References are not seeded (that needs the CLI's parser); everything else is the config's.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../bench_util.hpp"
#include "lgp/config/config.hpp"
#include "lgp/io/result.hpp"
#include "lgp/io/table_file.hpp"
#include "lgp/search/search.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: %s CONFIG TABLE [--evaluations N] [--reps N] [--threads N] "
                 "[--entries N]\n",
                 argv[0]);
    return 2;
  }
  long long evaluations = 2000000, entries = -1;
  int reps = 3, threads = 1;
  for (int i = 3; i < argc; ++i) {
    const std::string opt = argv[i];
    const char* v = lgp::bench::optionValue(argc, argv, i);
    if (opt == "--evaluations")
      evaluations = std::atoll(v);
    else if (opt == "--reps")
      reps = std::atoi(v);
    else if (opt == "--threads")
      threads = std::atoi(v);
    else if (opt == "--entries")
      entries = std::atoll(v);
    else {
      std::fprintf(stderr, "unknown option %s\n", opt.c_str());
      return 2;
    }
  }
  nlohmann::json j = lgp::bench::benchConfigJson(argv[1], argv[2], threads);
  j["search"]["generations"] = 0;
  j["search"]["max_evaluations"] = evaluations;
  if (entries >= 0) j["search"]["semantic_cache"] = entries;
  auto on_cfg = lgp::parseRunConfig(j, std::filesystem::path(argv[1]).parent_path());
  if (!on_cfg) {
    std::fprintf(stderr, "%s\n", on_cfg.error().c_str());
    return 1;
  }
  auto table = lgp::loadTableFile(on_cfg->data, ".");
  if (!table) {
    std::fprintf(stderr, "%s\n", table.error().c_str());
    return 1;
  }
  lgp::RunConfig off_cfg = *on_cfg;
  off_cfg.search.semantic_cache = 0;
  std::printf("# %s, %s, %d thread(s), %lld evaluations, cache %d entries\n",
              lgp::bench::cpuModel().c_str(), lgp::bench::utcNow().c_str(), threads, evaluations,
              on_cfg->search.semantic_cache);
  std::printf("%-5s %4s %9s %9s %6s %12s %11s %9s %9s %6s\n", "cache", "rep", "wall_s", "cpu_s",
              "gens", "evals", "score_hits", "lm_replays", "lm_fits", "same");
  nlohmann::json reference;
  std::vector<double> ratios;
  for (int rep = 0; rep < reps; ++rep) {
    double wall_off = 0;
    for (const bool on : {false, true}) {
      const std::clock_t c0 = std::clock();
      const auto t0 = std::chrono::steady_clock::now();
      lgp::Search s(on ? *on_cfg : off_cfg, *table);
      s.setSnapTwins(false);
      s.run();
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      const double cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
      const auto members = lgp::frontToJson(s, s.front())["members"];
      if (reference.is_null()) reference = members;
      const lgp::SearchProgress p = s.progress();
      const lgp::RefineStats r = s.refineStats();
      std::printf("%-5s %4d %9.2f %9.2f %6d %12llu %11llu %9llu %9llu %6s\n", on ? "on" : "off",
                  rep, wall, cpu, p.generation, static_cast<unsigned long long>(p.evaluations),
                  static_cast<unsigned long long>(r.cache_score_hits),
                  static_cast<unsigned long long>(r.cache_lm_replays),
                  static_cast<unsigned long long>(r.lm_fits), members == reference ? "yes" : "NO");
      std::fflush(stdout);
      if (on)
        ratios.push_back(wall_off / wall);
      else
        wall_off = wall;
    }
  }
  std::sort(ratios.begin(), ratios.end());
  std::printf("median wall-time ratio off/on: %.3f (%d pairs)\n", ratios[ratios.size() / 2],
              static_cast<int>(ratios.size()));
  return 0;
}
