// The operator table: every opcode is described once, here. The interpreter kernels, the
// double reference evaluator, the cost models, mutation and the emitters all read it.
//
// Protected semantics (identical in the float32 interpreter and the double reference; the
// emitters reproduce them exactly unless told a member never reaches a guard):
//   guard(b)  = |b| < kDivGuard ? copysign(kDivGuard, b) : b
//   div(a,b)  = a / guard(b)             rcp(a)   = 1 / guard(a)
//   sqrt(a)   = sqrt(a > 0 ? a : 0)      rsqrt(a) = 1 / sqrt(a > kMinPos ? a : kMinPos)
//   log2(a)   = log2(a > kMinPos ? a : kMinPos)       (so log2 >= -126: no -inf, no NaN)
//   log(a)    = log2(a) * ln 2 with the same floor
//   exp2(a)   = 2^clamp(a, -kExpClamp, kExpClamp)     (never overflows to +inf)
//   exp(a)    = exp2(a * log2 e)  with the same clamp
//   pow(a,b)  = exp2(b * log2(a)) with the protected log2 and exp2 above; pow of a <= 0 is
//               pow of kMinPos, i.e. ~0 for b > 0 (HLSL's pow is undefined there)
//   saturate(a) = a > 0 ? (a < 1 ? a : 1) : 0         (NaN -> 0, as GPUs do)
//   min(a,b) = a < b ? a : b    max(a,b) = a > b ? a : b    select(a,b,c,d) = a > b ? c : d
//   mad(a,b,c) = a*b + c (two roundings)   lerp(a,b,t) = a + (b - a)*t   square(a) = a*a
// Anything else that is not finite (overflowing products, inf - inf) propagates; the
// fitness layer turns any non-finite output into the worst possible error.
//
// select has four operands; every other operator has at most three.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lgp {

inline constexpr float kDivGuard = 1e-20f;
inline constexpr float kMinPos = 1.17549435e-38f;  // FLT_MIN: floor of log/rsqrt/pow arguments
inline constexpr float kExpClamp = 126.0f;         // |exponent| limit of exp2/exp/pow
inline constexpr int kMaxArity = 4;

// Cost targets (eval/cost_model.hpp; docs/cost-models.md derives every entry).
// rdna, gcn: machine instructions, fitted by least squares to what Mesa's ACO compiler emits
//   for RDNA2 (navi21) and GCN5 (vega10) through RADV's null device (bench/cost: 2400 random
//   programs over every operator plus published formulas; held-out RMS error 0.8 and 0.9
//   instructions). Prices are fractional where the compiler fuses (a mul feeding an add
//   becomes one fma) or folds (neg and abs are source modifiers most of the time).
// gpu-generic: the mean of the RDNA2, RDNA3 and GCN5 fits.
// nvidia: issue slots from NVIDIA's documented throughputs: SFU (MUFU) ops 4, sqrt = rsq+rcp,
//   div = rcp+mul; no guard, literal or modifier prices (no compiler to measure them with).
// cpu: AVX2 reciprocal throughput relative to an FMA, with the vectorised polynomial libm
//   (eval/vecmath.hpp) for exp/log/sin/cos.
enum class CostTarget : uint8_t { GpuGeneric, Nvidia, Gcn, Rdna, Cpu };
inline constexpr int kNumCostTargets = 5;
inline constexpr std::array<std::string_view, kNumCostTargets> kCostTargetNames = {
    "gpu-generic", "nvidia", "gcn", "rdna", "cpu"};
// Per target, what the cost model (eval/cost_model.hpp) prices beside the operators: a distinct
// constant the ISA cannot encode inline, a neg or abs that cannot be a source modifier, and a
// saturate that cannot be the clamp bit of the instruction writing its operand.
struct CostExtras {
  double literal;
  double unfolded_neg_abs;
  double unfolded_saturate;
};
inline constexpr std::array<CostExtras, kNumCostTargets> kCostExtras = {
    {{0.25, 0.25, 0.5}, {0, 0, 0}, {0.25, 0, 0.25}, {0.25, 0.25, 0.5}, {0, 0, 0}}};

// How far the interpreter's float32 result of an operator may lie from its exact value on the
// same operands, for the interval analysis (core/interval.hpp): Exact (the value of an operand
// or a constant: nothing is rounded), Rounded (one IEEE rounding per arithmetic step), Approx
// (the polynomial approximations of eval/vecmath.hpp: a few ulp).
enum class OpRounding : uint8_t { Exact, Rounded, Approx };

// Where an operator's value has a branch (the discontinuity objective counts it unless the
// interval analysis proves it never switches on the table's domain; the exhaustive
// enumeration keeps apart the sides of it): None (smooth), Sign (abs: at 0), Unit
// (saturate: at 0 and at 1), Less (min: a < b ? a : b), Greater (max: a > b ? a : b),
// Compare (select: a > b ? c : d).
enum class OpKink : uint8_t { None, Sign, Unit, Less, Greater, Compare };

// An operator's protected branch (the semantics at the top): None; Divisor (its last operand
// goes through guard()); Root (sqrt of a negative is sqrt 0); Floor (the operand floored at
// kMinPos); Clamp (the exponent clamped at kExpClamp); ScaledClamp (exp: the operand times
// log2 e, clamped); PowClamp (pow: the base floored, the exponent clamped); NanToZero
// (saturate); NanOrder (min, max: a NaN operand gives the other one or itself by the order of
// the comparison, which raw std::min does not reproduce). The emitters write a helper for
// each unless the interval analysis proves the branch unreachable (core/interval.hpp
// provenUnguarded); every kind but NanOrder is priced as a guard (OpInfo::guarded).
enum class OpGuard : uint8_t {
  None,
  Divisor,
  Root,
  Floor,
  Clamp,
  ScaledClamp,
  PowClamp,
  NanToZero,
  NanOrder
};

// When the value never has its sign bit set (it is >= +0 unless NaN), for the simplifier's
// sign-of-zero reasoning (core/expr.cpp): Never (as far as the rules know), Always, IfOperands
// (when no operand has its sign bit set), IfBranches (select: when neither c nor d has).
enum class OpNonNeg : uint8_t { Never, Always, IfOperands, IfBranches };

// How the sign of a zero operand reaches the value (div and rcp's guard turn +0 and -0 into
// +-1e20, so the simplifier keeps a zero's sign wherever it can reach one): Blocks (+0 and -0
// give the same value bits), Passes (they may give a value of the other zero sign, never
// another value), Reads (they may give different values), DivisorReads (div: the dividend
// passes, the divisor reads), BranchesPass (select: c and d pass, a and b block).
enum class OpZeroSign : uint8_t { Blocks, Passes, Reads, DivisorReads, BranchesPass };

// X(Enum, name, arity, kink, guard, (nonneg, zero sign), default_set, commutative, rounding,
//   cost {generic, nvidia, gcn, rdna, cpu}, guard cost {same targets}, infix, hlsl, glsl, cpp)
// kink, guard, nonneg, zero sign: the enums above. cost: the operator's price per DAG node;
// guard cost: what its protected branch adds where interval analysis cannot prove it
// unreachable on the table's domain (cost_model.hpp). default_set: in the operators a config
// that names none searches (config.hpp defaultOps). commutative: op(a, b) = op(b, a) for
// every operand (the exhaustive enumeration keeps one order). rounding: OpRounding above.
// Templates use {0}..{3} for operands. `infix` is the function-call spelling the parser
// accepts (the formula printer, core/formula.hpp, prints arithmetic with operators instead);
// it names protected functions by their op name. A language's spelling `name({0}, ...)` is
// also a name the parser reads back (GLSL's mix, inversesqrt).
//
// Besides this row, an operator is described in three places that an `if constexpr` chain
// ending in a static_assert or a switch with no `default:` makes the compiler name: its
// semantics and partial derivatives (eval/semantics.hpp; binary16 semantics instantiate the
// same template), its interval rule (core/interval.cpp rawInterval) and how the emitters
// write it (emit/src/emit.cpp). Everything else that varies by operator reads the columns.
// tests/core/registry_coverage_test.cpp holds every operator to its row (CONTRIBUTING.md,
// "An operator").
#define LGP_OPS(X)                                                                                 \
  X(Add, "add", 2, None, None, (IfOperands, Passes), true, true, Rounded, (1, 1, 1, 1, 1),         \
    (0, 0, 0, 0, 0), "({0} + {1})", "({0} + {1})", "({0} + {1})", "({0} + {1})")                   \
  X(Sub, "sub", 2, None, None, (Never, Passes), true, false, Rounded, (1, 1, 1, 1, 1),             \
    (0, 0, 0, 0, 0), "({0} - {1})", "({0} - {1})", "({0} - {1})", "({0} - {1})")                   \
  X(Mul, "mul", 2, None, None, (IfOperands, Passes), true, true, Rounded,                          \
    (0.75, 1, 0.75, 0.75, 1), (0, 0, 0, 0, 0), "({0} * {1})", "({0} * {1})", "({0} * {1})",        \
    "({0} * {1})")                                                                                 \
  X(Div, "div", 2, None, Divisor, (IfOperands, DivisorReads), true, false, Rounded,                \
    (1.75, 5, 1.5, 1.5, 4), (5.5, 0, 6.5, 4.75, 0), "({0} / {1})", "({0} / {1})", "({0} / {1})",   \
    "({0} / {1})")                                                                                 \
  X(Mad, "mad", 3, None, None, (IfOperands, Passes), true, false, Rounded,                         \
    (1.25, 1, 1.25, 1.25, 1), (0, 0, 0, 0, 0), "mad({0}, {1}, {2})", "mad({0}, {1}, {2})",         \
    "({0} * {1} + {2})", "({0} * {1} + {2})")                                                      \
  X(Neg, "neg", 1, None, None, (Never, Passes), true, false, Exact, (0.5, 0, 0.75, 0.5, 1),        \
    (0, 0, 0, 0, 0), "(-{0})", "(-{0})", "(-{0})", "(-{0})")                                       \
  X(Rcp, "rcp", 1, None, Divisor, (Never, Reads), true, false, Rounded, (0.75, 4, 0.75, 0.75, 4),  \
    (5.5, 0, 6.5, 4.75, 0), "rcp({0})", "rcp({0})", "(1.0 / {0})", "(1.0f / {0})")                 \
  X(Sqrt, "sqrt", 1, None, Root, (Always, Blocks), true, false, Rounded, (1, 8, 0.75, 0.75, 4),    \
    (2, 0, 2, 1.75, 0), "sqrt({0})", "sqrt({0})", "sqrt({0})", "std::sqrt({0})")                   \
  X(Rsqrt, "rsqrt", 1, None, Floor, (Always, Blocks), true, false, Rounded, (1, 4, 0.75, 0.75, 5), \
    (2, 0, 2.5, 1.75, 0), "rsqrt({0})", "rsqrt({0})", "inversesqrt({0})",                          \
    "(1.0f / std::sqrt({0}))")                                                                     \
  X(Square, "square", 1, None, None, (Always, Blocks), true, false, Rounded,                       \
    (1, 1, 0.75, 0.75, 1), (0, 0, 0, 0, 0), "square({0})", "({0} * {0})", "({0} * {0})",           \
    "({0} * {0})")                                                                                 \
  X(Exp2, "exp2", 1, None, Clamp, (Always, Blocks), true, false, Approx, (0.75, 4, 0.75, 0.75, 8), \
    (4.5, 0, 5.5, 4, 0), "exp2({0})", "exp2({0})", "exp2({0})", "std::exp2({0})")                  \
  X(Log2, "log2", 1, None, Floor, (Never, Blocks), true, false, Approx, (0.5, 4, 0.5, 0.5, 8),     \
    (2.75, 0, 3.5, 2.5, 0), "log2({0})", "log2({0})", "log2({0})", "std::log2({0})")               \
  X(Exp, "exp", 1, None, ScaledClamp, (Always, Blocks), true, false, Approx,                       \
    (1.75, 5, 1.5, 1.5, 9), (3.25, 0, 3.75, 2.75, 0), "exp({0})", "exp({0})", "exp({0})",          \
    "std::exp({0})")                                                                               \
  X(Log, "log", 1, None, Floor, (Never, Blocks), true, false, Approx, (2, 5, 1.75, 1.75, 9),       \
    (2.25, 0, 2.75, 2, 0), "log({0})", "log({0})", "log({0})", "std::log({0})")                    \
  X(Pow, "pow", 2, None, PowClamp, (Always, Blocks), true, false, Approx,                          \
    (2.75, 9, 2.25, 2.5, 17), (7.25, 0, 9, 6.25, 0), "pow({0}, {1})", "pow({0}, {1})",             \
    "pow({0}, {1})", "std::pow({0}, {1})")                                                         \
  X(Sin, "sin", 1, None, None, (Never, Passes), false, false, Approx, (2, 4, 1.75, 1.75, 10),      \
    (0, 0, 0, 0, 0), "sin({0})", "sin({0})", "sin({0})", "std::sin({0})")                          \
  X(Cos, "cos", 1, None, None, (Never, Blocks), false, false, Approx, (2, 4, 1.75, 1.75, 10),      \
    (0, 0, 0, 0, 0), "cos({0})", "cos({0})", "cos({0})", "std::cos({0})")                          \
  X(Min, "min", 2, Less, NanOrder, (IfOperands, Passes), true, true, Exact, (1, 1, 1, 1, 1),       \
    (0, 0, 0, 0, 0), "min({0}, {1})", "min({0}, {1})", "min({0}, {1})", "std::min({0}, {1})")      \
  X(Max, "max", 2, Greater, NanOrder, (IfOperands, Passes), true, true, Exact, (1, 1, 1, 1, 1),    \
    (0, 0, 0, 0, 0), "max({0}, {1})", "max({0}, {1})", "max({0}, {1})", "std::max({0}, {1})")      \
  X(Abs, "abs", 1, Sign, None, (Always, Blocks), true, false, Exact, (0.5, 0, 0.75, 0.5, 1),       \
    (0, 0, 0, 0, 0), "abs({0})", "abs({0})", "abs({0})", "std::fabs({0})")                         \
  X(Saturate, "saturate", 1, Unit, NanToZero, (Always, Blocks), true, false, Exact,                \
    (0.5, 0, 0.5, 0.25, 2), (0, 0, 0, 0, 0), "saturate({0})", "saturate({0})",                     \
    "clamp({0}, 0.0, 1.0)", "std::clamp({0}, 0.0f, 1.0f)")                                         \
  X(Lerp, "lerp", 3, None, None, (Never, Passes), true, false, Rounded, (1.25, 2, 1.25, 1.25, 2),  \
    (0, 0, 0, 0, 0), "lerp({0}, {1}, {2})", "lerp({0}, {1}, {2})", "mix({0}, {1}, {2})",           \
    "({0} + ({1} - {0}) * {2})")                                                                   \
  X(Select, "select", 4, Compare, None, (IfBranches, BranchesPass), true, false, Exact,            \
    (2.25, 2, 2.5, 2, 2), (0, 0, 0, 0, 0), "select({0}, {1}, {2}, {3})",                           \
    "(({0} > {1}) ? {2} : {3})", "(({0} > {1}) ? {2} : {3})", "(({0} > {1}) ? {2} : {3})")

enum class Op : uint8_t {
#define LGP_X_ENUM(E, ...) E,
  LGP_OPS(LGP_X_ENUM)
#undef LGP_X_ENUM
};

inline constexpr int kNumOps = 0
#define LGP_X_COUNT(...) +1
    LGP_OPS(LGP_X_COUNT)
#undef LGP_X_COUNT
    ;

struct OpInfo {
  Op op;
  std::string_view name;  // config / JSON / CLI spelling
  int arity;
  OpKink kink;
  OpGuard guard;
  OpNonNeg nonneg;
  OpZeroSign zero_sign;
  bool piecewise;    // kink != None: counts towards the discontinuity objective by default
  bool guarded;      // guard other than None and NanOrder: a priced protected branch
  bool default_set;  // searched when a config names no operators
  bool commutative;  // op(a, b) = op(b, a)
  OpRounding rounding;
  std::array<double, kNumCostTargets> cost;        // per target, the operator itself
  std::array<double, kNumCostTargets> guard_cost;  // per target, its guard where it stays
  std::string_view infix;                          // readable form, {0}..{3} placeholders
  std::string_view hlsl;                           // raw (unprotected) spelling per language
  std::string_view glsl;
  std::string_view cpp;
};

namespace detail {
#define LGP_X_COST(a, b, c, d, e) \
  { a, b, c, d, e }
#define LGP_X_SIGN(NN, ZS) OpNonNeg::NN, OpZeroSign::ZS
#define LGP_X_INFO(E, NAME, AR, KINK, GUARD, SIGN, DS, CM, RND, COST, GCOST, INF, HL, GL, CP) \
  OpInfo{Op::E,                                                                               \
         NAME,                                                                                \
         AR,                                                                                  \
         OpKink::KINK,                                                                        \
         OpGuard::GUARD,                                                                      \
         LGP_X_SIGN SIGN,                                                                     \
         OpKink::KINK != OpKink::None,                                                        \
         OpGuard::GUARD != OpGuard::None && OpGuard::GUARD != OpGuard::NanOrder,              \
         DS,                                                                                  \
         CM,                                                                                  \
         OpRounding::RND,                                                                     \
         LGP_X_COST COST,                                                                     \
         LGP_X_COST GCOST,                                                                    \
         INF,                                                                                 \
         HL,                                                                                  \
         GL,                                                                                  \
         CP},
inline constexpr std::array<OpInfo, kNumOps> kOpTable = {{LGP_OPS(LGP_X_INFO)}};
#undef LGP_X_INFO
#undef LGP_X_SIGN
#undef LGP_X_COST
}  // namespace detail

constexpr const OpInfo& opInfo(Op op) {
  return detail::kOpTable[static_cast<int>(op)];
}
constexpr int arity(Op op) {
  return opInfo(op).arity;
}
constexpr std::string_view opName(Op op) {
  return opInfo(op).name;
}
constexpr const std::array<OpInfo, kNumOps>& allOps() {
  return detail::kOpTable;
}

std::optional<Op> opFromString(std::string_view name);
// Fills a spelling template of the table: each {k} becomes args[k].
std::string fillOpTemplate(std::string_view tmpl, const std::vector<std::string>& args);
std::optional<CostTarget> costTargetFromString(std::string_view name);
inline std::string_view toString(CostTarget t) {
  return kCostTargetNames[static_cast<int>(t)];
}

// A set of allowed operators, as a bitmask over Op.
class OpSet {
 public:
  OpSet() = default;
  static OpSet all() {
    OpSet s;
    for (const auto& i : allOps()) s.insert(i.op);
    return s;
  }
  void insert(Op op) { bits_ |= (1u << static_cast<int>(op)); }
  void erase(Op op) { bits_ &= ~(1u << static_cast<int>(op)); }
  bool contains(Op op) const { return (bits_ >> static_cast<int>(op)) & 1u; }
  bool empty() const { return bits_ == 0; }
  uint32_t bits() const { return bits_; }

 private:
  uint32_t bits_ = 0;
  static_assert(kNumOps <= 32);
};

}  // namespace lgp
