// The data-parallel bytecode interpreter.
//
// Rules it relies on:
//  1. Bind once, evaluate many: a Program is decoded once into a BoundProgram holding only its
//     effective opcodes, each with a kernel pointer and operand slots.
//  2. Rows are processed in blocks of `block_size` (a multiple of 16, sized so that
//     registers x block fits in L1/L2). Each opcode runs over the whole block in one kernel
//     call: dispatch cost is per opcode per block, never per row.
//  3. Every operand is a float column of the block: an input column of the Dataset, a
//     register row of the scratch buffer, or a constant broadcast row. Kernels are plain loops
//     over `float*` that the compiler vectorises; transcendentals come from vecmath.hpp.
//  4. The scratch buffer belongs to the Interpreter (one per thread) and is sized once; the
//     hot loop never allocates, throws or calls scalar libm.
//  5. Reductions over rows accumulate per block (in float lanes of a fixed layout, see
//     fastErrorBound in objectives.hpp), and blocks are combined in double in block order, so
//     results do not depend on the thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/core/table.hpp"

namespace lgp {

// 64-byte aligned storage, so that every block column starts on a cache line and the kernels
// can tell the compiler so (no peeling, aligned vector loads).
template <class T>
struct AlignedAllocator {
  using value_type = T;
  AlignedAllocator() = default;
  template <class U>
  AlignedAllocator(const AlignedAllocator<U>&) {}
  T* allocate(size_t n) {
    return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t(64)));
  }
  void deallocate(T* p, size_t) { ::operator delete(p, std::align_val_t(64)); }
  template <class U>
  bool operator==(const AlignedAllocator<U>&) const {
    return true;
  }
};

// A double column prepared for float error accumulation (see accumulate in objectives.cpp):
// y * scale = hi + lo with hi = float(y * scale) and lo = float(y * scale - hi), so a float
// prediction's difference to y keeps about 48 bits of y. scale is a power of two (exact) that
// puts max |y| in [0.5, 1): squared differences stay far from float overflow and underflow
// whatever the target's magnitude. Also the column's statistics over the real rows, for the
// closed-form error of a constant prediction.
struct SplitColumn {
  std::vector<float, AlignedAllocator<float>> hi, lo;  // every padded row
  float scale = 1;
  double inv_scale = 1;
  double mean = 0, ss_tot = 0;  // weighted mean; weighted sum of squares about it (R^2)
  double min = 0, max = 0;      // over every row, whatever its weight
  SplitColumn() = default;
  SplitColumn(const double* y, const double* w, size_t rows, size_t padded);
};

// Float32 copy of a table's columns, padded to a whole number of blocks (padding repeats the
// last row so that it stays inside every operator's domain; padded rows carry weight 0).
class Dataset {
 public:
  Dataset() = default;
  Dataset(const Table& t, int block_size);

  size_t rows() const { return rows_; }
  size_t paddedRows() const { return padded_; }
  int blockSize() const { return block_; }
  size_t numBlocks() const { return padded_ / block_; }
  int numInputs() const { return static_cast<int>(inputs_.size()); }
  int numOutputs() const { return static_cast<int>(targets_.size()); }
  const float* input(int i) const { return inputs_[i].data(); }
  const double* target(int o) const { return targets_[o].data(); }  // double ground truth
  const SplitColumn& split(int o) const { return split_[o]; }       // float form of target(o)
  const double* weight() const { return weights_.data(); }          // always present
  const float* weightF() const { return weights_f_.data(); }        // the same in float
  bool unitWeights() const { return unit_weights_; }                // every real row has weight 1
  double weightSum() const { return weight_sum_; }

 private:
  size_t rows_ = 0, padded_ = 0;
  int block_ = 256;
  std::vector<std::vector<float, AlignedAllocator<float>>> inputs_;
  std::vector<std::vector<double>> targets_;
  std::vector<SplitColumn> split_;
  std::vector<double> weights_;
  std::vector<float, AlignedAllocator<float>> weights_f_;
  double weight_sum_ = 0;
  bool unit_weights_ = true;
};

using Kernel = void (*)(float* out, const float* a, const float* b, const float* c, const float* d,
                        int n);
// Two fused opcodes: t = O1(a, b, c) stays in a register, out = O2 over (p0, p1, p2) with t
// substituted for the operands selected at bind time.
using PairKernel = void (*)(float* out, const float* a, const float* b, const float* c,
                            const float* p0, const float* p1, const float* p2, int n);

// A decoded program: effective opcodes only, operands as slot numbers.
// Slots: [0, num_inputs) inputs, then constants, then registers.
//
// Pair fusion: every kernel stores its result column, so cheap operators are bound by stores
// (one vector store per 8 rows). When an arithmetic opcode (add/sub/mul/mad/min/max) is read
// only by the next one, also arithmetic, both run in one PairKernel and the intermediate never
// leaves a register. Results are bit-identical (same operations, same rounding).
struct BoundProgram {
  struct Step {
    Kernel kernel;                       // used when pair is null
    PairKernel pair = nullptr;           // fused pair: src = first opcode's operands
    std::array<int32_t, kMaxArity> src;  // slot per operand (unused ones point at slot 0)
    std::array<int32_t, 3> src2{};       // fused pair: the second opcode's other operands
    int32_t dst;                         // register slot
    // The operators, for evaluators in another precision (eval/fidelity.hpp): op, and for a
    // fused pair op2 over (src2 with op's result at the operands in mask's bits).
    Op op = Op::Add, op2 = Op::Add;
    uint8_t mask = 0;
  };
  std::vector<Step> steps;
  std::vector<float> const_values;  // one per bound constant slot
  std::vector<int32_t> output_slots;
  int num_inputs = 0;
  int num_slots = 0;
  uint64_t bind_id = 0;  // unique per bind(): lets an Interpreter skip re-broadcasting constants

  std::vector<int32_t> const_source;  // program constant slot of each bound constant
  bool fuse = true;                   // allow pair fusion (off: one kernel per opcode)
  std::vector<int> effective;         // effectiveIndices(p) of the bound program
  bool constant = false;  // no effective opcode reads an input: each output is one value

  // Rebinding reuses every buffer: no allocation once they have grown to the largest program.
  void bind(const Program& p, int num_inputs);
  // Refreshes constant values after p's constants changed (same structure); cheap, used by
  // Nelder-Mead so that it binds once per refinement.
  void updateConstants(const Program& p);

 private:
  // bind()'s working buffers.
  std::vector<int32_t> const_slot_, reg_slot_;
  std::vector<int> readers_;
  std::vector<Step> fused_;
};

Kernel kernelFor(Op op);

class Interpreter {
 public:
  explicit Interpreter(int block_size = 256);

  // Evaluates rows [block*bs, (block+1)*bs) and returns one pointer per output, valid until
  // the next call. Never allocates once the scratch has grown to the largest program.
  // rows > 0 evaluates only the block's first `rows` rows (a multiple of 16).
  const std::vector<const float*>& evalBlock(const BoundProgram& bp, const Dataset& ds,
                                             size_t block, int rows = 0);

  // Convenience: all outputs for all rows (allocates; not for the hot loop). [output][row]
  std::vector<std::vector<float>> evaluate(const Program& p, const Dataset& ds);

  int blockSize() const { return block_; }

 private:
  void reserve(int slots);
  int block_;
  int capacity_slots_ = 0;
  uint64_t filled_id_ = 0;  // bind_id whose constants are broadcast in the scratch
  std::unique_ptr<float[], void (*)(float*)> scratch_;
  std::vector<const float*> ptrs_;
  std::vector<const float*> outs_;
};

// Double-precision reference evaluation of every row, [output][row]. Same protected
// semantics (semantics.hpp); used by tests and for final scoring.
std::vector<std::vector<double>> evaluateReference(const Program& p, const Table& t);
std::vector<double> evaluateReferenceRow(const Program& p, const double* inputs);
// The same with the constants given in double (one per constant slot), e.g. to take finite
// differences smaller than a float step.
std::vector<double> evaluateReferenceRow(const Program& p, const double* inputs,
                                         const double* constants);

// Naive per-row scalar interpreter (switch per opcode per row), kept as the baseline the
// benchmarks compare against. Not used by the search.
void evaluateScalarRows(const Program& p, const Dataset& ds, std::vector<std::vector<float>>& out);

}  // namespace lgp
