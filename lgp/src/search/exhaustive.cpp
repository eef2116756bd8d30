#include "lgp/search/exhaustive.hpp"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <unordered_map>
#include <unordered_set>

#include "lgp/core/formula.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/eval/cost_model.hpp"
#include "lgp/eval/discontinuity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/search/levenberg_marquardt.hpp"
#include "lgp/search/pareto.hpp"

namespace lgp {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Expressions built per operator count before the enumeration stops growing (memory: each
// keeps its canonical text).
constexpr size_t kMaxPerLevel = size_t{1} << 21;

// A node of an expression tree: an input, a free constant, or an operator over earlier nodes.
struct Node {
  int input = -1;  // >= 0: input column
  bool constant = false;
  Op op = Op::Add;
  std::array<int, kMaxArity> kids{-1, -1, -1, -1};
  int ops = 0;        // operators in the tree
  int constants = 0;  // free-constant leaves in the tree
  std::string canon;  // canonical text
};

bool commutative(Op op) {
  return op == Op::Add || op == Op::Mul || op == Op::Min || op == Op::Max;
}

class Enumerator {
 public:
  Enumerator(int inputs, std::vector<Op> ops, int max_constants)
      : ops_(std::move(ops)), max_constants_(max_constants) {
    levels_.emplace_back();
    for (int i = 0; i < inputs; ++i) {
      Node n;
      n.input = i;
      n.canon = "x" + std::to_string(i);
      levels_[0].push_back(add(std::move(n)));
    }
    if (max_constants_ > 0) {
      Node n;
      n.constant = true;
      n.constants = 1;
      n.canon = "c";
      levels_[0].push_back(add(std::move(n)));
    }
  }

  // Builds every distinct tree with `s` operators; false when the level would exceed the cap
  // or the deadline passed first.
  bool grow(int s, std::chrono::steady_clock::time_point deadline) {
    std::vector<int> level;
    std::unordered_set<std::string> seen;
    bool capped = false;
    auto offer = [&](Op op, std::array<int, kMaxArity> kids, int arity) {
      if (capped) return;
      Node n;
      n.op = op;
      n.kids = kids;
      n.ops = 1;
      bool all_const = true;
      for (int a = 0; a < arity; ++a) {
        const Node& k = nodes_[kids[a]];
        n.ops += k.ops;
        n.constants += k.constants;
        all_const = all_const && k.constants > 0 && k.input < 0 && k.ops == 0;
      }
      if (all_const || n.constants > max_constants_) return;
      const Node& a = nodes_[kids[0]];
      if (arity >= 2) {
        const Node& b = nodes_[kids[1]];
        // One order of a commutative pair (mad's product too).
        if ((commutative(op) || op == Op::Mad) && b.canon < a.canon) return;
        // x - x, x / x, min(x, x), max(x, x): a constant or x itself (without free constants,
        // whose two copies are independent parameters).
        if ((op == Op::Sub || op == Op::Div || op == Op::Min || op == Op::Max) &&
            a.constants == 0 && a.canon == b.canon)
          return;
      }
      n.canon = std::string(opName(op)) + "(";
      for (int i = 0; i < arity; ++i) n.canon += (i ? "," : "") + nodes_[kids[i]].canon;
      n.canon += ")";
      if (!seen.insert(n.canon).second) return;
      if (level.size() >= kMaxPerLevel || ((++offers_ & 4095) == 0 && past(deadline))) {
        capped = true;
        return;
      }
      level.push_back(add(std::move(n)));
    };
    for (Op op : ops_) {
      const int ar = arity(op);
      if (ar == 1) {
        for (int a : levels_[s - 1]) offer(op, {a, -1, -1, -1}, 1);
      } else if (ar == 2) {
        for (int i = 0; i <= s - 1 && !capped; ++i)
          for (int a : levels_[i]) {
            for (int b : levels_[s - 1 - i]) offer(op, {a, b, -1, -1}, 2);
            if (capped || (++rows_ & 63) == 0 && past(deadline)) break;
          }
      } else if (ar == 3) {
        for (int i = 0; i <= s - 1 && !capped; ++i)
          for (int j = 0; i + j <= s - 1 && !capped; ++j)
            for (int a : levels_[i]) {
              for (int b : levels_[j]) {
                for (int c : levels_[s - 1 - i - j]) offer(op, {a, b, c, -1}, 3);
                if (capped) break;
              }
              if (capped || (++rows_ & 63) == 0 && past(deadline)) break;
            }
      }
      // select (arity 4) is left out: piecewise, and four operands multiply the count.
      if (capped || past(deadline)) return false;
    }
    if (capped) return false;
    levels_.push_back(std::move(level));
    return true;
  }

  const std::vector<int>& level(int s) const { return levels_[s]; }

  // The tree as a one-output program: post-order, sub-trees without free constants shared
  // (common-subexpression elimination), each free constant its own slot.
  Program program(int root, int num_constants) const {
    Program p;
    p.constants.assign(std::max(num_constants, nodes_[root].constants), 1.0f);
    std::unordered_map<std::string, int> shared;
    int next_const = 0;
    std::function<Operand(int)> emit = [&](int id) -> Operand {
      const Node& n = nodes_[id];
      if (n.input >= 0) return inputOperand(n.input);
      if (n.constant) return constOperand(next_const++);
      if (n.constants == 0)
        if (auto it = shared.find(n.canon); it != shared.end()) return regOperand(it->second);
      Instr ins;
      ins.op = n.op;
      for (int a = 0; a < arity(n.op); ++a) ins.args[a] = emit(n.kids[a]);
      p.code.push_back(ins);
      const int reg = static_cast<int>(p.code.size()) - 1;
      if (n.constants == 0) shared.emplace(n.canon, reg);
      return regOperand(reg);
    };
    emit(root);
    p.outputs = {static_cast<uint8_t>(p.code.size() - 1)};
    return p;
  }

 private:
  int add(Node n) {
    nodes_.push_back(std::move(n));
    return static_cast<int>(nodes_.size()) - 1;
  }
  static bool past(std::chrono::steady_clock::time_point t) {
    return std::chrono::steady_clock::now() > t;
  }
  std::vector<Op> ops_;
  int max_constants_;
  uint64_t offers_ = 0, rows_ = 0;
  std::vector<Node> nodes_;
  std::vector<std::vector<int>> levels_;
};

// The rows the screening fit uses: every stride-th row.
Table subsetRows(const Table& t, size_t rows) {
  if (rows == 0 || rows >= t.rows()) return t;
  Table s;
  s.input_names = t.input_names;
  s.output_names = t.output_names;
  s.meta = t.meta;
  const double stride = static_cast<double>(t.rows()) / static_cast<double>(rows);
  s.inputs.assign(t.numInputs(), {});
  s.outputs.assign(t.numOutputs(), {});
  for (size_t k = 0; k < rows; ++k) {
    const size_t r = static_cast<size_t>(static_cast<double>(k) * stride);
    for (size_t i = 0; i < t.numInputs(); ++i) s.inputs[i].push_back(t.inputs[i][r]);
    for (size_t o = 0; o < t.numOutputs(); ++o) s.outputs[o].push_back(t.outputs[o][r]);
    if (!t.weights.empty()) s.weights.push_back(t.weights[r]);
  }
  return s;
}

// Per thread: a scorer and a constant fitter on one dataset.
struct Fitters {
  Fitters(const Dataset& ds, const ErrorConfig& e, int block, int threads) {
    for (int i = 0; i < threads; ++i) {
      scorers.push_back(std::make_unique<Scorer>(ds, e, block));
      fitters.push_back(std::make_unique<ConstantFitter>(ds, e));
    }
  }
  // The run's error after fitting p's constants from +1 and (both_signs) from -1, the better
  // one kept in p; without constants, the error as is.
  double fit(int thread, Program& p, int lm_iterations, bool both_signs = true) {
    Scorer& s = *scorers[thread];
    if (effectiveConstants(p).empty()) {
      const double e = s.error(p);
      return std::isfinite(e) ? e : kInf;
    }
    LevenbergMarquardtConfig lm;
    lm.max_iterations = lm_iterations;
    double best = kInf;
    Program best_p = p;
    for (float start : {1.0f, -1.0f}) {
      if (start < 0 && !both_signs) break;
      Program w = p;
      std::fill(w.constants.begin(), w.constants.end(), start);
      fitters[thread]->fit(w, lm);
      const double e = s.error(w);
      if (std::isfinite(e) && e < best) {
        best = e;
        best_p = std::move(w);
      }
    }
    p = std::move(best_p);
    return best;
  }
  std::vector<std::unique_ptr<Scorer>> scorers;
  std::vector<std::unique_ptr<ConstantFitter>> fitters;
};

// The operators enumerated: search.exhaustive.ops, else the program's, else the default set;
// select (four operands) left out.
std::vector<Op> enumeratedOps(const RunConfig& cfg) {
  const auto& x = cfg.search.exhaustive;
  std::vector<Op> ops = x.ops.empty() ? cfg.program.ops : x.ops;
  if (ops.empty()) ops = defaultOps();
  ops.erase(std::remove_if(ops.begin(), ops.end(), [](Op op) { return arity(op) > 3; }), ops.end());
  return ops;
}

}  // namespace

nlohmann::json ExhaustiveResult::toJson(const RunConfig& cfg, const Table& t) const {
  const auto& x = cfg.search.exhaustive;
  nlohmann::json ops = nlohmann::json::array();
  for (Op op : enumeratedOps(cfg)) ops.push_back(std::string(opName(op)));
  nlohmann::json best = nlohmann::json::array();
  for (size_t k = 1; k < best_by_ops.size(); ++k) {
    const auto& m = best_by_ops[k];
    best.push_back({{"max_ops", k},
                    {"enumerated", k < enumerated.size() ? enumerated[k] : 0},
                    {"complete", static_cast<int>(k) <= complete_ops},
                    {"error", std::isfinite(m.obj.error) ? nlohmann::json(m.obj.error)
                                                         : nlohmann::json(nullptr)},
                    {"cost", m.obj.cost},
                    {"formula", m.formula}});
  }
  return {{"grammar",
           {{"ops", ops},
            {"inputs", t.input_names},
            {"free_constants", x.constants},
            {"max_ops", x.max_ops}}},
          {"complete_ops", complete_ops},
          {"fitted", fitted},
          {"seconds", seconds},
          {"constant_fit", "Levenberg-Marquardt from +1 on " + std::to_string(x.screen_rows) +
                               " rows (8 iterations), the best " + std::to_string(x.keep) +
                               " per operator count refitted from those constants, +1 and -1 on "
                               "every row (local: a better constant may "
                               "exist)"},
          {"best", best}};
}

Expected<ExhaustiveResult> exhaustiveSearch(const RunConfig& cfg, const Table& t) {
  const auto& x = cfg.search.exhaustive;
  if (x.max_ops <= 0) return Status::error("/search/exhaustive/max_ops: enumeration is off");
  if (t.numOutputs() != 1)
    return Status::error("/search/exhaustive: one output only (this table has " +
                         std::to_string(t.numOutputs()) + ")");
  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  const std::vector<Op> ops = enumeratedOps(cfg);
  const auto deadline = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                 std::chrono::duration<double>(x.seconds));

  ErrorConfig err = cfg.errorConfig(t.output_names);
  err.linear_scaling = cfg.search.linear_scaling;
  const int block = cfg.eval.block_size;
  const Table screen_t = subsetRows(t, static_cast<size_t>(x.screen_rows));
  const Dataset screen_ds(screen_t, block), full_ds(t, block);
  const int threads = cfg.search.threads > 0 ? cfg.search.threads : omp_get_max_threads();
  Fitters screen(screen_ds, err, block, threads), full(full_ds, err, block, threads);
  CostModel cost = cfg.costModel();
  DiscontinuityModel disc = cfg.discontinuityModel();
  const auto domain = tableDomain(t);
  cost.domain = domain;
  disc.domain = domain;
  const double transform_cost = cost.transformCost(err.transforms);
  const int num_constants = std::max(cfg.program.num_constants, x.constants);

  ExhaustiveResult res;
  res.enumerated.push_back(0);
  ExhaustiveMember none;
  res.best_by_ops.push_back(none);
  std::vector<ExhaustiveMember> all;
  Enumerator en(static_cast<int>(t.numInputs()), ops, x.constants);
  for (int s = 1; s <= x.max_ops; ++s) {
    if (seconds() > x.seconds || !en.grow(s, deadline)) break;
    const auto& level = en.level(s);
    res.enumerated.push_back(level.size());
    // Screening: every expression of this size, on the row subset.
    std::vector<double> screen_err(level.size(), kInf);
    std::vector<Program> progs(level.size());
    std::atomic<bool> out_of_time{false};
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads)
    for (size_t i = 0; i < level.size(); ++i) {
      if (out_of_time.load(std::memory_order_relaxed)) continue;
      if ((i & 255) == 0 && seconds() > x.seconds) out_of_time = true;
      progs[i] = en.program(level[i], num_constants);
      // One start, few iterations: a ranking, not the answer (the kept ones are refitted).
      screen_err[i] = screen.fit(omp_get_thread_num(), progs[i], 8, false);
    }
    if (out_of_time) break;
    // The best `keep` go on to the whole table.
    std::vector<size_t> order(level.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    const size_t keep = std::min(order.size(), static_cast<size_t>(x.keep));
    std::partial_sort(order.begin(), order.begin() + static_cast<long>(keep), order.end(),
                      [&](size_t a, size_t b) { return screen_err[a] < screen_err[b]; });
    std::vector<ExhaustiveMember> fitted(keep);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (size_t j = 0; j < keep; ++j) {
      const int th = omp_get_thread_num();
      ExhaustiveMember& m = fitted[j];
      m.program = progs[order[j]];
      m.ops = s;
      // From the screened constants first, then as on the subset.
      Program from_screen = m.program;
      LevenbergMarquardtConfig lm;
      lm.max_iterations = 30;
      if (!effectiveConstants(from_screen).empty()) full.fitters[th]->fit(from_screen, lm);
      Scorer& sc = *full.scorers[th];
      double e = sc.error(from_screen);
      Program other = m.program;
      const double e2 = full.fit(th, other, 30);
      if (!(e <= e2)) {
        from_screen = std::move(other);
        e = e2;
      }
      m.program = std::move(from_screen);
      m.obj.error = sc.error(m.program);
      if (!std::isfinite(m.obj.error)) m.obj.error = kInf;
      const Program exported =
          err.linear_scaling ? applyLinearScaling(m.program, sc.scales()) : m.program;
      m.obj.cost = cost.programCost(exported) + transform_cost;
      m.obj.discontinuity = disc.programDiscontinuity(m.program, sc.bound().effective);
      m.formula = programFormula(exported, t.input_names, t.output_names, domain);
    }
    res.fitted += keep;
    ExhaustiveMember best = res.best_by_ops.back();
    for (auto& m : fitted) {
      if (m.obj.error < best.obj.error) best = m;
      if (m.obj.finite()) all.push_back(std::move(m));
    }
    res.best_by_ops.push_back(best);
    res.complete_ops = s;
  }
  // The non-dominated ones (sorted by cost, then error).
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.obj.cost != b.obj.cost ? a.obj.cost < b.obj.cost : a.obj.error < b.obj.error;
  });
  for (const auto& m : all) {
    bool dominated = false;
    for (const auto& f : res.front)
      if (f.obj.cost <= m.obj.cost && f.obj.error <= m.obj.error &&
          f.obj.discontinuity <= m.obj.discontinuity) {
        dominated = true;
        break;
      }
    if (!dominated) res.front.push_back(m);
  }
  res.seconds = seconds();
  return res;
}

}  // namespace lgp
