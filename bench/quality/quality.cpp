// lgp_quality: what accuracy costs in time (issue 6). For every table of a quality spec
// (bench/quality/quality.json) it runs the table's config once, to the largest budget,
// snapshotting the front at each smaller one; scores the published formulas on the same
// table; runs the search-lever ablation; and writes a report folder (report.md, SVG plots,
// emitted HLSL). See bench/quality/README.md.
//
// Budgets are nominal minutes converted to program evaluations with the table's calibrated
// rate (evals_per_minute, measured on the reference 2-core machine), so a report depends on
// the seed and thread count only, never on machine load. Measured wall times go to
// timing.json, outside the deterministic report.
#include <cxxopts.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "../bench_util.hpp"
#include "lgp/config/config.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/score.hpp"
#include "lgp/emit/vulkan_run.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/io/result.hpp"
#include "lgp/io/svg_plot.hpp"
#include "lgp/search/search.hpp"
#include "lgp/search/two_step.hpp"
#include "run_state.hpp"
#include "table_source.hpp"

namespace fs = std::filesystem;
using json = nlohmann::json;
using lgp::bench::mdEscape;

namespace {

struct TargetSpec {
  std::string name;
  std::vector<std::string> channels;  // channel or output names; every one must satisfy
  double max_cost = 0;                // or the cost of reference `max_cost_of`
  std::string max_cost_of;
  double rmse_max = NAN, max_abs_max = NAN;  // absolute thresholds (NaN = none)
  std::string beat;                          // or: below this reference's rmse and max
};

struct AblationSpec {
  std::string name;
  json patch;  // JSON merge patch applied to the table's config
};

struct TableSpec {
  std::string name, title, config;
  double evals_per_minute = 0;
  std::vector<double> minutes;  // empty = the command line's budgets
  std::vector<double> cost_levels;
  std::vector<double> isa_levels;  // measured instructions (kCostFamily) for the budget table
  std::vector<TargetSpec> targets;
  std::vector<AblationSpec> ablation;
  double ablation_minutes = 2;
};

[[noreturn]] void die(const std::string& msg) {
  std::fprintf(stderr, "lgp_quality: error: %s\n", msg.c_str());
  std::exit(2);
}

double getNum(const json& j, const std::string& k, double dflt = NAN) {
  return j.contains(k) && j[k].is_number() ? j[k].get<double>() : dflt;
}

std::vector<TableSpec> parseSpec(const json& j, const std::string& file) {
  std::vector<TableSpec> out;
  if (!j.is_object() || !j.contains("tables") || !j["tables"].is_array())
    die(file + ": /tables: must be an array");
  for (size_t i = 0; i < j["tables"].size(); ++i) {
    const json& t = j["tables"][i];
    const std::string at = file + ": /tables/" + std::to_string(i);
    TableSpec s;
    if (!t.contains("name") || !t["name"].is_string()) die(at + "/name: must be a string");
    s.name = t["name"];
    s.title = t.value("title", s.name);
    if (!t.contains("config") || !t["config"].is_string()) die(at + "/config: must be a path");
    s.config = t["config"];
    s.evals_per_minute = getNum(t, "evals_per_minute", 0);
    if (!(s.evals_per_minute > 0)) die(at + "/evals_per_minute: must be a number > 0");
    for (const auto& m : t.value("minutes", json::array())) {
      if (!m.is_number() || !(m.get<double>() > 0)) die(at + "/minutes: numbers > 0");
      s.minutes.push_back(m);
    }
    for (const auto& c : t.value("cost_levels", json::array())) {
      if (!c.is_number()) die(at + "/cost_levels: numbers");
      s.cost_levels.push_back(c);
    }
    if (s.cost_levels.empty()) die(at + "/cost_levels: give at least one cost level");
    for (const auto& c : t.value("isa_levels", json::array())) {
      if (!c.is_number() || !(c.get<double>() > 0)) die(at + "/isa_levels: numbers > 0");
      s.isa_levels.push_back(c);
    }
    for (size_t k = 0; k < t.value("targets", json::array()).size(); ++k) {
      const json& g = t["targets"][k];
      const std::string gat = at + "/targets/" + std::to_string(k);
      TargetSpec ts;
      ts.name = g.value("name", "");
      if (ts.name.empty()) die(gat + "/name: must be a non-empty string");
      for (const auto& c : g.value("channels", json::array())) ts.channels.push_back(c);
      if (ts.channels.empty()) die(gat + "/channels: name at least one channel or output");
      ts.max_cost = getNum(g, "max_cost", 0);
      ts.max_cost_of = g.value("max_cost_of", "");
      if ((ts.max_cost > 0) == !ts.max_cost_of.empty())
        die(gat + ": give exactly one of max_cost and max_cost_of");
      ts.rmse_max = getNum(g, "rmse_max");
      ts.max_abs_max = getNum(g, "max_abs_max");
      ts.beat = g.value("beat", "");
      if (std::isnan(ts.rmse_max) && std::isnan(ts.max_abs_max) && ts.beat.empty())
        die(gat + ": give rmse_max, max_abs_max or beat");
      s.targets.push_back(ts);
    }
    for (const auto& a : t.value("ablation", json::array())) {
      if (!a.contains("name") || !a.contains("patch")) die(at + "/ablation: {name, patch}");
      s.ablation.push_back({a["name"], a["patch"]});
    }
    s.ablation_minutes = getNum(t, "ablation_minutes", 2);
    out.push_back(std::move(s));
  }
  return out;
}

std::string fmt(double v, const char* f = "%.4g") {
  if (!std::isfinite(v)) return "-";
  char b[64];
  std::snprintf(b, sizeof(b), f, v);
  return b;
}

// A metric of a front member or scored reference, by channel or output name.
double metricOf(const json& m, const std::string& name, const char* metric) {
  for (const char* key : {"channels", "outputs"})
    if (m.contains(key))
      for (const auto& c : m[key])
        if (c.value("name", "") == name && c.contains("float32"))
          return getNum(c["float32"], metric, INFINITY);
  return INFINITY;
}

std::string memberExpression(const json& m) {
  std::string s;
  const auto& outs = m.at("outputs");
  for (const auto& o : outs) {
    if (!s.empty()) s += "; ";
    if (outs.size() > 1) s += o.value("name", "") + " = ";
    s += o.value("expression", "");
  }
  return s;
}

// The measured instructions of a member or reference on the report's family (NaN if none).
constexpr const char* kCostFamily = "rdna2";
double measuredInstructions(const json& m) {
  if (!m.contains("cost_measured") || !m["cost_measured"].is_object() ||
      !m["cost_measured"].contains(kCostFamily))
    return NAN;
  return getNum(m["cost_measured"][kCostFamily], "instructions");
}

// "14/15/14": every measured family, as `lgp front` shows it.
std::string isaCell(const json& m) {
  if (!m.contains("cost_measured") || !m["cost_measured"].is_object()) return "-";
  std::string s;
  for (const char* f : {"rdna2", "rdna3", "gcn5"})
    s += (s.empty() ? "" : "/") + (m["cost_measured"].contains(f)
                                       ? fmt(getNum(m["cost_measured"][f], "instructions"))
                                       : std::string("-"));
  return s;
}

// Best objective error among members of cost <= c.
double bestAtCost(const json& members, double c) {
  double best = INFINITY;
  for (const auto& m : members)
    if (getNum(m, "cost", INFINITY) <= c) best = std::min(best, getNum(m, "error", INFINITY));
  return best;
}

using lgpq::CurvePoint;
using lgpq::Snapshot;

// Best objective error among members of measured instructions <= k.
double bestAtIsa(const json& members, double k) {
  double best = INFINITY;
  for (const auto& m : members)
    if (measuredInstructions(m) <= k) best = std::min(best, getNum(m, "error", INFINITY));
  return best;
}

struct AblationResult {
  std::string name;
  uint64_t evaluations = 0;
  std::vector<double> best;  // per cost level
  double wall_s = 0;
  std::string error;
};

struct TableResult {
  TableSpec spec;
  lgp::RunConfig cfg;
  lgp::Table table;
  json refs;
  // Measured cost (docs/cost-models.md) of the final front and the references; the targets'
  // cost limits use `cost_family`'s instructions when there are any.
  bool measured = false;
  std::string measured_note;  // why not, or the compiler
  json vulkan;                // per member of the final front: lavapipe agreement (or why not)
  std::vector<Snapshot> snaps;
  std::vector<CurvePoint> curve;
  std::vector<AblationResult> ablation;
  std::vector<std::string> channel_names;
};

lgp::RunConfig loadConfig(const fs::path& path, const json& patch, int threads, uint64_t seed) {
  std::ifstream in(path);
  if (!in) die(path.string() + ": cannot open");
  json j;
  try {
    in >> j;
  } catch (const json::exception& e) {
    die(path.string() + ": invalid JSON: " + e.what());
  }
  if (!patch.is_null()) j.merge_patch(patch);
  auto c = lgp::parseRunConfig(j, path.parent_path());
  if (!c) die(path.string() + ": " + c.error());
  c->search.threads = threads;
  c->search.seed = seed;
  c->search.generations = 0;
  c->search.wall_time_s = 0;
  return *c;
}

std::vector<lgp::NamedProgram> seedsFor(const lgp::RunConfig& cfg, const lgp::Table& t) {
  if (!cfg.search.seed_references) return {};
  auto progs = lgp::emit::referencePrograms(cfg, t);
  if (!progs) die(progs.error());
  return *progs;
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Where a run keeps its state (--state) and when it stops (--stop-after).
struct StateOptions {
  fs::path path;  // empty: no state
  double save_every_s = 300;
  double stop_after_s = 0;  // 0: run to the last budget
  uint64_t seed = 0;
  int threads = 0;
};

void saveState(const lgpq::RunState& st, const fs::path& path) {
  if (auto s = lgpq::writeState(st, path); !s) die(s.message());
}

// Runs the table's search to the last budget, snapshotting the front at each. With a state
// file it starts from the state (a finished one is not searched again) and saves it every
// save_every_s, at each budget and when it stops. False when --stop-after stopped it first.
bool runTable(TableResult& r, const std::vector<double>& minutes, const StateOptions& so) {
  const TableSpec& s = r.spec;
  std::vector<uint64_t> budgets;
  for (double m : minutes)
    budgets.push_back(std::max<uint64_t>(1, static_cast<uint64_t>(m * s.evals_per_minute)));
  lgp::RunConfig cfg = r.cfg;
  cfg.search.max_evaluations = budgets.back();
  cfg.output.progress_cost_levels = s.cost_levels;
  if (cfg.search.multi_output.mode != lgp::MultiOutputMode::Joint)
    die(s.config +
        ": the main config of a quality table must use the joint mode (two_step "
        "belongs in the ablation)");
  lgpq::RunState st;
  st.table = s.name;
  st.seed = so.seed;
  st.threads = so.threads;
  st.minutes = minutes;
  const bool resume = !so.path.empty() && fs::exists(so.path);
  if (resume) {
    auto saved = lgpq::readState(so.path);
    if (!saved) die(saved.error());
    if (auto m = lgpq::checkStateMatches(*saved, st); !m)
      die(so.path.string() + ": " + m.message());
    st = std::move(*saved);
    std::fprintf(stderr, "  [%s] resuming %s: %zu of %zu budgets reached, %.0f s so far%s\n",
                 s.name.c_str(), so.path.string().c_str(), st.snaps.size(), minutes.size(),
                 st.wall_s, st.finished ? " (finished: no search)" : "");
  }
  if (st.finished) {
    r.snaps = st.snaps;
    r.curve = st.curve;
    return true;
  }
  lgp::Search search(cfg, r.table);
  if (resume) {
    if (auto rs = search.restore(st.search); !rs) die(so.path.string() + ": " + rs.message());
  } else {
    for (const auto& why : search.addSeeds(seedsFor(cfg, r.table)))
      std::fprintf(stderr, "  [%s] not seeded: %s\n", s.name.c_str(), why.c_str());
    search.initialize();
  }
  const double t0 = now();
  double last_save = t0;
  auto save = [&](bool finished) {
    if (so.path.empty()) return;
    lgpq::RunState out = st;
    out.wall_s = st.wall_s + (now() - t0);
    out.sessions = st.sessions + 1;
    out.finished = finished;
    out.search = finished ? json() : search.checkpoint();
    saveState(out, so.path);
    last_save = now();
  };
  size_t next = st.snaps.size();
  bool stopped = false;
  while (true) {
    const auto p = search.progress();
    const double mins = static_cast<double>(p.evaluations) / s.evals_per_minute;
    if (mins >= st.next_curve || p.finished) {
      CurvePoint cp{mins, {}};
      for (const auto& [c, e] : p.best_at_cost) cp.best.push_back(e);
      st.curve.push_back(cp);
      st.next_curve = std::max(mins * 1.15, minutes.front() / 20);
    }
    bool snapped = false;
    while (next < budgets.size() && (p.evaluations >= budgets[next] || p.finished)) {
      Snapshot sn;
      sn.minutes = minutes[next];
      sn.evaluations = p.evaluations;
      sn.generation = p.generation;
      sn.wall_s = st.wall_s + (now() - t0);
      sn.front = lgp::frontToJson(search, search.front());
      std::fprintf(stderr, "  [%s] %g min budget: %llu evaluations, %d generations, %.1f s\n",
                   s.name.c_str(), sn.minutes, static_cast<unsigned long long>(sn.evaluations),
                   sn.generation, sn.wall_s);
      st.snaps.push_back(std::move(sn));
      ++next;
      snapped = true;
    }
    if (p.finished || next >= budgets.size()) break;
    if (so.stop_after_s > 0 && now() - t0 >= so.stop_after_s) {
      stopped = true;
      break;
    }
    if (snapped || now() - last_save >= so.save_every_s) save(false);
    search.step();
  }
  save(!stopped);
  if (stopped) {
    const auto p = search.progress();
    std::fprintf(stderr,
                 "  [%s] stopped after %.0f s at %.1f of %g nominal minutes; state in %s "
                 "(run the same command again to go on)\n",
                 s.name.c_str(), now() - t0,
                 static_cast<double>(p.evaluations) / s.evals_per_minute, minutes.back(),
                 so.path.string().c_str());
    return false;
  }
  r.snaps = std::move(st.snaps);
  r.curve = std::move(st.curve);
  return true;
}

AblationResult runAblation(const TableResult& r, const AblationSpec& a, const fs::path& cfg_path,
                           int threads, uint64_t seed, double minutes) {
  AblationResult out;
  out.name = a.name;
  lgp::RunConfig cfg = loadConfig(cfg_path, a.patch, threads, seed);
  cfg.search.max_evaluations =
      std::max<uint64_t>(1, static_cast<uint64_t>(minutes * r.spec.evals_per_minute));
  const double t0 = now();
  json members;
  if (cfg.search.multi_output.mode == lgp::MultiOutputMode::TwoStep) {
    lgp::TwoStepSearch ts(cfg, r.table);
    ts.run();
    members = lgp::frontToJson(ts.result(), ts.result().front())["members"];
    out.evaluations = ts.result().progress().evaluations;
  } else {
    lgp::Search search(cfg, r.table);
    search.addSeeds(seedsFor(cfg, r.table));
    search.run();
    members = lgp::frontToJson(search, search.front())["members"];
    out.evaluations = search.progress().evaluations;
  }
  out.wall_s = now() - t0;
  for (double c : r.spec.cost_levels) out.best.push_back(bestAtCost(members, c));
  return out;
}

// ---- report ----

struct TargetOutcome {
  std::string name, limit_desc, threshold_desc;
  double limit = INFINITY;
  bool met = false;
  int member = -1;
  double cost = NAN;        // the member's measured instructions, else its model cost
  double model_cost = NAN;  // the member's model cost
  std::vector<std::pair<double, double>> measured;  // (rmse, max) per channel
};

const json* findRef(const json& refs, const std::string& name) {
  for (const auto& r : refs)
    if (r.value("name", "") == name && !r.contains("invalid")) return &r;
  return nullptr;
}

// A cost limit is in measured instructions (kCostFamily) when the front was measured: "at or
// below Karis's cost" compares what the compiler makes of both, and the model figure is shown
// beside it. Without measurements it is the model's.
TargetOutcome evaluateTarget(const TargetSpec& t, const json& members, const json& refs,
                             bool measured) {
  TargetOutcome o;
  o.name = t.name;
  auto costOf = [&](const json& m) {
    return measured ? measuredInstructions(m) : getNum(m, "cost", INFINITY);
  };
  const std::string unit = measured ? std::string(kCostFamily) + " instructions" : "cost";
  if (!t.max_cost_of.empty()) {
    const json* ref = findRef(refs, t.max_cost_of);
    if (!ref) die("target '" + t.name + "': no scored reference named '" + t.max_cost_of + "'");
    o.limit = costOf(*ref);
    o.limit_desc = unit + " <= " + fmt(o.limit) + " (" + t.max_cost_of +
                   (measured ? "; model " + fmt(getNum(*ref, "cost")) : std::string()) + ")";
  } else {
    o.limit = t.max_cost;
    o.limit_desc = unit + " <= " + fmt(o.limit);
  }
  const json* beat = nullptr;
  if (!t.beat.empty()) {
    beat = findRef(refs, t.beat);
    if (!beat) die("target '" + t.name + "': no scored reference named '" + t.beat + "'");
  }
  std::string th;
  for (const auto& ch : t.channels) {
    if (!th.empty()) th += "; ";
    th += ch + ":";
    if (!std::isnan(t.rmse_max)) th += " RMS <= " + fmt(t.rmse_max);
    if (!std::isnan(t.max_abs_max)) th += " max <= " + fmt(t.max_abs_max);
    if (beat)
      th += " RMS < " + fmt(metricOf(*beat, ch, "rmse")) + " and max < " +
            fmt(metricOf(*beat, ch, "max_abs")) + " (" + t.beat + ")";
  }
  o.threshold_desc = th;
  auto passes = [&](const json& m) {
    for (const auto& ch : t.channels) {
      const double rm = metricOf(m, ch, "rmse"), mx = metricOf(m, ch, "max_abs");
      if (!std::isnan(t.rmse_max) && !(rm <= t.rmse_max)) return false;
      if (!std::isnan(t.max_abs_max) && !(mx <= t.max_abs_max)) return false;
      if (beat && !(rm < metricOf(*beat, ch, "rmse") && mx < metricOf(*beat, ch, "max_abs")))
        return false;
    }
    return true;
  };
  // The passing member of lowest RMS on the first channel, else the lowest-RMS candidate.
  const std::string& first = t.channels.front();
  for (int pass = 1; pass >= 0 && o.member < 0; --pass)
    for (size_t i = 0; i < members.size(); ++i) {
      const json& m = members[i];
      if (!(costOf(m) <= o.limit)) continue;
      if (pass && !passes(m)) continue;
      if (o.member < 0 || metricOf(m, first, "rmse") < metricOf(members[o.member], first, "rmse"))
        o.member = static_cast<int>(i);
    }
  if (o.member >= 0) {
    const json& m = members[o.member];
    o.met = passes(m);
    o.cost = costOf(m);
    o.model_cost = getNum(m, "cost");
    for (const auto& ch : t.channels)
      o.measured.emplace_back(metricOf(m, ch, "rmse"), metricOf(m, ch, "max_abs"));
  }
  return o;
}

std::string write(const fs::path& p, const std::string& text) {
  std::string err;
  if (!lgp::plot::writeTextFile(p.string(), text, &err)) die(err);
  return p.filename().string();
}

// ---- report.md, one function per section in the order they appear ----

// The report's title and what makes its figures reproducible.
void writeReportHeader(std::ostringstream& md, bool quick, uint64_t seed, int threads) {
  md << "# lgp quality report\n\n"
     << "Generated by `lgp_quality" << (quick ? " --quick" : "") << "` (seed " << seed << ", "
     << threads << " threads). Every figure below is deterministic for this seed and "
     << "thread count: budgets are evaluation counts (nominal minutes x the table's calibrated "
     << "rate). Errors are float32-interpreter figures on the ground-truth table; \"error\" is "
     << "the run's objective, the RMS/max columns are per error channel (or output).\n\n";
}

// "## <title>" and the table's settings.
void writeTableHeader(std::ostringstream& md, const TableResult& r) {
  const TableSpec& s = r.spec;
  const json& table = r.snaps.back().front["table"];
  md << "## " << s.title << "\n\n";
  md << "- Config: `" << s.config << "`; " << r.table.rows() << " rows; inputs "
     << table["inputs"].dump() << "; outputs " << table["outputs"].dump() << ".\n";
  md << "- Error objective: " << lgp::toString(r.cfg.objectives.metric) << ", "
     << lgp::toString(r.cfg.objectives.combine) << " over "
     << nlohmann::json(r.channel_names).dump() << "; cost model "
     << lgp::toString(r.cfg.objectives.cost_model) << ".\n";
  md << "- Levers on: linear scaling " << (r.cfg.search.linear_scaling ? "yes" : "no")
     << ", seeded with the references " << (r.cfg.search.seed_references ? "yes" : "no")
     << ", refinement " << lgp::toString(r.cfg.search.refine.method) << "; population "
     << r.cfg.search.population << ", seed " << r.cfg.search.seed << ", threads "
     << r.cfg.search.threads << ".\n";
  md << "- Budgets: " << fmt(s.evals_per_minute, "%.3g")
     << " evaluations per nominal minute (calibrated on 2 cores; measured times are in "
        "`timing.json`).\n\n";
}

// "### Targets": each target against the final front. Returns the rows for summary.json.
json writeTargets(std::ostringstream& md, const TableResult& r) {
  const TableSpec& s = r.spec;
  const json& members = r.snaps.back().front.at("members");
  json tsum = json::array();
  if (s.targets.empty()) return tsum;
  md << "### Targets\n\n"
     << (r.measured
             ? "Cost limits are measured " + std::string(kCostFamily) +
                   " instructions (ACO, `lgp emit --lang hlsl --fast` code); the member's "
                   "model cost is beside its measured count.\n\n"
             : "Cost limits are model costs (no measured cost: " + r.measured_note + ").\n\n")
     << "| target | limit | threshold | error (RMS / max) | cost | met |\n"
        "|---|---|---|---|---|---|\n";
  for (const auto& t : s.targets) {
    const auto o = evaluateTarget(t, members, r.refs, r.measured);
    std::string meas;
    for (size_t k = 0; k < o.measured.size(); ++k)
      meas += (k ? "; " : "") + t.channels[k] + ": " + fmt(o.measured[k].first) + " / " +
              fmt(o.measured[k].second);
    md << "| " << mdEscape(o.name) << " | " << mdEscape(o.limit_desc) << " | "
       << mdEscape(o.threshold_desc) << " | " << (meas.empty() ? "no member" : meas) << " | "
       << fmt(o.cost) << (r.measured ? " (model " + fmt(o.model_cost) + ")" : "")
       << (o.member >= 0 ? " (#" + std::to_string(o.member) + ")" : "") << " | "
       << (o.met ? "yes" : "**no**") << " |\n";
    json mj = json::array();
    for (const auto& [a, b] : o.measured) mj.push_back({a, b});
    tsum.push_back({{"target", o.name},
                    {"limit", o.limit_desc},
                    {"threshold", o.threshold_desc},
                    {"measured", mj},
                    {"cost", o.cost},
                    {"model_cost", o.model_cost},
                    {"cost_unit", r.measured ? std::string(kCostFamily) + " instructions"
                                             : std::string("model")},
                    {"member", o.member},
                    {"met", o.met}});
  }
  md << "\n";
  // Every budget's front was measured (isa_levels): whether each target is met at each budget.
  if (r.measured && !s.isa_levels.empty() && r.snaps.size() > 1) {
    md << "Met at each budget (nominal minutes):\n\n| target |";
    for (const auto& sn : r.snaps) md << " " << fmt(sn.minutes) << " |";
    md << "\n|---|";
    for (size_t i = 0; i < r.snaps.size(); ++i) md << "---|";
    md << "\n";
    for (size_t k = 0; k < s.targets.size(); ++k) {
      md << "| " << mdEscape(s.targets[k].name) << " |";
      json per = json::array();
      for (const auto& sn : r.snaps) {
        const bool met = evaluateTarget(s.targets[k], sn.front.at("members"), r.refs, true).met;
        md << " " << (met ? "yes" : "no") << " |";
        per.push_back(met);
      }
      tsum[k]["met_at_budgets"] = per;
      md << "\n";
    }
    md << "\n";
  }
  return tsum;
}

// "| c <= 1 | c <= 4 |", then the `extra` header cells, and the rule, after the first `cols`
// columns of a table.
void costLevelColumns(std::ostringstream& md, const TableSpec& s, size_t cols,
                      const std::vector<std::string>& extra = {}) {
  for (double c : s.cost_levels) md << " c <= " << fmt(c) << " |";
  for (const auto& e : extra) md << " " << e << " |";
  md << "\n|";
  for (size_t k = 0; k < cols + s.cost_levels.size() + extra.size(); ++k) md << "---|";
  md << "\n";
}

// "### Accuracy against search time": the best error at each cost level per budget.
void writeBudgetTable(std::ostringstream& md, const TableResult& r) {
  const TableSpec& s = r.spec;
  const bool isa = r.measured && !s.isa_levels.empty();
  md << "### Accuracy against search time\n\nBest objective error at cost <= c (model cost)"
     << (isa ? std::string(" and at ") + kCostFamily +
                   " <= k (measured instructions of every budget's front)"
             : std::string())
     << ".\n\n| budget (nominal min) | evaluations | generations | front |";
  std::vector<std::string> isa_cols;
  if (isa)
    for (double k : s.isa_levels) isa_cols.push_back(std::string(kCostFamily) + " <= " + fmt(k));
  costLevelColumns(md, s, 4, isa_cols);
  for (const auto& sn : r.snaps) {
    md << "| " << fmt(sn.minutes) << " | " << sn.evaluations << " | " << sn.generation << " | "
       << sn.front["members"].size() << " |";
    for (double c : s.cost_levels) md << " " << fmt(bestAtCost(sn.front["members"], c)) << " |";
    if (isa)
      for (double k : s.isa_levels) md << " " << fmt(bestAtIsa(sn.front["members"], k)) << " |";
    md << "\n";
  }
  md << "\n";
}

// The front of every budget as a staircase, with the published formulas as labelled markers.
void writeFrontPlot(std::ostringstream& md, const TableResult& r, const fs::path& dir) {
  const TableSpec& s = r.spec;
  lgp::plot::Axes ax;
  ax.title = s.title + ": Pareto front (objective error against cost)";
  ax.xlabel = "cost (" + std::string(lgp::toString(r.cfg.objectives.cost_model)) + ")";
  ax.ylabel = "error";
  ax.logy = true;
  ax.generator = "lgp quality";
  std::vector<lgp::plot::Series> ser;
  for (const auto& sn : r.snaps) {
    lgp::plot::Series f;
    f.name = fmt(sn.minutes) + " min";
    f.style = lgp::plot::Series::Style::Steps;
    for (const auto& m : sn.front["members"]) {
      f.x.push_back(getNum(m, "cost"));
      f.y.push_back(getNum(m, "error", INFINITY));
    }
    ser.push_back(f);
  }
  lgp::plot::Series refs;
  refs.name = "published";
  refs.style = lgp::plot::Series::Style::Markers;
  refs.marker = lgp::plot::Series::Marker::Diamond;
  refs.color = "#d62728";
  for (const auto& ref : r.refs) {
    if (ref.contains("invalid")) continue;
    refs.x.push_back(getNum(ref, "cost"));
    refs.y.push_back(getNum(ref, "error", INFINITY));
    refs.labels.push_back(ref.value("name", ""));
  }
  ser.push_back(refs);
  md << "![front](" << write(dir / (s.name + "_front.svg"), lgp::plot::svgPlot(ax, ser)) << ")\n\n";
}

// The best error at each cost level against search time.
void writeCurvePlot(std::ostringstream& md, const TableResult& r, const fs::path& dir) {
  const TableSpec& s = r.spec;
  lgp::plot::Axes cx;
  cx.title = s.title + ": best error at cost <= c against search time";
  cx.xlabel = "search time (nominal minutes)";
  cx.ylabel = "error";
  cx.logx = cx.logy = true;
  cx.generator = "lgp quality";
  std::vector<lgp::plot::Series> cs;
  for (size_t k = 0; k < s.cost_levels.size(); ++k) {
    lgp::plot::Series l;
    l.name = "cost <= " + fmt(s.cost_levels[k]);
    l.style = lgp::plot::Series::Style::Line;
    for (const auto& cp : r.curve) {
      l.x.push_back(cp.minutes);
      l.y.push_back(k < cp.best.size() ? cp.best[k] : INFINITY);
    }
    cs.push_back(l);
  }
  md << "![curve](" << write(dir / (s.name + "_curve.svg"), lgp::plot::svgPlot(cx, cs)) << ")\n\n";
}

// The " <RMS> | <max> |" cells of a member or reference, one pair per channel.
std::string metricCells(const json& m, const std::vector<std::string>& chans) {
  std::string out;
  for (const auto& ch : chans)
    out += " " + fmt(metricOf(m, ch, "rmse")) + " | " + fmt(metricOf(m, ch, "max_abs")) + " |";
  return out;
}

// "### Final front": every member of the last budget's front.
void writeFinalFront(std::ostringstream& md, const TableResult& r) {
  const Snapshot& fin = r.snaps.back();
  const json& members = fin.front.at("members");
  std::string head = "| # | cost | ISA rdna2/rdna3/gcn5 | disc | error |",
              rule = "|---|---|---|---|---|";
  for (const auto& ch : r.channel_names) {
    head += " " + ch + " RMS | " + ch + " max |";
    rule += "---|---|";
  }
  md << "### Final front (" << fmt(fin.minutes) << " nominal minutes)\n\n"
     << head << " expression |\n"
     << rule << "---|\n";
  for (size_t i = 0; i < members.size(); ++i) {
    const json& m = members[i];
    md << "| " << i << " | " << fmt(getNum(m, "cost")) << " | " << isaCell(m) << " | "
       << fmt(getNum(m, "discontinuity")) << " | " << fmt(getNum(m, "error", INFINITY)) << " |"
       << metricCells(m, r.channel_names) << " `" << mdEscape(memberExpression(m)) << "` |\n";
  }
  md << "\n";
}

// "### Published formulas on the same table": the scored references and their refits.
void writeReferences(std::ostringstream& md, const TableResult& r) {
  const auto& chans = r.channel_names;
  md << "### Published formulas on the same table\n\n"
     << "\"(refit)\": the published structure with its constants fitted to this table "
        "(Nelder-Mead with restarts). ISA: measured instructions of the same emitted code as "
        "the members'.\n\n| name | cost | ISA rdna2/rdna3/gcn5 | disc | error |";
  for (const auto& ch : chans) md << " " << ch << " RMS | " << ch << " max |";
  md << "\n|---|---|---|---|---|";
  for (size_t k = 0; k < chans.size(); ++k) md << "---|---|";
  md << "\n";
  for (const auto& ref : r.refs) {
    if (ref.contains("invalid")) {
      md << "| " << mdEscape(ref.value("name", ""))
         << " | invalid: " << mdEscape(ref.value("invalid", "")) << " |\n";
      continue;
    }
    md << "| " << mdEscape(ref.value("name", "")) << " | " << fmt(getNum(ref, "cost")) << " | "
       << isaCell(ref) << " | " << fmt(getNum(ref, "discontinuity")) << " | "
       << fmt(getNum(ref, "error", INFINITY)) << " |" << metricCells(ref, chans) << "\n";
  }
  md << "\n";
}

// Every member of the final front run on lavapipe (emit/vulkan_run.hpp): GLSL and HLSL, float
// and half, over the whole table.
json verifyFront(const TableResult& r) {
  const json& front = r.snaps.back().front;
  const auto st = lgp::emit::vulkanRunStatus();
  if (!st.available) return {{"unavailable", st.detail}};
  json members = json::array();
  for (size_t i = 0; i < front["members"].size(); ++i) {
    auto in = lgp::emit::emitInputFromFront(front, i);
    if (!in) die("member " + std::to_string(i) + ": " + in.error());
    auto checks = lgp::emit::verifyOnVulkan(*in, r.table);
    json cj = json::array();
    if (!checks) {
      cj = {{{"error", checks.error()}}};
    } else {
      for (const auto& c : *checks) {
        json j = lgp::emit::toJson(c);
        j["worst_scaled_ulp"] = c.skipped ? json(nullptr) : json(c.worstScaledUlp());
        cj.push_back(j);
      }
    }
    members.push_back({{"member", i}, {"checks", cj}});
  }
  return {{"device", st.detail}, {"rows", r.table.rows()}, {"members", members}};
}

// "### In a Vulkan driver": the agreement of every member's shaders with lgp.
void writeVulkan(std::ostringstream& md, const TableResult& r) {
  md << "### In a Vulkan driver\n\n";
  if (r.vulkan.contains("unavailable")) {
    md << "Not run: " << mdEscape(r.vulkan["unavailable"].get<std::string>()) << ".\n\n";
    return;
  }
  md << "Every member of the final front as GLSL and HLSL compute shaders, in float and half, "
        "on "
     << mdEscape(r.vulkan["device"].get<std::string>()) << " over all " << r.table.rows()
     << " rows (`lgp emit --verify vulkan`). Largest difference from lgp in ulps of the "
        "output's largest |value| (float: the float32 interpreter; half: lgp's binary16 "
        "emulation), and the driver's RMS error against the ground truth on the first output "
        "beside the interpreter's.\n\n| # | GLSL float | GLSL half | HLSL float | HLSL half | "
        "RMS (driver / lgp) |\n|---|---|---|---|---|---|\n";
  double worst_f = 0, worst_h = 0;
  std::vector<std::string> nonfinite;  // member and check where driver and lgp disagree on
                                       // which rows are finite (no ulp distance exists)
  for (const auto& m : r.vulkan["members"]) {
    md << "| " << m["member"].get<size_t>() << " |";
    std::string rms = "-";
    for (const auto& c : m["checks"]) {
      if (c.contains("error")) {
        md << " error: " << mdEscape(c["error"].get<std::string>()) << " |";
        continue;
      }
      if (c.contains("skipped")) {
        md << " skipped |";
        continue;
      }
      const double w =
          c["worst_scaled_ulp"].is_number() ? c["worst_scaled_ulp"].get<double>() : INFINITY;
      double& worst = c["precision"] == "half" ? worst_h : worst_f;
      if (std::isfinite(w))
        worst = std::max(worst, w);
      else
        nonfinite.push_back("#" + std::to_string(m["member"].get<size_t>()) + " " +
                            c["lang"].get<std::string>() + " " + c["precision"].get<std::string>());
      md << " " << fmt(w) << " |";
      if (rms == "-" && c["precision"] == "float" && !c["outputs"].empty())
        rms = fmt(getNum(c["outputs"][0]["driver"], "rmse", INFINITY)) + " / " +
              fmt(getNum(c["outputs"][0]["reference"], "rmse", INFINITY));
    }
    md << " " << rms << " |\n";
  }
  md << "\nWorst: " << fmt(worst_f) << " ulps (float), " << fmt(worst_h) << " binary16 ulps (half)";
  if (!nonfinite.empty()) {
    md << "; not finite on the same rows (\"-\"): ";
    for (size_t i = 0; i < nonfinite.size(); ++i) md << (i ? ", " : "") << nonfinite[i];
  }
  md << ".\n\n";
}

// "### Search levers": the ablation runs (none: no section).
void writeAblation(std::ostringstream& md, const TableResult& r) {
  const TableSpec& s = r.spec;
  if (r.ablation.empty()) return;
  md << "### Search levers (" << fmt(s.ablation_minutes)
     << " nominal minutes each, same seed)\n\nBest objective error at cost <= c.\n\n| variant "
        "| evaluations |";
  costLevelColumns(md, s, 2);
  for (const auto& a : r.ablation) {
    md << "| " << mdEscape(a.name) << " | " << a.evaluations << " |";
    for (double e : a.best) md << " " << fmt(e) << " |";
    md << "\n";
  }
  md << "\n";
}

// The most accurate member at each cost level, each once, in cost-level order.
std::vector<int> recommendedMembers(const TableResult& r) {
  std::vector<int> rec;
  for (double c : r.spec.cost_levels) {
    lgp::emit::MemberSelector sel;
    sel.max_cost = c;
    const auto i = lgp::emit::selectMember(r.snaps.back().front, sel);
    if (i && std::find(rec.begin(), rec.end(), static_cast<int>(*i)) == rec.end())
      rec.push_back(static_cast<int>(*i));
  }
  return rec;
}

// Model minus truth at every row, of the first error channel (or of output `err_name`).
std::vector<double> signedError(const TableResult& r, const lgp::Program& prog,
                                const std::string& err_name) {
  const auto pred = lgp::Interpreter(256).evaluate(prog, lgp::Dataset(r.table, 256));
  const auto ec = r.cfg.errorConfig(r.table.output_names);
  std::vector<double> err(r.table.rows(), 0.0);
  for (size_t row = 0; row < r.table.rows(); ++row) {
    double pv = 0, yv = 0;
    for (size_t o = 0; o < pred.size(); ++o) {
      const double w = ec.channels.empty() ? (r.table.output_names[o] == err_name ? 1.0 : 0.0)
                                           : ec.channels.front().weights[o];
      pv += w * lgp::invertTransform(ec.transforms[o], pred[o][row]);
      yv += w * r.table.outputs[o][row];
    }
    err[row] = pv - yv;
  }
  return err;
}

// The signed error over the input grid: a heatmap for two inputs, else against the first
// input. Returns the markdown link (", [error map](file)").
std::string writeErrorPlot(const TableResult& r, int i, const std::vector<double>& err,
                           const std::string& err_name, const fs::path& dir) {
  const TableSpec& s = r.spec;
  const std::string title = s.title + " #" + std::to_string(i) + ": signed error of " + err_name;
  if (r.table.numInputs() == 2) {
    std::vector<double> xs(r.table.inputs[0]), ys(r.table.inputs[1]);
    for (auto* v : {&xs, &ys}) {
      std::sort(v->begin(), v->end());
      v->erase(std::unique(v->begin(), v->end()), v->end());
    }
    lgp::plot::Heatmap h;
    h.title = title;
    h.xlabel = r.table.input_names[0];
    h.ylabel = r.table.input_names[1];
    h.value_label = "model - truth";
    h.diverging = true;
    h.generator = "lgp quality";
    h.xs = xs;
    h.ys = ys;
    h.values.assign(xs.size() * ys.size(), NAN);
    for (size_t row = 0; row < r.table.rows(); ++row) {
      const size_t ix = std::lower_bound(xs.begin(), xs.end(), r.table.inputs[0][row]) - xs.begin();
      const size_t iy = std::lower_bound(ys.begin(), ys.end(), r.table.inputs[1][row]) - ys.begin();
      h.values[iy * xs.size() + ix] = err[row];
    }
    return ", [error map](" +
           write(dir / (s.name + "_heat_m" + std::to_string(i) + ".svg"),
                 lgp::plot::svgHeatmap(h)) +
           ")";
  }
  lgp::plot::Axes ax;
  ax.title = title;
  ax.xlabel = r.table.input_names[0];
  ax.ylabel = "model - truth";
  ax.generator = "lgp quality";
  lgp::plot::Series e;
  e.name = err_name;
  e.style = lgp::plot::Series::Style::Markers;
  e.x = r.table.inputs[0];
  e.y = err;
  return ", [error plot](" +
         write(dir / (s.name + "_err_m" + std::to_string(i) + ".svg"),
               lgp::plot::svgPlot(ax, {e})) +
         ")";
}

// "### Recommended members": for each, its HLSL and an error plot. Returns the members.
std::vector<int> writeRecommended(std::ostringstream& md, const TableResult& r,
                                  const fs::path& dir) {
  const TableSpec& s = r.spec;
  const Snapshot& fin = r.snaps.back();
  const json& members = fin.front.at("members");
  const std::vector<int> rec = recommendedMembers(r);
  md << "### Recommended members\n\nThe most accurate member at each cost level.\n\n";
  const std::string err_name = r.channel_names.empty() ? "" : r.channel_names.front();
  for (int i : rec) {
    const json& m = members[i];
    md << "- #" << i << ", cost " << fmt(getNum(m, "cost")) << " (measured " << isaCell(m)
       << " instructions on rdna2/rdna3/gcn5), error " << fmt(getNum(m, "error", INFINITY)) << ": ";
    lgp::emit::EmitOptions eo;
    eo.function_name = "lgp_" + s.name + "_" + std::to_string(i);
    eo.source = "report member " + std::to_string(i);
    auto code =
        lgp::emit::emitFromFront(fin.front, static_cast<size_t>(i), lgp::emit::Language::Hlsl, eo);
    if (code)
      md << "[HLSL](" << write(dir / (s.name + "_m" + std::to_string(i) + ".hlsl"), *code) << ")";
    else
      md << "HLSL failed: " << code.error();
    if (auto prog = lgp::memberProgram(fin.front, static_cast<size_t>(i)))
      md << writeErrorPlot(r, i, signedError(r, *prog, err_name), err_name, dir);
    md << "\n  `" << mdEscape(memberExpression(m)) << "`\n";
  }
  md << "\n";
  return rec;
}

// One "## <table>" part of report.md; the targets met and the recommended members go to
// `summary`.
void writeTableReport(std::ostringstream& md, const TableResult& r, const fs::path& dir,
                      json& summary) {
  writeTableHeader(md, r);
  summary["targets"] = writeTargets(md, r);
  writeBudgetTable(md, r);
  writeFrontPlot(md, r, dir);
  writeCurvePlot(md, r, dir);
  writeFinalFront(md, r);
  writeReferences(md, r);
  writeAblation(md, r);
  writeVulkan(md, r);
  summary["vulkan"] = r.vulkan;
  {
    // The final front with its references and measured cost, as `lgp run` writes fronts (for
    // lgp front, lgp emit and bench/cost).
    json f = r.snaps.back().front;
    f["references"] = r.refs;
    write(dir / (r.spec.name + "_front.json"), f.dump(1) + "\n");
    md << "The final front with its references: [" << r.spec.name << "_front.json](" << r.spec.name
       << "_front.json).\n\n";
  }
  summary["recommended"] = writeRecommended(md, r, dir);
}

int qualityMain(int argc, char** argv) {
  cxxopts::Options opts("lgp_quality",
                        "Quality runs and report: accuracy against search time "
                        "and GPU cost, with the published formulas.");
  opts.add_options()("spec", "quality spec (JSON)",
                     cxxopts::value<std::string>()->default_value(std::string(LGP_SOURCE_DIR) +
                                                                  "/bench/quality/quality.json"))(
      "o,out", "report folder", cxxopts::value<std::string>()->default_value("quality-report"))(
      "budgets", "nominal minutes, comma-separated (tables may override)",
      cxxopts::value<std::string>()->default_value("1,5,20"))(
      "quick", "minutes in total: budgets 0.02,0.05 and ablation 0.02 (structure check)")(
      "tables", "only these tables, comma-separated", cxxopts::value<std::string>())(
      "no-ablation", "skip the search-lever runs")("threads", "OpenMP threads",
                                                   cxxopts::value<int>()->default_value("2"))(
      "seed", "search seed", cxxopts::value<uint64_t>()->default_value("1"))(
      "state",
      "folder for each table's run state (<table>.state.json): saved as the run goes, a run "
      "resumes from it (same seed, threads and budgets) and a finished one is not searched again",
      cxxopts::value<std::string>())("save-every", "seconds between state saves",
                                     cxxopts::value<double>()->default_value("300"))(
      "stop-after",
      "wall seconds after which the search saves its state and lgp_quality exits with 3 "
      "(needs --state)",
      cxxopts::value<double>()->default_value("0"))("h,help", "help");
  cxxopts::ParseResult args;
  try {
    args = opts.parse(argc, argv);
  } catch (const std::exception& e) {
    die(e.what());
  }
  if (args.count("help")) {
    std::printf("%s\n", opts.help().c_str());
    return 0;
  }
  const bool quick = args.count("quick") > 0;
  const int threads = args["threads"].as<int>();
  const uint64_t seed = args["seed"].as<uint64_t>();
  const fs::path spec_path = args["spec"].as<std::string>();
  std::ifstream in(spec_path);
  if (!in) die(spec_path.string() + ": cannot open");
  json spec;
  try {
    in >> spec;
  } catch (const json::exception& e) {
    die(spec_path.string() + ": invalid JSON: " + e.what());
  }
  auto tables = parseSpec(spec, spec_path.string());
  std::set<std::string> only;
  if (args.count("tables")) {
    std::stringstream ss(args["tables"].as<std::string>());
    for (std::string t; std::getline(ss, t, ',');) only.insert(t);
  }
  std::vector<double> budgets;
  {
    std::stringstream ss(quick ? std::string("0.02,0.05") : args["budgets"].as<std::string>());
    for (std::string t; std::getline(ss, t, ',');) {
      try {
        budgets.push_back(std::stod(t));
      } catch (...) {
        die("--budgets: '" + t + "' is not a number");
      }
      if (!(budgets.back() > 0)) die("--budgets: minutes must be > 0");
    }
    std::sort(budgets.begin(), budgets.end());
  }
  StateOptions so;
  so.seed = seed;
  so.threads = threads;
  so.save_every_s = args["save-every"].as<double>();
  so.stop_after_s = args["stop-after"].as<double>();
  if (!(so.save_every_s > 0)) die("--save-every: must be > 0 seconds");
  if (!(so.stop_after_s >= 0)) die("--stop-after: must be >= 0 seconds");
  fs::path state_dir;
  if (args.count("state")) {
    state_dir = args["state"].as<std::string>();
    std::error_code ec;
    fs::create_directories(state_dir, ec);
    if (ec) die("--state: cannot create " + state_dir.string() + ": " + ec.message());
  } else if (so.stop_after_s > 0) {
    die("--stop-after: needs --state (where the stopped run is saved)");
  }
  const fs::path out = args["out"].as<std::string>();
  fs::create_directories(out);
  std::ostringstream md;
  writeReportHeader(md, quick, seed, threads);
  json timing = json::object();
  json summary = json::object();
  for (auto& spec_t : tables) {
    if (!only.empty() && !only.count(spec_t.name)) continue;
    TableResult r;
    r.spec = spec_t;
    const fs::path cfg_path = spec_path.parent_path() / spec_t.config;
    r.cfg = loadConfig(cfg_path, json(), threads, seed);
    std::fprintf(stderr, "lgp_quality: %s: loading the table\n", spec_t.name.c_str());
    auto table = lgp::cli::loadRunTable(r.cfg);
    if (!table) die(cfg_path.string() + ": " + table.error());
    r.table = std::move(*table);
    if (auto st = lgp::emit::checkReferences(r.cfg, r.table); !st)
      die(cfg_path.string() + ": " + st.message());
    r.channel_names =
        lgp::channelNames(r.cfg.errorConfig(r.table.output_names), r.table.output_names);
    r.refs = lgp::emit::scoreReferences(r.cfg, r.table);
    std::vector<double> mins =
        quick ? budgets : (spec_t.minutes.empty() ? budgets : spec_t.minutes);
    std::fprintf(stderr, "lgp_quality: %s: searching to %g nominal minutes\n", spec_t.name.c_str(),
                 mins.back());
    so.path = state_dir.empty() ? fs::path() : state_dir / (spec_t.name + ".state.json");
    if (!runTable(r, mins, so)) return 3;
    {
      // Measured cost of the final front and of the references (docs/cost-models.md).
      json f = r.snaps.back().front;
      f["references"] = r.refs;
      lgp::emit::addMeasuredCost(f);
      r.refs = f["references"];
      f.erase("references");
      const auto& info = f["cost_measured_info"];
      r.measured = !info.contains("unavailable");
      r.measured_note = r.measured ? info.value("compiler", std::string())
                                   : info["unavailable"].get<std::string>();
      r.snaps.back().front = std::move(f);
      // The earlier budgets' fronts too, for the budget table's measured columns.
      if (r.measured && !spec_t.isa_levels.empty())
        for (size_t i = 0; i + 1 < r.snaps.size(); ++i)
          lgp::emit::addMeasuredCost(r.snaps[i].front);
      std::fprintf(stderr, "lgp_quality: %s: running the final front on lavapipe\n",
                   spec_t.name.c_str());
      r.vulkan = verifyFront(r);
    }
    if (!args.count("no-ablation")) {
      const double am = quick ? 0.02 : spec_t.ablation_minutes;
      for (const auto& a : spec_t.ablation) {
        std::fprintf(stderr, "lgp_quality: %s: lever run '%s'\n", spec_t.name.c_str(),
                     a.name.c_str());
        r.ablation.push_back(runAblation(r, a, cfg_path, threads, seed, am));
      }
    }
    json ts = json::object();
    for (const auto& sn : r.snaps)
      ts[fmt(sn.minutes) + " min"] = {{"evaluations", sn.evaluations}, {"wall_s", sn.wall_s}};
    for (const auto& a : r.ablation)
      ts["lever: " + a.name] = {{"evaluations", a.evaluations}, {"wall_s", a.wall_s}};
    timing[spec_t.name] = ts;
    json tsum;
    writeTableReport(md, r, out, tsum);
    summary[spec_t.name] = tsum;
  }
  write(out / "report.md", md.str());
  write(out / "timing.json", timing.dump(2) + "\n");
  write(out / "summary.json", summary.dump(2) + "\n");
  std::fprintf(stderr, "lgp_quality: report in %s\n", (out / "report.md").string().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return qualityMain(argc, argv);
}
