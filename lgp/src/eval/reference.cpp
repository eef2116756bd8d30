// Double-precision reference evaluator: the same protected semantics as the interpreter
// (semantics.hpp), evaluated row by row with libm. For tests and final scoring only.
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/semantics.hpp"

namespace lgp {

std::vector<double> evaluateReferenceRow(const Program& p, const double* inputs) {
  const std::vector<double> constants(p.constants.begin(), p.constants.end());
  return evaluateReferenceRow(p, inputs, constants.data());
}

std::vector<double> evaluateReferenceRow(const Program& p, const double* inputs,
                                         const double* constants) {
  std::vector<double> regs(p.code.size(), 0.0);
  for (int i : effectiveIndices(p)) {
    const Instr& ins = p.code[i];
    double v[kMaxArity] = {0, 0, 0, 0};
    for (int a = 0; a < arity(ins.op); ++a) {
      const Operand& o = ins.args[a];
      v[a] = o.kind == OperandKind::Var     ? inputs[o.index]
             : o.kind == OperandKind::Const ? constants[o.index]
                                            : regs[o.index];
    }
    regs[i] = sem::applyDynamic<double>(ins.op, v[0], v[1], v[2], v[3]);
  }
  std::vector<double> out;
  for (uint8_t o : p.outputs) out.push_back(regs[o]);
  return out;
}

std::vector<std::vector<double>> evaluateReference(const Program& p, const Table& t) {
  const size_t n = t.rows();
  std::vector<std::vector<double>> out(p.outputs.size(), std::vector<double>(n));
  std::vector<double> row(t.numInputs());
  for (size_t r = 0; r < n; ++r) {
    for (size_t i = 0; i < t.numInputs(); ++i) row[i] = t.inputs[i][r];
    const auto v = evaluateReferenceRow(p, row.data());
    for (size_t k = 0; k < v.size(); ++k) out[k][r] = v[k];
  }
  return out;
}

}  // namespace lgp
