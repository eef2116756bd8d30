// Forward-mode derivatives of a program's outputs with respect to its effective constants,
// over the same row blocks and float32 kernels as the interpreter (interpreter.hpp).
//
// Each effective opcode first computes its value column with the interpreter's kernel (so
// values are bit-identical to Interpreter::evalBlock), then one derivative column per constant
// it depends on: d v / d c_k = sum over operands j of (d op / d operand_j) * (d operand_j / d
// c_k). Opcodes that depend on no constant carry no derivative columns at all.
//
// Derivatives follow the protected semantics of ops.hpp: where a guard, clamp or floor is
// active, the derivative with respect to the guarded operand is 0 (div/rcp with
// |b| < kDivGuard, sqrt at a <= 0, rsqrt/log/log2/pow at a <= kMinPos, exp/exp2/pow at an
// exponent outside (-kExpClamp, kExpClamp)); piecewise operators take the derivative of the
// active branch (min, max, select, abs, saturate). Select's comparison operands have
// derivative 0. Near the float range limits a derivative may overflow to +-inf (rsqrt near
// kMinPos, say); callers that need finite Jacobians check.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/eval/interpreter.hpp"

namespace lgp {

// Derivative kernel of one opcode with respect to one constant: out = sum over operands of
// d op / d operand * d operand / d c. v is the opcode's value column, a..d its operands,
// da..dd their derivative columns (operands without a derivative are never read).
using DerivKernel = void (*)(float* out, const float* v, const float* a, const float* b,
                             const float* c, const float* d, const float* da, const float* db,
                             const float* dc, const float* dd, int n);

// Values and derivatives d out_o / d c_k of a program's outputs with respect to its effective
// constants, block by block over one Dataset, in float32 like the interpreter. One instance
// per thread.
//
// Opcodes that depend on no constant compute the same columns on every pass, so the first
// pass over a block keeps those that constant-dependent opcodes or outputs read, and later
// passes (a constant fit evaluates one program many times) skip them all.
class JacobianEvaluator {
 public:
  JacobianEvaluator() = default;

  // Decodes p for ds (allocates; once per program). The parameters are effectiveConstants(p),
  // in ascending slot order, initialised to p's constant values. ds must outlive the binding.
  void bind(const Program& p, const Dataset& ds);
  // Program constant slot of each parameter.
  const std::vector<int>& parameters() const { return params_; }
  int numParameters() const { return static_cast<int>(params_.size()); }
  int numOutputs() const { return static_cast<int>(output_cols_.size()); }
  int blockSize() const { return block_; }

  // New parameter values (one per parameter, rounded to float like program constants).
  void setParameters(const double* x);
  // Evaluates rows [block*bs, (block+1)*bs): values, and derivatives unless told not to.
  // Never allocates.
  void evalBlock(size_t block, bool derivatives = true);

  // Columns of the last evalBlock, block_size rows each, valid until the next call.
  const float* value(int output) const { return cols_[output_cols_[output]]; }
  // Whether the output depends on the parameter at all (structurally).
  bool hasDerivative(int output, int param) const {
    return output_dcols_[static_cast<size_t>(output) * params_.size() + param] != zero_col_;
  }
  // The zero column when the output does not depend on the parameter.
  const float* derivative(int output, int param) const {
    return cols_[output_dcols_[static_cast<size_t>(output) * params_.size() + param]];
  }

 private:
  struct Step {  // one effective opcode
    Kernel kernel;
    std::array<int32_t, kMaxArity> src;  // value columns of the operands
    int32_t dst;                         // value column
    int32_t dbegin, dend;                // its derivative steps
    bool constant_free;                  // depends on no parameter
    int32_t cache = -1;                  // constant-free and read by others: its cache slot
  };
  struct DStep {  // derivative of one opcode with respect to one parameter
    DerivKernel kernel;
    std::array<int32_t, kMaxArity> dsrc;  // derivative columns of the operands
    int32_t dst;                          // derivative column
  };

  // Writable column c (every column but the inputs lives in the scratch).
  float* own(int32_t c) { return scratch_.data() + static_cast<size_t>(c - param_col0_) * block_; }

  const Dataset* ds_ = nullptr;
  int block_ = 0;
  int num_inputs_ = 0;
  std::vector<int> params_;
  std::vector<Step> steps_;
  std::vector<DStep> dsteps_;
  std::vector<int32_t> output_cols_;
  std::vector<int32_t> output_dcols_;  // [output][param]
  // Columns: inputs (pointers into the Dataset, set per block), parameter broadcasts,
  // register values, then the zero and ones columns and the derivative columns.
  std::vector<const float*> cols_;
  int32_t param_col0_ = 0, zero_col_ = 0, one_col_ = 0;
  std::vector<float, AlignedAllocator<float>> scratch_;
  // Cached constant-free columns, [slot][padded row], and which blocks hold them.
  std::vector<float, AlignedAllocator<float>> cache_;
  std::vector<uint8_t> cached_;
};

// The derivative kernel of `op` where bit j of `mask` says that operand j carries a derivative.
DerivKernel derivKernelFor(Op op, int mask);

}  // namespace lgp
