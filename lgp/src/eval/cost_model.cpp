// The cost model of cost_model.hpp.
#include "lgp/eval/cost_model.hpp"

#include <cmath>
#include <set>

#include "lgp/core/formula.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

std::optional<GpuFamily> gpuFamilyFromString(std::string_view s) {
  for (int i = 0; i < kNumGpuFamilies; ++i)
    if (kGpuFamilyNames[i] == s) return static_cast<GpuFamily>(i);
  return std::nullopt;
}

std::vector<GpuFamily> allGpuFamilies() {
  std::vector<GpuFamily> v;
  for (int i = 0; i < kNumGpuFamilies; ++i) v.push_back(static_cast<GpuFamily>(i));
  return v;
}

std::optional<CostCalibration> costCalibration(CostTarget t) {
  // bench/results/cost/calibration.md (lgp_cost --calibrate --programs 2400 --seed 1).
  switch (t) {
    case CostTarget::GpuGeneric:
      return CostCalibration{"rdna2", 1.05, 6.0, 0.92};
    case CostTarget::Gcn:
      return CostCalibration{"gcn5", 0.91, 5.2, 0.96};
    case CostTarget::Rdna:
      return CostCalibration{"rdna2", 0.80, 3.8, 0.96};
    case CostTarget::Nvidia:
    case CostTarget::Cpu:
      break;
  }
  return std::nullopt;
}

bool inlineConstant(double v) {
  const double a = std::fabs(v);
  return a == 0 || a == 0.5 || a == 1 || a == 2 || a == 4;
}

CostModel CostModel::preset(CostTarget t, std::vector<Interval> domain) {
  CostModel m;
  m.target = t;
  m.domain = std::move(domain);
  const int k = static_cast<int>(t);
  for (const auto& i : allOps()) {
    m.cost[static_cast<int>(i.op)] = i.cost[k];
    m.guard[static_cast<int>(i.op)] = i.guard_cost[k];
  }
  m.extras = kCostExtras[k];
  return m;
}

CostFeatures costFeatures(const Dag& d, const std::vector<Interval>& domain) {
  CostFeatures f;
  const std::vector<Interval> iv = nodeIntervals(d, domain);
  const std::vector<int> uses = d.useCounts();
  std::vector<uint8_t> is_output(d.nodes.size(), 0);
  for (int o : d.outputs) is_output[o] = 1;
  std::set<double> literals;
  for (int id = 0; id < static_cast<int>(d.nodes.size()); ++id) {
    const Node& n = d.nodes[id];
    if (n.isConst()) {
      if (!inlineConstant(n.value)) literals.insert(std::fabs(n.value));
      continue;
    }
    if (!n.isOp()) continue;
    ++f.ops[static_cast<int>(n.op)];
    if (isProtected(n.op) && !provenUnguarded(d, id, iv)) ++f.guards[static_cast<int>(n.op)];
    if ((n.op == Op::Neg || n.op == Op::Abs) && is_output[id]) ++f.unfolded_neg_abs;
    if (n.op == Op::Saturate) {
      const Node& a = d.nodes[n.args[0]];
      if (a.isLeaf() || a.op == Op::Select || uses[n.args[0]] > 1 || is_output[n.args[0]])
        ++f.unfolded_saturate;
    }
  }
  // A negated constant is the same literal with a free source negation.
  f.literals = static_cast<int>(literals.size());
  // A product read only by adds and subtractions compiles into each of them as a fused
  // multiply-add (NIR's late ffma fusion asks exactly that of the fmul; measured: `x*y + z` is
  // one RDNA2 instruction, (x*y + a)*(x*y + b) three), so the product goes and each sum is
  // priced as the mad it becomes: a weighted operand c*x is nearly free inside a sum, and a
  // program's mul-then-add costs what its printed `a*b + c` costs when parsed. A sum fuses one
  // product; a product that is an output, or read by anything else, stays.
  // Readers of each node, flat (this runs for every scored program).
  const int nn = static_cast<int>(d.nodes.size());
  const std::vector<uint8_t> live = d.reachable();
  std::vector<int> first(nn + 1, 0), readers;
  for (int id = 0; id < nn; ++id)
    if (d.nodes[id].isOp() && live[id])
      for (int k = 0; k < arity(d.nodes[id].op); ++k) ++first[d.nodes[id].args[k] + 1];
  for (int id = 0; id < nn; ++id) first[id + 1] += first[id];
  readers.resize(first[nn]);
  std::vector<int> fill(first.begin(), first.end() - 1);
  for (int id = 0; id < nn; ++id)
    if (d.nodes[id].isOp() && live[id])
      for (int k = 0; k < arity(d.nodes[id].op); ++k) readers[fill[d.nodes[id].args[k]]++] = id;
  std::vector<uint8_t> sum_taken(nn, 0);
  for (int id = 0; id < nn; ++id) {
    const Node& m = d.nodes[id];
    if (!m.isOp() || m.op != Op::Mul || is_output[id] || first[id] == first[id + 1]) continue;
    bool fusable = true;
    for (int j = first[id]; j < first[id + 1] && fusable; ++j) {
      const Node& n = d.nodes[readers[j]];
      fusable =
          (n.op == Op::Add || n.op == Op::Sub) && n.args[0] != n.args[1] && !sum_taken[readers[j]];
    }
    if (!fusable) continue;
    --f.ops[static_cast<int>(Op::Mul)];
    for (int j = first[id]; j < first[id + 1]; ++j) {
      sum_taken[readers[j]] = 1;
      --f.ops[static_cast<int>(d.nodes[readers[j]].op)];
      ++f.ops[static_cast<int>(Op::Mad)];
    }
  }
  return f;
}

double CostModel::price(const CostFeatures& f) const {
  double c = extras.literal * f.literals + extras.unfolded_neg_abs * f.unfolded_neg_abs +
             extras.unfolded_saturate * f.unfolded_saturate;
  for (int o = 0; o < kNumOps; ++o) c += cost[o] * f.ops[o] + guard[o] * f.guards[o];
  return c;
}

double CostModel::dagCost(const Dag& d) const {
  return price(costFeatures(d, domain));
}

double CostModel::programCost(const Program& p) const {
  int inputs = static_cast<int>(domain.size());
  for (const Instr& ins : p.code)
    for (int a = 0; a < arity(ins.op); ++a)
      if (ins.args[a].kind == OperandKind::Var) inputs = std::max(inputs, ins.args[a].index + 1);
  return dagCost(formulaDag(p, inputs, domain));
}

std::array<double, kNumCostTargets> costByTarget(const Program& p,
                                                 const std::vector<Interval>& domain,
                                                 const std::vector<TargetTransform>& transforms) {
  std::array<double, kNumCostTargets> c{};
  for (int t = 0; t < kNumCostTargets; ++t) {
    const CostModel m = CostModel::preset(static_cast<CostTarget>(t), domain);
    c[t] = m.programCost(p) + m.transformCost(transforms);
  }
  return c;
}

double CostModel::transformCost(const std::vector<TargetTransform>& ts) const {
  double c = 0;
  for (auto t : ts) {
    switch (t) {
      case TargetTransform::None:
        break;
      case TargetTransform::Log:
        c += cost[static_cast<int>(Op::Exp)];
        break;
      case TargetTransform::Sqrt:
        c += cost[static_cast<int>(Op::Square)];
        break;
      case TargetTransform::Rcp:
        c += cost[static_cast<int>(Op::Rcp)];
        break;
    }
  }
  return c;
}

}  // namespace lgp
