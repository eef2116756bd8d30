#include "lgp/config/config.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "lgp/config/json_reader.hpp"
#include "lgp/core/table.hpp"
#include "lgp/core/text_check.hpp"

namespace lgp {

std::string_view toString(RefineMethod m) {
  return m == RefineMethod::DeThenNm ? "de+nm" : "nm";
}

std::string_view toString(LmObjective o) {
  switch (o) {
    case LmObjective::LeastSquares:
      return "least_squares";
    case LmObjective::Configured:
      return "configured";
    case LmObjective::Auto:
      break;
  }
  return "auto";
}
std::string_view toString(ArchiveRefineOrder o) {
  return o == ArchiveRefineOrder::Oldest ? "oldest" : "accurate";
}
std::string_view toString(IslandDeal d) {
  return d == IslandDeal::ByCost ? "by_cost" : "interleaved";
}
std::string_view toString(MigrationTopology t) {
  return t == MigrationTopology::ByProfile ? "by_profile" : "ring";
}
std::string_view toString(MultiOutputMode m) {
  return m == MultiOutputMode::TwoStep ? "two_step" : "joint";
}

std::string_view toString(MigrationMode m) {
  return m == MigrationMode::Sync ? "sync" : "async";
}

std::vector<Op> defaultOps() {
  std::vector<Op> ops;
  for (const auto& i : allOps())
    if (i.default_set) ops.push_back(i.op);
  return ops;
}

namespace {

// Raised inside the parser only; parseRunConfig turns it into a Status.
struct ConfigError {
  std::string msg;
};

[[noreturn]] void fail(const std::string& path, const std::string& why) {
  throw ConfigError{jsonError(path, why)};
}

std::string typeName(const nlohmann::json& v) {
  return v.type_name();
}

// Reads one JSON object with the run config's typed checks; the keys it did not read are
// unknown (finish()).
class Obj {
 public:
  Obj(const nlohmann::json& j, std::string path) : r_(j, std::move(path)) {
    if (!r_.isObject()) fail(r_.path(), "must be an object (got " + typeName(j) + ")");
  }
  bool has(const std::string& k) { return r_.has(k); }
  const nlohmann::json& at(const std::string& k) { return r_.at(k); }
  std::string path(const std::string& k) const { return r_.path(k); }
  void finish() const {
    if (auto k = r_.unknownKey()) fail(*k, "unknown key");
  }

  void integer(const std::string& k, int& out, long long lo, long long hi) {
    if (!has(k)) return;
    const auto& v = at(k);
    if (!v.is_number_integer())
      fail(path(k), "must be an integer (got " + typeName(v) + " " + v.dump() + ")");
    const long long x = v.get<long long>();
    if (x < lo || x > hi)
      fail(path(k), "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "] (got " +
                        std::to_string(x) + ")");
    out = static_cast<int>(x);
  }
  void uinteger(const std::string& k, uint64_t& out) {
    if (!has(k)) return;
    const auto& v = at(k);
    if (!v.is_number_integer() ||
        (v.is_number_integer() && !v.is_number_unsigned() && v.get<long long>() < 0))
      fail(path(k), "must be a non-negative integer (got " + v.dump() + ")");
    out = v.get<uint64_t>();
  }
  void number(const std::string& k, double& out, double lo, double hi, bool open_lo = false) {
    if (!has(k)) return;
    const auto& v = at(k);
    if (!v.is_number())
      fail(path(k), "must be a number (got " + typeName(v) + " " + v.dump() + ")");
    const double x = v.get<double>();
    if (!std::isfinite(x) || x < lo || x > hi || (open_lo && x == lo)) {
      std::ostringstream os;
      os << "must be in " << (open_lo ? "(" : "[") << lo << ", " << hi << "] (got " << x << ")";
      fail(path(k), os.str());
    }
    out = x;
  }
  void boolean(const std::string& k, bool& out) {
    if (!has(k)) return;
    const auto& v = at(k);
    if (!v.is_boolean()) fail(path(k), "must be true or false (got " + typeName(v) + ")");
    out = v.get<bool>();
  }
  void string(const std::string& k, std::string& out) {
    if (!has(k)) return;
    const auto& v = at(k);
    if (!v.is_string()) fail(path(k), "must be a string (got " + typeName(v) + ")");
    out = v.get<std::string>();
  }
  void strings(const std::string& k, std::vector<std::string>& out) {
    if (!has(k)) return;
    const auto& v = at(k);
    if (!v.is_array()) fail(path(k), "must be an array of strings (got " + typeName(v) + ")");
    out.clear();
    for (size_t i = 0; i < v.size(); ++i) {
      if (!v[i].is_string()) fail(jsonPath(path(k), i), "must be a string");
      out.push_back(v[i].get<std::string>());
    }
  }
  template <class E, class F>
  void enumeration(const std::string& k, E& out, F from, const std::string& choices) {
    if (!has(k)) return;
    const auto& v = at(k);
    if (!v.is_string()) fail(path(k), "must be one of " + choices);
    auto e = from(v.get<std::string>());
    if (!e) fail(path(k), "'" + v.get<std::string>() + "' is not one of " + choices);
    out = *e;
  }

 private:
  JsonObjectReader r_;
};

std::string opChoices() {
  std::string s;
  for (const auto& i : allOps()) s += (s.empty() ? "" : ", ") + std::string(i.name);
  return s;
}

Op parseOp(const nlohmann::json& v, const std::string& path) {
  if (!v.is_string()) fail(path, "must be an operator name");
  auto op = opFromString(v.get<std::string>());
  if (!op)
    fail(path, "unknown operator '" + v.get<std::string>() + "' (known: " + opChoices() + ")");
  return *op;
}

std::map<Op, double> opNumberMap(Obj& o, const std::string& k) {
  std::map<Op, double> out;
  if (!o.has(k)) return out;
  const auto& v = o.at(k);
  if (!v.is_object()) fail(o.path(k), "must be an object of operator -> number");
  for (auto it = v.begin(); it != v.end(); ++it) {
    const std::string p = jsonPath(o.path(k), it.key());
    const Op op = parseOp(nlohmann::json(it.key()), p);
    if (!it.value().is_number() || !(it.value().get<double>() >= 0) ||
        !std::isfinite(it.value().get<double>()))
      fail(p, "must be a finite number >= 0");
    out[op] = it.value().get<double>();
  }
  return out;
}

void parseData(const nlohmann::json& j, DataConfig& d) {
  Obj o(j, "/data");
  o.string("path", d.path);
  o.string("scene", d.scene);
  o.strings("inputs", d.inputs);
  o.strings("outputs", d.outputs);
  o.string("weights", d.weights);
  o.string("cache_dir", d.cache_dir);
  if (o.has("transforms")) {
    const auto& t = o.at("transforms");
    if (!t.is_object()) fail(o.path("transforms"), "must be an object of output -> transform");
    for (auto it = t.begin(); it != t.end(); ++it) {
      const std::string p = jsonPath(o.path("transforms"), it.key());
      if (!it.value().is_string()) fail(p, "must be one of none, log, sqrt, rcp");
      auto tr = targetTransformFromString(it.value().get<std::string>());
      if (!tr)
        fail(p, "'" + it.value().get<std::string>() + "' is not one of none, log, sqrt, rcp");
      d.transforms[it.key()] = *tr;
    }
  }
  if (o.has("edges")) {
    Obj e(o.at("edges"), o.path("edges"));
    if (!e.has("domain") || !e.at("domain").is_object() || e.at("domain").empty())
      fail(e.path("domain"), "must be a non-empty object of input -> [lo, hi]");
    const auto& dom = e.at("domain");
    for (auto it = dom.begin(); it != dom.end(); ++it) {
      const std::string p = jsonPath(e.path("domain"), it.key());
      const auto& v = it.value();
      if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number() ||
          !std::isfinite(v[0].get<double>()) || !std::isfinite(v[1].get<double>()) ||
          !(v[0].get<double>() < v[1].get<double>()))
        fail(p, "must be [lo, hi], finite numbers with lo < hi (got " + v.dump() + ")");
      if (auto why = controlCharacterReason(it.key()); !why.empty()) fail(p, why);
      d.edges.domain[it.key()] = {v[0].get<double>(), v[1].get<double>()};
    }
    e.number("weight", d.edges.weight, 0, 1e6, true);
    e.finish();
  }
  o.finish();
  // These texts reach messages and the comments of emitted code.
  for (const auto& [key, text] : {std::pair<const char*, const std::string*>{"path", &d.path},
                                  {"scene", &d.scene},
                                  {"weights", &d.weights},
                                  {"cache_dir", &d.cache_dir}})
    if (auto why = controlCharacterReason(*text); !why.empty()) fail(o.path(key), why);
  for (const auto& [key, names] :
       {std::pair<const char*, const std::vector<std::string>*>{"inputs", &d.inputs},
        {"outputs", &d.outputs}})
    for (size_t i = 0; i < names->size(); ++i)
      if (auto why = controlCharacterReason((*names)[i]); !why.empty())
        fail(jsonPath(o.path(key), i), why);
  for (const auto& [name, tr] : d.transforms)
    if (auto why = controlCharacterReason(name); !why.empty())
      fail(o.path("transforms"), "an output name " + why);
  if (d.path.empty() == d.scene.empty())
    fail("/data", "exactly one of \"path\" and \"scene\" is required");
}

void parseProgram(const nlohmann::json& j, ProgramConfig& p) {
  Obj o(j, "/program");
  o.integer("max_length", p.max_length, 1, 255);
  o.integer("constants", p.num_constants, 0, 255);
  if (o.has("output_mode")) {
    const auto& v = o.at("output_mode");
    if (v == "last")
      p.output_mode = OutputMode::Last;
    else if (v == "designated")
      p.output_mode = OutputMode::Designated;
    else
      fail("/program/output_mode", "must be \"last\" or \"designated\"");
  }
  if (o.has("ops")) {
    const auto& v = o.at("ops");
    if (!v.is_array() || v.empty())
      fail("/program/ops", "must be a non-empty array of operator names");
    p.ops.clear();
    std::set<Op> seen;
    for (size_t i = 0; i < v.size(); ++i) {
      const Op op = parseOp(v[i], jsonPath(o.path("ops"), i));
      if (seen.insert(op).second) p.ops.push_back(op);
    }
  }
  o.integer("init_min_length", p.init_min_length, 1, 255);
  o.integer("init_max_length", p.init_max_length, 1, 255);
  o.number("const_min", p.const_min, -1e30, 1e30);
  o.number("const_max", p.const_max, -1e30, 1e30);
  o.integer("genes", p.genes, 1, kMaxGenes);
  o.finish();
}

void parseObjectives(const nlohmann::json& j, ObjectiveConfig& c) {
  Obj o(j, "/objectives");
  o.enumeration("error", c.metric, errorMetricFromString, "rmse, max_abs, mae, mean_rel");
  o.enumeration("combine", c.combine, outputCombineFromString, "mean, max");
  o.number("rel_floor", c.rel_floor, 0, 1e30, true);
  std::string targets;
  for (auto n : kCostTargetNames) targets += (targets.empty() ? "" : ", ") + std::string(n);
  o.enumeration("cost_model", c.cost_model, costTargetFromString, targets);
  c.cost_overrides = opNumberMap(o, "cost_overrides");
  c.discontinuity_weights = opNumberMap(o, "discontinuity_weights");
  if (o.has("measured_cost")) {
    Obj m(o.at("measured_cost"), o.path("measured_cost"));
    std::vector<std::string> fams;
    m.strings("families", fams);
    if (m.has("families")) {
      c.measured_cost.families.clear();
      std::string choices;
      for (auto n : kGpuFamilyNames) choices += (choices.empty() ? "" : ", ") + std::string(n);
      for (size_t i = 0; i < fams.size(); ++i) {
        auto f = gpuFamilyFromString(fams[i]);
        if (!f) fail(jsonPath(m.path("families"), i), "'" + fams[i] + "' is not one of " + choices);
        if (std::find(c.measured_cost.families.begin(), c.measured_cost.families.end(), *f) !=
            c.measured_cost.families.end())
          fail(jsonPath(m.path("families"), i), "'" + fams[i] + "' is listed twice");
        c.measured_cost.families.push_back(*f);
      }
    }
    m.boolean("in_search", c.measured_cost.in_search);
    if (c.measured_cost.in_search && c.measured_cost.families.empty())
      fail(m.path("in_search"), "needs at least one family in families");
    m.finish();
  }
  if (o.has("channels")) {
    const auto& v = o.at("channels");
    if (!v.is_array())
      fail("/objectives/channels", "must be an array of {\"name\", \"weights\"} objects");
    std::set<std::string> names;
    for (size_t i = 0; i < v.size(); ++i) {
      Obj ch(v[i], jsonPath(o.path("channels"), i));
      ChannelConfig cc;
      ch.string("name", cc.name);
      if (cc.name.empty()) fail(ch.path("name"), "must be a non-empty string");
      if (!names.insert(cc.name).second)
        fail(ch.path("name"), "duplicate channel '" + cc.name + "'");
      if (!ch.has("weights") || !ch.at("weights").is_object() || ch.at("weights").empty())
        fail(ch.path("weights"), "must be a non-empty object of output name -> weight");
      for (auto it = ch.at("weights").begin(); it != ch.at("weights").end(); ++it) {
        if (!it.value().is_number() || !std::isfinite(it.value().get<double>()))
          fail(jsonPath(ch.path("weights"), it.key()), "must be a finite number");
        cc.weights[it.key()] = it.value().get<double>();
      }
      ch.finish();
      c.channels.push_back(std::move(cc));
    }
  }
  o.finish();
}

void parseRefine(const nlohmann::json& j, RefineSchedule& r) {
  Obj o(j, "/search/refine");
  o.number("offspring_share", r.offspring_share, 0, 1);
  o.integer("lm_iterations", r.lm_iterations, 0, 1 << 20);
  o.integer("archive_lm_iterations", r.archive_lm_iterations, 0, 1 << 20);
  o.integer("offspring_evaluations", r.offspring_evaluations, 1, 1 << 30);
  o.integer("archive_period", r.archive_period, 0, 1 << 30);
  o.integer("archive_max", r.archive_max, 0, 1 << 20);
  if (o.has("archive_order")) {
    const auto& v = o.at("archive_order");
    if (v == "accurate")
      r.archive_order = ArchiveRefineOrder::Accurate;
    else if (v == "oldest")
      r.archive_order = ArchiveRefineOrder::Oldest;
    else
      fail("/search/refine/archive_order",
           "must be \"accurate\" or \"oldest\" (got " + v.dump() + ")");
  }
  o.integer("max_evaluations", r.nm.max_evaluations, 1, 1 << 30);
  o.integer("restarts", r.nm.restarts, 0, 1000);
  o.number("initial_step", r.nm.initial_step, 0, 1e6, true);
  o.number("tolerance", r.nm.tolerance, 0, 1);
  if (o.has("method")) {
    const auto& v = o.at("method");
    if (v == "nm")
      r.method = RefineMethod::NelderMead;
    else if (v == "de+nm")
      r.method = RefineMethod::DeThenNm;
    else
      fail("/search/refine/method", "must be \"nm\" or \"de+nm\" (got " + v.dump() + ")");
  }
  o.integer("de_evaluations", r.de_evaluations, 1, 1 << 30);
  if (o.has("lm_metric")) {
    const auto& v = o.at("lm_metric");
    if (v == "auto")
      r.lm_metric = LmObjective::Auto;
    else if (v == "configured")
      r.lm_metric = LmObjective::Configured;
    else if (v == "least_squares")
      r.lm_metric = LmObjective::LeastSquares;
    else
      fail("/search/refine/lm_metric",
           "must be \"auto\", \"configured\" or \"least_squares\" (got " + v.dump() + ")");
  }
  o.finish();
}

void parseMultiOutput(const nlohmann::json& j, MultiOutputConfig& m) {
  Obj o(j, "/search/multi_output");
  if (o.has("mode")) {
    const auto& v = o.at("mode");
    if (v == "joint")
      m.mode = MultiOutputMode::Joint;
    else if (v == "two_step")
      m.mode = MultiOutputMode::TwoStep;
    else
      fail("/search/multi_output/mode", "must be \"joint\" or \"two_step\" (got " + v.dump() + ")");
  }
  o.string("first", m.first);
  o.number("first_share", m.first_share, 0, 1, true);
  o.number("first_max_cost", m.first_max_cost, 0, 1e9);
  o.finish();
  if (m.first_share >= 1)
    fail("/search/multi_output/first_share", "must be < 1 (the second step needs a budget)");
}

void parseArchive(const nlohmann::json& j, ArchiveConfig& a) {
  Obj o(j, "/search/archive");
  o.integer("max_size", a.max_size, 1, 1 << 20);
  o.number("eps_log10_error", a.eps_log10_error, 0, 10);
  o.number("eps_cost", a.eps_cost, 0, 1e6);
  o.number("eps_discontinuity", a.eps_discontinuity, 0, 1e6);
  o.finish();
}

void parseVariation(const nlohmann::json& j, VariationConfig& v) {
  Obj o(j, "/search/variation");
  o.number("crossover_rate", v.crossover_rate, 0, 1);
  o.number("macro_rate", v.macro_rate, 0, 1);
  o.number("micro_rate", v.micro_rate, 0, 1);
  o.integer("micro_max", v.micro_max, 1, 64);
  o.number("constant_sigma", v.constant_sigma, 0, 1e6);
  o.number("effective_bias", v.effective_bias, 0, 1);
  o.number("wrap_share", v.wrap_share, 0, 1);
  o.number("weight_rate", v.weight_rate, 0, 1);
  o.integer("weight_min_length", v.weight_min_length, 0, 256);
  o.finish();
}

void parseIslands(const nlohmann::json& j, IslandConfig& c) {
  Obj o(j, "/search/islands");
  o.integer("count", c.count, 1, 4096);
  o.integer("migration_interval", c.migration_interval, 0, 1 << 30);
  o.integer("migrants", c.migrants, 0, 1 << 20);
  o.integer("restart_after", c.restart_after, 0, 1 << 30);
  o.number("adaptive", c.adaptive, 0, 0.95);
  o.integer("adaptive_halflife", c.adaptive_halflife, 1, 1 << 20);
  if (o.has("deal")) {
    const auto& v = o.at("deal");
    if (v == "interleaved")
      c.deal = IslandDeal::Interleaved;
    else if (v == "by_cost")
      c.deal = IslandDeal::ByCost;
    else
      fail("/search/islands/deal", "must be \"interleaved\" or \"by_cost\" (got " + v.dump() + ")");
  }
  if (o.has("topology")) {
    const auto& v = o.at("topology");
    if (v == "ring")
      c.topology = MigrationTopology::Ring;
    else if (v == "by_profile")
      c.topology = MigrationTopology::ByProfile;
    else
      fail(o.path("topology"), "must be \"ring\" or \"by_profile\" (got " + v.dump() + ")");
  }
  if (o.has("profiles")) {
    const auto& v = o.at("profiles");
    if (!v.is_array() || v.empty())
      fail(o.path("profiles"),
           "must be a non-empty array of {\"max_length\", \"constants\", \"weight_rate\", "
           "\"share\", \"error_bias\", \"cost_strata\"} objects (island k takes entry k mod its "
           "size)");
    c.profiles.clear();  // the given list replaces the default one
    for (size_t i = 0; i < v.size(); ++i) {
      Obj p(v[i], jsonPath(o.path("profiles"), i));
      IslandProfile ip;
      p.integer("max_length", ip.max_length, 0, 255);
      p.integer("constants", ip.constants, 0, 255);
      p.number("weight_rate", ip.weight_rate, 0, 1);
      p.number("share", ip.share, 0.01, 100);
      p.number("error_bias", ip.error_bias, 0, 1);
      p.integer("cost_strata", ip.cost_strata, 0, 1024);
      p.finish();
      c.profiles.push_back(ip);
    }
  }
  o.finish();
}

void parseExhaustive(const nlohmann::json& j, ExhaustiveConfig& c) {
  Obj o(j, "/search/exhaustive");
  o.integer("max_ops", c.max_ops, 0, 8);
  if (o.has("ops")) {
    const auto& v = o.at("ops");
    // Empty: the program's operators (what toJson writes for the default).
    if (!v.is_array()) fail("/search/exhaustive/ops", "must be an array of operator names");
    c.ops.clear();
    std::set<Op> seen;
    for (size_t i = 0; i < v.size(); ++i) {
      const Op op = parseOp(v[i], jsonPath(o.path("ops"), i));
      if (arity(op) > 3)
        fail(jsonPath(o.path("ops"), i), "select is not enumerated (four operands)");
      if (seen.insert(op).second) c.ops.push_back(op);
    }
  }
  o.integer("constants", c.constants, 0, 8);
  o.number("seconds", c.seconds, 0, 1e9, true);
  o.integer("screen_rows", c.screen_rows, 16, 1 << 24);
  o.integer("keep", c.keep, 1, 1 << 20);
  o.finish();
}

void parseStructured(const nlohmann::json& j, StructuredConfig& c) {
  Obj o(j, "/search/structured");
  o.integer("max_degree", c.max_degree, 0, 16);
  o.boolean("rational", c.rational);
  o.boolean("exp2", c.exp2);
  o.boolean("sqrt_inputs", c.sqrt_inputs);
  o.boolean("square_inputs", c.square_inputs);
  o.boolean("tensor", c.tensor);
  o.integer("polish", c.polish, 0, 1000);
  o.integer("max_rows", c.max_rows, 64, 1 << 24);
  o.number("share", c.share, 0, 1);
  o.finish();
}

void parseStages(const nlohmann::json& j, StageConfig& c) {
  Obj o(j, "/search/stages");
  o.integer("islands", c.islands, 0, 64);
  o.integer("population", c.population, 4, 1 << 20);
  o.integer("retarget", c.retarget, 1, 1 << 20);
  o.integer("max_length", c.max_length, 1, 128);
  o.integer("constants", c.constants, 0, 64);
  o.integer("bases", c.bases, 1, 1024);
  o.enumeration(
      "pick", c.pick,
      [](const std::string& s) -> std::optional<StagePick> {
        if (s == "accurate") return StagePick::Accurate;
        if (s == "spread") return StagePick::Spread;
        return std::nullopt;
      },
      "accurate, spread");
  if (o.has("modes")) {
    const auto& v = o.at("modes");
    if (!v.is_array() || v.empty())
      fail(o.path("modes"), "must be a non-empty array of add, mul, inside");
    c.modes.clear();
    for (size_t i = 0; i < v.size(); ++i) {
      const std::string p = jsonPath(o.path("modes"), i);
      if (!v[i].is_string()) fail(p, "must be add, mul or inside");
      const std::string m = v[i].get<std::string>();
      if (m == "add")
        c.modes.push_back(StageMode::Add);
      else if (m == "mul")
        c.modes.push_back(StageMode::Mul);
      else if (m == "inside")
        c.modes.push_back(StageMode::Inside);
      else
        fail(p, "'" + m + "' is not one of add, mul, inside");
    }
  }
  o.finish();
}

void parseSearch(const nlohmann::json& j, SearchConfig& s) {
  Obj o(j, "/search");
  o.integer("population", s.population, 4, 1 << 20);
  o.integer("generations", s.generations, 0, 1 << 30);
  o.uinteger("max_evaluations", s.max_evaluations);
  o.number("wall_time_s", s.wall_time_s, 0, 1e9);
  o.uinteger("seed", s.seed);
  o.integer("threads", s.threads, 0, 4096);
  o.integer("tournament_size", s.tournament_size, 1, 64);
  o.number("error_bias", s.error_bias, 0, 1);
  o.integer("cost_strata", s.cost_strata, 0, 1024);
  o.integer("semantic_cache", s.semantic_cache, 0, 1 << 26);
  o.boolean("linear_scaling", s.linear_scaling);
  o.boolean("seed_references", s.seed_references);
  if (o.has("multi_output")) parseMultiOutput(o.at("multi_output"), s.multi_output);
  if (o.has("islands")) parseIslands(o.at("islands"), s.islands);
  if (o.has("variation")) parseVariation(o.at("variation"), s.variation);
  if (o.has("refine")) parseRefine(o.at("refine"), s.refine);
  if (o.has("archive")) parseArchive(o.at("archive"), s.archive);
  if (o.has("exhaustive")) parseExhaustive(o.at("exhaustive"), s.exhaustive);
  if (o.has("structured")) parseStructured(o.at("structured"), s.structured);
  if (o.has("stages")) parseStages(o.at("stages"), s.stages);
  o.finish();
}

void parseEval(const nlohmann::json& j, EvalConfig& e) {
  Obj o(j, "/eval");
  o.integer("block_size", e.block_size, 16, 16384);
  o.finish();
  if (e.block_size % 16 != 0)
    fail("/eval/block_size", "must be a multiple of 16 (got " + std::to_string(e.block_size) + ")");
}

// A relative output path named in a config file is relative to that file, like data.path, so a
// run writes the same files from any working directory.
void resolveNamedPath(std::string& p, const std::filesystem::path& base_dir) {
  if (p.empty() || base_dir.empty() || std::filesystem::path(p).is_absolute()) return;
  p = (base_dir / p).lexically_normal().string();
}

void parseOutput(const nlohmann::json& j, OutputConfig& out, const std::filesystem::path& base) {
  Obj o(j, "/output");
  for (auto [key, path] : {std::pair<const char*, std::string*>{"front_json", &out.front_json},
                           {"front_csv", &out.front_csv},
                           {"checkpoint", &out.checkpoint}})
    if (o.has(key)) {
      o.string(key, *path);
      resolveNamedPath(*path, base);
    }
  o.number("progress_interval_s", out.progress_interval_s, 0, 1e6);
  o.number("checkpoint_interval_s", out.checkpoint_interval_s, 0, 1e9);
  if (o.has("progress_cost_levels")) {
    const auto& v = o.at("progress_cost_levels");
    if (!v.is_array()) fail("/output/progress_cost_levels", "must be an array of numbers");
    for (size_t i = 0; i < v.size(); ++i) {
      if (!v[i].is_number() || !(v[i].get<double>() >= 0))
        fail(jsonPath(o.path("progress_cost_levels"), i), "must be a number >= 0");
      out.progress_cost_levels.push_back(v[i].get<double>());
    }
  }
  o.finish();
}

void parseMpi(const nlohmann::json& j, MpiConfig& m) {
  Obj o(j, "/mpi");
  if (o.has("launcher") || o.has("hostfile"))
    fail("/mpi",
         "the launcher and the hostfile are set by whoever starts the run (mpirun's "
         "command line, or lgpd's daemon config), not by the run config");
  o.integer("np", m.np, 0, 4096);
  o.enumeration(
      "migration", m.migration,
      [](const std::string& s) -> std::optional<MigrationMode> {
        if (s == "async") return MigrationMode::Async;
        if (s == "sync") return MigrationMode::Sync;
        return std::nullopt;
      },
      "\"async\", \"sync\"");
  o.finish();
}

}  // namespace

Status IslandConfig::validate() const {
  if (count < 1) return Status::error("count: must be >= 1");
  if (migrants < 0) return Status::error("migrants: must be >= 0");
  if (!(adaptive >= 0 && adaptive <= 0.95)) return Status::error("adaptive: must be in [0, 0.95]");
  if (adaptive_halflife < 1) return Status::error("adaptive_halflife: must be >= 1");
  return Status::ok();
}

Status RunConfig::validate() const {
  if (data.path.empty() == data.scene.empty())
    return Status::error("/data: exactly one of \"path\" and \"scene\" is required");
  if (program.max_length < 1 || program.max_length > 255)
    return Status::error("/program/max_length: must be in [1, 255]");
  if (program.init_min_length > program.init_max_length)
    return Status::error("/program/init_min_length: must be <= init_max_length");
  if (program.init_min_length > program.max_length)
    return Status::error("/program/init_min_length: must be <= max_length");
  if (program.const_min > program.const_max)
    return Status::error("/program/const_min: must be <= const_max");
  if (search.population < 4) return Status::error("/search/population: must be >= 4");
  if (search.generations == 0 && search.max_evaluations == 0 && search.wall_time_s == 0)
    return Status::error(
        "/search: set at least one budget (generations, max_evaluations or wall_time_s)");
  if (auto s = search.archive.validate(); !s)
    return Status::error("/search/archive/" + s.message());
  if (auto s = search.islands.validate(); !s)
    return Status::error("/search/islands/" + s.message());
  // A profile's max_length and constants above the run's are capped at the run's
  // (islandShape): the default profiles hold for a run of shorter programs too.
  if (auto s = search.refine.nm.validate(); !s)
    return Status::error("/search/refine/" + s.message());
  if (eval.block_size < 16 || eval.block_size % 16 != 0)
    return Status::error("/eval/block_size: must be a multiple of 16 in [16, 16384]");
  if (output.front_json.empty()) return Status::error("/output/front_json: must not be empty");
  const auto isOutput = [&](const std::string& n) {
    return std::find(data.outputs.begin(), data.outputs.end(), n) != data.outputs.end();
  };
  for (size_t i = 0; i < objectives.channels.size(); ++i) {
    const std::string p = jsonPath(jsonPath("/objectives/channels", i), "weights");
    if (data.outputs.empty())
      return Status::error(jsonError(p, "channels need the outputs listed in data.outputs"));
    for (const auto& [name, _] : objectives.channels[i].weights)
      if (!isOutput(name))
        return Status::error(jsonError(jsonPath(p, name), "not one of data.outputs"));
  }
  if (search.multi_output.mode == MultiOutputMode::TwoStep) {
    const std::string p = "/search/multi_output/first";
    if (data.outputs.size() < 2)
      return Status::error(p + ": two_step needs at least two outputs listed in data.outputs");
    if (!isOutput(search.multi_output.first))
      return Status::error(p + ": '" + search.multi_output.first + "' is not one of data.outputs");
  }
  if (program.genes > 1 && !search.linear_scaling)
    return Status::error("/program/genes: the output layer needs search.linear_scaling: true");
  if (program.genes > 1 && search.multi_output.mode == MultiOutputMode::TwoStep)
    return Status::error("/program/genes: two_step multi-output fits one gene per output");
  return validateShape(data.outputs.size());
}

Status RunConfig::validateShape(size_t num_outputs) const {
  if (!search.linear_scaling) return Status::ok();
  const uint64_t outputs = num_outputs, genes = static_cast<uint64_t>(program.genes);
  const std::string have = " (" + std::to_string(num_outputs) + " outputs x " +
                           std::to_string(program.genes) + " genes)";
  if (outputs * genes > 255)
    return Status::error("/program/genes: outputs * genes must be <= 255" + have +
                         "; lower program.genes or fit fewer outputs at once");
  if (static_cast<uint64_t>(program.max_length) + outputs * genes > 255)
    return Status::error(
        "/program/max_length: linear scaling adds up to genes opcodes per output; "
        "max_length + outputs * genes must be <= 255" +
        have);
  if (static_cast<uint64_t>(program.num_constants) + outputs * (genes + 1) > 255)
    return Status::error(
        "/program/constants: linear scaling adds up to genes + 1 constants per output; "
        "constants + outputs * (genes + 1) must be <= 255" +
        have);
  return Status::ok();
}

ProgramShape RunConfig::shape(int num_inputs, int num_outputs) const {
  ProgramShape s;
  // Under linear scaling each output reads `genes` program results, and the exported program
  // adds the layer's opcodes and constants: the shape leaves them room below 255 (validate()
  // refuses a config that asks for more where data.outputs names the outputs).
  const int genes = search.linear_scaling ? program.genes : 1;
  s.num_inputs = num_inputs;
  s.num_outputs = num_outputs * genes;
  s.genes = genes;
  s.max_length = std::max(program.max_length, s.num_outputs);
  s.num_constants = program.num_constants;
  if (search.linear_scaling) {
    s.max_length = std::max(s.num_outputs, std::min(s.max_length, 255 - num_outputs * genes));
    s.num_constants = std::max(0, std::min(s.num_constants, 255 - num_outputs * (genes + 1)));
  }
  s.output_mode = program.output_mode;
  s.ops = OpSet();
  for (Op op : program.ops.empty() ? defaultOps() : program.ops) s.ops.insert(op);
  return s;
}

CostModel RunConfig::costModel() const {
  CostModel m = CostModel::preset(objectives.cost_model);
  for (const auto& [op, c] : objectives.cost_overrides) m.cost[static_cast<int>(op)] = c;
  return m;
}

DiscontinuityModel RunConfig::discontinuityModel() const {
  DiscontinuityModel m = DiscontinuityModel::defaults();
  for (const auto& [op, w] : objectives.discontinuity_weights) m.weight[static_cast<int>(op)] = w;
  return m;
}

ErrorConfig RunConfig::errorConfig(const std::vector<std::string>& output_names) const {
  ErrorConfig e;
  e.metric = objectives.metric;
  e.combine = objectives.combine;
  e.rel_floor = objectives.rel_floor;
  e.genes = program.genes;  // used under linear scaling only
  for (const auto& n : output_names) {
    auto it = data.transforms.find(n);
    e.transforms.push_back(it == data.transforms.end() ? TargetTransform::None : it->second);
  }
  for (const auto& ch : objectives.channels) {
    ErrorChannel ec{ch.name, std::vector<double>(output_names.size(), 0.0)};
    for (size_t o = 0; o < output_names.size(); ++o) {
      auto it = ch.weights.find(output_names[o]);
      if (it != ch.weights.end()) ec.weights[o] = it->second;
    }
    e.channels.push_back(std::move(ec));
  }
  return e;
}

Expected<RunConfig> parseRunConfig(const nlohmann::json& j, const std::filesystem::path& base_dir) {
  RunConfig c;
  c.base_dir = base_dir;
  try {
    Obj o(j, "");
    if (!o.has("data")) fail("/data", "required (an object with \"path\" or \"scene\")");
    parseData(o.at("data"), c.data);
    if (o.has("program")) parseProgram(o.at("program"), c.program);
    if (o.has("objectives")) parseObjectives(o.at("objectives"), c.objectives);
    if (o.has("search")) parseSearch(o.at("search"), c.search);
    if (o.has("eval")) parseEval(o.at("eval"), c.eval);
    if (o.has("output")) parseOutput(o.at("output"), c.output, base_dir);
    if (o.has("mpi")) parseMpi(o.at("mpi"), c.mpi);
    if (o.has("references")) {
      const auto& r = o.at("references");
      if (!r.is_array()) fail("/references", "must be an array of {\"name\", \"expr\"} objects");
      for (size_t i = 0; i < r.size(); ++i) {
        const std::string p = jsonPath(o.path("references"), i);
        if (!r[i].is_object() || !r[i].contains("expr"))
          fail(p, "must be an object with \"name\" and \"expr\"");
      }
      c.references = r;
    }
    o.finish();
  } catch (const ConfigError& e) {
    return Status::error(e.msg);
  }
  for (const auto& [name, _] : c.data.transforms)
    if (!c.data.outputs.empty() &&
        std::find(c.data.outputs.begin(), c.data.outputs.end(), name) == c.data.outputs.end())
      return Status::error(
          jsonError(jsonPath("/data/transforms", name), "not one of data.outputs"));
  if (auto s = c.validate(); !s) return s;
  return c;
}

Expected<RunConfig> loadRunConfig(const std::filesystem::path& path) {
  // A regular file only, read without blocking: a directory or a FIFO is named, not parsed.
  auto text = readInputFile(path, kMaxConfigBytes);
  if (!text) return text.status();
  return parseRunConfigText(*text, path);
}

Expected<RunConfig> parseRunConfigText(const std::string& text, const std::filesystem::path& path) {
  auto parsed = parseJson(text);
  if (!parsed) return Status::error(path.string() + ": " + parsed.error());
  const nlohmann::json& j = *parsed;
  auto base = path.parent_path();
  if (base.empty()) base = ".";
  auto c = parseRunConfig(j, base);
  if (!c) return Status::error(path.string() + ": " + c.error());
  return c;
}

nlohmann::json toJson(const RunConfig& c) {
  using nlohmann::json;
  json data = {{"inputs", c.data.inputs}, {"outputs", c.data.outputs}};
  if (!c.data.path.empty()) data["path"] = c.data.path;
  if (!c.data.scene.empty()) data["scene"] = c.data.scene;
  if (!c.data.weights.empty()) data["weights"] = c.data.weights;
  if (!c.data.cache_dir.empty()) data["cache_dir"] = c.data.cache_dir;
  if (!c.data.transforms.empty()) {
    json t = json::object();
    for (const auto& [k, v] : c.data.transforms) t[k] = std::string(toString(v));
    data["transforms"] = t;
  }
  if (!c.data.edges.domain.empty()) {
    json dom = json::object();
    for (const auto& [k, v] : c.data.edges.domain) dom[k] = {v.first, v.second};
    data["edges"] = {{"domain", dom}, {"weight", c.data.edges.weight}};
  }
  json ops = json::array();
  for (Op op : c.program.ops.empty() ? defaultOps() : c.program.ops)
    ops.push_back(std::string(opName(op)));
  auto opMap = [](const std::map<Op, double>& m) {
    json o = json::object();
    for (const auto& [op, v] : m) o[std::string(opName(op))] = v;
    return o;
  };
  const auto& s = c.search;
  json channels = json::array();
  for (const auto& ch : c.objectives.channels)
    channels.push_back({{"name", ch.name}, {"weights", ch.weights}});
  json out = {{"data", data},
          {"program",
           {{"max_length", c.program.max_length},
            {"constants", c.program.num_constants},
            {"output_mode", c.program.output_mode == OutputMode::Last ? "last" : "designated"},
            {"ops", ops},
            {"init_min_length", c.program.init_min_length},
            {"init_max_length", c.program.init_max_length},
            {"const_min", c.program.const_min},
            {"const_max", c.program.const_max}}},
          {"objectives",
           {{"error", std::string(toString(c.objectives.metric))},
            {"combine", std::string(toString(c.objectives.combine))},
            {"rel_floor", c.objectives.rel_floor},
            {"cost_model", std::string(toString(c.objectives.cost_model))},
            {"cost_overrides", opMap(c.objectives.cost_overrides)},
            {"channels", channels},
            {"discontinuity_weights", opMap(c.objectives.discontinuity_weights)},
            {"measured_cost",
             {{"families",
               [&] {
                 nlohmann::json a = nlohmann::json::array();
                 for (GpuFamily f : c.objectives.measured_cost.families)
                   a.push_back(std::string(toString(f)));
                 return a;
               }()},
              {"in_search", c.objectives.measured_cost.in_search}}}}},
          {"search",
           {{"population", s.population},
            {"generations", s.generations},
            {"max_evaluations", s.max_evaluations},
            {"wall_time_s", s.wall_time_s},
            {"seed", s.seed},
            {"threads", s.threads},
            {"tournament_size", s.tournament_size},
            {"error_bias", s.error_bias},
            {"cost_strata", s.cost_strata},
            {"semantic_cache", s.semantic_cache},
            {"linear_scaling", s.linear_scaling},
            {"seed_references", s.seed_references},
            {"multi_output",
             {{"mode", std::string(toString(s.multi_output.mode))},
              {"first", s.multi_output.first},
              {"first_share", s.multi_output.first_share},
              {"first_max_cost", s.multi_output.first_max_cost}}},
            {"islands",
             {{"count", s.islands.count},
              {"migration_interval", s.islands.migration_interval},
              {"migrants", s.islands.migrants},
              {"restart_after", s.islands.restart_after},
              {"deal", std::string(toString(s.islands.deal))}}},
            {"variation",
             {{"crossover_rate", s.variation.crossover_rate},
              {"macro_rate", s.variation.macro_rate},
              {"micro_rate", s.variation.micro_rate},
              {"micro_max", s.variation.micro_max},
              {"constant_sigma", s.variation.constant_sigma},
              {"effective_bias", s.variation.effective_bias},
              {"wrap_share", s.variation.wrap_share}}},
            {"refine",
             {{"offspring_share", s.refine.offspring_share},
              {"lm_iterations", s.refine.lm_iterations},
              {"archive_lm_iterations", s.refine.archive_lm_iterations},
              {"offspring_evaluations", s.refine.offspring_evaluations},
              {"archive_period", s.refine.archive_period},
              {"archive_max", s.refine.archive_max},
              {"archive_order", std::string(toString(s.refine.archive_order))},
              {"max_evaluations", s.refine.nm.max_evaluations},
              {"restarts", s.refine.nm.restarts},
              {"initial_step", s.refine.nm.initial_step},
              {"tolerance", s.refine.nm.tolerance},
              {"method", std::string(toString(s.refine.method))},
              {"de_evaluations", s.refine.de_evaluations},
              {"lm_metric", std::string(toString(s.refine.lm_metric))}}},
            {"archive",
             {{"max_size", s.archive.max_size},
              {"eps_log10_error", s.archive.eps_log10_error},
              {"eps_cost", s.archive.eps_cost},
              {"eps_discontinuity", s.archive.eps_discontinuity}}},
            {"exhaustive",
             {{"max_ops", s.exhaustive.max_ops},
              {"ops",
               [&] {
                 nlohmann::json a = nlohmann::json::array();
                 for (Op op : s.exhaustive.ops) a.push_back(std::string(opName(op)));
                 return a;
               }()},
              {"constants", s.exhaustive.constants},
              {"seconds", s.exhaustive.seconds},
              {"screen_rows", s.exhaustive.screen_rows},
              {"keep", s.exhaustive.keep}}},
            {"structured",
             {{"max_degree", s.structured.max_degree},
              {"rational", s.structured.rational},
              {"exp2", s.structured.exp2},
              {"sqrt_inputs", s.structured.sqrt_inputs},
              {"square_inputs", s.structured.square_inputs},
              {"tensor", s.structured.tensor},
              {"polish", s.structured.polish},
              {"max_rows", s.structured.max_rows},
              {"share", s.structured.share}}},
            {"stages",
             {{"islands", s.stages.islands},
              {"population", s.stages.population},
              {"retarget", s.stages.retarget},
              {"max_length", s.stages.max_length},
              {"constants", s.stages.constants},
              {"modes",
               [&] {
                 nlohmann::json a = nlohmann::json::array();
                 for (StageMode m : s.stages.modes) a.push_back(std::string(toString(m)));
                 return a;
               }()},
              {"bases", s.stages.bases},
              {"pick", std::string(toString(s.stages.pick))}}}}},
          {"eval", {{"block_size", c.eval.block_size}}},
          {"output",
           {{"front_json", c.output.front_json},
            {"front_csv", c.output.front_csv},
            {"progress_interval_s", c.output.progress_interval_s},
            {"progress_cost_levels", c.output.progress_cost_levels},
            {"checkpoint", c.output.checkpoint},
            {"checkpoint_interval_s", c.output.checkpoint_interval_s}}},
          {"mpi", {{"np", c.mpi.np}, {"migration", std::string(toString(c.mpi.migration))}}},
          {"references", c.references}};
  // The rule for every field (tests/core/config_roundtrip_test.cpp holds each to it): toJson
  // writes it, so that the config round-trips and the checkpoint digest sees it; a field added
  // after checkpoints were written may be left out where it holds its default (absence reads
  // back as that default), so that those checkpoints still resume.
  if (c.program.genes != 1) out["program"]["genes"] = c.program.genes;
  out["search"]["variation"]["weight_rate"] = c.search.variation.weight_rate;
  out["search"]["variation"]["weight_min_length"] = c.search.variation.weight_min_length;
  if (c.search.islands.adaptive != 0)
    out["search"]["islands"]["adaptive"] = c.search.islands.adaptive;
  if (c.search.islands.adaptive_halflife != 50)
    out["search"]["islands"]["adaptive_halflife"] = c.search.islands.adaptive_halflife;
  if (c.search.islands.topology != MigrationTopology::Ring)
    out["search"]["islands"]["topology"] = std::string(toString(c.search.islands.topology));
  {
    // No profiles (possible in code) is written as [{}], which searches the same way.
    auto& a = out["search"]["islands"]["profiles"] = nlohmann::json::array();
    if (c.search.islands.profiles.empty()) a.push_back(nlohmann::json::object());
    for (const auto& ip : c.search.islands.profiles) {
      nlohmann::json e = nlohmann::json::object();
      if (ip.max_length != 0) e["max_length"] = ip.max_length;
      if (ip.constants != 0) e["constants"] = ip.constants;
      if (ip.weight_rate >= 0) e["weight_rate"] = ip.weight_rate;
      if (ip.share != 1) e["share"] = ip.share;
      if (ip.error_bias >= 0) e["error_bias"] = ip.error_bias;
      if (ip.cost_strata >= 0) e["cost_strata"] = ip.cost_strata;
      a.push_back(std::move(e));
    }
  }
  return out;
}

}  // namespace lgp
