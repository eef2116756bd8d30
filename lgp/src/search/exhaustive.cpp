#include "lgp/search/exhaustive.hpp"

#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <memory>
#include <new>
#include <unordered_map>
#include <unordered_set>

#include "lgp/core/formula.hpp"
#include "lgp/core/interval.hpp"
#include "lgp/core/rng.hpp"
#include "lgp/eval/cost_model.hpp"
#include "lgp/eval/discontinuity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/semantics.hpp"
#include "lgp/search/levenberg_marquardt.hpp"
#include "lgp/search/pareto.hpp"

namespace lgp {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Expressions kept per operator count before the enumeration stops growing. Memory: a size
// whose trees become operands keeps each one's probe values (48 doubles, 6 GiB at the cap);
// the largest size keeps only its nodes and fingerprints (about 100 bytes each).
constexpr size_t kMaxPerOperandLevel = size_t{1} << 24;
constexpr size_t kMaxPerLastLevel = size_t{1} << 26;
// Probe points: the corners of the table's box, some of its rows and random points in the box.
constexpr int kProbeRows = 8;
constexpr int kProbeRandom = 12;
// Draws of the free constants' values: an identity that holds at both draws (and every probe
// point) is taken to hold for every value, so the expression adds no new function.
constexpr int kDraws = 2;
// Candidates whose probe values are computed together (in parallel) before they are inserted
// in order, so that the result does not depend on the thread count.
constexpr size_t kBatch = 8192;
// Memory accounting (Enumerator::fits): a fingerprint in a hash set is a heap node (the key,
// the next pointer, the cached hash, the allocator's header); a tree to fit costs the
// screening its error and its place in the ranking.
constexpr size_t kSetNodeBytes = 48;
constexpr size_t kScreenBytesPerFit = sizeof(double) + sizeof(size_t);

// 128-bit fingerprint of an expression's values at the probe points.
struct Key {
  uint64_t a = 0, b = 0;
  bool operator==(const Key& o) const { return a == o.a && b == o.b; }
};
struct KeyHash {
  size_t operator()(const Key& k) const { return k.a ^ (k.b * 0x9E3779B97F4A7C15ull); }
};

struct KeyBuilder {
  uint64_t a = 0x243F6A8885A308D3ull, b = 0x13198A2E03707344ull;
  void add(uint64_t q) {
    a = (a ^ q) * 0x100000001B3ull;
    a ^= a >> 29;
    b = (b + q + 0x9E3779B97F4A7C15ull) * 0xBF58476D1CE4E5B9ull;
    b ^= b >> 31;
  }
  Key key() const { return {a, b}; }
};

// A value rounded to about 30 significant bits, so that two evaluation orders of one function
// (a + b) + c and a + (b + c) agree; non-finite values and near-zeros get their own codes.
uint64_t quantize(double v) {
  if (std::isnan(v)) return 1;
  if (std::isinf(v)) return v > 0 ? 2 : 3;
  if (std::fabs(v) < 1e-12) return 0;
  int e = 0;
  const double m = std::frexp(v, &e);
  auto q = static_cast<int64_t>(std::llround(m * 0x1.0p30));
  if (q == (int64_t{1} << 30) || q == -(int64_t{1} << 30)) {
    q /= 2;
    ++e;
  }
  return (static_cast<uint64_t>(static_cast<uint32_t>(e)) << 32) ^
         static_cast<uint64_t>(static_cast<uint32_t>(q)) ^ 0xA5A5000000000000ull;
}

// A node of an expression tree: an input, a free constant, or an operator over earlier nodes.
struct Node {
  int8_t input = -1;  // >= 0: input column
  bool constant = false;
  Op op = Op::Add;
  uint8_t ops = 0;        // operators in the tree
  uint8_t constants = 0;  // free-constant leaves in the tree
  // A kink whose place depends on a free constant lies outside the box at every draw (see
  // branch()): the tree is never merged with another.
  bool fragile = false;
  std::array<int32_t, 3> kids{-1, -1, -1};
};

// Which side of its kink a piecewise operator, or a protected one whose guard changes the
// function over a range of operands (sqrt, rsqrt, log, log2 and pow below zero), takes; -1 for
// an operator without such a kink (the exp clamp at 2^126 and the division guard at 1e-20
// are never reached by a fit).
int branch(Op op, double a, double b) {
  switch (opInfo(op).kink) {
    case OpKink::Less:
      return a < b;
    case OpKink::Greater:
      return a > b;
    case OpKink::Sign:
      return a < 0;
    case OpKink::Unit:
      return a <= 0 ? 0 : (a < 1 ? 1 : 2);
    case OpKink::Compare:  // never enumerated (four operands; see the operator list below)
      return -1;
    case OpKink::None:
      break;
  }
  switch (opInfo(op).guard) {
    case OpGuard::Root:
      return a > 0;
    case OpGuard::Floor:
    case OpGuard::PowClamp:
      return a > static_cast<double>(kMinPos);
    case OpGuard::None:
    case OpGuard::Divisor:
    case OpGuard::Clamp:
    case OpGuard::ScaledClamp:
    case OpGuard::NanToZero:
    case OpGuard::NanOrder:
      return -1;
  }
  return -1;
}

bool commutative(Op op) {
  return opInfo(op).commutative;
}

// The enumeration, de-duplicated by value: every tree is evaluated (double, the interpreter's
// protected semantics) at fixed probe points, with each free constant at fixed values in
// kDraws draws, and a tree whose values equal an earlier tree's is the same function of its
// inputs and constants: it is dropped, the earlier one (of no more operators) stands for it as
// an operand too. With linear scaling, trees that are affine images of an earlier one at every
// draw (f and a f + b: the same error after scaling) are kept as operands but not fitted again.
class Enumerator {
 public:
  Enumerator(const Table& t, std::vector<Op> ops, int max_constants, bool affine_roots, int threads,
             size_t memory_bytes)
      : ops_(std::move(ops)),
        max_constants_(max_constants),
        affine_roots_(affine_roots),
        threads_(threads),
        memory_bytes_(memory_bytes) {
    const int inputs = static_cast<int>(t.numInputs());
    const auto domain = tableDomain(t);
    // Probe points: corners, rows spread over the table, random points of the box.
    std::vector<std::vector<double>> pts;
    for (int c = 0; c < (1 << std::min(inputs, 4)); ++c) {
      std::vector<double> p(inputs);
      for (int i = 0; i < inputs; ++i) p[i] = (i < 4 && (c >> i & 1)) ? domain[i].hi : domain[i].lo;
      pts.push_back(p);
    }
    for (int k = 0; k < kProbeRows && t.rows() > 0; ++k) {
      const size_t r = (t.rows() - 1) * static_cast<size_t>(2 * k + 1) / (2 * kProbeRows);
      std::vector<double> p(inputs);
      for (int i = 0; i < inputs; ++i) p[i] = t.inputs[i][r];
      pts.push_back(p);
    }
    Rng rng(0x5EED0F0E5A11ull);
    for (int k = 0; k < kProbeRandom; ++k) {
      std::vector<double> p(inputs);
      for (int i = 0; i < inputs; ++i)
        p[i] = domain[i].finite() ? rng.uniform(domain[i].lo, domain[i].hi) : rng.uniform(-1, 1);
      pts.push_back(p);
    }
    points_ = static_cast<int>(pts.size());
    width_ = points_ * kDraws;
    // Constant values: one draw of moderate magnitudes, one over a wider range, random signs.
    const int nc = std::max(max_constants_, 1);
    cvals_.assign(static_cast<size_t>(kDraws) * nc, 0.0);
    for (int d = 0; d < kDraws; ++d)
      for (int j = 0; j < nc; ++j) {
        const double mag = d == 0 ? rng.uniform(0.3, 1.7) : std::exp2(rng.uniform(-4, 4));
        cvals_[d * nc + j] = rng.chance(0.5) ? mag : -mag;
      }
    levels_.emplace_back();
    for (int i = 0; i < inputs; ++i) {
      Node n;
      n.input = static_cast<int8_t>(i);
      std::vector<double> v(width_);
      for (int d = 0; d < kDraws; ++d)
        for (int p = 0; p < points_; ++p) v[d * points_ + p] = pts[p][i];
      levels_[0].push_back(add(n, v.data()));
      exact_.insert(keyOf(v.data()));
    }
    if (max_constants_ > 0) {
      Node n;
      n.constant = true;
      n.constants = 1;
      std::vector<double> v(width_);
      evaluate(n, 0, v.data());
      levels_[0].push_back(add(n, v.data()));
    }
    fit_.emplace_back();
  }

  // Builds every distinct tree with `s` operators; false when the level would exceed the cap
  // or the memory bound, or the deadline passed first.
  // `operand`: the trees may become operands of larger ones (their values are kept).
  bool grow(int s, bool operand, std::chrono::steady_clock::time_point deadline) {
    std::vector<int> level;
    std::vector<int> fit;
    std::vector<Node> batch;
    bool capped = false;
    auto flush = [&] {
      std::vector<double> vals(batch.size() * width_);
      std::vector<Key> keys(batch.size());
#pragma omp parallel for schedule(static) num_threads(threads_)
      for (size_t i = 0; i < batch.size(); ++i) {
        evaluate(batch[i], 0, &vals[i * width_], &batch[i].fragile);
        keys[i] = keyOf(&vals[i * width_]);
      }
      for (size_t i = 0; i < batch.size() && !capped; ++i) {
        const double* v = &vals[i * width_];
        if (!batch[i].fragile) {
          if (!exact_.insert(keys[i]).second) continue;
          // A function of the constants alone: a free constant does as well (not when the
          // tree has none, as x / x: replacing it would add a constant).
          if (batch[i].constants > 0 && constantOverPoints(v)) continue;
        }
        if (level.size() >= (operand ? kMaxPerOperandLevel : kMaxPerLastLevel)) {
          capped = true;
          size_capped_ = true;
          break;
        }
        if (!fits(operand, level, fit)) {
          capped = true;
          memory_capped_ = true;
          break;
        }
        level.push_back(add(batch[i], operand ? v : nullptr));
        // The first of its function (with linear scaling, up to an affine map) is fitted.
        if (batch[i].fragile || roots_.insert(affine_roots_ ? affineKeyOf(v) : keyOf(v)).second)
          fit.push_back(level.back());
      }
      batch.clear();
      if (past(deadline)) capped = true;
    };
    auto offer = [&](Op op, std::array<int32_t, 3> kids, int ar) {
      Node n;
      n.op = op;
      n.kids = kids;
      n.ops = 1;
      bool all_const = true;
      for (int a = 0; a < ar; ++a) {
        const Node& k = nodes_[kids[a]];
        n.ops = static_cast<uint8_t>(n.ops + k.ops);
        n.constants = static_cast<uint8_t>(n.constants + k.constants);
        all_const = all_const && k.constant;
      }
      if (all_const || n.constants > max_constants_) return;
      if (ar >= 2) {
        // One order of a commutative pair (mad's product too): ids order the trees.
        if ((commutative(op) || op == Op::Mad) && kids[1] < kids[0]) return;
        // x - x, x / x, min(x, x), max(x, x): a constant or x itself (without free constants,
        // whose two copies are independent parameters).
        if ((op == Op::Sub || op == Op::Div || op == Op::Min || op == Op::Max) &&
            kids[0] == kids[1] && nodes_[kids[0]].constants == 0)
          return;
      }
      batch.push_back(n);
      if (batch.size() >= kBatch) flush();
    };
    for (Op op : ops_) {
      const int ar = arity(op);
      if (ar == 1) {
        for (int a : levels_[s - 1]) {
          offer(op, {a, -1, -1}, 1);
          if (capped) break;
        }
      } else if (ar == 2) {
        for (int i = 0; i <= s - 1 && !capped; ++i)
          for (int a : levels_[i]) {
            for (int b : levels_[s - 1 - i]) {
              offer(op, {a, b, -1}, 2);
              if (capped) break;
            }
            if (capped) break;
          }
      } else if (ar == 3) {
        for (int i = 0; i <= s - 1 && !capped; ++i)
          for (int j = 0; i + j <= s - 1 && !capped; ++j)
            for (int a : levels_[i]) {
              for (int b : levels_[j]) {
                for (int c : levels_[s - 1 - i - j]) {
                  offer(op, {a, b, c}, 3);
                  if (capped) break;
                }
                if (capped) break;
              }
              if (capped) break;
            }
      }
      // select (arity 4) is left out: piecewise, and four operands multiply the count.
      if (capped) return false;
    }
    flush();
    if (capped) return false;
    levels_.push_back(std::move(level));
    fit_.push_back(std::move(fit));
    return true;
  }

  // The last grow() stopped at the cap on expressions per size (not at the deadline).
  bool sizeCapped() const {
    return size_capped_;
  }
  // The last grow() stopped at the memory bound.
  bool memoryCapped() const {
    return memory_capped_;
  }

  const std::vector<int>& level(int s) const {
    return levels_[s];
  }

  // The trees of size s to fit: the first of each function (with linear scaling, of each
  // function up to an affine map).
  const std::vector<int>& toFit(int s) const {
    return fit_[s];
  }

  // The tree as a one-output program: post-order, sub-trees without free constants shared
  // (common-subexpression elimination), each free constant its own slot.
  Program program(int root, int num_constants) const {
    Program p;
    p.constants.assign(std::max<int>(num_constants, nodes_[root].constants), 1.0f);
    std::unordered_map<int, int> shared;
    int next_const = 0;
    std::function<Operand(int)> emit = [&](int id) -> Operand {
      const Node& n = nodes_[id];
      if (n.input >= 0) return inputOperand(n.input);
      if (n.constant) return constOperand(next_const++);
      if (n.constants == 0)
        if (auto it = shared.find(id); it != shared.end()) return regOperand(it->second);
      Instr ins;
      ins.op = n.op;
      for (int a = 0; a < arity(n.op); ++a) ins.args[a] = emit(n.kids[a]);
      p.code.push_back(ins);
      const int reg = static_cast<int>(p.code.size()) - 1;
      if (n.constants == 0) shared.emplace(id, reg);
      return regOperand(reg);
    };
    emit(root);
    p.outputs = {static_cast<uint8_t>(p.code.size() - 1)};
    return p;
  }

 private:
  // A tree that is never an operand keeps no values (the largest size: most of the memory).
  int add(const Node& n, const double* v) {
    nodes_.push_back(n);
    if (v) {
      if (vals_.size() < nodes_.size() * width_) vals_.resize(nodes_.size() * width_);
      std::copy_n(v, width_, &vals_[(nodes_.size() - 1) * width_]);
    }
    return static_cast<int>(nodes_.size()) - 1;
  }
  static bool past(std::chrono::steady_clock::time_point t) {
    return std::chrono::steady_clock::now() > t;
  }
  // Whether one more tree in `level` (and `fit`) keeps the enumeration within its memory
  // bound: what it holds (the nodes, the operand values, both fingerprint sets, the levels'
  // lists and what screening them will take), plus the largest block that insertion may
  // allocate while the one it replaces still lives (a vector's capacity and a hash set's
  // buckets double), plus a batch's values.
  bool fits(bool operand, const std::vector<int>& level, const std::vector<int>& fit) const {
    size_t held = nodes_.capacity() * sizeof(Node) + vals_.capacity() * sizeof(double) +
                  (exact_.size() + roots_.size()) * kSetNodeBytes +
                  (exact_.bucket_count() + roots_.bucket_count()) * sizeof(void*) +
                  (level.capacity() + fit.capacity()) * sizeof(int) +
                  fit.size() * kScreenBytesPerFit + kBatch * (width_ * sizeof(double) + 16);
    for (const auto* lists : {&levels_, &fit_})
      for (const auto& l : *lists) held += l.capacity() * sizeof(int);
    const auto doubled = [](size_t size, size_t capacity, size_t bytes) {
      return size + 1 > capacity ? std::max<size_t>(2 * capacity, 1) * bytes : 0;
    };
    size_t growth = std::max({doubled(nodes_.size(), nodes_.capacity(), sizeof(Node)),
                              doubled(level.size(), level.capacity(), sizeof(int)),
                              doubled(fit.size(), fit.capacity(), sizeof(int))});
    if (operand && vals_.size() + width_ > vals_.capacity())
      growth =
          std::max(growth, std::max(2 * vals_.capacity(), vals_.size() + width_) * sizeof(double));
    for (const auto* set : {&exact_, &roots_})
      if (static_cast<double>(set->size() + 1) >
          static_cast<double>(set->bucket_count()) * set->max_load_factor())
        growth = std::max(growth, 2 * set->bucket_count() * sizeof(void*));
    return held + growth <= memory_bytes_;
  }
  // The values of tree `n` with its first free constant in slot `offset`; with `fragile`,
  // also whether the tree is fragile (a fragile operand, or a kink of its operator whose place
  // depends on a free constant and that no probe point crosses at any draw).
  void evaluate(const Node& n, int offset, double* out, bool* fragile = nullptr) const {
    const int nc = std::max(max_constants_, 1);
    if (n.constant) {
      for (int d = 0; d < kDraws; ++d)
        for (int p = 0; p < points_; ++p) out[d * points_ + p] = cvals_[d * nc + offset];
      return;
    }
    // (An input has no free constant: its stored values serve at every offset.)
    const int ar = arity(n.op);
    std::array<const double*, 3> arg{};
    std::array<std::vector<double>, 3> tmp;
    int off = offset;
    bool kids_fragile = false;
    for (int a = 0; a < ar; ++a) {
      const Node& k = nodes_[n.kids[a]];
      kids_fragile = kids_fragile || k.fragile;
      if (off == 0 || k.constants == 0) {
        arg[a] = &vals_[static_cast<size_t>(n.kids[a]) * width_];
      } else {
        tmp[a].resize(width_);
        evaluate(k, off, tmp[a].data());
        arg[a] = tmp[a].data();
      }
      off += k.constants;
    }
    for (int w = 0; w < width_; ++w)
      out[w] = sem::applyDynamic<double>(n.op, arg[0][w], ar > 1 ? arg[1][w] : 0.0,
                                         ar > 2 ? arg[2][w] : 0.0, 0.0);
    if (!fragile) return;
    *fragile = kids_fragile;
    if (kids_fragile || n.constants == 0 || branch(n.op, 0, 0) < 0) return;
    bool crossed = false;
    for (int d = 0; d < kDraws && !crossed; ++d) {
      const int first = branch(n.op, arg[0][d * points_], ar > 1 ? arg[1][d * points_] : 0.0);
      for (int p = 1; p < points_ && !crossed; ++p)
        crossed =
            branch(n.op, arg[0][d * points_ + p], ar > 1 ? arg[1][d * points_ + p] : 0.0) != first;
    }
    *fragile = !crossed;
  }
  Key keyOf(const double* v) const {
    KeyBuilder k;
    for (int w = 0; w < width_; ++w) k.add(quantize(v[w]));
    return k.key();
  }
  // Per draw, the values up to an affine map: centred, scaled to unit spread, sign fixed by
  // the first value off the mean. A draw with non-finite values keeps them as they are.
  Key affineKeyOf(const double* v) const {
    KeyBuilder k;
    for (int d = 0; d < kDraws; ++d) {
      const double* x = v + d * points_;
      double mean = 0;
      bool finite = true;
      for (int p = 0; p < points_; ++p) {
        finite = finite && std::isfinite(x[p]);
        mean += x[p];
      }
      if (!finite) {
        for (int p = 0; p < points_; ++p) k.add(quantize(x[p]));
        continue;
      }
      mean /= points_;
      double var = 0;
      for (int p = 0; p < points_; ++p) var += (x[p] - mean) * (x[p] - mean);
      const double sd = std::sqrt(var / points_);
      if (!(sd > 1e-9 * (1 + std::fabs(mean)))) {
        k.add(4);  // constant over the points
        continue;
      }
      double sign = 0;
      for (int p = 0; p < points_ && sign == 0; ++p) {
        const double z = (x[p] - mean) / sd;
        if (std::fabs(z) > 1e-6) sign = z > 0 ? 1 : -1;
      }
      for (int p = 0; p < points_; ++p)
        k.add(static_cast<uint64_t>(std::llround(sign * (x[p] - mean) / sd * 0x1.0p20)));
    }
    return k.key();
  }
  bool constantOverPoints(const double* v) const {
    for (int d = 0; d < kDraws; ++d)
      for (int p = 1; p < points_; ++p)
        if (quantize(v[d * points_ + p]) != quantize(v[d * points_])) return false;
    return true;
  }

  std::vector<Op> ops_;
  int max_constants_;
  bool affine_roots_;
  int threads_;
  size_t memory_bytes_;
  int points_ = 0, width_ = 0;
  std::vector<double> cvals_;  // [draw][slot]
  std::vector<Node> nodes_;
  std::vector<double> vals_;  // [node][draw][point]
  std::vector<std::vector<int>> levels_, fit_;
  bool size_capped_ = false;
  bool memory_capped_ = false;
  std::unordered_set<Key, KeyHash> exact_, roots_;
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
                    {"screened", k < screened.size() ? screened[k] : 0},
                    {"seconds", k < level_seconds.size() ? level_seconds[k] : 0.0},
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
          {"stopped", stopped.empty() ? nlohmann::json(nullptr) : nlohmann::json(stopped)},
          {"fitted", fitted},
          {"seconds", seconds},
          {"constant_fit", "Levenberg-Marquardt from +1 on " + std::to_string(x.screen_rows) +
                               " rows (8 iterations), the best " + std::to_string(x.keep) +
                               " per operator count refitted from those constants, +1 and -1 on "
                               "every row (local: a better constant may "
                               "exist)"},
          {"best", best}};
}

size_t exhaustiveMemoryBudget() {
  const size_t page = static_cast<size_t>(std::max(1L, ::sysconf(_SC_PAGESIZE)));
  size_t avail = static_cast<size_t>(std::max(0L, ::sysconf(_SC_PHYS_PAGES))) * page;
  std::ifstream meminfo("/proc/meminfo");
  for (std::string key; meminfo >> key;) {
    size_t kib = 0;
    if (key == "MemAvailable:" && meminfo >> kib) {
      avail = kib << 10;
      break;
    }
    meminfo.ignore(1 << 10, '\n');
  }
  // Under a limit, what is left of it: the address space counts every mapping (thread stacks,
  // malloc arenas), and this process has some already.
  size_t vm = 0;
  std::ifstream("/proc/self/statm") >> vm;
  vm *= page;
  for (int which : {RLIMIT_AS, RLIMIT_DATA}) {
    rlimit rl{};
    if (::getrlimit(which, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY)
      avail = std::min<size_t>(avail, rl.rlim_cur > vm ? rl.rlim_cur - vm : 0);
  }
  return avail / 2;
}

Expected<ExhaustiveResult> exhaustiveSearch(const RunConfig& cfg, const Table& t,
                                            size_t memory_bytes) {
  if (memory_bytes == 0) memory_bytes = exhaustiveMemoryBudget();
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
  // An enumerated expression is one gene: with an output layer it seeds the search as its
  // lead gene (fitToShape), and is scored here as the plain a*f + b it then is.
  err.genes = 1;
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
  res.screened.push_back(0);
  res.level_seconds.push_back(0);
  ExhaustiveMember none;
  res.best_by_ops.push_back(none);
  std::vector<ExhaustiveMember> all;
  Enumerator en(t, ops, x.constants, err.linear_scaling, threads, memory_bytes);
  for (int s = 1; s <= x.max_ops; ++s) {
    bool grown = false;
    try {
      grown = seconds() <= x.seconds && en.grow(s, s < x.max_ops, deadline);
    } catch (const std::bad_alloc&) {
      // The bound is an estimate; the machine had less (another process took it meanwhile).
      res.stopped = "memory";
      break;
    }
    if (!grown) {
      res.stopped = en.memoryCapped() ? "memory" : en.sizeCapped() ? "expression cap" : "seconds";
      break;
    }
    const std::vector<int>& level = en.toFit(s);
    res.enumerated.push_back(en.level(s).size());
    res.screened.push_back(level.size());
    // Screening: every expression of this size, on the row subset.
    // One start, few iterations: a ranking, not the answer (the kept ones are refitted). The
    // programs are not kept (millions at 5 operators): the kept ones are screened again.
    auto screened = [&](int thread, size_t i, Program& p) {
      p = en.program(level[i], num_constants);
      return screen.fit(thread, p, 8, false);
    };
    std::vector<double> screen_err(level.size(), kInf);
    std::atomic<bool> out_of_time{false};
#pragma omp parallel for schedule(dynamic, 64) num_threads(threads)
    for (size_t i = 0; i < level.size(); ++i) {
      if (out_of_time.load(std::memory_order_relaxed)) continue;
      if ((i & 255) == 0 && seconds() > x.seconds) out_of_time = true;
      Program p;
      screen_err[i] = screened(omp_get_thread_num(), i, p);
    }
    if (out_of_time) {
      res.stopped = "seconds";
      break;
    }
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
      screened(th, order[j], m.program);
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
    res.level_seconds.push_back(seconds());
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
