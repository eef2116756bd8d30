// Residual tables and composite programs of residual stages (stage.hpp).
#include "lgp/search/stage.hpp"

#include <cmath>
#include <map>

namespace lgp {

std::string_view toString(StageMode m) {
  switch (m) {
    case StageMode::Add:
      return "add";
    case StageMode::Mul:
      return "mul";
  }
  return "add";
}

Table residualTable(const Table& t, const std::vector<std::vector<float>>& f,
                    const std::vector<TargetTransform>& transforms, StageMode mode) {
  Table r;
  r.input_names = t.input_names;
  r.inputs = t.inputs;
  r.output_names = t.output_names;
  const size_t rows = t.rows();
  r.weights = t.weights.empty() ? std::vector<double>(rows, 1.0) : t.weights;
  for (size_t o = 0; o < t.numOutputs(); ++o) {
    r.input_names.push_back("f_" + t.output_names[o]);
    std::vector<double> col(rows), res(rows);
    const TargetTransform tr = o < transforms.size() ? transforms[o] : TargetTransform::None;
    for (size_t i = 0; i < rows; ++i) {
      const double fv = f[o][i];
      col[i] = std::isfinite(fv) ? fv : 0.0;
      const double y = applyTransform(tr, t.outputs[o][i]);
      switch (mode) {
        case StageMode::Add:
          res[i] = y - col[i];
          break;
        case StageMode::Mul:
          // (y - f g)^2 = f^2 (y / f - g)^2: the composite's squared error, row by row.
          if (std::fabs(col[i]) > 1e-6 * (1.0 + std::fabs(y))) {
            res[i] = y / col[i];
            r.weights[i] *= col[i] * col[i];
          } else {
            res[i] = 0;
            r.weights[i] = 0;
          }
          break;
      }
      if (!std::isfinite(res[i])) res[i] = 0, r.weights[i] = 0;
    }
    r.inputs.push_back(std::move(col));
    r.outputs.push_back(std::move(res));
  }
  return r;
}

Program composeStage(const Program& base, const Program& correction, int num_inputs,
                     StageMode mode) {
  Program c;
  // Register operands are bytes: a composite past 255 opcodes cannot be written (the caller
  // refuses the empty program, as fitToShape would refuse the long one).
  if (base.code.size() + correction.code.size() + base.outputs.size() > 255 ||
      base.outputs.size() != correction.outputs.size())
    return c;
  std::map<int, int> base_const, corr_const;
  auto constant = [&](std::map<int, int>& m, const Program& from, int slot) {
    auto it = m.find(slot);
    if (it != m.end()) return it->second;
    c.constants.push_back(from.constants[static_cast<size_t>(slot)]);
    return m[slot] = static_cast<int>(c.constants.size()) - 1;
  };
  for (const Instr& in : base.code) {
    Instr out = in;
    for (int a = 0; a < arity(in.op); ++a)
      if (in.args[a].kind == OperandKind::Const)
        out.args[a] = constOperand(constant(base_const, base, in.args[a].index));
    c.code.push_back(out);
  }
  const int offset = static_cast<int>(base.code.size());
  for (const Instr& in : correction.code) {
    Instr out = in;
    for (int a = 0; a < arity(in.op); ++a) {
      const Operand& x = in.args[a];
      if (x.kind == OperandKind::Const)
        out.args[a] = constOperand(constant(corr_const, correction, x.index));
      else if (x.kind == OperandKind::Reg)
        out.args[a] = regOperand(x.index + offset);
      else if (x.index >= num_inputs)
        out.args[a] = regOperand(base.outputs[x.index - num_inputs]);
    }
    c.code.push_back(out);
  }
  for (size_t o = 0; o < base.outputs.size(); ++o) {
    Instr join;
    join.op = mode == StageMode::Add ? Op::Add : Op::Mul;
    join.args[0] = regOperand(base.outputs[o]);
    join.args[1] = regOperand(correction.outputs[o] + offset);
    c.code.push_back(join);
  }
  for (size_t o = 0; o < base.outputs.size(); ++o)
    c.outputs.push_back(static_cast<uint8_t>(c.code.size() - base.outputs.size() + o));
  return c;
}

}  // namespace lgp
