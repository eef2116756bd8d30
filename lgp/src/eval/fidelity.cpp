// The fidelity check (fidelity.hpp): the bound program in float32 through the interpreter and
// in double through the same steps, on the same rows, then the output layer and the inverse
// transforms in each precision, compared row by row.
#include "lgp/eval/fidelity.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "lgp/eval/objectives.hpp"
#include "lgp/eval/semantics.hpp"
#include "output_layer.hpp"

namespace lgp {

namespace {

using DoubleColumn = std::vector<double, AlignedAllocator<double>>;
constexpr double kInf = std::numeric_limits<double>::infinity();

// One operator over n rows in double (the reference's semantics, vectorised over rows).
template <Op OP>
void doubleKernel(double* out, const double* a, const double* b, const double* c, const double* d,
                  size_t n) {
#pragma omp simd
  for (size_t i = 0; i < n; ++i) out[i] = sem::apply<OP, double>(a[i], b[i], c[i], d[i]);
}
using DoubleKernel = void (*)(double*, const double*, const double*, const double*, const double*,
                              size_t);
constexpr DoubleKernel kDoubleKernels[] = {
#define LGP_X_DKERNEL(E, ...) &doubleKernel<Op::E>,
    LGP_OPS(LGP_X_DKERNEL)
#undef LGP_X_DKERNEL
};

// `rows` evenly spaced row indices of an n-row table (all of them for rows 0 or >= n).
std::vector<size_t> pickRows(size_t n, size_t rows) {
  std::vector<size_t> idx;
  if (rows == 0 || rows >= n) {
    for (size_t r = 0; r < n; ++r) idx.push_back(r);
  } else {
    for (size_t i = 0; i < rows; ++i) idx.push_back(i * n / rows);
  }
  return idx;
}

Table subTable(const Table& t, const std::vector<size_t>& idx) {
  Table s;
  s.input_names = t.input_names;
  s.output_names = t.output_names;
  s.inputs.resize(t.numInputs());
  s.outputs.resize(t.numOutputs());
  for (size_t r : idx) {
    for (size_t i = 0; i < t.numInputs(); ++i) s.inputs[i].push_back(t.inputs[i][r]);
    for (size_t o = 0; o < t.numOutputs(); ++o) s.outputs[o].push_back(t.outputs[o][r]);
    if (!t.weights.empty()) s.weights.push_back(t.weights[r]);
  }
  return s;
}

// Rows per block of the check's interpreter: the sample in one block, or the usual 256.
int blockFor(size_t rows) {
  const int padded = static_cast<int>((std::max<size_t>(rows, 1) + 15) / 16 * 16);
  return std::min(padded, 256);
}

}  // namespace

std::vector<double> fidelityTolerances(const Table& t) {
  std::vector<double> tol;
  const double unit = std::ldexp(1.0, -kFidelityBits);
  for (size_t o = 0; o < t.numOutputs(); ++o) {
    double sw = 0, swy2 = 0;
    for (size_t r = 0; r < t.rows(); ++r) {
      const double w = t.weights.empty() ? 1.0 : t.weights[r];
      sw += w;
      swy2 += w * t.outputs[o][r] * t.outputs[o][r];
    }
    const double rms = sw > 0 ? std::sqrt(swy2 / sw) : 0.0;
    tol.push_back(unit * (rms > 0 && std::isfinite(rms) ? rms : 1.0));
  }
  return tol;
}

struct FidelityCheck::Impl {
  Dataset ds;                        // the rows in float32
  Interpreter interp;                // block = ds's
  std::vector<DoubleColumn> inputs;  // the rows in double, padded like ds
  std::vector<double> tolerance;     // per model output
  std::vector<TargetTransform> transforms;
  int genes = 1;
  size_t rows = 0;
  // Scratch: double slots of one block, and per program output the values of one block.
  DoubleColumn slots;
  std::vector<const double*> ptr;
  std::vector<std::vector<float>> f32;
  std::vector<DoubleColumn> f64;
  std::vector<LinearScale> identity;
  std::vector<float> layer32;
  std::vector<double> layer64;
  std::vector<const float*> g32;
  std::vector<const double*> g64;

  Impl(const Table& t, const ErrorConfig& cfg, const std::vector<size_t>& idx)
      : ds(subTable(t, idx), blockFor(idx.size())),
        interp(ds.blockSize()),
        tolerance(fidelityTolerances(t)),
        transforms(cfg.transforms),
        genes(std::max(1, cfg.genes)),
        rows(idx.size()) {
    transforms.resize(t.numOutputs(), TargetTransform::None);
    inputs.resize(t.numInputs());
    for (size_t i = 0; i < t.numInputs(); ++i) {
      inputs[i].resize(ds.paddedRows());
      for (size_t r = 0; r < ds.paddedRows(); ++r)
        inputs[i][r] = t.inputs[i][idx[std::min(r, idx.size() - 1)]];
    }
  }

  // The program's outputs on block b in double: the steps of `bp` (fused pairs unfolded).
  void evalDouble(const BoundProgram& bp, size_t b) {
    const size_t bs = static_cast<size_t>(ds.blockSize());
    const size_t scratch = static_cast<size_t>(bp.num_slots - bp.num_inputs);
    if (slots.size() < scratch * bs + bs) slots.resize(scratch * bs + bs);
    ptr.assign(bp.num_slots, nullptr);
    for (int i = 0; i < bp.num_inputs; ++i) ptr[i] = inputs[i].data() + b * bs;
    auto own = [&](int32_t s) {
      return slots.data() + static_cast<size_t>(s - bp.num_inputs) * bs;
    };
    for (int s = bp.num_inputs; s < bp.num_slots; ++s) ptr[s] = own(s);
    for (size_t c = 0; c < bp.const_values.size(); ++c)
      std::fill_n(own(bp.num_inputs + static_cast<int32_t>(c)), bs,
                  static_cast<double>(bp.const_values[c]));
    double* tmp = slots.data() + scratch * bs;  // a fused pair's first result
    for (const auto& st : bp.steps) {
      const double* const* q = ptr.data();
      if (!st.pair) {
        kDoubleKernels[static_cast<int>(st.op)](own(st.dst), q[st.src[0]], q[st.src[1]],
                                                q[st.src[2]], q[st.src[3]], bs);
        continue;
      }
      kDoubleKernels[static_cast<int>(st.op)](tmp, q[st.src[0]], q[st.src[1]], q[st.src[2]],
                                              q[st.src[0]], bs);
      const double* p[3];
      for (int j = 0; j < 3; ++j) p[j] = (st.mask >> j) & 1 ? tmp : q[st.src2[j]];
      kDoubleKernels[static_cast<int>(st.op2)](own(st.dst), p[0], p[1], p[2], p[0], bs);
    }
    f64.resize(bp.output_slots.size());
    for (size_t o = 0; o < bp.output_slots.size(); ++o) {
      f64[o].resize(bs);
      std::copy_n(ptr[bp.output_slots[o]], bs, f64[o].begin());
    }
  }
};

FidelityCheck::FidelityCheck(const Table& t, const ErrorConfig& cfg, size_t rows)
    : impl_(std::make_unique<Impl>(t, cfg, pickRows(t.rows(), rows))) {
  rows_ = impl_->rows;
}

FidelityCheck::~FidelityCheck() = default;

bool FidelityCheck::passes(const BoundProgram& bp, const std::vector<LinearScale>& scales) {
  Impl& m = *impl_;
  last_ratio_ = 0;
  const int raw = static_cast<int>(bp.output_slots.size());
  const int genes = scales.empty() ? 1 : m.genes;
  const int outputs = raw / genes;
  const size_t bs = static_cast<size_t>(m.ds.blockSize());
  const LinearScale* sc = scales.data();
  if (scales.empty()) {
    m.identity.assign(raw, LinearScale{});
    sc = m.identity.data();
  }
  m.layer32.resize(bs);
  m.layer64.resize(bs);
  m.g32.resize(genes);
  m.g64.resize(genes);
  m.f32.resize(raw);
  for (size_t b = 0; b < m.ds.numBlocks(); ++b) {
    const auto& outs = m.interp.evalBlock(bp, m.ds, b);
    for (int o = 0; o < raw; ++o) m.f32[o].assign(outs[o], outs[o] + bs);
    m.evalDouble(bp, b);
    const size_t n = std::min(bs, m.rows - std::min(m.rows, b * bs));
    for (int o = 0; o < outputs; ++o) {
      for (int g = 0; g < genes; ++g) {
        m.g32[g] = m.f32[o * genes + g].data();
        m.g64[g] = m.f64[o * genes + g].data();
      }
      detail::applyLayer<float>(sc + o * genes, genes, m.g32.data(), m.layer32.data(), n);
      detail::applyLayer<double>(sc + o * genes, genes, m.g64.data(), m.layer64.data(), n);
      const TargetTransform t = m.transforms[o];
      const double tol = m.tolerance[o];
      for (size_t r = 0; r < n; ++r) {
        const double a = detail::invertValue<float>(t, m.layer32[r]);
        const double d = detail::invertValue<double>(t, m.layer64[r]);
        const double ratio = std::fabs(a - d) / tol;
        // A value that is not finite (NaN compares false) fails.
        if (!(ratio <= last_ratio_)) last_ratio_ = std::isfinite(ratio) ? ratio : kInf;
      }
    }
  }
  return last_ratio_ <= 1.0;
}

double valueDeviation(const Program& a, const Program& b, const Dataset& ds,
                      const std::vector<TargetTransform>& transforms,
                      const std::vector<double>& tolerance) {
  Interpreter in(ds.blockSize());
  const auto va = in.evaluate(a, ds);
  const auto vb = in.evaluate(b, ds);
  if (va.size() != vb.size()) return kInf;
  double worst = 0;
  for (size_t o = 0; o < va.size(); ++o) {
    const TargetTransform t = o < transforms.size() ? transforms[o] : TargetTransform::None;
    const double tol = o < tolerance.size() ? tolerance[o] : std::ldexp(1.0, -kFidelityBits);
    for (size_t r = 0; r < va[o].size(); ++r) {
      const float x = detail::invertValue<float>(t, va[o][r]);
      const float y = detail::invertValue<float>(t, vb[o][r]);
      if (!std::isfinite(x) || !std::isfinite(y)) {
        if (!(x == y) && !(std::isnan(x) && std::isnan(y))) return kInf;
        continue;
      }
      worst = std::max(worst, std::fabs(static_cast<double>(x) - y) / tol);
    }
  }
  return worst;
}

}  // namespace lgp
