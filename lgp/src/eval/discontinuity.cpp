#include "lgp/eval/discontinuity.hpp"

#include <cmath>

namespace lgp {

DiscontinuityModel DiscontinuityModel::defaults() {
  DiscontinuityModel m;
  for (const auto& i : allOps()) m.weight[static_cast<int>(i.op)] = i.piecewise ? 1.0 : 0.0;
  return m;
}

double DiscontinuityModel::programDiscontinuity(const Program& p) const {
  return programDiscontinuity(p, effectiveIndices(p));
}

double DiscontinuityModel::programDiscontinuity(const Program& p,
                                                const std::vector<int>& effective) const {
  double d = 0;
  bool any = false;
  for (int i : effective) {
    const double w = weight[static_cast<int>(p.code[i].op)];
    d += w;
    any = any || (w != 0 && opInfo(p.code[i].op).piecewise);
  }
  if (!any || domain.empty()) return d;
  // Only programs with a weighted piecewise operator pay for the intervals.
  thread_local std::vector<Interval> iv;
  programIntervals(p, domain, effective, iv);
  d = 0;
  Interval args[kMaxArity];
  for (int i : effective) {
    const Instr& in = p.code[i];
    const double w = weight[static_cast<int>(in.op)];
    if (w == 0) continue;
    if (!opInfo(in.op).piecewise) {
      d += w;
      continue;
    }
    for (int k = 0; k < arity(in.op) && k < kMaxArity; ++k) {
      const Operand& o = in.args[k];
      if (o.kind == OperandKind::Reg) {
        args[k] = iv[o.index];
      } else if (o.kind == OperandKind::Var) {
        args[k] = o.index < domain.size() ? inputInterval(domain[o.index]) : Interval{};
      } else {
        const double v = o.index < p.constants.size() ? p.constants[o.index] : 0.0;
        args[k] = Interval{v, v, std::isnan(v)};
      }
    }
    if (branchMaySwitch(in.op, args)) d += w;
  }
  return d;
}

}  // namespace lgp
