#include "run_pipeline.hpp"

#include <chrono>
#include <cstdio>

#include "lgp/io/result.hpp"
#include "lgp/search/exhaustive.hpp"

#ifdef LGP_HAVE_EMIT
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/score.hpp"
#endif

namespace lgp::cli {

namespace {

// Before the search: the references parse and fit the table (not after a night's work).
Status checkReferences(const RunConfig& cfg, const Table& t) {
#ifdef LGP_HAVE_EMIT
  return emit::checkReferences(cfg, t);
#else
  if (!cfg.references.empty())
    return Status::error("/references: this build has no emit library (formula parser)");
  (void)t;
  return Status::ok();
#endif
}

Expected<std::vector<NamedProgram>> referenceSeeds(const RunConfig& cfg, const Table& t) {
  if (!cfg.search.seed_references) return std::vector<NamedProgram>{};
#ifdef LGP_HAVE_EMIT
  return emit::referencePrograms(cfg, t);
#else
  (void)t;
  return Status::error("/search/seed_references: needs the emit library (parser)");
#endif
}

// What a two-step or MPI run cannot do.
Status checkMode(const RunConfig& cfg, bool has_seeds, bool distributed) {
  const bool two_step = cfg.search.multi_output.mode == MultiOutputMode::TwoStep;
  if (two_step && has_seeds)
    return Status::error("/search/seed_references: not available with two_step");
  if (cfg.objectives.measured_cost.in_search && (two_step || distributed))
    return Status::error(
        "/objectives/measured_cost/in_search: runs in one process with one step only");
  if (cfg.search.exhaustive.max_ops > 0 && (two_step || distributed))
    return Status::error("/search/exhaustive: runs in one process with one step only");
  return Status::ok();
}

Status enableArchiveMeasuredCost(Search& s) {
#ifdef LGP_HAVE_EMIT
  return emit::enableMeasuredCostInSearch(s);
#else
  if (s.config().objectives.measured_cost.in_search)
    return Status::error("/objectives/measured_cost/in_search: this build has no emit library");
  return Status::ok();
#endif
}

// search.exhaustive: the certificate, with "seeded", or null when the config does not ask.
Expected<nlohmann::json> runExhaustive(Search& s) {
  if (s.config().search.exhaustive.max_ops <= 0) return nlohmann::json();
  auto res = exhaustiveSearch(s.config(), s.table());
  if (!res) return res.status();
  std::vector<NamedProgram> seeds;
  for (const auto& m : res->front)
    seeds.push_back({"exhaustive " + std::to_string(m.ops) + " ops", m.program});
  const auto skipped = s.addSeeds(seeds);
  nlohmann::json cert = res->toJson(s.config(), s.table());
  cert["seeded"] = seeds.size() - skipped.size();
  return cert;
}

}  // namespace

Expected<std::vector<NamedProgram>> prepareRun(const RunConfig& cfg, const Table& t, bool resume,
                                               bool distributed) {
  if (auto st = checkReferences(cfg, t); !st) return st;
  std::vector<NamedProgram> seeds;
  if (!resume) {
    auto progs = referenceSeeds(cfg, t);
    if (!progs) return progs.status();
    seeds = std::move(*progs);
  }
  if (auto st = checkMode(cfg, !seeds.empty(), distributed); !st) return st;
  return seeds;
}

Expected<SearchStart> startSearch(Search& s, const std::vector<NamedProgram>& seeds, bool fresh) {
  if (auto st = enableArchiveMeasuredCost(s); !st) return st;
  SearchStart start;
  start.not_seeded = s.addSeeds(seeds);
  if (fresh) {
    auto cert = runExhaustive(s);
    if (!cert) return cert.status();
    start.exhaustive = std::move(*cert);
  }
  return start;
}

nlohmann::json frontJson(const Search& s, const nlohmann::json& exhaustive) {
  nlohmann::json j = frontToJson(s, s.front());
  if (!exhaustive.is_null()) j["exhaustive"] = exhaustive;
  return j;
}

std::string emptyFrontMessage(const Search& s) {
  const auto p = s.progress();
  return "the search ended with an empty front: " +
         (p.evaluations == 0
              ? std::string("no program was evaluated (stopped before the first generation)")
              : "none of the " + std::to_string(p.evaluations) +
                    " programs evaluated had a finite error, cost and discontinuity (NaN and "
                    "infinite errors are never kept): the targets, weights or target transforms "
                    "overflow the float32 evaluation or its sums");
}

FrontExtras::FrontExtras(const RunConfig& cfg, const Table& t)
    : families_(cfg.objectives.measured_cost.families) {
#ifdef LGP_HAVE_EMIT
  if (!cfg.references.empty()) references_ = emit::scoreReferences(cfg, t);
#else
  (void)t;
#endif
}

std::string FrontExtras::addTo(nlohmann::json& front) const {
#ifdef LGP_HAVE_EMIT
  if (!references_.is_null()) front["references"] = references_;
  if (families_.empty()) return "";
  // Every member and reference compiled to AMD ISA (emit/gpu_cost.hpp); a machine without the
  // backend still gets its front, with the reason recorded.
  emit::MeasureOptions mo;
  mo.families = families_;
  const auto t0 = std::chrono::steady_clock::now();
  emit::addMeasuredCost(front, mo);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto& info = front["cost_measured_info"];
  if (info.contains("unavailable"))
    return "no measured GPU cost: " + info["unavailable"].get<std::string>();
  char b[64];
  std::snprintf(b, sizeof b, " in %.1f s", secs);
  return "measured GPU cost of " + std::to_string(front["members"].size()) + " members on " +
         info["families"].dump() + b;
#else
  (void)front;
  return "";
#endif
}

}  // namespace lgp::cli
