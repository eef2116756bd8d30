// Block interpreter. Rules (see interpreter.hpp): decode once, dispatch per opcode per block,
// float32 columns in a registers-by-block scratch, no allocation/throw/libm in the hot loop.
#include "lgp/eval/interpreter.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "lgp/eval/semantics.hpp"

namespace lgp {

namespace {
std::atomic<uint64_t> g_bind_counter{1};

// A process-unique, non-zero id. Each thread takes a range of 2^20 at a time, so binding does
// not contend on one shared counter.
uint64_t nextBindId() {
  constexpr uint64_t kRange = uint64_t{1} << 20;
  thread_local uint64_t next = 0, end = 0;
  if (next == end) {
    next = g_bind_counter.fetch_add(kRange, std::memory_order_relaxed);
    end = next + kRange;
  }
  return next++;
}

float* allocAligned(size_t n) {
  const size_t bytes = ((n * sizeof(float) + 63) / 64) * 64;
  void* p = std::aligned_alloc(64, std::max<size_t>(bytes, 64));
  if (!p) throw std::bad_alloc();
  return static_cast<float*>(p);
}
void freeAligned(float* p) {
  std::free(p);
}

// Every column is 64-byte aligned and n is a multiple of 16 (Dataset, scratch, constants).
#define LGP_ALIGNED(p) static_cast<decltype(p)>(__builtin_assume_aligned(p, 64))

template <Op OP>
void kernel(float* __restrict out, const float* __restrict a, const float* __restrict b,
            const float* __restrict c, const float* __restrict d, int n) {
  out = LGP_ALIGNED(out);
  a = LGP_ALIGNED(a);
  b = LGP_ALIGNED(b);
  c = LGP_ALIGNED(c);
  d = LGP_ALIGNED(d);
  n &= ~15;
#pragma omp simd
  for (int i = 0; i < n; ++i) out[i] = sem::apply<OP, float>(a[i], b[i], c[i], d[i]);
}

// pow = exp2(b log2 a) as two passes over the block: one long dependent chain per row stalls
// on latency; two shorter loops pipeline (1.6x, bit-identical).
template <>
void kernel<Op::Pow>(float* __restrict out, const float* __restrict a, const float* __restrict b,
                     const float* __restrict, const float* __restrict, int n) {
#pragma omp simd
  for (int i = 0; i < n; ++i) out[i] = b[i] * sem::plog2(a[i]);
#pragma omp simd
  for (int i = 0; i < n; ++i) out[i] = sem::pexp2(out[i]);
}

constexpr std::array<Kernel, kNumOps> kKernels = {
#define LGP_X_KERNEL(E, ...) &kernel<Op::E>,
    LGP_OPS(LGP_X_KERNEL)
#undef LGP_X_KERNEL
};

// Pair kernels over the fusable arithmetic operators, indexed [O1][O2][mask-1], where bit j of
// mask says that operand j of O2 is O1's result.
constexpr std::array<Op, 6> kFusable = {Op::Add, Op::Sub, Op::Mul, Op::Mad, Op::Min, Op::Max};

template <Op O1, Op O2, int MASK>
void pairKernel(float* __restrict out, const float* __restrict a, const float* __restrict b,
                const float* __restrict c, const float* __restrict p0, const float* __restrict p1,
                const float* __restrict p2, int n) {
  out = LGP_ALIGNED(out);
  a = LGP_ALIGNED(a);
  b = LGP_ALIGNED(b);
  c = LGP_ALIGNED(c);
  p0 = LGP_ALIGNED(p0);
  p1 = LGP_ALIGNED(p1);
  p2 = LGP_ALIGNED(p2);
  n &= ~15;
#pragma omp simd
  for (int i = 0; i < n; ++i) {
    const float t = sem::apply<O1, float>(a[i], b[i], c[i], 0.0f);
    const float q0 = (MASK & 1) ? t : p0[i];
    const float q1 = (MASK & 2) ? t : p1[i];
    const float q2 = (MASK & 4) ? t : p2[i];
    out[i] = sem::apply<O2, float>(q0, q1, q2, 0.0f);
  }
}

template <size_t I>
constexpr PairKernel pairEntry() {
  return &pairKernel<kFusable[I / 42], kFusable[(I / 7) % 6], static_cast<int>(I % 7) + 1>;
}
template <size_t... I>
constexpr std::array<PairKernel, sizeof...(I)> pairTable(std::index_sequence<I...>) {
  return {pairEntry<I>()...};
}
constexpr std::array<PairKernel, 6 * 6 * 7> kPairKernels =
    pairTable(std::make_index_sequence<252>{});

int fusableIndex(Op op) {
  for (size_t k = 0; k < kFusable.size(); ++k)
    if (kFusable[k] == op) return static_cast<int>(k);
  return -1;
}
}  // namespace

Kernel kernelFor(Op op) {
  return kKernels[static_cast<int>(op)];
}

SplitColumn::SplitColumn(const double* y, const double* w, size_t rows, size_t padded) {
  double big = 0;
  min = rows > 0 ? y[0] : 0;
  max = min;
  for (size_t r = 0; r < rows; ++r) {
    big = std::max(big, std::fabs(y[r]));
    min = std::min(min, y[r]);
    max = std::max(max, y[r]);
  }
  // max |y| * scale in [0.5, 1); clamped so that scale stays a normal float.
  const int e = big > 0 && std::isfinite(big) ? std::clamp(std::ilogb(big) + 1, -120, 120) : 0;
  scale = std::ldexp(1.0f, -e);
  inv_scale = std::ldexp(1.0, e);
  hi.resize(padded);
  lo.resize(padded);
  for (size_t r = 0; r < padded; ++r) {
    const double v = y[r] * scale;
    hi[r] = static_cast<float>(v);
    lo[r] = static_cast<float>(v - hi[r]);
  }
  double sw = 0, swy = 0;
  for (size_t r = 0; r < rows; ++r) {
    sw += w[r];
    swy += w[r] * y[r];
  }
  mean = sw > 0 ? swy / sw : 0;
  ss_tot = 0;
  for (size_t r = 0; r < rows; ++r) {
    const double d = y[r] - mean;
    ss_tot += w[r] * d * d;
  }
}

Dataset::Dataset(const Table& t, int block_size) : rows_(t.rows()), block_(block_size) {
  if (block_ < 16 || block_ % 16 != 0)
    throw std::invalid_argument("block size must be a multiple of 16");
  padded_ = rows_ == 0 ? block_ : ((rows_ + block_ - 1) / block_) * block_;
  inputs_.resize(t.numInputs());
  for (size_t i = 0; i < t.numInputs(); ++i) {
    inputs_[i].resize(padded_);
    for (size_t r = 0; r < padded_; ++r)
      inputs_[i][r] = static_cast<float>(t.inputs[i][std::min(r, rows_ - 1)]);
  }
  targets_.resize(t.numOutputs());
  for (size_t o = 0; o < t.numOutputs(); ++o) {
    targets_[o].resize(padded_);
    for (size_t r = 0; r < padded_; ++r) targets_[o][r] = t.outputs[o][std::min(r, rows_ - 1)];
  }
  weights_.assign(padded_, 0.0);
  for (size_t r = 0; r < rows_; ++r) weights_[r] = t.weights.empty() ? 1.0 : t.weights[r];
  weights_f_.assign(weights_.begin(), weights_.end());
  weight_sum_ = 0;
  for (size_t r = 0; r < rows_; ++r) weight_sum_ += weights_[r];
  unit_weights_ =
      std::all_of(weights_.begin(), weights_.begin() + rows_, [](double w) { return w == 1.0; });
  for (size_t o = 0; o < t.numOutputs(); ++o)
    split_.emplace_back(targets_[o].data(), weights_.data(), rows_, padded_);
}

void BoundProgram::bind(const Program& p, int n_inputs) {
  num_inputs = n_inputs;
  steps.clear();
  const_values.clear();
  output_slots.clear();
  bind_id = nextBindId();
  effectiveIndices(p, effective);
  const auto& eff = effective;
  constant = true;
  const_slot_.assign(p.constants.size(), -1);
  for (int i : eff) {
    const Instr& ins = p.code[i];
    for (int a = 0; a < arity(ins.op); ++a) {
      if (ins.args[a].kind == OperandKind::Var) constant = false;
      if (ins.args[a].kind == OperandKind::Const && const_slot_[ins.args[a].index] < 0) {
        const_slot_[ins.args[a].index] = n_inputs + static_cast<int32_t>(const_values.size());
        const_values.push_back(p.constants[ins.args[a].index]);
      }
    }
  }
  const int32_t reg_base = n_inputs + static_cast<int32_t>(const_values.size());
  reg_slot_.assign(p.code.size(), -1);
  for (size_t k = 0; k < eff.size(); ++k) {
    const Instr& ins = p.code[eff[k]];
    Step s{};
    s.kernel = kernelFor(ins.op);
    s.op = ins.op;
    s.dst = reg_base + static_cast<int32_t>(k);
    reg_slot_[eff[k]] = s.dst;
    for (int a = 0; a < kMaxArity; ++a) {
      if (a >= arity(ins.op)) {
        s.src[a] = s.src[0];  // never read; any valid column
        continue;
      }
      const Operand& o = ins.args[a];
      s.src[a] = o.kind == OperandKind::Var     ? static_cast<int32_t>(o.index)
                 : o.kind == OperandKind::Const ? const_slot_[o.index]
                                                : reg_slot_[o.index];
    }
    steps.push_back(s);
  }
  for (uint8_t o : p.outputs) output_slots.push_back(reg_slot_[o]);
  num_slots = reg_base + static_cast<int32_t>(eff.size());
  const_source.assign(const_values.size(), 0);
  for (size_t c = 0; c < const_slot_.size(); ++c)
    if (const_slot_[c] >= 0) const_source[const_slot_[c] - n_inputs] = static_cast<int32_t>(c);
  if (!fuse || steps.size() < 2) return;

  // Pair fusion (see the header). readers[s] counts operand reads of slot s; outputs count too.
  readers_.assign(num_slots, 0);
  for (size_t k = 0; k < eff.size(); ++k)
    for (int a = 0; a < arity(p.code[eff[k]].op); ++a) ++readers_[steps[k].src[a]];
  for (int32_t o : output_slots) readers_[o] += 1000;
  fused_.clear();
  for (size_t k = 0; k < steps.size(); ++k) {
    Step s1 = steps[k];
    if (k + 1 < steps.size()) {
      const Op o1 = p.code[eff[k]].op, o2 = p.code[eff[k + 1]].op;
      const Step& s2 = steps[k + 1];
      const int i1 = fusableIndex(o1), i2 = fusableIndex(o2);
      int mask = 0, uses = 0;
      for (int a = 0; a < arity(o2); ++a)
        if (s2.src[a] == s1.dst) {
          mask |= 1 << a;
          ++uses;
        }
      if (i1 >= 0 && i2 >= 0 && mask != 0 && readers_[s1.dst] == uses) {
        s1.pair = kPairKernels[static_cast<size_t>(i1 * 42 + i2 * 7 + mask - 1)];
        s1.op2 = o2;
        s1.mask = static_cast<uint8_t>(mask);
        for (int a = 0; a < 3; ++a) s1.src2[a] = s2.src[a] == s1.dst ? s2.src[0] : s2.src[a];
        // Operands the pair kernel reads but ignores must still be valid columns.
        for (int a = 0; a < 3; ++a)
          if (s1.src2[a] == s1.dst) s1.src2[a] = s1.src[0];
        s1.dst = s2.dst;
        ++k;
      }
    }
    fused_.push_back(s1);
  }
  steps.swap(fused_);
}

void BoundProgram::updateConstants(const Program& p) {
  for (size_t c = 0; c < const_values.size(); ++c) const_values[c] = p.constants[const_source[c]];
  bind_id = nextBindId();
}

Interpreter::Interpreter(int block_size) : block_(block_size), scratch_(nullptr, &freeAligned) {
  if (block_ < 16 || block_ % 16 != 0)
    throw std::invalid_argument("block size must be a multiple of 16");
  reserve(64);
}

void Interpreter::reserve(int slots) {
  if (slots <= capacity_slots_) return;
  capacity_slots_ = std::max(slots, capacity_slots_ * 2);
  scratch_.reset(allocAligned(static_cast<size_t>(capacity_slots_) * block_));
  filled_id_ = 0;
}

const std::vector<const float*>& Interpreter::evalBlock(const BoundProgram& bp, const Dataset& ds,
                                                        size_t block, int rows) {
  const int n = rows > 0 ? std::min(rows, block_) : block_;
  const int scratch_slots = bp.num_slots - bp.num_inputs;
  reserve(scratch_slots);
  // The operand table holds the inputs' columns too, not only the scratch slots.
  if (ptrs_.size() < static_cast<size_t>(bp.num_slots)) ptrs_.resize(bp.num_slots);
  float* scratch = scratch_.get();
  const size_t off = block * static_cast<size_t>(block_);
  for (int i = 0; i < bp.num_inputs; ++i) ptrs_[i] = ds.input(i) + off;
  for (int s = bp.num_inputs; s < bp.num_slots; ++s)
    ptrs_[s] = scratch + static_cast<size_t>(s - bp.num_inputs) * block_;
  // Constant rows are broadcast once per bound program, not per block.
  if (filled_id_ != bp.bind_id) {
    for (size_t c = 0; c < bp.const_values.size(); ++c)
      std::fill_n(scratch + c * block_, block_, bp.const_values[c]);
    filled_id_ = bp.bind_id;
  }
  const float* const* q = ptrs_.data();
  for (const auto& st : bp.steps) {
    float* out = scratch + static_cast<size_t>(st.dst - bp.num_inputs) * block_;
    if (st.pair)
      st.pair(out, q[st.src[0]], q[st.src[1]], q[st.src[2]], q[st.src2[0]], q[st.src2[1]],
              q[st.src2[2]], n);
    else
      st.kernel(out, q[st.src[0]], q[st.src[1]], q[st.src[2]], q[st.src[3]], n);
  }
  outs_.resize(bp.output_slots.size());
  for (size_t o = 0; o < bp.output_slots.size(); ++o) outs_[o] = ptrs_[bp.output_slots[o]];
  return outs_;
}

std::vector<std::vector<float>> Interpreter::evaluate(const Program& p, const Dataset& ds) {
  if (ds.blockSize() != block_)
    throw std::invalid_argument("dataset and interpreter block sizes differ");
  BoundProgram bp;
  bp.bind(p, ds.numInputs());
  std::vector<std::vector<float>> out(p.outputs.size(), std::vector<float>(ds.rows()));
  for (size_t b = 0; b < ds.numBlocks(); ++b) {
    const auto& o = evalBlock(bp, ds, b);
    const size_t off = b * block_;
    const size_t n = std::min<size_t>(block_, ds.rows() - std::min(ds.rows(), off));
    for (size_t k = 0; k < o.size(); ++k) std::copy_n(o[k], n, out[k].begin() + off);
  }
  return out;
}

void evaluateScalarRows(const Program& p, const Dataset& ds, std::vector<std::vector<float>>& out) {
  const size_t n = ds.rows();
  out.assign(p.outputs.size(), std::vector<float>(n));
  std::vector<float> regs(p.code.size());
  const auto eff = effectiveIndices(p);
  for (size_t r = 0; r < n; ++r) {
    for (int i : eff) {
      const Instr& ins = p.code[i];
      float v[kMaxArity] = {0, 0, 0, 0};
      for (int a = 0; a < arity(ins.op); ++a) {
        const Operand& o = ins.args[a];
        v[a] = o.kind == OperandKind::Var     ? ds.input(o.index)[r]
               : o.kind == OperandKind::Const ? p.constants[o.index]
                                              : regs[o.index];
      }
      regs[i] = sem::applyDynamic<float>(ins.op, v[0], v[1], v[2], v[3]);
    }
    for (size_t k = 0; k < p.outputs.size(); ++k) out[k][r] = regs[p.outputs[k]];
  }
}

}  // namespace lgp
