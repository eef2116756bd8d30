#include "lgp/search/search.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

#include "lgp/core/variation.hpp"
#include "lgp/search/differential_evolution.hpp"
#include "lgp/search/nelder_mead.hpp"

namespace lgp {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

uint64_t fnv1a(const void* data, size_t n, uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

nlohmann::json objToJson(const Objectives& o) {
  // JSON has no infinity: a non-finite error is stored as null.
  return nlohmann::json::array(
      {o.finite() ? nlohmann::json(o.error) : nlohmann::json(nullptr), o.cost, o.discontinuity});
}

Expected<Objectives> objFromJson(const nlohmann::json& j) {
  if (!j.is_array() || j.size() != 3 || !j[1].is_number() || !j[2].is_number())
    return Status::error("bad objectives");
  Objectives o;
  o.error = j[0].is_number() ? j[0].get<double>() : kInf;
  o.cost = j[1].get<double>();
  o.discontinuity = j[2].get<double>();
  return o;
}
}  // namespace

Expected<Table> loadTableFile(const DataConfig& data, const std::filesystem::path& base_dir) {
  if (data.path.empty()) return Status::error("/data/path: no table file named");
  std::filesystem::path p = data.path;
  if (p.is_relative()) p = base_dir / p;
  auto raw = readTableFile(p);
  if (!raw) return raw.status();
  return selectColumns(*raw, data.inputs, data.outputs, data.weights, p.string());
}

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
  transform_cost_ = cost_.transformCost(err_cfg_.transforms);
  err_cfg_.linear_scaling = cfg_.search.linear_scaling;
  threads_ = cfg_.search.threads > 0 ? cfg_.search.threads : omp_get_max_threads();
  scorers_.resize(threads_);
  start_ = std::chrono::steady_clock::now();
}

Search::~Search() = default;

Scorer& Search::scorer(int thread) {
  auto& s = scorers_[thread];
  if (!s) s = std::make_unique<Scorer>(ds_, err_cfg_, cfg_.eval.block_size);
  return *s;
}

double Search::elapsed() const {
  return elapsed_before_ +
         std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

Objectives Search::score(Scorer& s, const Program& p) const {
  Objectives o;
  o.error = s.error(p);
  if (!std::isfinite(o.error)) o.error = kInf;
  const auto& effective = s.bound().effective;  // bound by error(p): computed once
  o.cost = cost_.programCost(p, effective) + transform_cost_;
  if (err_cfg_.linear_scaling) o.cost += scalingCost(cost_, s.scales());
  o.discontinuity = disc_.programDiscontinuity(p, effective);
  return o;
}

void Search::refineOne(Scorer& s, Individual& ind, uint64_t seed, uint64_t& evals,
                       bool full) const {
  const auto slots = effectiveConstants(ind.program);
  if (full) ind.refined = true;
  if (slots.empty() || !ind.obj.finite()) return;
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
  NelderMeadConfig nm = cfg_.search.refine.nm;
  if (!full) {
    nm.max_evaluations = cfg_.search.refine.offspring_evaluations;
    nm.restarts = 0;
  }
  std::vector<double> start = x0;
  if (full && cfg_.search.refine.method == RefineMethod::DeThenNm) {
    // A global step first: Nelder-Mead alone stalls in the nearest basin (seed 000 3.2.1).
    DifferentialEvolutionConfig de;
    de.max_evaluations = cfg_.search.refine.de_evaluations;
    const auto d = differentialEvolution(f, x0, de, rng);
    evals += static_cast<uint64_t>(d.evaluations);
    start = d.x;
  }
  const auto res = nelderMead(f, start, nm, rng);
  evals += static_cast<uint64_t>(res.evaluations);
  if (res.f < ind.obj.error) {
    for (size_t k = 0; k < slots.size(); ++k)
      ind.program.constants[slots[k]] = static_cast<float>(res.x[k]);
    const double e = s.error(ind.program);
    ++evals;
    if (std::isfinite(e) && e <= ind.obj.error)
      ind.obj.error = e;
    else
      for (size_t k = 0; k < slots.size(); ++k)
        ind.program.constants[slots[k]] = static_cast<float>(x0[k]);
  }
}

void Search::evaluateAll(std::vector<Individual>& inds, const std::vector<uint8_t>& refine,
                         uint64_t stream) {
  const int n = static_cast<int>(inds.size());
  uint64_t evals = 0;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 4) reduction(+ : evals)
  for (int i = 0; i < n; ++i) {
    Scorer& s = scorer(omp_get_thread_num());
    inds[i].obj = score(s, inds[i].program);
    ++evals;
    if (!refine.empty() && refine[i])
      refineOne(s, inds[i], hashSeed(cfg_.search.seed, stream, static_cast<uint64_t>(i), 3), evals,
                false);
  }
  evaluations_ += evals;
  session_evals_ += evals;
}

void Search::rankPopulation() {
  // Duplicated objective vectors rank after every distinct one: they add nothing to the front
  // and would otherwise crowd it out (the classic bloat of trivial programs).
  const int n = static_cast<int>(pop_.size());
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  auto err = [&](int i) { return pop_[i].obj.finite() ? pop_[i].obj.error : kInf; };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (err(a) != err(b)) return err(a) < err(b);
    if (pop_[a].obj.cost != pop_[b].obj.cost) return pop_[a].obj.cost < pop_[b].obj.cost;
    return pop_[a].obj.discontinuity < pop_[b].obj.discontinuity;
  });
  std::vector<uint8_t> is_dup(n, 0);
  for (int k = 1; k < n; ++k) {
    const int a = order[k - 1], b = order[k];
    is_dup[b] = err(a) == err(b) && pop_[a].obj.cost == pop_[b].obj.cost &&
                pop_[a].obj.discontinuity == pop_[b].obj.discontinuity;
  }
  std::vector<int> uniq, dup;
  for (int i = 0; i < n; ++i) (is_dup[i] ? dup : uniq).push_back(i);
  std::vector<Objectives> objs;
  for (int i : uniq) objs.push_back(pop_[i].obj);
  const auto r = nondominatedRanks(objs);
  rank_.assign(n, 0);
  crowd_.assign(n, 0.0);
  int max_rank = 0;
  for (size_t k = 0; k < uniq.size(); ++k) {
    rank_[uniq[k]] = r[k];
    max_rank = std::max(max_rank, r[k]);
  }
  for (int i : dup) rank_[i] = max_rank + 1;
  std::vector<Objectives> all;
  for (const auto& ind : pop_) all.push_back(ind.obj);
  std::vector<std::vector<int>> fronts(max_rank + 2);
  for (int i = 0; i < n; ++i) fronts[rank_[i]].push_back(i);
  for (const auto& members : fronts) {
    if (members.empty()) continue;
    const auto d = crowdingDistance(all, members);
    for (size_t k = 0; k < members.size(); ++k) crowd_[members[k]] = d[k];
  }
}

void Search::survive(std::vector<Individual>& pool) {
  pop_ = std::move(pool);
  rankPopulation();
  const int n = static_cast<int>(pop_.size());
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    if (rank_[a] != rank_[b]) return rank_[a] < rank_[b];
    return crowd_[a] > crowd_[b];
  });
  const int keep = std::min(n, cfg_.search.population);
  std::vector<Individual> next;
  next.reserve(keep);
  for (int k = 0; k < keep; ++k) next.push_back(std::move(pop_[order[k]]));
  pop_ = std::move(next);
  rankPopulation();
}

int Search::tournament(Rng& rng) const {
  const int n = static_cast<int>(pop_.size());
  const bool by_error = rng.chance(cfg_.search.error_bias);
  int best = static_cast<int>(rng.below(n));
  for (int t = 1; t < cfg_.search.tournament_size; ++t) {
    const int c = static_cast<int>(rng.below(n));
    if (by_error) {
      if (pop_[c].obj.error < pop_[best].obj.error) best = c;
    } else if (rank_[c] < rank_[best] || (rank_[c] == rank_[best] && crowd_[c] > crowd_[best])) {
      best = c;
    }
  }
  return best;
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
  const int n = cfg_.search.population;
  InitConfig init{cfg_.program.init_min_length, cfg_.program.init_max_length,
                  cfg_.program.const_min, cfg_.program.const_max};
  std::vector<Individual> inds(n);
  for (int i = 0; i < n; ++i) {
    Rng rng(hashSeed(cfg_.search.seed, 0, static_cast<uint64_t>(i), 1));
    inds[i].program = randomProgram(shape_, init, rng);
  }
  // Seeds take the first slots (at most half the population: the rest stays diverse).
  for (size_t k = 0; k < seeds_.size() && k < static_cast<size_t>(n / 2); ++k)
    inds[k].program = seeds_[k];
  evaluateAll(inds, {}, 0);
  for (const auto& ind : inds) archive_.insert(ind.program, ind.obj);
  survive(inds);
  generation_ = 0;
  initialized_ = true;
}

void Search::step() {
  if (!initialized_) {
    initialize();
    return;
  }
  if (done()) return;
  const int g = generation_ + 1;
  const int n = cfg_.search.population;
  const auto& var = cfg_.search.variation;
  std::vector<Individual> off(n);
#pragma omp parallel for num_threads(threads_) schedule(static)
  for (int i = 0; i < n; ++i) {
    Rng rng(hashSeed(cfg_.search.seed, static_cast<uint64_t>(g), static_cast<uint64_t>(i), 1));
    const int a = tournament(rng);
    Program child;
    if (rng.chance(var.crossover_rate)) {
      const int b = tournament(rng);
      child = crossover(pop_[a].program, pop_[b].program, shape_, rng);
    } else {
      child = pop_[a].program;
    }
    if (rng.chance(var.macro_rate)) macroMutate(child, shape_, rng);
    if (rng.chance(var.micro_rate)) {
      const int m = 1 + static_cast<int>(rng.below(var.micro_max));
      for (int k = 0; k < m; ++k)
        microMutate(child, shape_, rng, var.constant_sigma, var.effective_bias);
    }
    off[i].program = std::move(child);
  }
  std::vector<uint8_t> refine(n, 0);
  Rng pick(hashSeed(cfg_.search.seed, static_cast<uint64_t>(g), 0, 2));
  for (int i = 0; i < n; ++i) refine[i] = pick.chance(cfg_.search.refine.offspring_share);
  evaluateAll(off, refine, static_cast<uint64_t>(g));
  for (const auto& ind : off) archive_.insert(ind.program, ind.obj, ind.refined);

  std::vector<Individual> pool = std::move(pop_);
  pool.insert(pool.end(), std::make_move_iterator(off.begin()), std::make_move_iterator(off.end()));
  survive(pool);
  generation_ = g;
  if (cfg_.search.refine.archive_period > 0 && g % cfg_.search.refine.archive_period == 0)
    refineArchive();
}

void Search::refineArchive() {
  auto& members = archive_.mutableMembers();
  std::vector<int> todo;
  for (int i = 0; i < static_cast<int>(members.size()); ++i)
    if (!members[i].refined && static_cast<int>(todo.size()) < cfg_.search.refine.archive_max)
      todo.push_back(i);
  if (todo.empty()) return;
  std::vector<Individual> inds(todo.size());
  for (size_t k = 0; k < todo.size(); ++k) {
    inds[k].program = members[todo[k]].program;
    inds[k].obj = members[todo[k]].obj;
    members[todo[k]].refined = true;
  }
  const int n = static_cast<int>(inds.size());
  uint64_t evals = 0;
  const uint64_t stream = (static_cast<uint64_t>(generation_) << 20) | 0xA5A5u;
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1) reduction(+ : evals)
  for (int i = 0; i < n; ++i)
    refineOne(scorer(omp_get_thread_num()), inds[i],
              hashSeed(cfg_.search.seed, stream, static_cast<uint64_t>(i), 4), evals, true);
  evaluations_ += evals;
  session_evals_ += evals;
  for (const auto& ind : inds) archive_.insert(ind.program, ind.obj, true);
  // Refined members also rejoin the population so their constants propagate.
  std::vector<Individual> pool = std::move(pop_);
  for (auto& ind : inds) pool.push_back(std::move(ind));
  survive(pool);
}

void Search::adopt(const std::vector<Program>& programs, int generations, uint64_t evaluations,
                   double elapsed_s, const std::string& stop_reason) {
  std::vector<Individual> inds(programs.size());
  for (size_t i = 0; i < programs.size(); ++i) inds[i].program = programs[i];
  evaluateAll(inds, {}, 0);
  archive_ = Archive(cfg_.search.archive);
  for (const auto& ind : inds) archive_.insert(ind.program, ind.obj, true);
  pop_ = std::move(inds);
  rankPopulation();
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

SearchProgress Search::progress() const {
  SearchProgress p;
  p.generation = generation_;
  p.evaluations = evaluations_;
  p.elapsed_s = elapsed();
  const double session = p.elapsed_s - elapsed_before_;
  p.evals_per_s = session > 0 ? static_cast<double>(session_evals_) / session : 0;
  const auto& members = archive_.members();
  p.front_size = members.size();
  p.best_error = kInf;
  for (const auto& m : members) p.best_error = std::min(p.best_error, m.obj.error);
  std::vector<double> levels = cfg_.output.progress_cost_levels;
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
  p.stop_reason = stopReason();
  p.finished = !p.stop_reason.empty();
  return p;
}

std::vector<FrontEntry> Search::front() const {
  const auto members = archive_.sorted();
  std::vector<FrontEntry> out(members.size());
  std::array<CostModel, kNumCostTargets> models;
  for (int t = 0; t < kNumCostTargets; ++t)
    models[t] = CostModel::preset(static_cast<CostTarget>(t));
  const int n = static_cast<int>(members.size());
#pragma omp parallel for num_threads(threads_) schedule(dynamic, 1)
  for (int i = 0; i < n; ++i) {
    FrontEntry& e = out[i];
    Scorer s(ds_, err_cfg_, cfg_.eval.block_size);
    e.program = finalProgram(s, members[i].program);
    e.obj = members[i].obj;
    e.metrics = s.metrics(e.program);
    e.metrics_ref = referenceMetrics(e.program, table_, err_cfg_);
    if (!err_cfg_.channels.empty()) {
      e.channel_metrics = s.channelMetrics(e.program);
      e.channel_metrics_ref = referenceChannelMetrics(e.program, table_, err_cfg_);
    }
    for (int t = 0; t < kNumCostTargets; ++t)
      e.cost_by_target[t] =
          models[t].programCost(e.program) + models[t].transformCost(err_cfg_.transforms);
    e.infix = toInfix(e.program, table_.input_names);
  }
  return out;
}

Program Search::finalProgram(Scorer& s, const Program& p) const {
  Program body = pruneIntrons(p);
  if (!err_cfg_.linear_scaling) return body;
  s.error(body);  // fits the scales, exactly as when the member was scored
  return applyLinearScaling(body, s.scales());
}

Expected<Program> fitToShape(const Program& p, const ProgramShape& shape) {
  Program q = pruneIntrons(p);
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

std::string Search::configDigest() const {
  nlohmann::json c = toJson(cfg_);
  c.erase("output");  // where results go does not change the search
  c["search"].erase("threads");
  c["search"].erase("generations");  // budgets may be extended on resume
  c["search"].erase("max_evaluations");
  c["search"].erase("wall_time_s");
  const std::string s = c.dump();
  uint64_t h = fnv1a(s.data(), s.size());
  for (const auto& col : table_.inputs) h = fnv1a(col.data(), col.size() * sizeof(double), h);
  for (const auto& col : table_.outputs) h = fnv1a(col.data(), col.size() * sizeof(double), h);
  h = fnv1a(table_.weights.data(), table_.weights.size() * sizeof(double), h);
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

nlohmann::json Search::checkpoint() const {
  nlohmann::json pop = nlohmann::json::array();
  for (const auto& ind : pop_)
    pop.push_back(
        {{"program", toJson(ind.program)}, {"obj", objToJson(ind.obj)}, {"refined", ind.refined}});
  nlohmann::json arch = nlohmann::json::array();
  for (const auto& m : archive_.members())
    arch.push_back(
        {{"program", toJson(m.program)}, {"obj", objToJson(m.obj)}, {"refined", m.refined}});
  return {{"format", "lgp-checkpoint/1"},
          {"config_digest", configDigest()},
          {"initialized", initialized_},
          {"generation", generation_},
          {"evaluations", evaluations_},
          {"elapsed_s", elapsed()},
          {"population", pop},
          {"archive", arch}};
}

Status Search::restore(const nlohmann::json& st) {
  try {
    if (st.value("format", "") != "lgp-checkpoint/1")
      return Status::error("checkpoint: unknown format");
    if (st.at("config_digest").get<std::string>() != configDigest())
      return Status::error("checkpoint: made with a different config or table");
    std::vector<Individual> pop;
    for (const auto& j : st.at("population")) {
      auto p = programFromJson(j.at("program"), shape_);
      if (!p) return Status::error("checkpoint: population: " + p.error());
      auto o = objFromJson(j.at("obj"));
      if (!o) return Status::error("checkpoint: population: " + o.error());
      pop.push_back({*p, *o, j.value("refined", false)});
    }
    Archive arch(cfg_.search.archive);
    auto& members = arch.mutableMembers();
    for (const auto& j : st.at("archive")) {
      auto p = programFromJson(j.at("program"), shape_);
      if (!p) return Status::error("checkpoint: archive: " + p.error());
      auto o = objFromJson(j.at("obj"));
      if (!o) return Status::error("checkpoint: archive: " + o.error());
      members.push_back({*p, *o, j.value("refined", false)});
    }
    pop_ = std::move(pop);
    archive_ = std::move(arch);
    initialized_ = st.at("initialized").get<bool>();
    generation_ = st.at("generation").get<int>();
    evaluations_ = st.at("evaluations").get<uint64_t>();
    elapsed_before_ = st.at("elapsed_s").get<double>();
    start_ = std::chrono::steady_clock::now();
    session_evals_ = 0;
    if (!pop_.empty()) rankPopulation();
  } catch (const nlohmann::json::exception& e) {
    return Status::error(std::string("checkpoint: ") + e.what());
  }
  return Status::ok();
}

}  // namespace lgp
