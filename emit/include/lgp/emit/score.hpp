// Scoring formulas (hand-written or published, parsed with parser.hpp) on a table, with the
// same metrics and cost fields as front members, so they can be drawn on the same front.
//
// References in a run config ("references", a JSON array), scored by `lgp run` into
// front.json's "references":
//   [{"name": "Karis EnvBRDFApprox",
//     "expr": ["<expr for output 0>", "<expr for output 1>"],   // or one string
//     "aliases": {"NoV": "mu"},                                   // optional
//     "refit": true}]     // optional: also score "<name> (refit)", its constants fitted to
//                         // this table with the run's error (Nelder-Mead with restarts)
// "expr" follows parser.hpp's output rules (one text per output, or one text assigning every
// output). References predict the outputs directly: no target transform is applied.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/eval/discontinuity.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp::emit {

struct ScoreOptions {
  ErrorConfig error;  // metric and combination (no transforms)
  CostModel cost = CostModel::preset(CostTarget::GpuGeneric);  // the "cost" field
  DiscontinuityModel discontinuity = DiscontinuityModel::defaults();
  int block_size = 256;  // interpreter block (multiple of 16)
};

// Scores a program on `t`. The result has the fields of a front member: "error", "cost",
// "discontinuity" (counted on the table's domain unless `o.discontinuity` has one),
// "cost_by_target", "formula", "cancellation", "outputs" [{"name", "expression",
// "transform", "float32": {...}, "double": {...}}], "program", plus "opcodes" and
// "piecewise". Formula and expressions come from the front printer (core/formula.hpp) on the
// table's domain; `infix` is only used where it has no text.
Expected<nlohmann::json> scoreProgram(const Program& p, const Table& t, const ScoreOptions& o,
                                      const std::vector<std::string>& infix);

// Parses and scores one formula.
Expected<nlohmann::json> scoreFormula(const std::string& name,
                                      const std::vector<std::string>& texts,
                                      const std::map<std::string, std::string>& aliases,
                                      const Table& t, const ScoreOptions& o);

// One entry of RunConfig::references.
struct Reference {
  std::string name;
  std::vector<std::string> expr;
  std::map<std::string, std::string> aliases;
  bool refit = false;
};

struct RefitOptions {
  int evaluations = 20000;  // Nelder-Mead budget, restarts included
  int restarts = 8;
  uint64_t seed = 1;
};
// `p` with every constant slot fitted to `t` under `error` (no transforms, no scaling); the
// constants are kept when the fit does not lower the error.
Program refitConstants(const Program& p, const Table& t, const ErrorConfig& error, int block_size,
                       const RefitOptions& opts);
// The config's references parsed into programs over the table's columns (for seeding a run).
Expected<std::vector<NamedProgram>> referencePrograms(const RunConfig& cfg, const Table& t);
// Checks the format; errors name the JSON path, e.g. "/references/1/expr: ...".
Expected<std::vector<Reference>> parseReferences(const nlohmann::json& refs);
// Format and parse check against the table's columns (call before a run to fail early).
Status checkReferences(const RunConfig& cfg, const Table& t);
// Every reference scored with the run's error metric, combination and cost model. A
// reference that fails to parse or score is kept as {"name", "expr", "invalid": message}.
nlohmann::json scoreReferences(const RunConfig& cfg, const Table& t);

}  // namespace lgp::emit
