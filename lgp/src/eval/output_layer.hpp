// The output layer applied to a program's raw outputs, as the materialised opcodes compute it
// (applyLinearScaling, objectives.hpp), in float32 (the interpreter's rounding: mad rounds
// twice) or double. Shared by the Scorer and the fidelity check so that both compute exactly
// what the exported program does.
//
// Output o reads genes g = 0..G-1, raw outputs o*G + g, each with a LinearScale {a_g, b_g}.
// The lead gene is the first with a != 0 (gene 0 where every a is 0); only it carries an
// offset b. t = the lead's scale applied to it (mul by a where b = 0, add b where a = 1, else
// mad(f, a, b)); then t = mad(f_g, a_g, t) for each later gene with a_g != 0.
#pragma once

#include <cstddef>

#include "lgp/eval/objectives.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp::detail {

// Inverse target transform with the operators' protected semantics, in T precision (the
// float32 one is what an exported shader computes after its output).
template <class T>
inline T invertValue(TargetTransform t, T v) {
  switch (t) {
    case TargetTransform::None:
      return v;
    case TargetTransform::Log:
      return sem::apply<Op::Exp, T>(v, v, v, v);
    case TargetTransform::Sqrt:
      return v > T(0) ? v * v : T(0);
    case TargetTransform::Rcp:
      return sem::apply<Op::Rcp, T>(v, v, v, v);
  }
  return v;
}

// The lead gene of output o's scales s[0..genes).
inline int leadGene(const LinearScale* s, int genes) {
  for (int g = 0; g < genes; ++g)
    if (s[g].a != 0.0f) return g;
  return 0;
}

// out[r] = the layer over columns f[0..genes) (f[g][r]), for r < n. out may alias f[lead].
template <class T>
void applyLayer(const LinearScale* s, int genes, const T* const* f, T* out, size_t n) {
  const int lead = leadGene(s, genes);
  const LinearScale& ls = s[lead];
  const T a = static_cast<T>(ls.a), b = static_cast<T>(ls.b);
  const T* v = f[lead];
  switch (ls.op()) {
    case Op::Mul:
#pragma omp simd
      for (size_t r = 0; r < n; ++r) out[r] = v[r] * a;
      break;
    case Op::Add:
#pragma omp simd
      for (size_t r = 0; r < n; ++r) out[r] = v[r] + b;
      break;
    default:
#pragma omp simd
      for (size_t r = 0; r < n; ++r) out[r] = sem::apply<Op::Mad, T>(v[r], a, b, T(0));
      break;
  }
  for (int g = lead + 1; g < genes; ++g) {
    if (s[g].a == 0.0f) continue;
    const T ag = static_cast<T>(s[g].a);
    const T* fg = f[g];
#pragma omp simd
    for (size_t r = 0; r < n; ++r) out[r] = sem::apply<Op::Mad, T>(fg[r], ag, out[r], T(0));
  }
}

}  // namespace lgp::detail
