// lgp_scoreboard: every table a renderer ships a fit for, with the published fits beside lgp's
// front (issue 32). Per (table, published fit): the fit's measured RDNA2 ISA and its error on a
// held-out grid, and lgp's best member at or below that ISA after each budget. See README.md.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cxxopts.hpp>
#include <fstream>
#include <set>
#include <sstream>

#include "board.hpp"
#include "cli_args.hpp"
#include "lgp/config/json_reader.hpp"
#include "report.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace lgp::board;

namespace {
[[noreturn]] void die(const std::string& msg) {
  std::fprintf(stderr, "lgp_scoreboard: error: %s\n", msg.c_str());
  std::exit(2);
}

json readJson(const fs::path& p) {
  std::ifstream in(p);
  if (!in) die(p.string() + ": cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  auto j = lgp::parseJson(ss.str());
  if (!j) die(p.string() + ": " + j.error());
  return *j;
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  for (std::string l; std::getline(in, l);)
    if (l.rfind("model name", 0) == 0) return l.substr(l.find(':') + 2);
  return "unknown CPU";
}

double cpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

// --check: every row has a measured ISA and a finite held-out error (the fit's, and lgp's at
// every budget where a member fits under the ISA). 77 (CTest's skip) without the GPU backend.
int check(const std::vector<TableRun>& runs) {
  int bad = 0;
  for (const auto& r : runs) {
    if (!r.measured) {
      std::fprintf(stderr, "lgp_scoreboard: no measured cost (%s): skipped\n",
                   r.measure_note.c_str());
      return 77;
    }
    for (const auto& row : r.rows) {
      bool ok = std::isfinite(row.published.isa) && !row.published.channels.empty();
      for (const auto& c : row.published.channels)
        ok = ok && std::isfinite(c.rmse) && std::isfinite(c.max_abs);
      for (const auto& m : row.lgp)
        if (m.member >= 0) ok = ok && std::isfinite(m.m.isa) && std::isfinite(m.rms_factor);
      if (!ok) {
        std::fprintf(
            stderr, "lgp_scoreboard: check: row %s / %s lacks a measured ISA or a held-out error\n",
            row.table.c_str(), row.fit.c_str());
        ++bad;
      }
    }
  }
  return bad ? 1 : 0;
}
}  // namespace

int main(int argc, char** argv) {
  cxxopts::Options opts("lgp_scoreboard", "Published fits against lgp's front, table by table.");
  opts.add_options()("spec", "board spec (JSON)",
                     cxxopts::value<std::string>()->default_value(
                         std::string(LGP_SOURCE_DIR) + "/bench/scoreboard/scoreboard.json"))(
      "o,out", "report folder", cxxopts::value<std::string>()->default_value("scoreboard-report"))(
      "budgets", "nominal minutes, comma-separated",
      cxxopts::value<std::string>()->default_value("5,20"))(
      "quick", "coarse tables (<= 5 points per axis) and budgets 0.002,0.005 (a structure check)")(
      "tables", "only these tables, comma-separated", cxxopts::value<std::string>())(
      "operon", "the peer benchmark's results (README.md: format)", cxxopts::value<std::string>())(
      "threads", "search threads", cxxopts::value<int>()->default_value("2"))(
      "seed", "search seed", cxxopts::value<uint64_t>()->default_value("1"))(
      "cache-dir", "table cache (default: lgp data's)", cxxopts::value<std::string>())(
      "no-vulkan", "do not run the recommended members on lavapipe")(
      "check",
      "exit 1 unless every row has a measured ISA and a held-out error (77: no GPU backend)")(
      "h,help", "help");
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "", "");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  const auto t0 = std::chrono::steady_clock::now();
  Options o;
  o.quick = args.count("quick") > 0;
  o.threads = args["threads"].as<int>();
  o.seed = args["seed"].as<uint64_t>();
  o.vulkan = !args.count("no-vulkan");
  if (args.count("cache-dir")) o.cache_dir = args["cache-dir"].as<std::string>();
  o.minutes.clear();
  {
    std::stringstream ss(o.quick ? std::string("0.002,0.005") : args["budgets"].as<std::string>());
    for (std::string t; std::getline(ss, t, ',');) {
      char* end = nullptr;
      const double m = std::strtod(t.c_str(), &end);
      if (end == t.c_str() || *end || !(m > 0)) die("--budgets: '" + t + "' is not a number > 0");
      o.minutes.push_back(m);
    }
    std::sort(o.minutes.begin(), o.minutes.end());
  }
  std::set<std::string> only;
  if (args.count("tables")) {
    std::stringstream ss(args["tables"].as<std::string>());
    for (std::string t; std::getline(ss, t, ',');) only.insert(t);
  }
  const fs::path spec_path = args["spec"].as<std::string>();
  const auto specs = parseSpec(readJson(spec_path), spec_path.string());
  const fs::path out = args["out"].as<std::string>();
  fs::create_directories(out);
  std::vector<TableRun> runs;
  for (const auto& spec : specs) {
    if (!only.empty() && !only.count(spec.name)) continue;
    TableRun r;
    r.spec = spec;
    const fs::path cfg_path = spec_path.parent_path() / spec.config;
    auto cfg = lgp::parseRunConfig(readJson(cfg_path), cfg_path.parent_path());
    if (!cfg) die(cfg_path.string() + ": " + cfg.error());
    r.cfg = *cfg;
    std::fprintf(stderr, "lgp_scoreboard: %s: tables\n", spec.name.c_str());
    const auto tt = std::chrono::steady_clock::now();
    if (auto st = loadTables(r, spec_path.parent_path(), o); !st) die(st.message());
    r.table_wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - tt).count();
    std::fprintf(stderr, "lgp_scoreboard: %s: search to %g nominal minutes\n", spec.name.c_str(),
                 o.minutes.back());
    if (auto st = runTable(r, o); !st) die(spec.name + ": " + st.message());
    recommend(r, out, o);
    runs.push_back(std::move(r));
  }
  if (runs.empty()) die("no table selected");
  if (args.count("operon")) addOperon(runs, readJson(args["operon"].as<std::string>()));
  RunInfo info;
  info.quick = o.quick;
  info.threads = o.threads;
  info.seed = o.seed;
  info.minutes = o.minutes;
  info.cpu = cpuModel();
  info.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  info.cpu_s = cpuSeconds();
  const std::string sum = writeReport(runs, info, out);
  std::printf("%s\nreport: %s (wall %.1f s, CPU %.1f s, %s)\n", sum.c_str(),
              (out / "report.md").c_str(), info.wall_s, info.cpu_s, info.cpu.c_str());
  return args.count("check") ? check(runs) : 0;
}
