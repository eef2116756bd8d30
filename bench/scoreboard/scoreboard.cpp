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
#include <map>
#include <set>
#include <sstream>

#include "board.hpp"
#include "cli_args.hpp"
#include "lgp/config/json_reader.hpp"
#include "record.hpp"
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

// A table's run config: the spec names it relative to the spec's folder.
lgp::RunConfig tableConfig(const fs::path& spec_path, const TableSpec& spec) {
  const fs::path cfg_path = spec_path.parent_path() / spec.config;
  auto cfg = lgp::parseRunConfig(readJson(cfg_path), cfg_path.parent_path());
  if (!cfg) die(cfg_path.string() + ": " + cfg.error());
  return *cfg;
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
// report.md, summary.json, timing.json and readme.md from every record in `out` run with
// `settings` (the unseeded board, in the spec's order; tables the spec no longer names last) and
// the records of the same settings seeded with the published fits. False when there is none.
bool report(const std::vector<TableSpec>& specs, Settings settings, const fs::path& out) {
  settings.seed_references = false;
  Settings seeded_settings = settings;
  seeded_settings.seed_references = true;
  std::vector<std::string> skipped;
  auto records = readRecords(out, skipped);
  for (const auto& s : skipped)
    std::fprintf(stderr, "lgp_scoreboard: record left out: %s\n", s.c_str());
  RunInfo info;
  info.settings = settings;
  std::vector<TableRun> runs;
  std::map<std::string, TableRun> seeded;
  std::set<std::string> cpus;
  std::vector<bool> taken(records.size(), false);
  auto account = [&](size_t i) {
    info.wall_s += records[i].timing.wall_s;
    info.cpu_s += records[i].timing.cpu_s;
    cpus.insert(records[i].timing.cpu);
    taken[i] = true;
  };
  auto find = [&](const std::string& name, const Settings& s) {
    size_t i = 0;
    while (i < records.size() &&
           (taken[i] || !(records[i].settings == s && records[i].run.spec.name == name)))
      ++i;
    return i;
  };
  for (const auto& spec : specs) {
    if (size_t i = find(spec.name, settings); i < records.size()) {
      account(i);
      runs.push_back(std::move(records[i].run));
    } else {
      info.missing.push_back(spec.name);
    }
  }
  for (size_t i = 0; i < records.size(); ++i)
    if (!taken[i] && records[i].settings == settings) {
      account(i);
      runs.push_back(std::move(records[i].run));
    }
  for (size_t i = 0; i < records.size(); ++i) {
    if (taken[i]) continue;
    if (records[i].settings == seeded_settings) {
      account(i);
      const std::string name = records[i].run.spec.name;
      seeded.emplace(name, std::move(records[i].run));
    } else {
      info.other_settings.push_back(records[i].run.spec.name +
                                    (records[i].settings.seed_references ? " (seeded)" : ""));
    }
  }
  if (runs.empty()) return false;
  for (const auto& c : cpus) info.cpu += (info.cpu.empty() ? "" : "; ") + c;
  if (fs::exists(out / "operon.json")) addOperon(runs, readJson(out / "operon.json"));
  const std::string sum = writeReport(runs, seeded, info, out);
  std::printf("%s\nreport: %s (%zu tables, %zu seeded; wall %.1f s, CPU %.1f s, %s)\n", sum.c_str(),
              (out / "report.md").c_str(), runs.size(), seeded.size(), info.wall_s, info.cpu_s,
              info.cpu.c_str());
  return true;
}

// --re-emit: each record of these settings (and --tables) gets its recommended code written
// again from its saved front, with no search: its tables are generated again and must be the
// ones the record was scored on.
void reEmit(const std::vector<TableSpec>& specs, const fs::path& spec_path, const Options& o,
            const std::set<std::string>& only, const fs::path& out) {
  std::vector<std::string> skipped;
  auto records = readRecords(out, skipped);
  for (const auto& s : skipped)
    std::fprintf(stderr, "lgp_scoreboard: record left out: %s\n", s.c_str());
  const Settings& settings = o;
  int done = 0;
  for (auto& rec : records) {
    if (!(rec.settings == settings) || (!only.empty() && !only.count(rec.run.spec.name))) continue;
    TableRun& r = rec.run;
    const auto spec = std::find_if(specs.begin(), specs.end(),
                                   [&](const TableSpec& t) { return t.name == r.spec.name; });
    if (spec == specs.end()) die(r.spec.name + ": the record's table is not in the spec");
    r.cfg = tableConfig(spec_path, *spec);
    const std::string train_desc = r.train_desc, heldout_desc = r.heldout_desc;
    std::fprintf(stderr, "lgp_scoreboard: %s: tables\n", r.spec.name.c_str());
    if (auto st = loadTables(r, spec_path.parent_path(), o); !st) die(st.message());
    if (r.train_desc != train_desc || r.heldout_desc != heldout_desc)
      die(r.spec.name + ": the tables are not the record's (training " + r.train_desc +
          ", held out " + r.heldout_desc + "; the record: " + train_desc + ", " + heldout_desc +
          "): run the table again");
    if (auto st = readFronts(r, settings, out); !st) die(st.message());
    const fs::path rec_dir = settings.seed_references ? out / "seeded" : out;
    fs::create_directories(rec_dir);
    recommend(r, rec_dir, o);
    writeRecord(r, settings, rec.timing, out);
    ++done;
  }
  if (done == 0) die(out.string() + ": no record with these settings (and --tables)");
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
      "seed-references",
      "start the search from the published fits: runs the seeded board only (the unseeded "
      "one is a run without this flag, into the same --out)")(
      "edge-objective",
      "the declared domain's edge rows are part of the search's objective (data.edges)")(
      "no-vulkan", "do not run the recommended members on lavapipe")(
      "report-only", "run nothing: rebuild the report from the folder's table records")(
      "re-emit",
      "no search: write each record's recommended code again from its saved front (the "
      "records of these settings and --tables), then the report")(
      "check",
      "exit 1 unless every row has a measured ISA and a held-out error (77: no GPU backend)")(
      "h,help", "help");
  auto parsed = lgp::cli::parseArgs(opts, argc, argv, "", "");
  if (const int* code = std::get_if<int>(&parsed)) return *code;
  const cxxopts::ParseResult& args = std::get<cxxopts::ParseResult>(parsed);
  Options o;
  o.quick = args.count("quick") > 0;
  o.threads = args["threads"].as<int>();
  o.seed = args["seed"].as<uint64_t>();
  o.vulkan = !args.count("no-vulkan");
  o.seed_references = args.count("seed-references") > 0;
  o.edge_objective = args.count("edge-objective") > 0;
  const bool report_only = args.count("report-only") > 0;
  const bool re_emit = args.count("re-emit") > 0;
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
  // The Operon figures stay with the board: a later table-by-table invocation keeps them.
  if (args.count("operon")) {
    const json operon = readJson(args["operon"].as<std::string>());
    std::ofstream(out / "operon.json") << operon.dump(1) << "\n";
  }
  const Settings& settings = o;
  std::vector<TableRun> runs;
  for (const auto& name : only)
    if (std::none_of(specs.begin(), specs.end(),
                     [&](const TableSpec& t) { return t.name == name; }))
      die("--tables: '" + name + "' is not a table of the spec");
  for (const auto& spec : specs) {
    if (report_only || re_emit || (!only.empty() && !only.count(spec.name))) continue;
    const auto tw = std::chrono::steady_clock::now();
    const double tc = cpuSeconds();
    TableRun r;
    r.spec = spec;
    r.cfg = tableConfig(spec_path, spec);
    std::fprintf(stderr, "lgp_scoreboard: %s: tables\n", spec.name.c_str());
    const auto tt = std::chrono::steady_clock::now();
    if (auto st = loadTables(r, spec_path.parent_path(), o); !st) die(st.message());
    r.table_wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - tt).count();
    std::fprintf(stderr, "lgp_scoreboard: %s: search to %g nominal minutes\n", spec.name.c_str(),
                 o.minutes.back());
    if (auto st = runTable(r, o); !st) die(spec.name + ": " + st.message());
    // A seeded board's members are not what the headline ships: they go apart.
    const fs::path rec_dir = o.seed_references ? out / "seeded" : out;
    fs::create_directories(rec_dir);
    recommend(r, rec_dir, o);
    const RecordTiming timing{
        cpuModel(), std::chrono::duration<double>(std::chrono::steady_clock::now() - tw).count(),
        cpuSeconds() - tc};
    writeRecord(r, settings, timing, out);
    // The report after every table: a board stopped part way shows what it has.
    report(specs, settings, out);
    runs.push_back(std::move(r));
  }
  if (re_emit) reEmit(specs, spec_path, o, only, out);
  if (report_only || re_emit) {
    if (!report(specs, settings, out)) die(out.string() + ": no record with these settings");
  } else if (runs.empty()) {
    die("no table selected");
  }
  return args.count("check") ? check(runs) : 0;
}
