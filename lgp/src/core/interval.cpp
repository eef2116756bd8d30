// Interval arithmetic over the operator table (see interval.hpp).
#include "lgp/core/interval.hpp"

#include <algorithm>
#include <cfloat>
#include <cmath>

#include "lgp/core/program.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

Interval whole() {
  return Interval{-kInf, kInf, true};
}

// Outward widening for float rounding; magnitudes beyond FLT_MAX may be inf in float.
Interval widen(Interval v) {
  if (std::isnan(v.lo) || std::isnan(v.hi)) return whole();
  const double m = std::max(std::fabs(v.lo), std::fabs(v.hi));
  if (std::isfinite(m)) {
    const double w = m * 0x1p-20 + 0x1p-126;
    v.lo -= w;
    v.hi += w;
  }
  if (v.lo < -FLT_MAX) v.lo = -kInf;
  if (v.hi > FLT_MAX) v.hi = kInf;
  return v;
}

// The widening of one correctly rounded step (IEEE add, sub, mul, div, sqrt; exact abs, neg,
// min, max, select, saturate): rounding is monotone and 0 is a float, so a result whose real
// range is >= 0 (or <= 0) keeps that sign. Approximated transcendentals get widen() alone.
Interval widenExact(Interval raw) {
  Interval v = widen(raw);
  if (raw.lo >= 0) v.lo = std::max(v.lo, 0.0);
  if (raw.hi <= 0) v.hi = std::min(v.hi, 0.0);
  return v;
}

Interval mk(double lo, double hi, bool nan) {
  if (std::isnan(lo) || std::isnan(hi)) return whole();
  return Interval{lo, hi, nan};
}

Interval ivAdd(Interval a, Interval b) {
  return mk(a.lo + b.lo, a.hi + b.hi, a.nan || b.nan || !a.finite() || !b.finite());
}
Interval ivNeg(Interval a) {
  return Interval{-a.hi, -a.lo, a.nan};
}
Interval ivSub(Interval a, Interval b) {
  return ivAdd(a, ivNeg(b));
}
Interval ivMul(Interval a, Interval b) {
  const double p[4] = {a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi};
  double lo = kInf, hi = -kInf;
  for (double v : p) {
    if (std::isnan(v)) return whole();
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  return mk(lo, hi, a.nan || b.nan || !a.finite() || !b.finite());
}
// Protected reciprocal: 1/guard(b).
Interval ivRcp(Interval b) {
  const double g = kDivGuard;
  if (b.lo > 0) {
    const double lo = std::max(b.lo, g);
    return mk(1.0 / std::max(b.hi, lo), 1.0 / lo, b.nan);
  }
  if (b.hi < 0) {
    const double hi = std::min(b.hi, -g);
    return mk(1.0 / hi, 1.0 / std::min(b.lo, hi), b.nan);
  }
  return Interval{-1.0 / g, 1.0 / g, b.nan};
}
Interval ivDiv(Interval a, Interval b) {
  Interval r = ivMul(a, ivRcp(b));
  r.nan = r.nan || !b.finite();  // inf / inf
  return r;
}
Interval ivMono(Interval a, double (*f)(double)) {
  return mk(f(a.lo), f(a.hi), a.nan);
}
double clampExpD(double x) {
  return std::clamp(x, -double(kExpClamp), double(kExpClamp));
}
double floorPosD(double x) {
  return std::max(x, double(kMinPos));
}
Interval ivExp2(Interval a) {
  return ivMono(a, [](double x) { return std::exp2(clampExpD(x)); });
}
Interval ivLog2(Interval a) {
  return ivMono(a, [](double x) { return std::log2(floorPosD(x)); });
}
Interval ivScale(Interval a, double s) {
  return ivMul(a, Interval{s, s, false});
}
Interval ivMin(Interval a, Interval b) {
  return Interval{std::min(a.lo, b.lo), std::min(a.hi, b.hi), a.nan || b.nan};
}
Interval ivMax(Interval a, Interval b) {
  return Interval{std::max(a.lo, b.lo), std::max(a.hi, b.hi), a.nan || b.nan};
}
Interval ivHull(Interval a, Interval b) {
  return Interval{std::min(a.lo, b.lo), std::max(a.hi, b.hi), a.nan || b.nan};
}

Interval rawInterval(Op op, const Interval& a, const Interval& b, const Interval& c,
                     const Interval& d) {
  switch (op) {
    case Op::Add:
      return ivAdd(a, b);
    case Op::Sub:
      return ivSub(a, b);
    case Op::Mul:
      return ivMul(a, b);
    case Op::Div:
      return ivDiv(a, b);
    case Op::Mad:
      return ivAdd(widenExact(ivMul(a, b)), c);
    case Op::Neg:
      return ivNeg(a);
    case Op::Rcp:
      return ivRcp(a);
    case Op::Sqrt:
      return ivMono(a, [](double x) { return std::sqrt(std::max(x, 0.0)); });
    case Op::Rsqrt: {
      Interval r = ivMono(a, [](double x) { return 1.0 / std::sqrt(floorPosD(x)); });
      return Interval{r.hi, r.lo, r.nan};
    }
    case Op::Square: {
      if (a.lo >= 0) return mk(a.lo * a.lo, a.hi * a.hi, a.nan);
      if (a.hi <= 0) return mk(a.hi * a.hi, a.lo * a.lo, a.nan);
      return mk(0.0, std::max(a.lo * a.lo, a.hi * a.hi), a.nan);
    }
    case Op::Exp2:
      return ivExp2(a);
    case Op::Log2:
      return ivLog2(a);
    case Op::Exp:
      return ivExp2(widen(ivScale(a, sem::kLog2E)));
    case Op::Log:
      return ivScale(widen(ivLog2(a)), sem::kLn2);
    case Op::Pow: {
      Interval l = widen(ivLog2(a));
      Interval e = widen(ivMul(b, l));
      return ivExp2(e);
    }
    case Op::Sin:
    case Op::Cos:
      return Interval{-1.0, 1.0, a.nan || !a.finite()};
    case Op::Min:
      return ivMin(a, b);
    case Op::Max:
      return ivMax(a, b);
    case Op::Abs: {
      if (a.lo >= 0) return a;
      if (a.hi <= 0) return ivNeg(a);
      return Interval{0.0, std::max(-a.lo, a.hi), a.nan};
    }
    case Op::Saturate:
      return Interval{std::clamp(a.lo, 0.0, 1.0), std::clamp(a.hi, 0.0, 1.0), false};
    case Op::Lerp:
      return ivAdd(a, widenExact(ivMul(widenExact(ivSub(b, a)), c)));
    case Op::Select:
      return ivHull(c, d);
  }
  return whole();
}

// Whether a value in `a` may be -0 or +0 is decided by the caller; here only the ordering.
bool dominatesBelow(const Interval& a, const Interval& b) {  // a <= b everywhere
  return !a.nan && !b.nan && a.hi <= b.lo;
}
}  // namespace

std::vector<Interval> tableDomain(const Table& t) {
  std::vector<Interval> d;
  for (const auto& col : t.inputs) {
    Interval v;
    double lo = kInf, hi = -kInf;
    bool nan = false;
    bool neg_zero = false;
    for (double x : col) {
      if (std::isnan(x)) {
        nan = true;
        continue;
      }
      lo = std::min(lo, x);
      hi = std::max(hi, x);
      neg_zero = neg_zero || (x == 0 && std::signbit(x));
    }
    if (lo == 0 && neg_zero) lo = -0.0;  // the simplifier keeps the sign of zeros
    if (!nan && lo <= hi) v = Interval{lo, hi, false};
    d.push_back(v);
  }
  return d;
}

Interval inputInterval(const Interval& domain) {
  Interval v = domain;
  v.nan = v.nan && !(std::isfinite(v.lo) && std::isfinite(v.hi));
  if (std::isnan(v.lo) || std::isnan(v.hi)) return whole();
  float lo = static_cast<float>(v.lo), hi = static_cast<float>(v.hi);
  if (lo > v.lo) lo = std::nextafter(lo, -INFINITY);
  if (hi < v.hi) hi = std::nextafter(hi, INFINITY);
  v.lo = lo;
  v.hi = hi;
  return v;
}

Interval opInterval(Op op, const Interval* args) {
  const Interval none = whole();
  const int n = arity(op);
  const Interval r = rawInterval(op, args[0], n > 1 ? args[1] : none, n > 2 ? args[2] : none,
                                 n > 3 ? args[3] : none);
  switch (opInfo(op).rounding) {
    case OpRounding::Approx:
      return widen(r);  // polynomial approximations in the interpreter
    case OpRounding::Exact:
      return r;  // one operand's value (or 0, 1) exactly: nothing to round
    case OpRounding::Rounded:
      return widenExact(r);
  }
  return widen(r);
}

bool branchMaySwitch(Op op, const Interval* a) {
  switch (opInfo(op).kink) {
    case OpKink::None:
      return false;
    case OpKink::Sign:
      return a[0].nan || !(a[0].lo >= 0 || a[0].hi <= 0);
    case OpKink::Unit:  // kinks at 0 and 1; NaN -> 0 is a jump
      return a[0].nan || !(a[0].hi <= 0 || (a[0].lo >= 0 && a[0].hi <= 1) || a[0].lo >= 1);
    case OpKink::Less:
    case OpKink::Greater:
      return !(dominatesBelow(a[0], a[1]) || dominatesBelow(a[1], a[0]));
    case OpKink::Compare:  // a > b ? c : d
      return !((!a[0].nan && !a[1].nan && a[0].lo > a[1].hi) || dominatesBelow(a[0], a[1]));
  }
  return true;
}

bool provenUnguarded(Op op, const Interval* args) {
  const Interval& a = args[0];
  const double g = kDivGuard, m = kMinPos, e = kExpClamp;
  auto noGuard = [&](const Interval& b) { return !b.nan && (b.lo >= g || b.hi <= -g); };
  switch (opInfo(op).guard) {
    case OpGuard::None:
      return true;
    case OpGuard::Divisor:  // the last operand: div's b, rcp's a
      return noGuard(args[std::min(arity(op), kMaxArity) - 1]);
    case OpGuard::Root:
      return !a.nan && a.lo >= 0;
    case OpGuard::Floor:
      return !a.nan && a.lo > m;
    case OpGuard::Clamp:
      return !a.nan && a.lo >= -e && a.hi <= e;
    case OpGuard::ScaledClamp: {
      const Interval s = widen(ivScale(a, sem::kLog2E));
      return !s.nan && s.lo >= -e && s.hi <= e;
    }
    case OpGuard::PowClamp: {
      if (a.nan || !(a.lo > m)) return false;
      const Interval s = widen(ivMul(args[1], widen(ivLog2(a))));
      return !s.nan && s.lo >= -e && s.hi <= e;
    }
    case OpGuard::NanToZero:
      return !a.nan;
    case OpGuard::NanOrder: {  // the C++ helpers order NaN like the interpreter; raw std::min does
                               // not
      bool nan = false;
      for (int k = 0; k < std::min(arity(op), kMaxArity); ++k) nan = nan || args[k].nan;
      return !nan;
    }
  }
  return false;
}

void programIntervals(const Program& p, const std::vector<Interval>& domain,
                      const std::vector<int>& effective, std::vector<Interval>& out) {
  out.resize(p.code.size());
  Interval args[kMaxArity];
  for (int i : effective) {
    const Instr& in = p.code[i];
    for (int k = 0; k < arity(in.op) && k < kMaxArity; ++k) {
      const Operand& o = in.args[k];
      switch (o.kind) {
        case OperandKind::Var:
          args[k] = o.index < domain.size() ? inputInterval(domain[o.index]) : whole();
          break;
        case OperandKind::Const: {
          const double v = o.index < p.constants.size() ? p.constants[o.index] : 0.0;
          args[k] = Interval{v, v, std::isnan(v)};
          break;
        }
        case OperandKind::Reg:
          args[k] = o.index < i ? out[o.index] : whole();
          break;
      }
    }
    out[i] = opInterval(in.op, args);
  }
}

}  // namespace lgp
