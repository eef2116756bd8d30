// Scoring of formulas and of the run config's references (see score.hpp).
#include "lgp/emit/score.hpp"

#include <cmath>

#include "lgp/emit/dag.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/io/result.hpp"

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
  const double err = combineError(mf, ec);
  j["error"] = std::isfinite(err) ? nlohmann::json(err) : nlohmann::json(nullptr);
  j["cost"] = o.cost.programCost(p);
  j["discontinuity"] = o.discontinuity.programDiscontinuity(p);
  nlohmann::json cbt = nlohmann::json::object();
  for (int k = 0; k < kNumCostTargets; ++k)
    cbt[std::string(kCostTargetNames[k])] =
        CostModel::preset(static_cast<CostTarget>(k)).programCost(p);
  j["cost_by_target"] = cbt;
  nlohmann::json outs = nlohmann::json::array();
  for (size_t k = 0; k < t.numOutputs(); ++k)
    outs.push_back({{"name", t.output_names[k]},
                    {"expression", k < infix.size() ? infix[k] : std::string()},
                    {"transform", "none"},
                    {"float32", metricsToJson(mf[k])},
                    {"double", metricsToJson(md[k])}});
  j["outputs"] = outs;
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
    const std::string path = "/references/" + std::to_string(i);
    const auto& r = refs[i];
    if (!r.is_object()) return Status::error(path + ": must be an object {\"name\", \"expr\"}");
    for (const auto& [key, v] : r.items())
      if (key != "name" && key != "expr" && key != "aliases")
        return Status::error(path + "/" + key + ": unknown key (name, expr, aliases)");
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
          return Status::error(path + "/expr/" + std::to_string(k) + ": must be a string");
        ref.expr.push_back(e[k].get<std::string>());
      }
    } else {
      return Status::error(path + "/expr: must be a string or a non-empty array of strings");
    }
    if (r.contains("aliases")) {
      if (!r["aliases"].is_object())
        return Status::error(path + "/aliases: must be an object {\"NoV\": \"mu\"}");
      for (const auto& [from, to] : r["aliases"].items()) {
        if (!to.is_string()) return Status::error(path + "/aliases/" + from + ": must be a string");
        ref.aliases[from] = to.get<std::string>();
      }
    }
    out.push_back(std::move(ref));
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
    }
  }
  return out;
}

}  // namespace lgp::emit
