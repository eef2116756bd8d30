// Forward-mode Jacobian pass (see jacobian.hpp). Same rules as the interpreter: decode once,
// one kernel call per opcode (and per constant it depends on) per block, float32 columns in a
// scratch sized at bind, no allocation in evalBlock.
#include "lgp/eval/jacobian.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "lgp/eval/semantics.hpp"

namespace lgp {

namespace {

#define LGP_ALIGNED(p) static_cast<decltype(p)>(__builtin_assume_aligned(p, 64))

// partial * dx when operand J carries a derivative and the operator takes it at this row, else
// nothing. -0.0f is the exact identity of float addition, so an absent term folds away; an
// absent operand's partial (which may be inf) is never multiplied by a zero derivative, which
// would give NaN.
template <int M, int J>
inline float term(const sem::Partials<float>& q, float dx) {
  if constexpr (((M >> J) & 1) != 0)
    return q.on[J] ? q.p[J] * dx : -0.0f;
  else
    return -0.0f;
}

// d op / d c at one row, given the value v, operands a..d and operand derivatives da..dd: the
// partial derivatives of eval/semantics.hpp, summed in operand order (den is 1 but for div).
template <Op OP, int M>
inline float derivative(float v, float a, float b, float c, float d, float da, float db, float dc,
                        float dd) {
  const sem::Partials<float> q = sem::partials<OP, float>(v, a, b, c, d);
  return (((term<M, 0>(q, da) + term<M, 1>(q, db)) + term<M, 2>(q, dc)) + term<M, 3>(q, dd)) /
         q.den;
}

template <Op OP, int M>
void derivKernel(float* __restrict out, const float* __restrict v, const float* __restrict a,
                 const float* __restrict b, const float* __restrict c, const float* __restrict d,
                 const float* __restrict da, const float* __restrict db, const float* __restrict dc,
                 const float* __restrict dd, int n) {
  out = LGP_ALIGNED(out);
  v = LGP_ALIGNED(v);
  a = LGP_ALIGNED(a);
  b = LGP_ALIGNED(b);
  c = LGP_ALIGNED(c);
  d = LGP_ALIGNED(d);
  da = LGP_ALIGNED(da);
  db = LGP_ALIGNED(db);
  dc = LGP_ALIGNED(dc);
  dd = LGP_ALIGNED(dd);
  n &= ~15;
#pragma omp simd
  for (int i = 0; i < n; ++i)
    out[i] = derivative<OP, M>(v[i], a[i], b[i], c[i], d[i], da[i], db[i], dc[i], dd[i]);
}

// Operands through which a derivative can flow: all of them, except select's comparison.
constexpr int differentiableMask(Op op) {
  return op == Op::Select ? 0b1100 : (1 << arity(op)) - 1;
}

// Table [op][mask] of kernels; masks are reduced to the differentiable operands, so each
// operator instantiates only the combinations it can see.
template <size_t I>
constexpr DerivKernel derivEntry() {
  constexpr Op op = allOps()[I / 16].op;
  return &derivKernel<op, static_cast<int>(I % 16) & differentiableMask(op)>;
}
template <size_t... I>
constexpr std::array<DerivKernel, sizeof...(I)> derivTable(std::index_sequence<I...>) {
  return {derivEntry<I>()...};
}
constexpr std::array<DerivKernel, 16 * kNumOps> kDerivKernels =
    derivTable(std::make_index_sequence<16 * kNumOps>{});

// Largest cache of constant-free columns (floats, 16 MiB); beyond it they are recomputed.
constexpr size_t kMaxCacheFloats = size_t{1} << 22;

}  // namespace

DerivKernel derivKernelFor(Op op, int mask) {
  return kDerivKernels[static_cast<size_t>(op) * 16 + (mask & 15)];
}

void JacobianEvaluator::bind(const Program& p, const Dataset& ds) {
  ds_ = &ds;
  block_ = ds.blockSize();
  num_inputs_ = ds.numInputs();
  params_ = effectiveConstants(p);
  const int np = static_cast<int>(params_.size());
  const auto eff = effectiveIndices(p);
  std::vector<int> param_of(p.constants.size(), -1);
  for (int k = 0; k < np; ++k) param_of[params_[k]] = k;

  // Column layout: [inputs][parameters][registers][zero][one][derivatives].
  param_col0_ = num_inputs_;
  const int32_t reg0 = param_col0_ + np;
  zero_col_ = reg0 + static_cast<int32_t>(eff.size());
  one_col_ = zero_col_ + 1;
  int32_t next_dcol = one_col_ + 1;
  std::vector<int32_t> reg_col(p.code.size(), -1);
  std::vector<int32_t> step_of(p.code.size(), -1);
  // dcol[opcode * np + k]: derivative column of an opcode's value w.r.t. parameter k, or -1.
  std::vector<int32_t> dcol(p.code.size() * np, -1);
  steps_.clear();
  dsteps_.clear();
  for (size_t s = 0; s < eff.size(); ++s) {
    const Instr& ins = p.code[eff[s]];
    const int ar = arity(ins.op);
    Step st{};
    st.kernel = kernelFor(ins.op);
    st.dst = reg0 + static_cast<int32_t>(s);
    reg_col[eff[s]] = st.dst;
    step_of[eff[s]] = static_cast<int32_t>(s);
    st.constant_free = true;
    for (int a = 0; a < kMaxArity; ++a) {
      const Operand& o = ins.args[a < ar ? a : 0];  // unused operands: any valid column
      st.src[a] = o.kind == OperandKind::Var     ? static_cast<int32_t>(o.index)
                  : o.kind == OperandKind::Const ? param_col0_ + param_of[o.index]
                                                 : reg_col[o.index];
      if (a < ar && (o.kind == OperandKind::Const ||
                     (o.kind == OperandKind::Reg && !steps_[step_of[o.index]].constant_free)))
        st.constant_free = false;
    }
    st.dbegin = static_cast<int32_t>(dsteps_.size());
    for (int k = 0; k < np; ++k) {
      DStep ds_k{};
      int mask = 0;
      for (int a = 0; a < kMaxArity; ++a) {
        int32_t c = -1;
        if (a < ar && ((differentiableMask(ins.op) >> a) & 1)) {
          const Operand& o = ins.args[a];
          if (o.kind == OperandKind::Const && param_of[o.index] == k)
            c = one_col_;
          else if (o.kind == OperandKind::Reg)
            c = dcol[static_cast<size_t>(o.index) * np + k];
        }
        if (c >= 0) mask |= 1 << a;
        ds_k.dsrc[a] = c >= 0 ? c : zero_col_;
      }
      if (mask == 0) continue;
      ds_k.kernel = derivKernelFor(ins.op, mask);
      ds_k.dst = next_dcol++;
      dcol[static_cast<size_t>(eff[s]) * np + k] = ds_k.dst;
      dsteps_.push_back(ds_k);
    }
    st.dend = static_cast<int32_t>(dsteps_.size());
    steps_.push_back(st);
  }
  output_cols_.clear();
  output_dcols_.clear();
  for (uint8_t o : p.outputs) {
    output_cols_.push_back(reg_col[o]);
    for (int k = 0; k < np; ++k) {
      const int32_t c = dcol[static_cast<size_t>(o) * np + k];
      output_dcols_.push_back(c >= 0 ? c : zero_col_);
    }
  }

  // Constant-free opcodes read by a constant-dependent one or by an output get a cache slot.
  std::vector<uint8_t> frontier(steps_.size(), 0);
  for (const Step& st : steps_) {
    if (st.constant_free) continue;
    for (int a = 0; a < kMaxArity; ++a)
      if (st.src[a] >= reg0 && st.src[a] < zero_col_) frontier[st.src[a] - reg0] = 1;
  }
  for (int32_t c : output_cols_) frontier[c - reg0] = 1;
  int32_t slots = 0;
  for (size_t s = 0; s < steps_.size(); ++s)
    if (steps_[s].constant_free && frontier[s]) steps_[s].cache = slots++;
  const size_t cache_floats = static_cast<size_t>(slots) * ds.paddedRows();
  if (cache_floats > kMaxCacheFloats) {
    for (Step& st : steps_) st.cache = -1;
    cache_.clear();
    cached_.clear();
  } else {
    cache_.resize(cache_floats);
    cached_.assign(slots > 0 ? ds.numBlocks() : 0, 0);
  }

  const size_t owned = static_cast<size_t>(next_dcol - param_col0_) * block_;
  if (owned > scratch_.size()) scratch_.resize(std::max(owned, 2 * scratch_.size()));
  cols_.assign(next_dcol, nullptr);
  for (int32_t c = param_col0_; c < next_dcol; ++c) cols_[c] = own(c);
  std::fill_n(own(zero_col_), block_, 0.0f);
  std::fill_n(own(one_col_), block_, 1.0f);
  for (int k = 0; k < np; ++k) std::fill_n(own(param_col0_ + k), block_, p.constants[params_[k]]);
}

void JacobianEvaluator::setParameters(const double* x) {
  for (size_t k = 0; k < params_.size(); ++k)
    std::fill_n(own(param_col0_ + static_cast<int32_t>(k)), block_, static_cast<float>(x[k]));
}

void JacobianEvaluator::evalBlock(size_t block, bool derivatives) {
  const size_t off = block * static_cast<size_t>(block_);
  for (int i = 0; i < num_inputs_; ++i) cols_[i] = ds_->input(i) + off;
  // Without a cache (none needed, or too large) constant-free opcodes run every time.
  const bool caching = !cached_.empty();
  const bool have = caching && cached_[block];
  const float* const* q = cols_.data();
  for (const Step& st : steps_) {
    float* v;
    if (st.constant_free) {
      if (st.cache >= 0) {
        v = cache_.data() + static_cast<size_t>(st.cache) * ds_->paddedRows() + off;
        cols_[st.dst] = v;
      } else {
        v = own(st.dst);
      }
      if (have) continue;  // cached, or only read by constant-free opcodes (skipped too)
    } else {
      v = own(st.dst);
    }
    st.kernel(v, q[st.src[0]], q[st.src[1]], q[st.src[2]], q[st.src[3]], block_);
    if (!derivatives) continue;
    for (int32_t j = st.dbegin; j < st.dend; ++j) {
      const DStep& d = dsteps_[j];
      d.kernel(own(d.dst), v, q[st.src[0]], q[st.src[1]], q[st.src[2]], q[st.src[3]], q[d.dsrc[0]],
               q[d.dsrc[1]], q[d.dsrc[2]], q[d.dsrc[3]], block_);
    }
  }
  if (caching) cached_[block] = 1;
}

}  // namespace lgp
