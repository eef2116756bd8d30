// Residual tables and composite programs of residual stages (stage.hpp).
#include "lgp/search/stage.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include "lgp/eval/interpreter.hpp"

namespace lgp {

std::string_view toString(StageMode m) {
  switch (m) {
    case StageMode::Add:
      return "add";
    case StageMode::Mul:
      return "mul";
    case StageMode::Inside:
      return "inside";
  }
  return "add";
}

std::string_view toString(StagePick p) {
  return p == StagePick::Spread ? "spread" : "accurate";
}

std::vector<size_t> stageBases(const std::vector<std::pair<double, double>>& error_cost, int bases,
                               StagePick pick) {
  std::vector<size_t> idx(error_cost.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  const size_t n = std::min(idx.size(), static_cast<size_t>(std::max(bases, 0)));
  if (pick == StagePick::Accurate) {
    std::stable_sort(idx.begin(), idx.end(),
                     [&](size_t a, size_t b) { return error_cost[a] < error_cost[b]; });
    idx.resize(n);
    return idx;
  }
  std::stable_sort(idx.begin(), idx.end(), [&](size_t a, size_t b) {
    const auto &x = error_cost[a], &y = error_cost[b];
    return x.second != y.second ? x.second < y.second : x.first < y.first;
  });
  std::vector<size_t> stair;
  for (size_t i : idx)
    if (stair.empty() || error_cost[i].first < error_cost[stair.back()].first) stair.push_back(i);
  const size_t m = std::min(stair.size(), n);
  std::vector<size_t> out;
  for (size_t i = 0; i < m; ++i)
    out.push_back(stair[m == 1 ? 0 : i * (stair.size() - 1) / (m - 1)]);
  return out;
}

Table residualTable(const Table& t, const std::vector<std::vector<float>>& f,
                    const std::vector<TargetTransform>& transforms, StageMode mode, int input,
                    const std::vector<double>& slope) {
  Table r;
  r.input_names = t.input_names;
  r.inputs = t.inputs;
  r.output_names = t.output_names;
  const size_t rows = t.rows();
  r.weights = t.weights.empty() ? std::vector<double>(rows, 1.0) : t.weights;
  double span = 0;
  if (mode == StageMode::Inside && input >= 0 && static_cast<size_t>(input) < t.numInputs() &&
      rows > 0) {
    const auto [lo, hi] = std::minmax_element(t.inputs[input].begin(), t.inputs[input].end());
    span = *hi - *lo;
  }
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
        case StageMode::Inside: {
          // (y - f(x + g))^2 ~ f'^2 ((y - f) / f' - g)^2: a Gauss-Newton step in x_input. A
          // step past the input's span is no linearisation of anything: such a row is out.
          const double s = i < slope.size() ? slope[i] : 0.0;
          const double step = s != 0 ? (y - col[i]) / s : INFINITY;
          if (std::isfinite(step) && std::fabs(step) <= span) {
            res[i] = step;
            r.weights[i] *= s * s;
          } else {
            res[i] = 0;
            r.weights[i] = 0;
          }
          break;
        }
      }
      if (!std::isfinite(res[i])) res[i] = 0, r.weights[i] = 0;
    }
    r.inputs.push_back(std::move(col));
    r.outputs.push_back(std::move(res));
  }
  return r;
}

std::vector<double> inputSlope(const Program& base, const Table& t, int input, int block_size) {
  const size_t rows = t.rows();
  std::vector<double> slope(rows, 0.0);
  if (input < 0 || static_cast<size_t>(input) >= t.numInputs() || rows == 0) return slope;
  const auto& x = t.inputs[input];
  const auto [lo_it, hi_it] = std::minmax_element(x.begin(), x.end());
  const double lo = *lo_it, hi = *hi_it;
  const double h = 1e-3 * (hi > lo ? hi - lo : 1.0);
  Table up = t, down = t;
  up.outputs.clear();
  down.outputs.clear();
  for (size_t r = 0; r < rows; ++r) {
    up.inputs[input][r] = std::min(x[r] + h, hi);
    down.inputs[input][r] = std::max(x[r] - h, lo);
  }
  Interpreter interp(block_size);
  const auto fu = interp.evaluate(base, Dataset(up, block_size));
  const auto fd = interp.evaluate(base, Dataset(down, block_size));
  for (size_t r = 0; r < rows; ++r) {
    const double dx = up.inputs[input][r] - down.inputs[input][r];
    const double v = (static_cast<double>(fu[0][r]) - fd[0][r]) / dx;
    slope[r] = dx > 0 && std::isfinite(v) ? v : 0.0;
  }
  return slope;
}

Program composeStage(const Program& base, const Program& correction, int num_inputs, StageMode mode,
                     int input) {
  Program c;
  // Register operands are bytes: a composite past 255 opcodes cannot be written (the caller
  // refuses the empty program, as fitToShape would refuse the long one).
  const size_t tail = mode == StageMode::Inside ? base.code.size() + 1 : base.outputs.size();
  if (base.code.size() + correction.code.size() + tail > 255 ||
      base.outputs.size() != correction.outputs.size() ||
      (mode == StageMode::Inside && (base.outputs.size() != 1 || input < 0 || input >= num_inputs)))
    return c;
  std::map<int, int> base_const, corr_const;
  auto constant = [&](std::map<int, int>& m, const Program& from, int slot) {
    auto it = m.find(slot);
    if (it != m.end()) return it->second;
    c.constants.push_back(from.constants[static_cast<size_t>(slot)]);
    return m[slot] = static_cast<int>(c.constants.size()) - 1;
  };
  // Appends `from`'s opcodes: constants through `consts`, registers moved by `shift`, inputs
  // through `read`.
  auto append = [&](const Program& from, std::map<int, int>& consts, int shift, auto&& read) {
    for (const Instr& in : from.code) {
      Instr out = in;
      for (int a = 0; a < arity(in.op); ++a) {
        const Operand& x = in.args[a];
        if (x.kind == OperandKind::Const)
          out.args[a] = constOperand(constant(consts, from, x.index));
        else if (x.kind == OperandKind::Reg)
          out.args[a] = regOperand(x.index + shift);
        else
          out.args[a] = read(x);
      }
      c.code.push_back(out);
    }
  };
  append(base, base_const, 0, [](const Operand& x) { return x; });
  const int offset = static_cast<int>(base.code.size());
  append(correction, corr_const, offset, [&](const Operand& x) {
    return x.index >= num_inputs ? regOperand(base.outputs[x.index - num_inputs]) : x;
  });
  if (mode == StageMode::Inside) {
    Instr arg;
    arg.op = Op::Add;
    arg.args[0] = inputOperand(input);
    arg.args[1] = regOperand(correction.outputs[0] + offset);
    c.code.push_back(arg);
    const int at = static_cast<int>(c.code.size()) - 1;
    const int again = at + 1;
    append(base, base_const, again,
           [&](const Operand& x) { return x.index == input ? regOperand(at) : x; });
    c.outputs.push_back(static_cast<uint8_t>(base.outputs[0] + again));
    return pruneIntrons(c);
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
