// Residual stages inside the search (search.stages, stage.hpp): each stage island searches a
// correction of an archive member on that member's residual table, and offers the composites
// to the archive. Every step here is sequential or per-program, on RNG streams of the stage's
// own (tag 7 and 8), so a run stays deterministic for its seed and thread count.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "lgp/core/variation.hpp"
#include "lgp/search/search.hpp"

namespace lgp {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

// A stage offspring's global index: rank (its first island), stage, offspring.
uint64_t stageIndex(int island_first, int stage, int i) {
  return (static_cast<uint64_t>(island_first) << 40) | (static_cast<uint64_t>(stage) << 32) |
         static_cast<uint64_t>(i);
}
}  // namespace

nlohmann::json Search::stagesInfo() const {
  if (stages_.empty()) return nullptr;
  nlohmann::json a = nlohmann::json::array();
  for (const auto& st : stages_) {
    nlohmann::json s = {{"mode", std::string(toString(st->mode))},
                        {"picks", st->picks},
                        {"composites", st->composites}};
    if (st->mode == StageMode::Inside) s["input"] = table_.input_names[st->input];
    if (!st->base.code.empty()) {
      s["base_error"] = st->base_error;
      s["base_opcodes"] = st->base.code.size();
      // The best correction of this base so far, on the composite's scale (inside: the
      // linearised error, not the composite's).
      double best = kInf;
      for (const auto& ind : st->isl.pop) best = std::min(best, ind.obj.error * st->error_scale);
      if (std::isfinite(best))
        s[st->mode == StageMode::Inside ? "best_linearised_error" : "best_composite_error"] = best;
    }
    a.push_back(std::move(s));
  }
  return a;
}

Scorer& Search::stageScorer(Stage& st, int thread) {
  auto& s = st.scorers[static_cast<size_t>(thread)];
  if (!s) s = std::make_unique<Scorer>(*st.ds, st.err, cfg_.eval.block_size);
  return *s;
}

Objectives Search::stageScore(Stage& st, int thread, const Program& p) {
  // One gene and no target transform: the correction's own a*g + b.
  return scoreWith(stageScorer(st, thread), p, st.cost, st.disc, st.err.linear_scaling, 1, 0.0);
}

void Search::bindStage(Stage& st) {
  const int k = static_cast<int>(table_.numOutputs());
  Interpreter interp(cfg_.eval.block_size);
  const auto f = interp.evaluate(st.base, ds_);
  const std::vector<double> slope =
      st.mode == StageMode::Inside ? inputSlope(st.base, table_, st.input, cfg_.eval.block_size)
                                   : std::vector<double>{};
  st.table = residualTable(table_, f, err_cfg_.transforms, st.mode, st.input, slope);
  st.ds = std::make_unique<Dataset>(st.table, cfg_.eval.block_size);
  // Program space: the residual is of what programs compute (T(y)), so no transform; one
  // gene (the correction's own a*g + b under linear scaling).
  st.err = err_cfg_;
  st.err.transforms.clear();
  st.err.genes = 1;
  st.cost = cost_;
  st.cost.domain = tableDomain(st.table);
  st.disc = disc_;
  st.disc.domain = st.cost.domain;
  const auto& sc = cfg_.search.stages;
  st.shape = shape_;
  st.shape.num_inputs = shape_.num_inputs + k;
  st.shape.num_outputs = k;
  st.shape.genes = 1;
  st.shape.max_length = sc.max_length;
  st.shape.num_constants = sc.constants;
  st.shape.output_mode = OutputMode::Last;
  // mul (inside): the residual's weights are w f^2 (w f'^2), and a weighted RMSE divides by
  // their sum.
  st.error_scale = 1;
  if (st.mode != StageMode::Add) {
    double main = 0, stage = 0;
    for (size_t r = 0; r < table_.rows(); ++r) {
      main += table_.weights.empty() ? 1.0 : table_.weights[r];
      stage += st.table.weights[r];
    }
    st.error_scale = main > 0 ? std::sqrt(stage / main) : 1;
  }
  st.scorers.clear();
  st.scorers.resize(static_cast<size_t>(threads_));
  st.fitters.clear();
  st.fitters.resize(static_cast<size_t>(threads_));
}

bool Search::pickBase(int k, Stage& st) {
  const auto& sc = cfg_.search.stages;
  const int outputs = static_cast<int>(table_.numOutputs());
  Scorer& s = scorer(0);
  struct Candidate {
    Program final_program;
    double error, cost;
  };
  std::vector<Candidate> cands;
  for (const auto& m : archive_.members()) {
    if (!m.obj.finite()) continue;
    Program fp = finalProgram(s, m.program);
    if (static_cast<int>(fp.code.size()) + sc.max_length + outputs > shape_.max_length ||
        static_cast<int>(effectiveConstants(fp).size()) + sc.constants > shape_.num_constants)
      continue;
    cands.push_back({std::move(fp), m.obj.error, m.obj.cost});
  }
  if (cands.empty()) return false;
  std::vector<std::pair<double, double>> ec;
  for (const auto& c : cands) ec.emplace_back(c.error, c.cost);
  const std::vector<size_t> order = stageBases(ec, sc.bases, sc.pick);
  const size_t pick =
      order[(static_cast<size_t>(st.picks) * stages_.size() + static_cast<size_t>(k)) %
            order.size()];
  // A multiplicative (inside) correction is the composite's (linearised) squared error only for
  // RMSE of one output without channels; elsewhere the stage corrects additively. Inside picks
  // take the inputs in turn.
  StageMode mode = sc.modes[static_cast<size_t>(st.picks) % sc.modes.size()];
  if (mode != StageMode::Add &&
      (outputs != 1 || !err_cfg_.channels.empty() || err_cfg_.metric != ErrorMetric::Rmse))
    mode = StageMode::Add;
  st.input = mode == StageMode::Inside
                 ? static_cast<int>((static_cast<size_t>(st.picks) / sc.modes.size()) %
                                    static_cast<size_t>(shape_.num_inputs))
                 : 0;
  st.base = std::move(cands[pick].final_program);
  st.base_error = cands[pick].error;
  st.mode = mode;
  ++st.picks;
  st.since = 0;
  bindStage(st);
  return true;
}

uint64_t Search::evaluateStage(Stage& st, std::vector<Individual>& inds,
                               const std::vector<uint8_t>& refine) {
  const int n = static_cast<int>(inds.size());
  const auto& sched = cfg_.search.refine;
  uint64_t evals = 0;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4) reduction(+ : evals)
  for (int i = 0; i < n; ++i) {
    const int thread = omp_get_thread_num();
    Individual& ind = inds[i];
    ind.obj = stageScore(st, thread, ind.program);
    ++evals;
    if (refine.empty() || !refine[i] || sched.lm_iterations <= 0 || !ind.obj.finite() ||
        effectiveConstants(ind.program).empty())
      continue;
    auto& f = st.fitters[static_cast<size_t>(thread)];
    if (!f) f = std::make_unique<ConstantFitter>(*st.ds, st.err);
    Program work = ind.program;
    LevenbergMarquardtConfig lm;
    lm.max_iterations = sched.lm_iterations;
    lm.objective = sched.lm_metric;
    const auto fit = f->fit(work, lm);
    evals += static_cast<uint64_t>(fit.evaluations);
    if (!fit.improved) continue;
    const Objectives o = stageScore(st, thread, work);
    ++evals;
    if (o.error < ind.obj.error) {
      ind.program = std::move(work);
      ind.obj = o;
    }
  }
  return evals;
}

void Search::offerComposites(Stage& st, const std::vector<Individual>& inds) {
  Scorer& gs = stageScorer(st, 0);
  Scorer& main = scorer(0);
  uint64_t evals = 0;
  for (const auto& ind : inds) {
    if (!ind.obj.finite()) continue;
    Program g = pruneIntrons(ind.program);
    if (st.err.linear_scaling) {
      gs.error(g);
      g = applyLinearScaling(g, gs.scales(), 1);
    }
    const Program c = composeStage(st.base, g, shape_.num_inputs, st.mode, st.input);
    if (c.code.empty()) continue;
    // What the composite would be: the stage's error is its error (add; mul rescaled; inside
    // only a linearisation, so not a bound: its cost alone may rule it out), its cost and
    // discontinuity are the composite's own. Only what the archive would take is built in the
    // run's shape and scored on the table.
    Objectives predicted;
    predicted.error = st.mode == StageMode::Inside ? 0.0 : ind.obj.error * st.error_scale;
    predicted.cost = cost_.programCost(c) + transform_cost_;
    predicted.discontinuity = disc_.programDiscontinuity(c, effectiveIndices(c));
    if (archive_.rejects(predicted)) continue;
    auto p = fitToShape(c, shape_);
    if (!p) continue;
    const Objectives o = score(main, *p);
    ++evals;
    if (!o.finite()) continue;
    archiveInsert(*p, o, false);
    for (const auto& m : archive_.members())
      if (m.program == *p) {
        ++st.composites;
        break;
      }
  }
  evaluations_ += evals;
  session_evals_ += evals;
}

void Search::stepStages(int g) {
  const auto& sc = cfg_.search.stages;
  if (sc.islands <= 0) return;
  while (static_cast<int>(stages_.size()) < sc.islands)
    stages_.push_back(std::make_unique<Stage>());
  const auto& var = cfg_.search.variation;
  InitConfig init{cfg_.program.init_min_length,
                  std::min(cfg_.program.init_max_length, sc.max_length), cfg_.program.const_min,
                  cfg_.program.const_max};
  for (int k = 0; k < static_cast<int>(stages_.size()); ++k) {
    Stage& st = *stages_[static_cast<size_t>(k)];
    uint64_t evals = 0;
    if (st.base.code.empty() || st.since >= sc.retarget) {
      if (!pickBase(k, st)) continue;
      // A new base: the population is scored on its residual (the corrections found for the
      // last base are a start like any), or drawn at random the first time.
      std::vector<Individual> pop = std::move(st.isl.pop);
      if (pop.empty()) {
        pop.resize(static_cast<size_t>(sc.population));
        for (int i = 0; i < sc.population; ++i) {
          Rng rng(hashSeed(cfg_.search.seed, static_cast<uint64_t>(g),
                           stageIndex(island_first_, k, i), 7));
          pop[static_cast<size_t>(i)].program = randomProgram(st.shape, init, rng);
          pop[static_cast<size_t>(i)].program.constants.resize(
              static_cast<size_t>(st.shape.num_constants), 0.0f);
        }
      }
      evals += evaluateStage(st, pop, {});
      offerComposites(st, pop);
      surviveStrata(0, st.isl, pop, sc.population);
      evaluations_ += evals;
      session_evals_ += evals;
      continue;
    }
    const int n = sc.population;
    std::vector<Individual> off(static_cast<size_t>(n));
#pragma omp parallel for num_threads(threads_) schedule(static)
    for (int i = 0; i < n; ++i) {
      Rng rng(
          hashSeed(cfg_.search.seed, static_cast<uint64_t>(g), stageIndex(island_first_, k, i), 7));
      const int a = tournamentBias(cfg_.search.error_bias, st.isl, rng);
      Program child;
      if (rng.chance(var.crossover_rate)) {
        const int b = tournamentBias(cfg_.search.error_bias, st.isl, rng);
        child = crossover(st.isl.pop[a].program, st.isl.pop[b].program, st.shape, rng);
      } else {
        child = st.isl.pop[a].program;
      }
      if (rng.chance(var.macro_rate)) macroMutate(child, st.shape, rng, var.wrap_share);
      if (rng.chance(var.micro_rate)) {
        const int m = 1 + static_cast<int>(rng.below(var.micro_max));
        for (int j = 0; j < m; ++j)
          microMutate(child, st.shape, rng, var.constant_sigma, var.effective_bias,
                      cfg_.program.const_min, cfg_.program.const_max);
      }
      off[static_cast<size_t>(i)].program = std::move(child);
    }
    std::vector<uint8_t> refine(static_cast<size_t>(n), 0);
    Rng pick(
        hashSeed(cfg_.search.seed, static_cast<uint64_t>(g), stageIndex(island_first_, k, 0), 8));
    for (auto& r : refine) r = pick.chance(cfg_.search.refine.offspring_share);
    evals += evaluateStage(st, off, refine);
    offerComposites(st, off);
    std::vector<Individual> pool = std::move(st.isl.pop);
    pool.insert(pool.end(), std::make_move_iterator(off.begin()),
                std::make_move_iterator(off.end()));
    surviveStrata(0, st.isl, pool, sc.population);
    ++st.since;
    evaluations_ += evals;
    session_evals_ += evals;
  }
}

}  // namespace lgp
