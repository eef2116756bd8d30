// `lgp data scene.json -o table.json`: generate a ground-truth table (datasets/) for a scene,
// through the cache, and write it as lgp-table/1 JSON (or CSV plus a .meta.json), optionally
// with SVG heatmaps and slices of every output.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cxxopts.hpp>
#include <fstream>
#include <iostream>

#include "cli_args.hpp"
#include "commands.hpp"
#include "lgp/datasets/generate.hpp"
#include "lgp/datasets/scene.hpp"
#include "lgp/io/result.hpp"

namespace {
namespace fs = std::filesystem;
namespace ds = lgp::datasets;

int dataMain(int argc, char** argv) {
  cxxopts::Options opts(argv[0], "Generate a ground-truth table from a scene JSON.");
  opts.positional_help("scene.json");
  opts.add_options()("scene", "scene (JSON); see datasets/README.md",
                     cxxopts::value<std::string>())(
      "o,out", "output table path", cxxopts::value<std::string>()->default_value("table.json"))(
      "csv", "write CSV (metadata goes to <out>.meta.json) instead of lgp-table/1 JSON")(
      "plot", "also write SVG heatmaps and 1-D slices of every output (next to the table)")(
      "plot-dir", "directory for the SVG plots (implies --plot)", cxxopts::value<std::string>())(
      "cache-dir", "cache directory (default $LGP_CACHE_DIR or ~/.cache/lgp)",
      cxxopts::value<std::string>())("no-cache",
                                     "always regenerate; do not read or write the cache")(
      "threads", "OpenMP threads (0 = all)", cxxopts::value<int>()->default_value("0"))(
      "q,quiet", "no summary")("h,help", "this help");
  opts.parse_positional({"scene"});
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "scene", "no scene given");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  const fs::path scene_path = args["scene"].as<std::string>();
  auto scene = ds::loadScene(scene_path);
  if (!scene) {
    std::fprintf(stderr, "error: %s\n", scene.error().c_str());
    return 2;
  }
  ds::GenerateOptions gopt;
  gopt.threads = args["threads"].as<int>();
  if (const int cores = std::max(1, omp_get_num_procs()); gopt.threads > cores)
    std::fprintf(stderr, "warning: --threads: %d capped at the %d cores this process may use\n",
                 gopt.threads, cores);
  const bool quiet = args.count("quiet") > 0;
  const auto t0 = std::chrono::steady_clock::now();
  ds::GeneratedTable table;
  bool hit = false;
  if (args.count("no-cache")) {
    auto g = ds::generate(*scene, gopt);
    if (!g) {
      std::fprintf(stderr, "error: %s: %s\n", scene_path.c_str(), g.error().c_str());
      return 1;
    }
    table = std::move(*g);
  } else {
    const fs::path dir = args.count("cache-dir") ? fs::path(args["cache-dir"].as<std::string>())
                                                 : ds::defaultCacheDir();
    auto c = ds::generateCached(*scene, dir, gopt);
    if (!c) {
      std::fprintf(stderr, "error: %s: %s\n", scene_path.c_str(), c.error().c_str());
      return 1;
    }
    if (!c->note.empty()) std::fprintf(stderr, "warning: %s\n", c->note.c_str());
    hit = c->hit;
    table = std::move(c->table);
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const fs::path out = args["out"].as<std::string>();
  if (out.has_parent_path()) fs::create_directories(out.parent_path());
  if (args.count("csv")) {
    if (auto st = ds::writeTableCsv(table, out); !st) {
      std::fprintf(stderr, "error: %s\n", st.message().c_str());
      return 1;
    }
    nlohmann::json meta = table.table.meta;
    meta["table_file"] = out.filename().string();
    meta["max_estimated_error_by_entry"] = "see the JSON form (lgp data without --csv)";
    if (auto st = lgp::writeTextAtomic(meta.dump(2) + "\n", out.string() + ".meta.json"); !st) {
      std::fprintf(stderr, "error: %s\n", st.message().c_str());
      return 1;
    }
  } else if (auto st = lgp::writeTextAtomic(ds::toTableJson(table).dump() + "\n", out); !st) {
    std::fprintf(stderr, "error: %s\n", st.message().c_str());
    return 1;
  }
  std::vector<fs::path> plots;
  if (args.count("plot") || args.count("plot-dir")) {
    std::string dir = args.count("plot-dir")  ? args["plot-dir"].as<std::string>()
                      : out.has_parent_path() ? out.parent_path().string()
                                              : std::string(".");
    auto p = ds::writePlots(table, dir, out.stem().string());
    if (!p) {
      std::fprintf(stderr, "error: %s\n", p.error().c_str());
      return 1;
    }
    plots = *p;
  }
  if (!quiet) {
    std::fprintf(stderr, "%s: %zu rows x %zu outputs, %s in %.2f s, max estimated error %.3g%s\n",
                 out.c_str(), table.table.rows(), table.table.numOutputs(),
                 hit ? "from cache" : "generated", secs, table.max_error,
                 table.converged ? "" : " (some integrals hit their budget)");
    if (!plots.empty()) std::fprintf(stderr, "plots: %zu SVG files\n", plots.size());
  }
  return 0;
}

}  // namespace

LGP_REGISTER_COMMAND(g_data_cmd, "data", "generate a ground-truth table from a scene JSON",
                     dataMain);
