// Measured GPU cost through RADV's null device (see gpu_cost.hpp).
#include "lgp/emit/gpu_cost.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <tuple>
#include <unordered_map>

#include "gpu_process.hpp"
#include "lgp/emit/compute_shader.hpp"

namespace lgp::emit {

namespace {

detail::DriverSpec statsDriver(GpuFamily f) {
  return {"stats", std::string(kGpuFamilyChips[static_cast<int>(f)])};
}

uint64_t fnv1a(uint64_t h, std::string_view s) {
  for (unsigned char ch : s) {
    h ^= ch;
    h *= 1099511628211ull;
  }
  return h;
}

class StatsCache {
 public:
  static StatsCache& instance() {
    static StatsCache c;
    return c;
  }
  bool find(uint64_t key, IsaStats& out) {
    std::lock_guard lock(mu_);
    auto it = map_.find(key);
    if (it == map_.end()) return false;
    out = it->second;
    return true;
  }
  void put(uint64_t key, const IsaStats& s) {
    std::lock_guard lock(mu_);
    map_[key] = s;
  }

 private:
  std::mutex mu_;
  std::unordered_map<uint64_t, IsaStats> map_;
};

// One statistic of the worker's reply: a finite number >= 0 (ACO's counts and cycles), or an
// error naming it. `required`: the cost objective's unit must be there; the others are 0 where
// a driver does not report them. Anything else is a worker gone wrong, not 0 instructions.
Status stat(const nlohmann::json& s, const char* name, bool required, double& out) {
  out = 0;
  const auto it = s.is_object() ? s.find(name) : s.end();
  if (it == s.end()) {
    if (!required) return Status::ok();
    return Status::error(std::string("the worker's statistics lack \"") + name + "\"");
  }
  if (!it->is_number() || !std::isfinite(it->get<double>()) || it->get<double>() < 0)
    return Status::error(std::string("the worker's statistic \"") + name +
                         "\" is not a count (got " + it->dump().substr(0, 40) + ")");
  out = it->get<double>();
  return Status::ok();
}

}  // namespace

IsaStats operator-(const IsaStats& a, const IsaStats& b) {
  return {a.instructions - b.instructions,
          a.latency - b.latency,
          a.inverse_throughput - b.inverse_throughput,
          a.vgprs - b.vgprs,
          a.sgprs - b.sgprs,
          a.code_bytes - b.code_bytes};
}

nlohmann::json toJson(const IsaStats& s) {
  return {{"instructions", s.instructions},
          {"latency", s.latency},
          {"inverse_throughput", s.inverse_throughput},
          {"vgprs", s.vgprs}};
}

GpuBackendStatus isaBackendStatus(GpuFamily f) {
  auto h = detail::gpuHello(statsDriver(f));
  if (!h) return {false, h.error()};
  return {true, h->value("device", std::string()) + ", " + h->value("driver", std::string())};
}

Expected<IsaStats> shaderIsaStats(GpuFamily f, Language lang, const std::string& shader) {
  if (!languageInfo(lang).shader)
    return Status::error("ISA statistics: " + std::string(languageInfo(lang).title) +
                         " does not run on a GPU");
  const std::string_view lname = toString(lang);
  const uint64_t key = fnv1a(fnv1a(fnv1a(14695981039346656037ull, toString(f)), lname), shader);
  IsaStats s;
  if (StatsCache::instance().find(key, s)) return s;
  auto r = detail::gpuRequest(statsDriver(f),
                              {{"op", "stats"}, {"lang", std::string(lname)}, {"source", shader}});
  if (!r) return r.status();
  const auto st = r->find("stats");
  if (st == r->end() || !st->is_object())
    return Status::error("lgp-gpu-worker: a reply without statistics");
  const std::tuple<const char*, double*, bool> fields[] = {
      {"Instructions", &s.instructions, true},
      {"Latency", &s.latency, false},
      {"Inverse Throughput", &s.inverse_throughput, false},
      {"VGPRs", &s.vgprs, false},
      {"SGPRs", &s.sgprs, false},
      {"Code size", &s.code_bytes, false}};
  for (const auto& [name, field, required] : fields)
    if (auto ok = stat(*st, name, required, *field); !ok)
      return Status::error("lgp-gpu-worker: " + ok.message());
  StatsCache::instance().put(key, s);
  return s;
}

Expected<IsaStats> measureEmitted(const Emitted& e, Language lang, Precision precision,
                                  GpuFamily f) {
  auto formula = computeShader(e, lang, precision, KernelBody::Formula);
  if (!formula) return formula.status();
  auto base = computeShader(e, lang, precision, KernelBody::IoBaseline);
  if (!base) return base.status();
  auto a = shaderIsaStats(f, lang, *formula);
  if (!a) return a.status();
  auto b = shaderIsaStats(f, lang, *base);
  if (!b) return b.status();
  // Below zero only where the compiler proved the formula independent of inputs the baseline
  // loads (a formula that folds to a constant): in a real shader those inputs are loaded for
  // other work anyway, so the formula costs nothing, not less than nothing.
  IsaStats m = *a - *b;
  for (double* v :
       {&m.instructions, &m.latency, &m.inverse_throughput, &m.vgprs, &m.sgprs, &m.code_bytes})
    *v = std::max(0.0, *v);
  return m;
}

Expected<Emitted> emitMeasured(const EmitInput& in, Language lang, EmitOptions opts) {
  auto e = emitProgram(in, lang, opts);
  if (!e || !languageInfo(lang).shader || !opts.header) return e;
  // Code printed without its helpers (defined elsewhere) is measured with them: the shader
  // compiler needs their definitions, and the user's build has them.
  if (!opts.helpers) {
    EmitOptions h = opts;
    h.helpers = true;
    e = emitProgram(in, lang, h);
    if (!e) return e;
  }
  std::string line =
      "Measured (ACO instructions / latency / VGPRs of this code over an I/O-only shader):";
  for (int f = 0; f < kNumGpuFamilies; ++f) {
    const auto fam = static_cast<GpuFamily>(f);
    auto m = measureEmitted(*e, lang, opts.precision, fam);
    if (!m) {
      line = "Measured: not available (" + m.error() + ")";
      break;
    }
    char b[96];
    std::snprintf(b, sizeof b, " %s %.0f/%.0f/%.0f", std::string(toString(fam)).c_str(),
                  m->instructions, m->latency, m->vgprs);
    line += b;
  }
  opts.header_lines.push_back(line);
  return emitProgram(in, lang, opts);
}

std::string describe(const MeasureOptions& o) {
  return std::string(toString(o.lang)) + (o.fast ? " --fast" : "");
}

Expected<nlohmann::json> measureProgram(const EmitInput& in, const MeasureOptions& o) {
  EmitOptions eo;
  eo.fast = o.fast;
  eo.header = false;
  auto e = emitProgram(in, o.lang, eo);
  if (!e) return e.status();
  nlohmann::json j = nlohmann::json::object();
  for (GpuFamily f : o.families) {
    auto m = measureEmitted(*e, o.lang, Precision::Float, f);
    if (!m) return m.status();
    j[std::string(toString(f))] = toJson(*m);
  }
  return j;
}

std::function<std::optional<double>(const Program&)> archiveCostMeasure(const RunConfig& cfg,
                                                                        const Table& t,
                                                                        GpuFamily family) {
  EmitInput base = emitInputForTable(Program{}, t);
  for (const auto& name : t.output_names) {
    auto it = cfg.data.transforms.find(name);
    base.transforms.push_back(it == cfg.data.transforms.end() ? TargetTransform::None : it->second);
  }
  return [base, family](const Program& p) -> std::optional<double> {
    EmitInput in = base;
    in.program = p;
    MeasureOptions o;
    o.families = {family};
    auto m = measureProgram(in, o);
    if (!m) return std::nullopt;
    return (*m)[std::string(toString(family))]["instructions"].get<double>();
  };
}

Status enableMeasuredCostInSearch(Search& s) {
  const auto& mc = s.config().objectives.measured_cost;
  if (!mc.in_search) return Status::ok();
  if (mc.families.empty()) return Status::error("/objectives/measured_cost/in_search: no family");
  const GpuFamily f = mc.families.front();
  const GpuBackendStatus st = isaBackendStatus(f);
  if (!st.available)
    return Status::error("/objectives/measured_cost/in_search: no ISA measurement here: " +
                         st.detail);
  const CostTarget model = f == GpuFamily::Gcn5 ? CostTarget::Gcn : CostTarget::Rdna;
  const auto cal = costCalibration(model);
  s.setCostMeasure(archiveCostMeasure(s.config(), s.table(), f), CostModel::preset(model),
                   cal ? cal->worst_abs : 0.0);
  return Status::ok();
}

void addMeasuredCost(nlohmann::json& front, const MeasureOptions& o) {
  if (o.families.empty()) return;
  const GpuBackendStatus st = isaBackendStatus(o.families.front());
  if (!st.available) {
    front["cost_measured_info"] = {{"unavailable", st.detail}};
    return;
  }
  nlohmann::json fams = nlohmann::json::array();
  for (GpuFamily f : o.families) fams.push_back(std::string(toString(f)));
  front["cost_measured_info"] = {{"emitted", describe(o)},
                                 {"families", fams},
                                 {"compiler", st.detail},
                                 {"unit", "marginal ACO statistics over an I/O-only shader"}};
  for (const char* list : {"members", "references"}) {
    if (!front.contains(list) || !front[list].is_array()) continue;
    auto& entries = front[list];
    for (size_t i = 0; i < entries.size(); ++i) {
      auto& entry = entries[i];
      if (!entry.is_object() || !entry.contains("program")) continue;  // an invalid reference
      auto in =
          emitInputFromFrontEntry(front, entry, "/" + std::string(list) + "/" + std::to_string(i));
      if (!in) {
        entry["cost_measured"] = {{"error", in.error()}};
        continue;
      }
      auto m = measureProgram(*in, o);
      entry["cost_measured"] = m ? *m : nlohmann::json{{"error", m.error()}};
    }
  }
}

}  // namespace lgp::emit
