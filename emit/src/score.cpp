// Scoring of formulas and of the run config's references (see score.hpp).
#include "lgp/emit/score.hpp"

#include <cmath>
#include <limits>

#include "lgp/config/json_reader.hpp"
#include "lgp/core/cancellation.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/emit/dag.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/nelder_mead.hpp"

namespace lgp::emit {

Expected<nlohmann::json> scoreProgram(const Program& p, const Table& t, const ScoreOptions& o,
                                      const std::vector<std::string>& infix) {
  if (Status s = t.validate(); !s) return s;
  if (p.outputs.size() != t.numOutputs())
    return Status::error("formula has " + std::to_string(p.outputs.size()) +
                         " outputs but the table has " + std::to_string(t.numOutputs()));
  ErrorConfig ec = o.error;
  ec.transforms.clear();
  Dataset ds(t, o.block_size);
  Scorer scorer(ds, ec, o.block_size);
  const auto mf = scorer.metrics(p);
  const auto md = referenceMetrics(p, t, ec);
  nlohmann::json j;
  const double err = combineError(scorer.channelMetrics(p), ec);
  j["error"] = std::isfinite(err) ? nlohmann::json(err) : nlohmann::json(nullptr);
  const auto domain = tableDomain(t);
  CostModel cost = o.cost;
  if (cost.domain.empty()) cost.domain = domain;
  j["cost"] = cost.programCost(p);
  DiscontinuityModel disc = o.discontinuity;
  if (disc.domain.empty()) disc.domain = domain;  // as the search counts it
  j["discontinuity"] = disc.programDiscontinuity(p);
  nlohmann::json cbt = nlohmann::json::object();
  const auto costs = costByTarget(p, domain, {});
  for (int k = 0; k < kNumCostTargets; ++k) cbt[std::string(kCostTargetNames[k])] = costs[k];
  j["cost_by_target"] = cbt;
  // The front's printer: the simplified DAG on the table's domain.
  const Dag fd = formulaDag(p, static_cast<int>(t.numInputs()), domain);
  const auto texts = printOutputs(fd, t.input_names);
  j["formula"] = printFormula(fd, t.input_names, t.output_names).text();
  const auto canc = cancellation(fd, t, {});
  j["cancellation"] = {{"bits_lost", canc.bits_lost}, {"flagged", canc.flagged}};
  nlohmann::json outs = nlohmann::json::array();
  for (size_t k = 0; k < t.numOutputs(); ++k)
    outs.push_back({{"name", t.output_names[k]},
                    {"expression", k < texts.size()   ? texts[k]
                                   : k < infix.size() ? infix[k]
                                                      : std::string()},
                    {"transform", "none"},
                    {"float32", metricsToJson(mf[k])},
                    {"double", metricsToJson(md[k])}});
  j["outputs"] = outs;
  if (!ec.channels.empty()) {
    const auto cf = scorer.channelMetrics(p);
    const auto cd = referenceChannelMetrics(p, t, ec);
    nlohmann::json chans = nlohmann::json::array();
    for (size_t c = 0; c < ec.channels.size(); ++c)
      chans.push_back({{"name", ec.channels[c].name},
                       {"float32", metricsToJson(cf[c])},
                       {"double", metricsToJson(cd[c])}});
    j["channels"] = chans;
  }
  j["program"] = toJson(p);
  const Dag d = buildDag(p, static_cast<int>(t.numInputs()));
  j["opcodes"] = d.numOps();
  j["piecewise"] = countPiecewise(d);
  return j;
}

Expected<nlohmann::json> scoreFormula(const std::string& name,
                                      const std::vector<std::string>& texts,
                                      const std::map<std::string, std::string>& aliases,
                                      const Table& t, const ScoreOptions& o) {
  ParseOptions po;
  po.input_names = t.input_names;
  po.output_names = t.output_names;
  po.aliases = aliases;
  auto pf = parseFormula(texts, po);
  if (!pf) return pf.status();
  auto j = scoreProgram(pf->program, t, o, pf->infix);
  if (!j) return j.status();
  nlohmann::json r = {{"name", name}, {"expr", texts}};
  r.update(*j);
  if (!aliases.empty()) r["aliases"] = aliases;
  return r;
}

Expected<std::vector<Reference>> parseReferences(const nlohmann::json& refs) {
  std::vector<Reference> out;
  if (refs.is_null()) return out;
  if (!refs.is_array()) return Status::error("/references: must be an array");
  for (size_t i = 0; i < refs.size(); ++i) {
    const std::string path = jsonPath("/references", i);
    const auto& r = refs[i];
    if (!r.is_object()) return Status::error(path + ": must be an object {\"name\", \"expr\"}");
    JsonObjectReader keys(r, path);
    keys.allow({"name", "expr", "aliases", "refit"});
    if (auto k = keys.unknownKey())
      return Status::error(jsonError(*k, "unknown key (name, expr, aliases, refit)"));
    Reference ref;
    if (!r.contains("name") || !r["name"].is_string() || r["name"].get<std::string>().empty())
      return Status::error(path + "/name: must be a non-empty string");
    ref.name = r["name"].get<std::string>();
    if (!r.contains("expr")) return Status::error(path + "/expr: missing");
    const auto& e = r["expr"];
    if (e.is_string()) {
      ref.expr.push_back(e.get<std::string>());
    } else if (e.is_array() && !e.empty()) {
      for (size_t k = 0; k < e.size(); ++k) {
        if (!e[k].is_string())
          return Status::error(jsonError(jsonPath(path + "/expr", k), "must be a string"));
        ref.expr.push_back(e[k].get<std::string>());
      }
    } else {
      return Status::error(path + "/expr: must be a string or a non-empty array of strings");
    }
    if (r.contains("aliases")) {
      if (!r["aliases"].is_object())
        return Status::error(path + "/aliases: must be an object {\"NoV\": \"mu\"}");
      for (const auto& [from, to] : r["aliases"].items()) {
        if (!to.is_string())
          return Status::error(jsonError(jsonPath(path + "/aliases", from), "must be a string"));
        ref.aliases[from] = to.get<std::string>();
      }
    }
    if (r.contains("refit")) {
      if (!r["refit"].is_boolean()) return Status::error(path + "/refit: must be true or false");
      ref.refit = r["refit"].get<bool>();
    }
    out.push_back(std::move(ref));
  }
  return out;
}

namespace {
Expected<ParsedFormula> parseReference(const Reference& r, const Table& t) {
  ParseOptions po;
  po.input_names = t.input_names;
  po.output_names = t.output_names;
  po.aliases = r.aliases;
  return parseFormula(r.expr, po);
}
}  // namespace

Program refitConstants(const Program& p, const Table& t, const ErrorConfig& error, int block_size,
                       const RefitOptions& opts) {
  if (p.constants.empty()) return p;
  ErrorConfig ec = error;
  ec.transforms.clear();
  ec.linear_scaling = false;
  Dataset ds(t, block_size);
  Scorer scorer(ds, ec, block_size);
  Program work = p;
  BoundProgram bp;
  bp.bind(work, ds.numInputs());
  auto f = [&](const std::vector<double>& x) {
    for (size_t k = 0; k < x.size(); ++k) {
      const float v = static_cast<float>(x[k]);
      if (!std::isfinite(v)) return std::numeric_limits<double>::infinity();
      work.constants[k] = v;
    }
    bp.updateConstants(work);
    return scorer.error(bp);
  };
  std::vector<double> x0(p.constants.begin(), p.constants.end());
  const double f0 = f(x0);
  Rng rng(opts.seed);
  NelderMeadConfig nm;
  nm.max_evaluations = opts.evaluations;
  nm.restarts = opts.restarts;
  const auto res = nelderMead(f, x0, nm, rng);
  Program out = p;
  if (res.f < f0)
    for (size_t k = 0; k < x0.size(); ++k) out.constants[k] = static_cast<float>(res.x[k]);
  return out;
}

Expected<std::vector<NamedProgram>> referencePrograms(const RunConfig& cfg, const Table& t) {
  auto refs = parseReferences(cfg.references);
  if (!refs) return refs.status();
  std::vector<NamedProgram> out;
  for (size_t i = 0; i < refs->size(); ++i) {
    auto pf = parseReference((*refs)[i], t);
    if (!pf)
      return Status::error("/references/" + std::to_string(i) + " (" + (*refs)[i].name +
                           "): " + pf.error());
    out.push_back({(*refs)[i].name, pf->program});
  }
  return out;
}

Status checkReferences(const RunConfig& cfg, const Table& t) {
  auto refs = parseReferences(cfg.references);
  if (!refs) return refs.status();
  for (size_t i = 0; i < refs->size(); ++i) {
    ParseOptions po;
    po.input_names = t.input_names;
    po.output_names = t.output_names;
    po.aliases = (*refs)[i].aliases;
    auto pf = parseFormula((*refs)[i].expr, po);
    if (!pf)
      return Status::error("/references/" + std::to_string(i) + " (" + (*refs)[i].name +
                           "): " + pf.error());
  }
  return Status::ok();
}

nlohmann::json scoreReferences(const RunConfig& cfg, const Table& t) {
  nlohmann::json out = nlohmann::json::array();
  auto refs = parseReferences(cfg.references);
  if (!refs) {
    out.push_back({{"name", "(references)"}, {"invalid", refs.error()}});
    return out;
  }
  ScoreOptions o;
  o.error = cfg.errorConfig(t.output_names);
  o.error.transforms.clear();
  o.cost = cfg.costModel();
  o.discontinuity = cfg.discontinuityModel();
  o.block_size = cfg.eval.block_size;
  for (const auto& r : *refs) {
    auto j = scoreFormula(r.name, r.expr, r.aliases, t, o);
    if (j) {
      out.push_back(*j);
    } else {
      out.push_back({{"name", r.name}, {"expr", r.expr}, {"invalid", j.error()}});
      continue;
    }
    if (!r.refit) continue;
    // The published structure with its constants fitted to this table: the fair baseline
    // when the published fit targeted a different table (e.g. uncorrelated Smith).
    auto pf = parseReference(r, t);
    const Program fitted = refitConstants(pf->program, t, o.error, o.block_size, RefitOptions{});
    const Dag d = buildDag(fitted, static_cast<int>(t.numInputs()));
    auto jf = scoreProgram(fitted, t, o, dagInfix(d, t.input_names));
    if (!jf) continue;
    nlohmann::json e = {
        {"name", r.name + " (refit)"}, {"expr", dagInfix(d, t.input_names)}, {"refit_of", r.name}};
    e.update(*jf);
    if (!r.aliases.empty()) e["aliases"] = r.aliases;
    out.push_back(e);
  }
  return out;
}

}  // namespace lgp::emit
