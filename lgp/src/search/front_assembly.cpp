// Front assembly: the archive's members turned into what the outputs need (Search::front(),
// with the post-run snapped-twin pass), and the archive summary of progress lines.
#include <algorithm>
#include <limits>
#include <optional>

#include "lgp/core/cancellation.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/core/snap.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/search/search.hpp"

namespace lgp {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

void summarizeArchive(SearchProgress& p, const std::vector<ArchiveMember>& members,
                      const std::vector<double>& cost_levels) {
  p.front_size = members.size();
  p.best_error = kInf;
  for (const auto& m : members) p.best_error = std::min(p.best_error, m.obj.error);
  std::vector<double> levels = cost_levels;
  p.best_at_cost.clear();
  if (levels.empty()) {
    std::vector<double> costs;
    for (const auto& m : members) costs.push_back(m.obj.cost);
    std::sort(costs.begin(), costs.end());
    costs.erase(std::unique(costs.begin(), costs.end()), costs.end());
    if (costs.size() <= 4) {
      levels = costs;
    } else {
      for (int k = 1; k <= 4; ++k) levels.push_back(costs[(costs.size() - 1) * k / 4]);
    }
  }
  for (double c : levels) {
    double best = kInf;
    for (const auto& m : members)
      if (m.obj.cost <= c) best = std::min(best, m.obj.error);
    p.best_at_cost.emplace_back(c, best);
  }
}

std::optional<Program> Search::snappedTwin(Scorer& s, const Program& p) const {
  SnapOptions o = snap_;  // changes below float32 rounding of the targets count as none
  o.abs_floor = std::max(o.abs_floor, float32ErrorFloor(err_cfg_, table_));
  const auto snapped = snapConstants(
      p, [&](const Program& q) { return score(s, q).error; }, o);
  // Simplified on the domain (exact there) and relinearised: snapping often leaves x*1, x + 0
  // or a constant sub-expression behind, which the simplifier removes.
  Program twin = snapped.program;
  auto lin = toProgram(formulaDag(twin, shape_.num_inputs, domain_));
  if (lin) {
    auto fitted = fitToShape(lin->program, shape_);
    if (fitted) twin = std::move(*fitted);
  }
  if (pruneIntrons(twin) == pruneIntrons(p)) return std::nullopt;
  return twin;
}

std::vector<FrontEntry> Search::front() const {
  std::vector<ArchiveMember> members = archive_.sorted();
  if (snap_twins_ && !members.empty()) {
    // The post-run pass on a copy of the archive (members in sorted order, so the result
    // depends only on the archive).
    const int n = static_cast<int>(members.size());
    std::vector<std::optional<Program>> twins(n);
    std::vector<Objectives> objs(n);
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1)
    for (int i = 0; i < n; ++i) {
      CheckedScorer cs(*this);
      twins[i] = snappedTwin(cs.scorer, members[i].program);
      if (!twins[i]) continue;
      objs[i] = score(cs.scorer, *twins[i]);
      // A twin joins only as an archive candidate would: checked on every row.
      FidelityCheck full(table_, err_cfg_, 0);
      if (objs[i].finite() &&
          !full.passes(cs.scorer.bound(),
                       err_cfg_.linear_scaling ? cs.scorer.scales() : std::vector<LinearScale>{}))
        twins[i].reset();
    }
    if (measure_) {  // twins compete in measured cost, as the members do
      Scorer s(ds_, err_cfg_, cfg_.eval.block_size);
      for (int i = 0; i < n; ++i)
        if (twins[i] && objs[i].finite())
          if (const auto c = measure_(finalProgram(s, *twins[i]))) objs[i].cost = *c;
    }
    // A twin that is no worse in cost and discontinuity and whose error differs from its
    // original's by float32 rounding alone (an exact formula scores a few ulp off a
    // noise-fitted one) replaces it; every other twin is offered to the archive.
    const double floor = float32ErrorFloor(err_cfg_, table_);
    Archive a(cfg_.search.archive);
    std::vector<uint8_t> replaced(n, 0);
    for (int i = 0; i < n; ++i) {
      const Objectives& o = members[i].obj;
      replaced[i] = twins[i] && objs[i].error <= o.error + floor && objs[i].cost <= o.cost &&
                    objs[i].discontinuity <= o.discontinuity;
      if (replaced[i])
        a.insert(*twins[i], objs[i], true);
      else
        a.insert(members[i].program, o, members[i].refined);
    }
    for (int i = 0; i < n; ++i)
      if (twins[i] && !replaced[i]) a.insert(*twins[i], objs[i], true);
    members = a.sorted();
  }
  std::vector<FrontEntry> out(members.size());
  const int n = static_cast<int>(members.size());
  // What is exported is what was scored (eval/fidelity.hpp): a member whose program or emitted
  // formula does not reproduce its float32 values leaves the front (restored checkpoints may
  // hold members the archive never checked).
  std::vector<uint8_t> faithful(n, 1);
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1)
  for (int i = 0; i < n; ++i) {
    FrontEntry& e = out[i];
    Scorer s(ds_, err_cfg_, cfg_.eval.block_size);
    e.program = finalProgram(s, members[i].program);
    {
      FidelityCheck full(table_, err_cfg_, 0);
      BoundProgram bp;
      bp.bind(e.program, shape_.num_inputs);
      faithful[i] = full.passes(bp, {}) && formulaReproduces(e.program);
      if (!faithful[i]) continue;
    }
    e.obj = members[i].obj;
    e.metrics = s.metrics(e.program);
    e.metrics_ref = referenceMetrics(e.program, table_, err_cfg_);
    if (!err_cfg_.channels.empty()) {
      e.channel_metrics = s.channelMetrics(e.program);
      e.channel_metrics_ref = referenceChannelMetrics(e.program, table_, err_cfg_);
    }
    e.cost_by_target = costByTarget(e.program, domain_, err_cfg_.transforms);
    const Dag d = formulaDag(e.program, shape_.num_inputs, domain_);
    e.infix = printOutputs(d, table_.input_names);
    e.formula = printFormula(d, table_.input_names, table_.output_names).text();
    // Cancellation in the program as scored and in the formula as emitted, the worse of the
    // two: simplification may fold constants that cancel, which the scored program still has.
    e.cancellation = cancellation(d, table_, err_cfg_.transforms);
    const Cancellation raw =
        cancellation(buildDag(e.program, shape_.num_inputs), table_, err_cfg_.transforms);
    if (raw.bits_lost > e.cancellation.bits_lost) e.cancellation = raw;
  }
  std::vector<FrontEntry> kept;
  kept.reserve(out.size());
  for (int i = 0; i < n; ++i)
    if (faithful[i]) kept.push_back(std::move(out[i]));
  return kept;
}

Program Search::finalProgram(Scorer& s, const Program& p) const {
  Program body = pruneIntrons(p);
  if (!err_cfg_.linear_scaling) return body;
  s.error(body);  // fits the scales, exactly as when the member was scored
  return applyLinearScaling(body, s.scales(), genes());
}

}  // namespace lgp
