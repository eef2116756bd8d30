#include "lgp/search/search.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "lgp/core/formula.hpp"
#include "lgp/core/variation.hpp"
#include "lgp/io/checkpoint.hpp"
#include "lgp/search/differential_evolution.hpp"
#include "lgp/search/levenberg_marquardt.hpp"
#include "lgp/search/nelder_mead.hpp"
#include "lgp/search/structured.hpp"

namespace lgp {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

Search::Search(RunConfig cfg, Table table)
    : cfg_(std::move(cfg)),
      table_(std::move(table)),
      shape_(
          cfg_.shape(static_cast<int>(table_.numInputs()), static_cast<int>(table_.numOutputs()))),
      err_cfg_(cfg_.errorConfig(table_.output_names)),
      cost_(cfg_.costModel()),
      disc_(cfg_.discontinuityModel()),
      ds_(table_, cfg_.eval.block_size),
      archive_(cfg_.search.archive) {
  for (const auto& ip : cfg_.search.islands.profiles)
    profile_shapes_.push_back(lgp::islandShape(shape_, ip));
  transform_cost_ = cost_.transformCost(err_cfg_.transforms);
  err_cfg_.linear_scaling = cfg_.search.linear_scaling;
  err_cfg_.genes = cfg_.search.linear_scaling ? cfg_.program.genes : 1;
  {
    const size_t channels =
        err_cfg_.channels.empty() ? table_.numOutputs() : err_cfg_.channels.size();
    lm_fits_the_error_ = lmPlan(cfg_.search.refine.lm_metric, err_cfg_, channels).fits_error;
  }
  domain_ = tableDomain(table_);
  fidelity_tol_ = fidelityTolerances(table_);
  disc_.domain = domain_;  // piecewise ops that never switch on the table count nothing
  cost_.domain = domain_;  // and guards that interval analysis removes cost nothing
  // Never more threads than the cores this process may use: more only cost memory and
  // switches, and thousands of them can fail to start (libgomp then ends the process).
  threads_ =
      std::min(cfg_.search.threads > 0 ? cfg_.search.threads : omp_get_max_threads(), maxThreads());
  scorers_.resize(threads_);
  checks_.resize(threads_);
  fitters_.resize(threads_);
  cache_ = std::make_unique<SemanticCache>(static_cast<size_t>(cfg_.search.semantic_cache));
  start_ = std::chrono::steady_clock::now();
}

Search::~Search() = default;

int Search::maxThreads() {
  return std::max(1, omp_get_num_procs());  // honours the affinity mask (taskset, cgroups)
}

ConstantFitter& Search::fitter(int thread) {
  auto& f = fitters_[thread];
  if (!f) {
    // With an output layer of several genes LM fits the exported program, whose layer is
    // opcodes and constants (see fitConstants): its outputs are the model's, unscaled.
    ErrorConfig cfg = err_cfg_;
    if (genes() > 1) {
      cfg.linear_scaling = false;
      cfg.genes = 1;
    }
    f = std::make_unique<ConstantFitter>(ds_, cfg);
  }
  return *f;
}

ConstantFitResult Search::fitConstants(int thread, Program& p, const LevenbergMarquardtConfig& lm) {
  if (genes() == 1) return fitter(thread).fit(p, lm);
  // The layer's coefficients are LM parameters like the program's constants, started at the
  // Scorer's closed-form fit and dropped afterwards (the Scorer fits them again): the
  // several-gene form of what LM does with a*f + b.
  Scorer& s = scorer(thread);
  if (!std::isfinite(s.error(p))) return {};
  Program full = applyLinearScaling(p, s.scales(), genes());
  ConstantFitResult r = fitter(thread).fit(full, lm);
  if (r.improved) std::copy_n(full.constants.begin(), p.constants.size(), p.constants.begin());
  return r;
}

Scorer& Search::scorer(int thread) {
  auto& s = scorers_[thread];
  if (!s) {
    checks_[thread] = std::make_unique<FidelityCheck>(table_, err_cfg_, kFidelitySampleRows);
    s = std::make_unique<Scorer>(ds_, err_cfg_, cfg_.eval.block_size);
    s->setFidelity(checks_[thread].get());
  }
  return *s;
}

Search::CheckedScorer::CheckedScorer(const Search& s)
    : check(s.table_, s.err_cfg_, kFidelitySampleRows),
      scorer(s.ds_, s.err_cfg_, s.cfg_.eval.block_size) {
  scorer.setFidelity(&check);
}

bool Search::fidelityOnEveryRow(const Program& p) {
  if (!full_check_) full_check_ = std::make_unique<FidelityCheck>(table_, err_cfg_, 0);
  Scorer& s = scorer(0);
  if (!std::isfinite(s.error(p))) return false;
  // The formula too: where the simplifier's rewrites do not hold for the program's float32
  // values, its cost (taken from the simplified formula) is not the cost of what was scored,
  // and such a member would dominate genuine ones out of the archive, then leave the front.
  if (full_check_->passes(s.bound(),
                          err_cfg_.linear_scaling ? s.scales() : std::vector<LinearScale>{}) &&
      formulaReproduces(finalProgram(s, p)))
    return true;
  ++fidelity_archive_rejects_;
  return false;
}

bool Search::formulaReproduces(const Program& final_program) const {
  const auto f = toProgram(formulaDag(final_program, shape_.num_inputs, domain_));
  return f &&
         valueDeviation(final_program, f->program, ds_, err_cfg_.transforms, fidelity_tol_) <= 1.0;
}

double Search::elapsed() const {
  return elapsed_before_ +
         std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

Objectives Search::score(Scorer& s, const Program& p) const {
  return scoreWith(s, p, cost_, disc_, err_cfg_.linear_scaling, genes(), transform_cost_);
}

Objectives Search::scoreWith(Scorer& s, const Program& p, const CostModel& cost,
                             const DiscontinuityModel& disc, bool linear_scaling, int genes,
                             double extra_cost) {
  Objectives o;
  o.error = s.error(p);
  if (!std::isfinite(o.error)) o.error = kInf;
  const auto& effective = s.bound().effective;  // bound by error(p): computed once
  // The program as exported: with linear scaling, its mad and constants are costed too.
  o.cost = (linear_scaling ? cost.programCost(applyLinearScaling(p, s.scales(), genes))
                           : cost.programCost(p)) +
           extra_cost;
  o.discontinuity = disc.programDiscontinuity(p, effective);
  return o;
}

void Search::refineOne(int thread, Individual& ind, uint64_t seed, uint64_t& evals, bool full,
                       const ProgramKey* key, const SemanticCache::Entry* known) {
  const auto slots = effectiveConstants(ind.program);
  if (full) ind.refined = true;
  if (slots.empty() || !ind.obj.finite()) return;
  Scorer& s = scorer(thread);
  const auto& sched = cfg_.search.refine;
  // Derivatives first: Levenberg-Marquardt with exact Jacobians, on the configured error
  // (reweighted least squares) or the plain sum of squares (lm_metric). The scorer has the
  // last word.
  const int lm_iterations = full ? sched.archive_lm_iterations : sched.lm_iterations;
  bool lm_helped = false;
  if (lm_iterations > 0) {
    Program work = ind.program;
    // An offspring fit of a program the cache knows is replayed: LM is deterministic, so the
    // same constants, flags and evaluations (semantic_cache.hpp).
    const bool cacheable = key && !full && slots.size() <= SemanticCache::LmOutcome::kMaxConstants;
    SemanticCache::LmOutcome out;
    if (cacheable && known && known->lm_known) {
      out = known->lm;
      for (size_t k = 0; k < slots.size(); ++k) work.constants[slots[k]] = out.after[k];
      cache_lm_replays_.fetch_add(1, std::memory_order_relaxed);
    } else {
      LevenbergMarquardtConfig lm;
      lm.max_iterations = lm_iterations;
      lm.objective = sched.lm_metric;
      const auto fit = fitConstants(thread, work, lm);
      out.improved = fit.improved;
      out.converged = fit.converged;
      out.evaluations = static_cast<uint32_t>(fit.evaluations);
      lm_fits_.fetch_add(1, std::memory_order_relaxed);
      lm_evaluations_.fetch_add(static_cast<uint64_t>(fit.evaluations), std::memory_order_relaxed);
      if (fit.converged && !fit.improved) lm_converged_.fetch_add(1, std::memory_order_relaxed);
      if (cacheable) {
        out.count = static_cast<uint8_t>(slots.size());
        for (size_t k = 0; k < slots.size(); ++k) out.after[k] = work.constants[slots[k]];
        cache_->storeLm(*key, out);
      }
    }
    evals += out.evaluations;
    // Constants already at LM's optimum (clones and intron-only mutants of refined parents,
    // mostly) of the error the scorer measures: a quick Nelder-Mead polish from there finds
    // nothing, so it is skipped. Where LM fits something else (least_squares with max_abs,
    // say) the polish still runs.
    if (!full && !out.improved && out.converged && lm_fits_the_error_) return;
    if (out.improved) {
      const Objectives o = score(s, work);
      ++evals;
      if (o.error < ind.obj.error) {
        ind.program = std::move(work);
        ind.obj = o;
        lm_helped = true;
        lm_accepted_.fetch_add(1, std::memory_order_relaxed);
      }
    }
  }
  // Nelder-Mead (and DE) where derivatives did not help: constants behind a kink, a
  // non-smooth metric, or a full refinement that polishes what LM found.
  if (lm_helped && !full) return;
  Program work = ind.program;
  std::vector<double> x0;
  for (int c : slots) x0.push_back(work.constants[c]);
  BoundProgram bp;  // bound once; each evaluation only refreshes the constants
  bp.bind(work, ds_.numInputs());
  auto f = [&](const std::vector<double>& x) {
    for (size_t k = 0; k < slots.size(); ++k) {
      const float v = static_cast<float>(x[k]);
      if (!std::isfinite(v)) return kInf;
      work.constants[slots[k]] = v;
    }
    bp.updateConstants(work);
    return s.error(bp);
  };
  Rng rng(seed);
  NelderMeadConfig nm = sched.nm;
  if (!full) {
    nm.max_evaluations = sched.offspring_evaluations;
    nm.restarts = 0;
  }
  std::vector<double> start = x0;
  const uint64_t evals_before = evals;
  if (full && sched.method == RefineMethod::DeThenNm) {
    // A global step first: Nelder-Mead alone stalls in the nearest basin.
    DifferentialEvolutionConfig de;
    de.max_evaluations = sched.de_evaluations;
    const auto d = differentialEvolution(f, x0, de, rng);
    evals += static_cast<uint64_t>(d.evaluations);
    start = d.x;
  }
  const auto res = nelderMead(f, start, nm, rng);
  evals += static_cast<uint64_t>(res.evaluations);
  nm_runs_.fetch_add(1, std::memory_order_relaxed);
  nm_evaluations_.fetch_add(evals - evals_before, std::memory_order_relaxed);
  if (res.f < ind.obj.error) {
    for (size_t k = 0; k < slots.size(); ++k)
      ind.program.constants[slots[k]] = static_cast<float>(res.x[k]);
    // Scored afresh: constants move the intervals (whether a piecewise op switches), the
    // linear scale and which constants are free inline literals, so cost and discontinuity
    // change with them.
    const Objectives o = score(s, ind.program);
    ++evals;
    if (std::isfinite(o.error) && o.error <= ind.obj.error) {
      ind.obj = o;
    } else {
      for (size_t k = 0; k < slots.size(); ++k)
        ind.program.constants[slots[k]] = static_cast<float>(x0[k]);
    }
  }
}

void Search::evaluateAll(std::vector<Individual>& inds, const std::vector<uint8_t>& refine,
                         uint64_t stream, uint64_t index_base) {
  const int n = static_cast<int>(inds.size());
  uint64_t evals = 0;
  uint64_t score_hits = 0;
  const bool cached = cache_->enabled();
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4) reduction(+ : evals, score_hits)
  for (int i = 0; i < n; ++i) {
    const int thread = omp_get_thread_num();
    Individual& ind = inds[i];
    const bool refined = !refine.empty() && refine[i];
    // A hit stands for the work it replaces, evaluations included (semantic_cache.hpp).
    ProgramKey key;
    SemanticCache::Entry known;
    const bool hit = cached && cache_->find(key = effectiveKey(ind.program), known);
    if (hit) {
      ind.obj = known.obj;
      ++score_hits;
    } else {
      ind.obj = score(scorer(thread), ind.program);
      if (cached) cache_->storeObjectives(key, ind.obj);
    }
    ++evals;
    if (!refined) continue;
    refineOne(thread, ind,
              hashSeed(cfg_.search.seed, stream, index_base + static_cast<uint64_t>(i), 3), evals,
              false, cached ? &key : nullptr, hit ? &known : nullptr);
    // New constants were scored afresh (refineOne): clones of the refined program hit too.
    if (cached) {
      const ProgramKey after = effectiveKey(ind.program);
      if (!(after == key)) cache_->storeObjectives(after, ind.obj);
    }
  }
  cache_score_hits_ += score_hits;
  evaluations_ += evals;
  session_evals_ += evals;
}

void Search::rankIsland(Island& isl) {
  // Duplicated objective vectors rank after every distinct one: they add nothing to the front
  // and would otherwise crowd it out (the classic bloat of trivial programs).
  const auto& pop = isl.pop;
  const int n = static_cast<int>(pop.size());
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  auto err = [&](int i) { return pop[i].obj.finite() ? pop[i].obj.error : kInf; };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (err(a) != err(b)) return err(a) < err(b);
    if (pop[a].obj.cost != pop[b].obj.cost) return pop[a].obj.cost < pop[b].obj.cost;
    return pop[a].obj.discontinuity < pop[b].obj.discontinuity;
  });
  std::vector<uint8_t> is_dup(n, 0);
  for (int k = 1; k < n; ++k) {
    const int a = order[k - 1], b = order[k];
    is_dup[b] = err(a) == err(b) && pop[a].obj.cost == pop[b].obj.cost &&
                pop[a].obj.discontinuity == pop[b].obj.discontinuity;
  }
  std::vector<int> uniq, dup;
  for (int i = 0; i < n; ++i) (is_dup[i] ? dup : uniq).push_back(i);
  std::vector<Objectives> objs;
  objs.reserve(uniq.size());
  for (int i : uniq) objs.push_back(pop[i].obj);
  const auto r = nondominatedRanks(objs);
  isl.rank.assign(n, 0);
  isl.crowd.assign(n, 0.0);
  int max_rank = 0;
  for (size_t k = 0; k < uniq.size(); ++k) {
    isl.rank[uniq[k]] = r[k];
    max_rank = std::max(max_rank, r[k]);
  }
  for (int i : dup) isl.rank[i] = max_rank + 1;
  std::vector<Objectives> all;
  all.reserve(n);
  for (const auto& ind : pop) all.push_back(ind.obj);
  std::vector<std::vector<int>> fronts(max_rank + 2);
  for (int i = 0; i < n; ++i) fronts[isl.rank[i]].push_back(i);
  for (const auto& members : fronts) {
    if (members.empty()) continue;
    const auto d = crowdingDistance(all, members);
    for (size_t k = 0; k < members.size(); ++k) isl.crowd[members[k]] = d[k];
  }
}

void Search::survive(int global, Island& isl, std::vector<Individual>& pool, int keep) const {
  surviveStrata(islandCostStrata(global), isl, pool, keep);
}

void Search::surviveStrata(int strata, Island& isl, std::vector<Individual>& pool, int keep) const {
  isl.pop = std::move(pool);
  rankIsland(isl);
  const int n = static_cast<int>(isl.pop.size());
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (isl.rank[a] != isl.rank[b]) return isl.rank[a] < isl.rank[b];
    return isl.crowd[a] > isl.crowd[b];
  });
  keep = std::min(n, keep);
  std::vector<Objectives> objs;
  objs.reserve(n);
  for (const auto& ind : isl.pop) objs.push_back(ind.obj);
  const std::vector<int> chosen = stratifiedSurvivors(objs, order, keep, strata);
  // Survivors keep the rank and crowding of the pool's ranking, as in NSGA-II (Deb et al.
  // 2002): tournaments compare them directly, so no second sort is needed.
  std::vector<Individual> next;
  std::vector<int> rank;
  std::vector<double> crowd;
  next.reserve(keep);
  rank.reserve(keep);
  crowd.reserve(keep);
  for (int i : chosen) {
    next.push_back(std::move(isl.pop[i]));
    rank.push_back(isl.rank[i]);
    crowd.push_back(isl.crowd[i]);
  }
  isl.pop = std::move(next);
  isl.rank = std::move(rank);
  isl.crowd = std::move(crowd);
}

int Search::tournament(int global, const Island& isl, Rng& rng) const {
  return tournamentBias(islandErrorBias(global), isl, rng);
}

int Search::tournamentBias(double error_bias, const Island& isl, Rng& rng) const {
  const auto& pop = isl.pop;
  const int n = static_cast<int>(pop.size());
  const bool by_error = rng.chance(error_bias);
  int best = static_cast<int>(rng.below(n));
  for (int t = 1; t < cfg_.search.tournament_size; ++t) {
    const int c = static_cast<int>(rng.below(n));
    if (by_error) {
      if (pop[c].obj.error < pop[best].obj.error) best = c;
    } else if (isl.rank[c] < isl.rank[best] ||
               (isl.rank[c] == isl.rank[best] && isl.crowd[c] > isl.crowd[best])) {
      best = c;
    }
  }
  return best;
}

int Search::islandCount(const RunConfig& cfg) {
  return std::clamp(cfg.search.islands.count, 1, std::max(1, cfg.search.population / 4));
}

bool Search::adoptCheckpointIslands(RunConfig& cfg, const nlohmann::json& ck) {
  if (!ck.is_object() || !ck.contains("island_total") || !ck["island_total"].is_number_integer())
    return false;
  const int total = ck["island_total"].get<int>();
  if (total <= islandCount(cfg) || total > std::max(1, cfg.search.population / 4)) return false;
  cfg.search.islands.count = total;
  return true;
}

void Search::setIslandRange(int first, int count, int total) {
  island_first_ = first;
  island_total_ = total;
  islands_.assign(count, Island{});
  range_set_ = true;
}

void Search::setTransport(std::unique_ptr<MigrationTransport> transport) {
  transport_ = std::move(transport);
}

int Search::islandSize(int k) const {
  const int count = island_total_ > 0 ? island_total_ : static_cast<int>(islands_.size());
  // Recomputed per call (a few islands): no cached state to race on inside parallel loops.
  return lgp::islandSizes(cfg_.search.population, count,
                          cfg_.search.islands.profiles)[static_cast<size_t>(k)];
}

int Search::localPopulation() const {
  int n = 0;
  for (int k = 0; k < static_cast<int>(islands_.size()); ++k) n += islandSize(island_first_ + k);
  return n;
}

const ProgramShape& Search::islandShape(int k) const {
  if (profile_shapes_.empty()) return shape_;
  return profile_shapes_[static_cast<size_t>(k) % profile_shapes_.size()];
}

const IslandProfile* Search::islandProfile(int k) const {
  const auto& profiles = cfg_.search.islands.profiles;
  return profiles.empty() ? nullptr : &profiles[static_cast<size_t>(k) % profiles.size()];
}

double Search::islandWeightRate(int k) const {
  const IslandProfile* p = islandProfile(k);
  return p && p->weight_rate >= 0 ? p->weight_rate : cfg_.search.variation.weight_rate;
}

double Search::islandErrorBias(int k) const {
  const IslandProfile* p = islandProfile(k);
  return p && p->error_bias >= 0 ? p->error_bias : cfg_.search.error_bias;
}

int Search::islandCostStrata(int k) const {
  const IslandProfile* p = islandProfile(k);
  return p && p->cost_strata >= 0 ? p->cost_strata : cfg_.search.cost_strata;
}

int Search::offspringBase() const {
  int n = 0;
  for (int k = 0; k < island_first_; ++k) n += islandSize(k);
  return n;
}

void Search::migrate(int generation) {
  const auto& ic = cfg_.search.islands;
  const int count = static_cast<int>(islands_.size());
  const int total = island_total_;
  if (total < 2 || ic.migrants == 0) return;
  // Each island sends its lowest-error member and random others from its first front. An
  // island with nothing to send still sends (an empty batch), so that a synchronous transport
  // always gets one message per island and round.
  if (static_cast<int>(targets_.size()) != total)
    targets_ = migrationTargets(total, ic.profiles, ic.topology);
  for (int k = 0; k < count; ++k) {
    const Island& isl = islands_[k];
    const int global = island_first_ + k;
    const int target = targets_[global];
    std::vector<int> first;
    int best = -1;
    for (int i = 0; i < static_cast<int>(isl.pop.size()); ++i) {
      if (isl.rank[i] != 0 || !isl.pop[i].obj.finite()) continue;
      first.push_back(i);
      if (best < 0 || isl.pop[i].obj.error < isl.pop[best].obj.error) best = i;
    }
    std::vector<Migrant> out;
    if (first.empty() || target == global) {  // alone with its profile: an empty batch
      transport_->send(global, target, std::move(out));
      continue;
    }
    Rng rng(hashSeed(cfg_.search.seed, static_cast<uint64_t>(generation),
                     static_cast<uint64_t>(global), 5));
    out.push_back({isl.pop[best].program, isl.pop[best].obj});
    first.erase(std::find(first.begin(), first.end(), best));
    while (static_cast<int>(out.size()) < ic.migrants && !first.empty()) {
      const size_t j = rng.below(static_cast<uint32_t>(first.size()));
      out.push_back({isl.pop[first[j]].program, isl.pop[first[j]].obj});
      first.erase(first.begin() + static_cast<std::ptrdiff_t>(j));
    }
    transport_->send(global, target, std::move(out));
  }
  // Arrivals join the island's pool; the worst leave (elitist, like any survival).
  std::vector<std::vector<Migrant>> arrived(count);
  for (int k = 0; k < count; ++k) arrived[k] = transport_->receive(island_first_ + k);
#pragma omp parallel for num_threads(threads_) schedule(static, 1)
  for (int k = 0; k < count; ++k) {
    if (arrived[k].empty()) continue;
    Island& isl = islands_[k];
    const ProgramShape& view = islandShape(island_first_ + k);
    std::vector<Individual> pool = std::move(isl.pop);
    for (auto& m : arrived[k])
      if (fitToIsland(m.program, shape_, view))  // what does not fit stays away
        pool.push_back({std::move(m.program), m.obj, false});
    survive(island_first_ + k, isl, pool, islandSize(island_first_ + k));
  }
}

std::vector<std::string> Search::addSeeds(const std::vector<NamedProgram>& seeds) {
  std::vector<std::string> skipped;
  for (const auto& seed : seeds) {
    auto p = fitToShape(seed.program, shape_);
    if (p)
      seeds_.push_back(std::move(*p));
    else
      skipped.push_back(seed.name + ": " + p.error());
  }
  return skipped;
}

void Search::initialize() {
  if (initialized_) return;
  if (!range_set_) {
    island_total_ = islandCount(cfg_);
    islands_.assign(island_total_, Island{});
  }
  const int count = static_cast<int>(islands_.size());
  if (!transport_) transport_ = std::make_unique<LocalTransport>(island_total_);
  const int n = localPopulation();
  const uint64_t base = static_cast<uint64_t>(offspringBase());
  InitConfig init{cfg_.program.init_min_length, cfg_.program.init_max_length,
                  cfg_.program.const_min, cfg_.program.const_max};
  std::vector<Individual> inds(n);
  const std::vector<Individual> structured = structuredStart();
  int first = 0;
  for (int k = 0; k < count; ++k) {
    const ProgramShape& view = islandShape(island_first_ + k);
    const int size = islandSize(island_first_ + k);
    for (int i = first; i < first + size; ++i) {
      Rng rng(hashSeed(cfg_.search.seed, 0, base + static_cast<uint64_t>(i), 1));
      inds[i].program = randomProgram(view, init, rng);
      inds[i].program.constants.resize(shape_.num_constants, 0.0f);
    }
    // Seeds take the first slots of every island (at most half of each: the rest stays
    // diverse), where they fit its profile.
    int j = 0;
    for (const Program& seed : seeds_) {
      if (j >= size / 2) break;
      Program p = seed;
      if (fitToIsland(p, shape_, view)) inds[first + j++].program = std::move(p);
    }
    // The structured fits join the islands that search the run's whole shape (the cheap
    // islands keep their random start), after the seeds, up to structured.share of each.
    if (view.max_length == shape_.max_length && view.num_constants == shape_.num_constants) {
      const int cap = j + static_cast<int>(cfg_.search.structured.share * size);
      for (const Individual& ind : structured) {
        if (j >= cap || j >= size) break;
        Program p = ind.program;
        if (fitToIsland(p, shape_, view)) inds[first + j++].program = std::move(p);
      }
    }
    first += size;
  }
  evaluateAll(inds, {}, 0, base);
  for (const auto& ind : inds) archiveInsert(ind.program, ind.obj, false);
  first = 0;
  for (int k = 0; k < count; ++k) {
    const int size = islandSize(island_first_ + k);
    std::vector<Individual> pool(std::make_move_iterator(inds.begin() + first),
                                 std::make_move_iterator(inds.begin() + first + size));
    survive(island_first_ + k, islands_[k], pool, size);
    for (const auto& ind : islands_[k].pop)
      islands_[k].best = std::min(islands_[k].best, ind.obj.error);
    first += size;
  }
  generation_ = 0;
  initialized_ = true;
}

std::vector<Search::Individual> Search::structuredStart() {
  if (cfg_.search.structured.max_degree <= 0) return {};
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Individual> inds;
  std::vector<std::string> families;
  for (auto& f : structuredFits(cfg_, table_, shape_, domain_, threads_)) {
    auto p = fitToShape(f.program, shape_);
    if (!p) continue;
    inds.push_back({std::move(*p), {}, false});
    families.push_back(f.family);
  }
  const size_t built = inds.size();
  // Streams of their own (index base 2^40): the random start's offspring indices stay as
  // they were.
  evaluateAll(inds, {}, 0, uint64_t{1} << 40);
  size_t finite = 0;
  std::vector<Individual> kept;
  std::vector<Objectives> objs;
  for (const auto& ind : inds)
    if (ind.obj.finite()) {
      ++finite;
      archiveInsert(ind.program, ind.obj, false);
      kept.push_back(ind);
      objs.push_back(ind.obj);
    }
  // The fits no other fit dominates, cheapest first: the islands' share.
  const auto ranks = nondominatedRanks(objs);
  std::vector<Individual> first;
  for (size_t i = 0; i < kept.size(); ++i)
    if (ranks[i] == 0) first.push_back(kept[i]);
  std::stable_sort(first.begin(), first.end(), [](const Individual& a, const Individual& b) {
    return a.obj.cost < b.obj.cost;
  });
  size_t archived = 0;
  for (const auto& m : archive_.members())
    for (const auto& ind : kept)
      if (m.program == ind.program) {
        ++archived;
        break;
      }
  structured_info_ = {
      {"fits", built},
      {"finite", finite},
      {"archived", archived},
      {"first_front", first.size()},
      {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}};
  return first;
}

void Search::step(bool check_budget) {
  if (!initialized_) {
    initialize();
    return;
  }
  if (check_budget && done()) return;
  const int g = generation_ + 1;
  const int n = localPopulation();
  const int base = offspringBase();  // offspring keep their global index in every RNG stream
  const int count = static_cast<int>(islands_.size());
  const auto& var = cfg_.search.variation;
  const auto& ic = cfg_.search.islands;
  // A stagnant island starts over: random programs, plus archive members to build on.
  std::vector<uint8_t> restart(count, 0);
  if (ic.restart_after > 0)
    for (int k = 0; k < count; ++k) restart[k] = islands_[k].stagnant >= ic.restart_after;
  // Offspring i belongs to island owner[i]; islands own consecutive ranges.
  const std::vector<int> bred = offspringPerIsland(restart);
  std::vector<int> owner(n), first(count + 1, 0);
  for (int k = 0; k < count; ++k) {
    first[k + 1] = first[k] + bred[k];
    for (int i = first[k]; i < first[k + 1]; ++i) owner[i] = k;
  }
  InitConfig init{cfg_.program.init_min_length, cfg_.program.init_max_length,
                  cfg_.program.const_min, cfg_.program.const_max};
  const auto& archived = archive_.members();
  std::vector<Individual> off(n);
  std::vector<uint8_t> weighted(n, 0);  // offspring given a weight: refined whatever the share
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int i = 0; i < n; ++i) {
    Rng rng(
        hashSeed(cfg_.search.seed, static_cast<uint64_t>(g), static_cast<uint64_t>(base + i), 1));
    const Island& isl = islands_[owner[i]];
    const ProgramShape& view = islandShape(island_first_ + owner[i]);
    if (restart[owner[i]]) {
      const int j = i - first[owner[i]];
      Program& p = off[i].program;
      const bool from_archive = j < ic.migrants && !archived.empty();
      if (from_archive) p = archived[rng.below(static_cast<uint32_t>(archived.size()))].program;
      if (!from_archive || !fitToIsland(p, shape_, view)) {
        p = randomProgram(view, init, rng);
        p.constants.resize(shape_.num_constants, 0.0f);
      }
      continue;
    }
    const int a = tournament(island_first_ + owner[i], isl, rng);
    Program child;
    if (rng.chance(var.crossover_rate)) {
      const int b = tournament(island_first_ + owner[i], isl, rng);
      child = crossover(isl.pop[a].program, isl.pop[b].program, view, rng);
    } else {
      child = isl.pop[a].program;
    }
    if (rng.chance(var.macro_rate)) macroMutate(child, view, rng, var.wrap_share);
    if (rng.chance(var.micro_rate)) {
      const int m = 1 + static_cast<int>(rng.below(var.micro_max));
      for (int k = 0; k < m; ++k)
        microMutate(child, view, rng, var.constant_sigma, var.effective_bias,
                    cfg_.program.const_min, cfg_.program.const_max);
    }
    // Last, so the new coefficient starts at 1 (no draw at all at rate 0, nor for a child
    // under weight_min_length: same runs as before, and as without weights where no child
    // reaches it).
    const double weight_rate = islandWeightRate(island_first_ + owner[i]);
    if (weight_rate > 0 &&
        (var.weight_min_length == 0 ||
         static_cast<int>(effectiveIndices(child).size()) >= var.weight_min_length) &&
        rng.chance(weight_rate))
      weighted[i] = weightMutate(child, view, rng);
    // Crossover and weights may place a constant in a slot past the island's (they look for a
    // free one among all): renumbered where possible, else the child is its parent again.
    if (&view != &shape_ && !fitToIsland(child, shape_, view)) {
      child = isl.pop[a].program;
      weighted[i] = 0;
    }
    off[i].program = std::move(child);
  }
  std::vector<uint8_t> refine(n, 0);
  Rng pick(hashSeed(cfg_.search.seed, static_cast<uint64_t>(g), 0, 2));
  for (int i = 0; i < base + n; ++i) {
    const bool chosen = pick.chance(cfg_.search.refine.offspring_share);
    if (i >= base) refine[i - base] = chosen || weighted[i - base];
  }
  evaluateAll(off, refine, static_cast<uint64_t>(g), static_cast<uint64_t>(base));
  const bool adaptive = ic.adaptive > 0 && count > 1;
  if (adaptive) {
    std::vector<Objectives> held;
    held.reserve(archived.size());
    for (const auto& m : archived) held.push_back(m.obj);
    front_gain_.reset(held);
  }
  std::vector<double> gain(count, 0.0);
  for (int i = 0; i < n; ++i) {
    Objectives stored;
    if (archiveInsert(off[i].program, off[i].obj, off[i].refined, &stored) && adaptive)
      gain[owner[i]] += front_gain_.add(stored);
  }
  if (adaptive) {
    const double fade = std::exp2(-1.0 / ic.adaptive_halflife);
    for (int k = 0; k < count; ++k) islands_[k].credit = islands_[k].credit * fade + gain[k];
  }

#pragma omp parallel for num_threads(threads_) schedule(static, 1)
  for (int k = 0; k < count; ++k) {
    Island& isl = islands_[k];
    std::vector<Individual> pool;
    if (!restart[k]) pool = std::move(isl.pop);
    pool.insert(pool.end(), std::make_move_iterator(off.begin() + first[k]),
                std::make_move_iterator(off.begin() + first[k + 1]));
    survive(island_first_ + k, isl, pool, islandSize(island_first_ + k));
    double best = kInf;
    for (const auto& ind : isl.pop) best = std::min(best, ind.obj.error);
    if (restart[k]) {
      isl.best = best;
      isl.stagnant = 0;
    } else if (best < isl.best * (1 - 1e-9)) {
      isl.best = best;
      isl.stagnant = 0;
    } else {
      ++isl.stagnant;
    }
  }
  for (int k = 0; k < count; ++k) restarts_ += restart[k];
  generation_ = g;
  if (ic.migration_interval > 0 && g % ic.migration_interval == 0) migrate(g);
  if (cfg_.search.refine.archive_period > 0 && g % cfg_.search.refine.archive_period == 0)
    refineArchive();
  stepStages(g);
}

void Search::refineArchive() {
  auto& members = archive_.mutableMembers();
  const std::vector<int> todo =
      refineQueue(members, cfg_.search.refine.archive_max, cfg_.search.refine.archive_order);
  if (todo.empty()) return;
  std::vector<Individual> inds(todo.size());
  for (size_t k = 0; k < todo.size(); ++k) {
    inds[k].program = members[todo[k]].program;
    inds[k].obj = members[todo[k]].obj;
    members[todo[k]].refined = true;
  }
  const int n = static_cast<int>(inds.size());
  uint64_t evals = 0;
  // Ranks of an MPI run refine their own archives on streams of their own.
  const uint64_t stream = ((static_cast<uint64_t>(generation_) << 20) | 0xA5A5u) +
                          (static_cast<uint64_t>(island_first_) << 44);
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1) reduction(+ : evals)
  for (int i = 0; i < n; ++i)
    refineOne(omp_get_thread_num(), inds[i],
              hashSeed(cfg_.search.seed, stream, static_cast<uint64_t>(i), 4), evals, true);
  evaluations_ += evals;
  session_evals_ += evals;
  for (const auto& ind : inds) archiveInsert(ind.program, ind.obj, true);
  // Refined members also rejoin the islands, each one island, so their constants propagate.
  const int count = static_cast<int>(islands_.size());
  std::vector<Objectives> objs;
  objs.reserve(inds.size());
  for (const auto& ind : inds) objs.push_back(ind.obj);
  const std::vector<int> to = dealIslands(objs, count, cfg_.search.islands.deal);
  std::vector<std::vector<Individual>> pools(count);
  for (int k = 0; k < count; ++k) pools[k] = std::move(islands_[k].pop);
  for (size_t j = 0; j < inds.size(); ++j)  // a member that does not fit its island stays away
    if (fitToIsland(inds[j].program, shape_, islandShape(island_first_ + to[j])))
      pools[to[j]].push_back(std::move(inds[j]));
#pragma omp parallel for num_threads(threads_) schedule(static, 1)
  for (int k = 0; k < count; ++k)
    survive(island_first_ + k, islands_[k], pools[k], islandSize(island_first_ + k));
}

void Search::adopt(const std::vector<Program>& programs, int generations, uint64_t evaluations,
                   double elapsed_s, const std::string& stop_reason) {
  std::vector<Individual> inds(programs.size());
  for (size_t i = 0; i < programs.size(); ++i) inds[i].program = programs[i];
  evaluateAll(inds, {}, 0);
  archive_ = Archive(cfg_.search.archive);
  for (const auto& ind : inds) archiveInsert(ind.program, ind.obj, true);
  islands_.assign(1, Island{});
  island_first_ = 0;
  island_total_ = 1;
  transport_ = std::make_unique<LocalTransport>(1);
  islands_[0].pop = std::move(inds);
  rankIsland(islands_[0]);
  initialized_ = true;
  generation_ = generations;
  evaluations_ = evaluations;
  elapsed_before_ = elapsed_s;
  start_ = std::chrono::steady_clock::now();
  session_evals_ = 0;
  adopted_stop_ = stop_reason.empty() ? "adopted" : stop_reason;
}

std::string Search::stopReason() const {
  if (!adopted_stop_.empty()) return adopted_stop_;
  if (!initialized_) return stop_.load() ? "stopped" : "";
  if (stop_.load()) return "stopped";
  const auto& s = cfg_.search;
  if (s.generations > 0 && generation_ >= s.generations) return "generations";
  if (s.max_evaluations > 0 && evaluations_ >= s.max_evaluations) return "evaluations";
  if (s.wall_time_s > 0 && elapsed() >= s.wall_time_s) return "wall_time";
  return "";
}

bool Search::done() const {
  return !stopReason().empty();
}

void Search::run(const std::function<void(const SearchProgress&)>& on_progress) {
  auto last = std::chrono::steady_clock::now();
  if (!initialized_) {
    initialize();
    if (on_progress) on_progress(progress());
  }
  while (!done()) {
    step();
    const auto now = std::chrono::steady_clock::now();
    if (on_progress &&
        std::chrono::duration<double>(now - last).count() >= cfg_.output.progress_interval_s) {
      on_progress(progress());
      last = now;
    }
  }
  if (on_progress) on_progress(progress());
}

void Search::setCostMeasure(CostMeasure measure, CostModel predictor, double slack) {
  measure_ = std::move(measure);
  measure_predictor_ = std::move(predictor);
  measure_predictor_.domain = domain_;
  measure_slack_ = slack;
}

bool Search::archiveInsert(const Program& p, const Objectives& o, bool refined,
                           Objectives* stored) {
  // Only what the archive would take is checked on every row (the sampled rows already passed).
  if (!o.finite()) return false;
  if (stored) *stored = o;
  if (!measure_)
    return !archive_.rejects(o) && fidelityOnEveryRow(p) && archive_.insert(p, o, refined);
  Scorer& s = scorer(0);
  const Program fp = finalProgram(s, p);
  Objectives m = o;
  m.cost =
      std::max(0.0, measure_predictor_.programCost(fp) +
                        measure_predictor_.transformCost(err_cfg_.transforms) - measure_slack_);
  if (archive_.rejects(m) || !fidelityOnEveryRow(p)) return false;
  const auto t0 = std::chrono::steady_clock::now();
  const auto c = measure_(fp);
  measure_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ++measurements_;
  m.cost = c ? *c : o.cost;
  if (stored) *stored = m;
  return archive_.insert(p, m, refined);
}

std::vector<int> Search::offspringPerIsland(const std::vector<uint8_t>& restart) const {
  const int count = static_cast<int>(islands_.size());
  std::vector<int> out(count), sizes;
  std::vector<double> credit;
  // A restarting island's offspring are its whole new population: it breeds its size, and
  // the others share the rest.
  for (int k = 0; k < count; ++k) {
    out[k] = islandSize(island_first_ + k);
    if (!restart.empty() && restart[k]) continue;
    sizes.push_back(out[k]);
    credit.push_back(islands_[k].credit);
  }
  const std::vector<int> dealt = offspringCounts(sizes, credit, cfg_.search.islands.adaptive);
  for (int k = 0, j = 0; k < count; ++k)
    if (restart.empty() || !restart[k]) out[k] = dealt[static_cast<size_t>(j++)];
  return out;
}

RefineStats Search::refineStats() const {
  RefineStats r;
  r.lm_fits = lm_fits_.load();
  r.lm_accepted = lm_accepted_.load();
  r.lm_converged = lm_converged_.load();
  r.lm_evaluations = lm_evaluations_.load();
  r.nm_runs = nm_runs_.load();
  r.nm_evaluations = nm_evaluations_.load();
  r.cache_score_hits = cache_score_hits_;
  r.cache_lm_replays = cache_lm_replays_.load();
  for (const auto& s : scorers_)
    if (s) r.fidelity_rejects += s->fidelityRejects();
  r.fidelity_archive_rejects = fidelity_archive_rejects_;
  return r;
}

SearchProgress Search::progress() const {
  SearchProgress p;
  p.generation = generation_;
  p.evaluations = evaluations_;
  p.elapsed_s = elapsed();
  const double session = p.elapsed_s - elapsed_before_;
  p.evals_per_s = session > 0 ? static_cast<double>(session_evals_) / session : 0;
  summarizeArchive(p, archive_.members(), cfg_.output.progress_cost_levels);
  p.stop_reason = stopReason();
  p.finished = !p.stop_reason.empty();
  p.islands = std::max<int>(1, static_cast<int>(islands_.size()));
  p.migrants = migrants_before_ + (transport_ ? transport_->sent() : 0);
  p.remote_migrants = remote_migrants_before_ + (transport_ ? transport_->sentRemote() : 0);
  p.restarts = restarts_;
  if (initialized_ && !islands_.empty()) p.island_offspring = offspringPerIsland();
  p.ranks = ranks_;
  p.threads = threads_;
  p.cost_measurements = measurements_;
  p.cost_measure_s = measure_s_;
  return p;
}

Expected<Program> fitToShape(const Program& p, const ProgramShape& shape) {
  Program q = pruneIntrons(p);
  const int have = static_cast<int>(q.outputs.size());
  if (shape.genes > 1 && have * shape.genes == shape.num_outputs) {
    // An output layer of several genes per output: each output's opcode is repeated as its
    // other genes (the least-squares fit gives the copies no weight).
    const int genes = shape.genes;
    std::vector<uint8_t> outs;
    for (int o = 0; o < have; ++o) {
      outs.push_back(q.outputs[o]);
      for (int g = 1; g < genes; ++g) {
        if (q.code.size() >= 255) return Status::error("too long for the output layer's genes");
        q.code.push_back(q.code[q.outputs[o]]);
        outs.push_back(static_cast<uint8_t>(q.code.size() - 1));
      }
    }
    q.outputs = std::move(outs);
  }
  if (static_cast<int>(q.outputs.size()) != shape.num_outputs)
    return Status::error("has " + std::to_string(q.outputs.size()) + " outputs, the run has " +
                         std::to_string(shape.num_outputs));
  if (static_cast<int>(q.code.size()) > shape.max_length)
    return Status::error("needs " + std::to_string(q.code.size()) +
                         " opcodes; program.max_length is " + std::to_string(shape.max_length));
  if (static_cast<int>(q.constants.size()) > shape.num_constants)
    return Status::error("needs " + std::to_string(q.constants.size()) +
                         " constants; program.constants is " + std::to_string(shape.num_constants));
  for (const Instr& in : q.code)
    if (!shape.ops.contains(in.op))
      return Status::error("uses '" + std::string(opName(in.op)) +
                           "', which program.ops does not allow");
  q.constants.resize(shape.num_constants, 0.0f);
  if (shape.output_mode == OutputMode::Last) {
    // Outputs must be the last k opcodes, in order: move each output opcode to the end when
    // no other opcode reads it (introns are gone, so every opcode is read or an output).
    const int n = static_cast<int>(q.code.size());
    const int k = shape.num_outputs;
    std::vector<int> order;  // new position -> old index
    std::vector<uint8_t> is_out(n, 0);
    for (int o = 0; o < k; ++o) {
      if (is_out[q.outputs[o]])
        return Status::error(
            "two outputs are the same opcode; output_mode \"last\" needs "
            "distinct ones (use \"designated\")");
      is_out[q.outputs[o]] = 1;
    }
    for (int i = 0; i < n; ++i)
      if (!is_out[i]) order.push_back(i);
    for (int o = 0; o < k; ++o) order.push_back(q.outputs[o]);
    std::vector<int> pos(n);
    for (int i = 0; i < n; ++i) pos[order[i]] = i;
    Program r = q;
    for (int i = 0; i < n; ++i) {
      Instr in = q.code[order[i]];
      for (int a = 0; a < arity(in.op); ++a)
        if (in.args[a].kind == OperandKind::Reg) {
          if (pos[in.args[a].index] >= i)
            return Status::error(
                "an output is read by a later opcode; output_mode \"last\" "
                "cannot hold it (use \"designated\")");
          in.args[a].index = static_cast<uint8_t>(pos[in.args[a].index]);
        }
      r.code[i] = in;
    }
    for (int o = 0; o < k; ++o) r.outputs[o] = static_cast<uint8_t>(n - k + o);
    q = std::move(r);
  }
  if (Status st = validate(q, shape); !st) return st;
  return q;
}

nlohmann::json Search::checkpoint() const {
  return checkpointToJson(*this);
}

Status Search::restore(const nlohmann::json& state, bool take_counters) {
  return restoreFromCheckpoint(*this, state, take_counters);
}

}  // namespace lgp
