// lgp_recovery: how often, and how fast, lgp and Operon recover known formulas from noiseless
// samples, on the same data, threads and wall-time budget. See bench/recovery/README.md.
//
// Per (problem, seed): training and held-out points drawn from the problem's ranges; lgp runs
// in-process, Operon as a subprocess on a CSV of the same points. A run is recovered at the
// first generation whose best model (lowest training error) has held-out R^2 > 0.99999; the
// run stops there, or at the budget. The report gives recovery rates, median times to
// recovery and median held-out R^2 per problem and over the suite.
#include <unistd.h>
#include <cxxopts.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "../bench_util.hpp"
#include "lgp/config/config.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/search.hpp"
#include "operon.hpp"
#include "suite.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;
using lgp::bench::cpuModel;
using lgp::bench::utcNow;
using recovery::Problem;

namespace {

struct Options {
  fs::path out;
  int budget_s = 60;
  int seeds = 10;
  int first_seed = 1;
  int threads = 2;
  int train_rows = 200;
  int test_rows = 1000;
  std::vector<const Problem*> problems;
  std::string problems_arg;
  bool run_lgp = true, run_operon = true;
  std::string operon;  // path; empty = not available
  std::string operon_note;
  json lgp_patch = json::object();
  bool keep_data = false;
  double r2_threshold = 0.99999;
};

struct Run {
  std::string engine, problem;
  uint64_t seed = 0;
  bool recovered = false;
  double time_s = NAN;    // wall time to recovery
  double test_r2 = NAN;   // best model's held-out R^2: at recovery, else at the end
  double train_r2 = NAN;  // same model, training points
  double elapsed_s = NAN;
  int generations = 0;
  uint64_t evaluations = 0;  // lgp only
  double check_s = 0;        // lgp: time spent scoring candidates on the held-out points
  int checks = 0;
  std::string model, stop, error;
};

[[noreturn]] void die(const std::string& msg) {
  std::fprintf(stderr, "lgp_recovery: error: %s\n", msg.c_str());
  std::exit(2);
}

double r2Of(const std::vector<double>& pred, const std::vector<double>& y) {
  double mean = 0;
  for (double v : y) mean += v;
  mean /= static_cast<double>(y.size());
  double sse = 0, sst = 0;
  for (size_t i = 0; i < y.size(); ++i) {
    if (!std::isfinite(pred[i])) return -INFINITY;
    sse += (pred[i] - y[i]) * (pred[i] - y[i]);
    sst += (y[i] - mean) * (y[i] - mean);
  }
  return 1 - sse / sst;
}

double variance(const std::vector<double>& y) {
  double mean = 0, ss = 0;
  for (double v : y) mean += v;
  mean /= static_cast<double>(y.size());
  for (double v : y) ss += (v - mean) * (v - mean);
  return ss / static_cast<double>(y.size());
}

// The lgp config of a run: a small JSON through parseRunConfig, so the engine's defaults
// apply; the user's patch on top; then the protocol keys, which a patch may not change.
json lgpConfigJson(const Options& o, const Problem& p, uint64_t seed) {
  json j = {{"data", {{"path", "in-memory"}}}, {"search", {{"linear_scaling", true}}}};
  j.merge_patch(o.lgp_patch);
  json ops = json::array();
  for (lgp::Op op : recovery::lgpOps(p)) ops.push_back(std::string(lgp::opName(op)));
  j["program"]["ops"] = ops;
  j["search"]["seed"] = seed;
  j["search"]["threads"] = o.threads;
  j["search"]["wall_time_s"] = o.budget_s;
  j["search"]["generations"] = 0;
  j["search"]["max_evaluations"] = 0;
  return j;
}

Run runLgp(const Options& o, const Problem& p, uint64_t seed, const lgp::Table& train,
           const lgp::Table& test) {
  Run r;
  r.engine = "lgp";
  r.problem = p.name;
  r.seed = seed;
  auto cfg = lgp::parseRunConfig(lgpConfigJson(o, p, seed), fs::current_path());
  if (!cfg) {
    r.error = "config: " + cfg.error();
    return r;
  }
  // With plain RMSE the training R^2 of the best member is known for free; the held-out
  // check (front() re-scores every archive member) runs only when it is within reach. Other
  // error metrics: check on improvement, at most every 0.5 s.
  const bool rmse = cfg->objectives.metric == lgp::ErrorMetric::Rmse &&
                    cfg->objectives.channels.empty() && cfg->data.transforms.empty();
  const double var = variance(train.outputs[0]);
  const auto t0 = std::chrono::steady_clock::now();
  auto since = [&t0] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  lgp::Search s(*cfg, train);
  auto check = [&] {
    const double c0 = since();
    const auto front = s.front();
    const lgp::FrontEntry* best = nullptr;
    for (const auto& e : front)
      if (std::isfinite(e.obj.error) && (!best || e.obj.error < best->obj.error)) best = &e;
    if (best) {
      // The program predicts T(y) where the target has a transform: judge it on y.
      std::vector<double> pred = lgp::evaluateReference(best->program, test)[0];
      if (auto t = cfg->data.transforms.find(test.output_names.at(0));
          t != cfg->data.transforms.end())
        for (double& v : pred) v = lgp::invertTransform(t->second, v);
      r.test_r2 = r2Of(pred, test.outputs[0]);
      r.train_r2 = best->metrics_ref.empty() ? NAN : best->metrics_ref[0].r2;
      r.model = best->infix.empty() ? "" : best->infix[0];
    }
    r.check_s += since() - c0;
    ++r.checks;
  };
  double checked_error = INFINITY, checked_at = -1;
  while (!s.done()) {
    s.step();
    const double t = since();
    const auto pr = s.progress();
    if (!(pr.best_error < checked_error)) continue;
    const bool due = rmse ? pr.best_error * pr.best_error / var < 10 * (1 - o.r2_threshold)
                          : t - checked_at >= 0.5;
    if (!due) continue;
    checked_error = pr.best_error;
    checked_at = t;
    check();
    if (r.test_r2 > o.r2_threshold) {
      r.recovered = true;
      r.time_s = t;
      s.requestStop();
      break;
    }
  }
  if (!r.recovered) check();  // the final best model
  const auto pr = s.progress();
  r.elapsed_s = since();
  r.generations = pr.generation;
  r.evaluations = pr.evaluations;
  r.stop = r.recovered ? "recovered" : pr.stop_reason;
  return r;
}

Run runOperon(const Options& o, const Problem& p, uint64_t seed, const lgp::Table& train,
              const lgp::Table& test) {
  Run r;
  r.engine = "operon";
  r.problem = p.name;
  r.seed = seed;
  const fs::path csv =
      o.out / "data" / (std::string(p.name) + "_s" + std::to_string(seed) + ".csv");
  {
    std::ofstream f(csv);
    f.precision(17);
    for (const auto& n : train.input_names) f << n << ',';
    f << train.output_names[0] << '\n';
    for (const lgp::Table* t : {&train, &test})
      for (size_t i = 0; i < t->rows(); ++i) {
        for (const auto& col : t->inputs) f << col[i] << ',';
        f << t->outputs[0][i] << '\n';
      }
    if (!f) {
      r.error = "cannot write " + csv.string();
      return r;
    }
  }
  recovery::OperonJob job{.exe = o.operon,
                          .csv = csv.string(),
                          .target = train.output_names[0],
                          .inputs = train.input_names,
                          .train_rows = static_cast<int>(train.rows()),
                          .test_rows = static_cast<int>(test.rows()),
                          .budget_s = o.budget_s,
                          .threads = o.threads,
                          .seed = seed,
                          .symbols = recovery::operonSymbols(p),
                          .r2_threshold = o.r2_threshold};
  const auto res = recovery::runOperon(job);
  if (!o.keep_data) fs::remove(csv);
  r.error = res.error;
  r.recovered = res.recovered;
  r.time_s = res.recovered ? res.time_s : NAN;
  r.test_r2 = res.generations ? res.test_r2 : NAN;
  r.train_r2 = res.generations ? res.train_r2 : NAN;
  r.elapsed_s = res.elapsed_s;
  r.generations = res.generations;
  r.model = res.model;
  r.stop = res.recovered ? "recovered" : (res.error.empty() ? "time limit" : "error");
  return r;
}

// ---- reporting ----

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string fmt(double v, const char* f = "%.3g") {
  if (std::isnan(v)) return "-";
  char b[64];
  std::snprintf(b, sizeof(b), f, v);
  return b;
}

// R^2 near 1 as 1-d, so that 0.99999 and 1-1e-12 read differently.
std::string fmtR2(double r) {
  if (std::isnan(r)) return "-";
  if (!std::isfinite(r)) return "-inf";
  if (r >= 1) return "1";
  if (r >= 0.999) return "1-" + fmt(1 - r, "%.1e");
  return fmt(r, "%.4f");
}

json toJson(const Run& r) {
  auto num = [](double v) { return std::isfinite(v) ? json(v) : json(nullptr); };
  json j = {{"engine", r.engine},
            {"problem", r.problem},
            {"seed", r.seed},
            {"recovered", r.recovered},
            {"time_s", num(r.time_s)},
            {"test_r2", num(r.test_r2)},
            {"train_r2", num(r.train_r2)},
            {"elapsed_s", num(r.elapsed_s)},
            {"generations", r.generations},
            {"stop", r.stop},
            {"model", r.model}};
  if (r.engine == "lgp") {
    j["evaluations"] = r.evaluations;
    j["check_s"] = r.check_s;
    j["checks"] = r.checks;
  }
  if (!r.error.empty()) j["error"] = r.error;
  return j;
}

json metaJson(const Options& o, const std::vector<std::string>& engines) {
  json seeds = json::array();
  for (int s = 0; s < o.seeds; ++s) seeds.push_back(o.first_seed + s);
  json probs = json::array();
  for (const Problem* p : o.problems) probs.push_back(p->name);
  json m = {{"date", utcNow()},
            {"cpu", cpuModel()},
            {"hardware_threads", std::thread::hardware_concurrency()},
            {"budget_s", o.budget_s},
            {"threads", o.threads},
            {"seeds", seeds},
            {"train_rows", o.train_rows},
            {"test_rows", o.test_rows},
            {"r2_threshold", o.r2_threshold},
            {"problems_arg", o.problems_arg},
            {"problems", probs},
            {"engines", engines},
            {"lgp_config_patch", o.lgp_patch}};
  if (!o.problems.empty()) {
    // The effective lgp config (first problem's; only ops and seed differ between runs).
    auto cfg = lgp::parseRunConfig(lgpConfigJson(o, *o.problems[0], o.first_seed), ".");
    if (cfg) {
      json c = lgp::toJson(*cfg);
      c.erase("data");
      c.erase("output");
      m["lgp_config"] = c;
    }
  }
  if (o.run_operon) {
    recovery::OperonJob job{.exe = "operon_gp",
                            .csv = "<data.csv>",
                            .target = "target",
                            .inputs = {"<inputs>"},
                            .train_rows = o.train_rows,
                            .test_rows = o.test_rows,
                            .budget_s = o.budget_s,
                            .threads = o.threads,
                            .seed = 0,
                            .symbols = {"<symbols>"}};
    std::string cmd;
    for (const auto& a : recovery::operonArgs(job)) cmd += (cmd.empty() ? "" : " ") + a;
    m["operon_command"] = cmd;
  }
  if (!o.operon_note.empty()) m["operon_note"] = o.operon_note;
  return m;
}

void writeResults(const fs::path& path, const json& meta, const std::vector<Run>& runs) {
  json j = {{"meta", meta}, {"runs", json::array()}};
  for (const auto& r : runs) j["runs"].push_back(toJson(r));
  std::ofstream(path) << j.dump(1) << '\n';
}

struct Stats {
  int runs = 0, recovered = 0, errors = 0;
  double median_time = NAN, median_r2 = NAN;
};

Stats stats(const std::vector<Run>& runs, const std::string& engine, const std::string& problem) {
  Stats s;
  std::vector<double> t, r2;
  for (const auto& r : runs) {
    if (r.engine != engine || (!problem.empty() && r.problem != problem)) continue;
    if (!r.error.empty() && std::isnan(r.test_r2)) {
      ++s.errors;
      continue;
    }
    ++s.runs;
    if (r.recovered) {
      ++s.recovered;
      t.push_back(r.time_s);
    }
    r2.push_back(std::isnan(r.test_r2) ? -INFINITY : r.test_r2);
  }
  s.median_time = median(t);
  s.median_r2 = median(r2);
  return s;
}

std::string rate(const Stats& s) {
  if (s.runs == 0) return s.errors ? "error" : "-";
  return std::to_string(s.recovered) + "/" + std::to_string(s.runs);
}

void writeReport(const fs::path& path, const Options& o, const json& meta,
                 const std::vector<std::string>& engines, const std::vector<Run>& runs,
                 bool complete) {
  std::ostringstream md;
  const std::map<std::string, std::string> label = {{"lgp", "lgp"}, {"operon", "Operon"}};
  md << "# Recovery benchmark: lgp and Operon\n\n";
  if (!complete) md << "**Partial: the run is still going or was interrupted.**\n\n";
  md << "| | |\n|---|---|\n";
  md << "| date | " << meta["date"].get<std::string>() << " |\n";
  md << "| CPU | " << meta["cpu"].get<std::string>() << " (" << meta["hardware_threads"]
     << " hardware threads) |\n";
  md << "| budget | " << o.budget_s << " s wall time per run |\n";
  md << "| threads | " << o.threads << " per run (runs are sequential) |\n";
  md << "| seeds | " << o.seeds << " (" << o.first_seed << ".." << o.first_seed + o.seeds - 1
     << ") |\n";
  md << "| points | " << o.train_rows << " training, " << o.test_rows
     << " held-out, uniform in the problem's ranges |\n";
  md << "| recovery | held-out R^2 > " << o.r2_threshold
     << " of the engine's best model (lowest training error) |\n";
  md << "| problems | `--problems " << o.problems_arg << "`: " << o.problems.size() << " |\n";
  std::string en;
  for (const auto& e : engines) en += (en.empty() ? "" : ", ") + label.at(e);
  md << "| engines | " << (en.empty() ? "none" : en) << " |\n";
  if (!o.operon_note.empty()) md << "| Operon | " << o.operon_note << " |\n";
  md << "\nlgp config (after `--config-json`; ops and seed are set per run):\n\n```json\n"
     << meta.value("lgp_config", json::object()).dump() << "\n```\n\n";
  if (meta.contains("operon_command"))
    md << "Operon command: `" << meta["operon_command"].get<std::string>() << "`\n\n";

  md << "## Suite\n\n| engine | recovered runs | rate | median time to recovery (s) | median "
        "held-out R^2 | problems recovered at least once |\n|---|---|---|---|---|---|\n";
  for (const auto& e : engines) {
    const Stats s = stats(runs, e, "");
    int solved = 0;
    for (const Problem* p : o.problems) solved += stats(runs, e, p->name).recovered > 0;
    md << "| " << label.at(e) << " | " << rate(s) << " | "
       << (s.runs ? fmt(100.0 * s.recovered / s.runs, "%.0f %%") : "-") << " | "
       << fmt(s.median_time) << " | " << fmtR2(s.median_r2) << " | " << solved << "/"
       << o.problems.size() << " |\n";
  }

  md << "\n## Per problem\n\nRate: recovered runs / runs. Time: median wall time to recovery "
        "over the recovered runs (s). R^2: median held-out R^2 of the best model over all "
        "runs (at recovery, else at the budget).\n\n| problem | formula |";
  for (const auto& e : engines)
    md << ' ' << label.at(e) << " rate | " << label.at(e) << " time | " << label.at(e) << " R^2 |";
  md << "\n|---|---|";
  for (size_t i = 0; i < engines.size(); ++i) md << "---|---|---|";
  md << '\n';
  for (const Problem* p : o.problems) {
    md << "| " << p->title << " | `" << p->formula << "` |";
    for (const auto& e : engines) {
      const Stats s = stats(runs, e, p->name);
      md << ' ' << rate(s) << " | " << fmt(s.median_time) << " | " << fmtR2(s.median_r2) << " |";
    }
    md << '\n';
  }
  bool any_error = false;
  for (const auto& r : runs) any_error |= !r.error.empty();
  if (any_error) {
    md << "\n## Errors\n\n";
    for (const auto& r : runs)
      if (!r.error.empty())
        md << "- " << r.engine << " " << r.problem << " seed " << r.seed << ": " << r.error << '\n';
  }
  md << "\nEvery run is in `results.json`. Problem definitions and protocol: "
        "bench/recovery/README.md.\n";
  std::ofstream(path) << md.str();
}

Options parseOptions(int argc, char** argv) {
  cxxopts::Options opts("lgp_recovery",
                        "Recovery benchmark: lgp and Operon on the same problems, data and budget");
  opts.add_options()("out", "report folder", cxxopts::value<std::string>())(
      "budget", "wall seconds per run", cxxopts::value<int>()->default_value("60"))(
      "seeds", "runs per problem and engine (seeds first..first+n-1)",
      cxxopts::value<int>()->default_value("10"))("first-seed", "first seed",
                                                  cxxopts::value<int>()->default_value("1"))(
      "threads", "threads per run", cxxopts::value<int>()->default_value("2"))(
      "problems", "comma list of problems or groups (nguyen, feynman, pbr), or all",
      cxxopts::value<std::string>()->default_value("all"))(
      "engines", "lgp,operon or one of them",
      cxxopts::value<std::string>()->default_value("lgp,operon"))(
      "operon", "path of operon_gp (default: $OPERON_GP)", cxxopts::value<std::string>())(
      "config-json", "JSON merge patch for the lgp config, inline or @file",
      cxxopts::value<std::string>())("train-rows", "training points",
                                     cxxopts::value<int>()->default_value("200"))(
      "test-rows", "held-out points", cxxopts::value<int>()->default_value("1000"))(
      "r2-threshold", "recovery: held-out R^2 above this",
      cxxopts::value<double>()->default_value("0.99999"))(
      "keep-data", "keep the CSV files given to Operon (out/data)")(
      "list", "print the suite and exit")("h,help", "this help");
  cxxopts::ParseResult a;
  try {
    a = opts.parse(argc, argv);
  } catch (const std::exception& e) {
    die(e.what());
  }
  if (a.count("help")) {
    std::printf("%s\n", opts.help().c_str());
    std::exit(0);
  }
  Options o;
  o.problems_arg = a["problems"].as<std::string>();
  std::vector<std::string> unknown;
  o.problems = recovery::select(o.problems_arg, unknown);
  if (!unknown.empty()) die("unknown problem or group '" + unknown[0] + "' (see --list)");
  if (a.count("list")) {
    for (const auto& p : recovery::suite()) {
      std::printf("%-16s %-8s %s = %s;", p.name, p.group, p.title, p.formula);
      for (const auto& in : p.inputs) std::printf(" %s in [%g, %g]", in.name, in.lo, in.hi);
      std::printf("\n");
    }
    std::exit(0);
  }
  if (!a.count("out")) die("--out DIR is required");
  o.out = a["out"].as<std::string>();
  o.budget_s = a["budget"].as<int>();
  o.seeds = a["seeds"].as<int>();
  o.first_seed = a["first-seed"].as<int>();
  o.threads = a["threads"].as<int>();
  o.train_rows = a["train-rows"].as<int>();
  o.test_rows = a["test-rows"].as<int>();
  o.keep_data = a.count("keep-data") > 0;
  o.r2_threshold = a["r2-threshold"].as<double>();
  if (!(o.r2_threshold > 0 && o.r2_threshold < 1)) die("--r2-threshold must be in (0, 1)");
  if (o.budget_s < 1 || o.seeds < 1 || o.threads < 1 || o.train_rows < 2 || o.test_rows < 2)
    die("--budget, --seeds, --threads must be >= 1 and --train-rows, --test-rows >= 2");
  if (o.problems.empty()) die("no problems selected");
  o.run_lgp = o.run_operon = false;
  std::stringstream es(a["engines"].as<std::string>());
  for (std::string e; std::getline(es, e, ',');) {
    if (e == "lgp")
      o.run_lgp = true;
    else if (e == "operon")
      o.run_operon = true;
    else if (!e.empty())
      die("unknown engine '" + e + "' (lgp, operon)");
  }
  if (a.count("config-json")) {
    std::string s = a["config-json"].as<std::string>();
    if (!s.empty() && s[0] == '@') {
      std::ifstream f(s.substr(1));
      if (!f) die("cannot read " + s.substr(1));
      s.assign(std::istreambuf_iterator<char>(f), {});
    }
    try {
      o.lgp_patch = json::parse(s);
    } catch (const std::exception& e) {
      die(std::string("--config-json: ") + e.what());
    }
    if (!o.lgp_patch.is_object()) die("--config-json: must be a JSON object");
  }
  if (o.run_operon) {
    if (a.count("operon"))
      o.operon = a["operon"].as<std::string>();
    else if (const char* env = std::getenv("OPERON_GP"))
      o.operon = env;
    if (o.operon.empty() || access(o.operon.c_str(), X_OK) != 0) {
      o.operon_note = o.operon.empty() ? "skipped: no operon_gp given (--operon PATH or OPERON_GP)"
                                       : "skipped: operon_gp not executable at the given path";
      std::fprintf(stderr, "lgp_recovery: Operon %s\n", o.operon_note.c_str());
      o.run_operon = false;
    }
  }
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  Options o = parseOptions(argc, argv);
  std::vector<std::string> engines;
  if (o.run_lgp) engines.push_back("lgp");
  if (o.run_operon) engines.push_back("operon");
  if (engines.empty()) die("no engine to run");
  std::error_code ec;
  fs::create_directories(o.out / "data", ec);
  if (ec) die("cannot create " + (o.out / "data").string() + ": " + ec.message());
  // Validates --config-json before any run.
  if (o.run_lgp) {
    auto cfg = lgp::parseRunConfig(lgpConfigJson(o, *o.problems[0], o.first_seed), ".");
    if (!cfg) die("lgp config: " + cfg.error());
  }
  const json meta = metaJson(o, engines);
  const size_t total = o.problems.size() * static_cast<size_t>(o.seeds) * engines.size();
  std::printf(
      "lgp_recovery: %zu problems x %d seeds x %zu engines, %d s each, %d threads "
      "(at most %.1f min)\n",
      o.problems.size(), o.seeds, engines.size(), o.budget_s, o.threads, total * o.budget_s / 60.0);
  std::fflush(stdout);

  std::vector<Run> runs;
  size_t k = 0;
  for (const Problem* p : o.problems)
    for (int si = 0; si < o.seeds; ++si) {
      const uint64_t seed = static_cast<uint64_t>(o.first_seed + si);
      const lgp::Table train = recovery::sample(*p, seed, 0, o.train_rows);
      const lgp::Table test = recovery::sample(*p, seed, 1, o.test_rows);
      for (const auto& e : engines) {
        Run r = e == "lgp" ? runLgp(o, *p, seed, train, test) : runOperon(o, *p, seed, train, test);
        ++k;
        std::printf("[%zu/%zu] %-16s seed %-3llu %-6s ", k, total, p->name,
                    static_cast<unsigned long long>(seed), e.c_str());
        if (r.recovered)
          std::printf("recovered in %6.2f s  (gen %d, held-out R2 %s)\n", r.time_s, r.generations,
                      fmtR2(r.test_r2).c_str());
        else
          std::printf("not recovered (%.1f s, gen %d, held-out R2 %s)%s%s\n", r.elapsed_s,
                      r.generations, fmtR2(r.test_r2).c_str(), r.error.empty() ? "" : ": ",
                      r.error.c_str());
        std::fflush(stdout);
        runs.push_back(std::move(r));
        // Rewritten after every run, so an interrupted benchmark still leaves its data.
        writeResults(o.out / "results.json", meta, runs);
        writeReport(o.out / "report.md", o, meta, engines, runs, k == total);
      }
    }
  if (!o.keep_data) fs::remove(o.out / "data", ec);
  std::printf("lgp_recovery: wrote %s and %s\n", (o.out / "report.md").c_str(),
              (o.out / "results.json").c_str());
  for (const auto& e : engines) {
    const Stats s = stats(runs, e, "");
    std::printf("  %-6s recovered %s runs, median time %s s\n", e.c_str(), rate(s).c_str(),
                fmt(s.median_time).c_str());
  }
  return 0;
}
