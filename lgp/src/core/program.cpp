#include "lgp/core/program.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>

namespace lgp {

namespace {
std::string where(size_t i) {
  return "opcode " + std::to_string(i);
}
}  // namespace

Status validate(const Program& p, const ProgramShape& shape) {
  const int n = static_cast<int>(p.code.size());
  if (n < shape.num_outputs || n < 1)
    return Status::error("program has " + std::to_string(n) + " opcodes, needs at least " +
                         std::to_string(std::max(1, shape.num_outputs)));
  if (n > shape.max_length || n > 255)
    return Status::error("program has " + std::to_string(n) + " opcodes, " +
                         (n > 255 ? std::string("at most 255 are allowed")
                                  : "max_length is " + std::to_string(shape.max_length)));
  if (static_cast<int>(p.constants.size()) != shape.num_constants)
    return Status::error("program has " + std::to_string(p.constants.size()) +
                         " constant slots, expected " + std::to_string(shape.num_constants));
  for (int i = 0; i < n; ++i) {
    const Instr& ins = p.code[i];
    if (static_cast<int>(ins.op) >= kNumOps) return Status::error(where(i) + ": bad operator");
    for (int a = 0; a < arity(ins.op); ++a) {
      const Operand& o = ins.args[a];
      switch (o.kind) {
        case OperandKind::Var:
          if (o.index >= shape.num_inputs)
            return Status::error(where(i) + ": input x" + std::to_string(o.index) +
                                 " out of range");
          break;
        case OperandKind::Const:
          if (o.index >= shape.num_constants)
            return Status::error(where(i) + ": constant c" + std::to_string(o.index) +
                                 " out of range");
          break;
        case OperandKind::Reg:
          if (o.index >= i)
            return Status::error(where(i) + ": reference r" + std::to_string(o.index) +
                                 " is not an earlier opcode");
          break;
      }
    }
  }
  if (static_cast<int>(p.outputs.size()) != shape.num_outputs)
    return Status::error("program has " + std::to_string(p.outputs.size()) + " outputs, expected " +
                         std::to_string(shape.num_outputs));
  for (size_t k = 0; k < p.outputs.size(); ++k) {
    if (p.outputs[k] >= n)
      return Status::error("output " + std::to_string(k) + " refers to missing opcode");
    if (shape.output_mode == OutputMode::Last &&
        p.outputs[k] != n - shape.num_outputs + static_cast<int>(k))
      return Status::error("output " + std::to_string(k) + " is not one of the last opcodes");
  }
  for (float c : p.constants)
    if (!std::isfinite(c)) return Status::error("non-finite constant");
  return Status::ok();
}

void syncOutputs(Program& p, const ProgramShape& shape) {
  const int n = static_cast<int>(p.code.size());
  if (shape.output_mode == OutputMode::Last) {
    p.outputs.resize(shape.num_outputs);
    for (int k = 0; k < shape.num_outputs; ++k)
      p.outputs[k] = static_cast<uint8_t>(n - shape.num_outputs + k);
  } else {
    p.outputs.resize(shape.num_outputs, static_cast<uint8_t>(n - 1));
    for (auto& o : p.outputs)
      if (o >= n) o = static_cast<uint8_t>(n - 1);
  }
}

std::vector<int> effectiveIndices(const Program& p) {
  std::vector<int> eff;
  effectiveIndices(p, eff);
  return eff;
}

void effectiveIndices(const Program& p, std::vector<int>& out) {
  const int n = static_cast<int>(p.code.size());
  // Programs have at most 255 opcodes (validate), so the marks normally live on the stack.
  std::array<uint8_t, 256> local;  // only the first n are cleared and used
  std::vector<uint8_t> heap;
  uint8_t* mark = local.data();
  if (n > static_cast<int>(local.size())) {
    heap.resize(n);
    mark = heap.data();
  }
  std::fill_n(mark, n, uint8_t{0});
  for (uint8_t o : p.outputs)
    if (o < n) mark[o] = 1;
  for (int i = n - 1; i >= 0; --i) {
    if (!mark[i]) continue;
    const Instr& ins = p.code[i];
    for (int a = 0; a < arity(ins.op); ++a)
      if (ins.args[a].kind == OperandKind::Reg && ins.args[a].index < i)
        mark[ins.args[a].index] = 1;
  }
  out.clear();
  for (int i = 0; i < n; ++i)
    if (mark[i]) out.push_back(i);
}

std::vector<int> effectiveConstants(const Program& p) {
  std::vector<uint8_t> used(p.constants.size(), 0);
  for (int i : effectiveIndices(p)) {
    const Instr& ins = p.code[i];
    for (int a = 0; a < arity(ins.op); ++a)
      if (ins.args[a].kind == OperandKind::Const && ins.args[a].index < used.size())
        used[ins.args[a].index] = 1;
  }
  std::vector<int> out;
  for (size_t c = 0; c < used.size(); ++c)
    if (used[c]) out.push_back(static_cast<int>(c));
  return out;
}

Program pruneIntrons(const Program& p) {
  const auto eff = effectiveIndices(p);
  std::vector<int> remap(p.code.size(), -1);
  Program q;
  q.constants = p.constants;
  for (int i : eff) {
    remap[i] = static_cast<int>(q.code.size());
    Instr ins = p.code[i];
    for (int a = 0; a < kMaxArity; ++a) {
      if (a >= arity(ins.op)) {
        ins.args[a] = Operand{};  // canonical unused operand
        continue;
      }
      if (ins.args[a].kind == OperandKind::Reg)
        ins.args[a].index = static_cast<uint8_t>(remap[ins.args[a].index]);
    }
    q.code.push_back(ins);
  }
  for (uint8_t o : p.outputs) q.outputs.push_back(static_cast<uint8_t>(remap[o]));
  return q;
}

std::string formatFloat(float v) {
  char buf[64];
  auto res = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, res.ptr);
}

std::string formatDouble(double v) {
  char buf[64];
  for (int prec = 1; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

nlohmann::json toJson(const Program& p) {
  nlohmann::json code = nlohmann::json::array();
  for (const Instr& ins : p.code) {
    nlohmann::json row = nlohmann::json::array();
    row.push_back(std::string(opName(ins.op)));
    for (int a = 0; a < arity(ins.op); ++a) {
      const Operand& o = ins.args[a];
      const char k = o.kind == OperandKind::Var ? 'x' : o.kind == OperandKind::Const ? 'c' : 'r';
      std::string tok(1, k);  // appended, not string + string: GCC 12 warns falsely there
      tok += std::to_string(o.index);
      row.push_back(tok);
    }
    code.push_back(row);
  }
  nlohmann::json consts = nlohmann::json::array();
  for (float c : p.constants) consts.push_back(c);
  return {{"code", code}, {"constants", consts}, {"outputs", p.outputs}};
}

Expected<Program> programFromJson(const nlohmann::json& j, const ProgramShape& shape) {
  if (!j.is_object() || !j.contains("code") || !j["code"].is_array())
    return Status::error("program: \"code\" must be an array");
  Program p;
  size_t i = 0;
  for (const auto& row : j["code"]) {
    const std::string at = "program/code/" + std::to_string(i);
    if (!row.is_array() || row.empty() || !row[0].is_string())
      return Status::error(at + ": must be [\"op\", operands...]");
    auto op = opFromString(row[0].get<std::string>());
    if (!op) return Status::error(at + ": unknown operator '" + row[0].get<std::string>() + "'");
    Instr ins;
    ins.op = *op;
    if (static_cast<int>(row.size()) != 1 + arity(*op))
      return Status::error(at + ": " + std::string(opName(*op)) + " takes " +
                           std::to_string(arity(*op)) + " operands");
    for (int a = 0; a < arity(*op); ++a) {
      if (!row[a + 1].is_string()) return Status::error(at + ": operand must be a string");
      const std::string s = row[a + 1].get<std::string>();
      if (s.size() < 2 || (s[0] != 'x' && s[0] != 'c' && s[0] != 'r'))
        return Status::error(at + ": bad operand '" + s + "'");
      int idx = 0;
      auto r = std::from_chars(s.data() + 1, s.data() + s.size(), idx);
      if (r.ec != std::errc() || r.ptr != s.data() + s.size() || idx < 0 || idx > 255)
        return Status::error(at + ": bad operand '" + s + "'");
      ins.args[a].kind = s[0] == 'x'   ? OperandKind::Var
                         : s[0] == 'c' ? OperandKind::Const
                                       : OperandKind::Reg;
      ins.args[a].index = static_cast<uint8_t>(idx);
    }
    p.code.push_back(ins);
    ++i;
  }
  if (j.contains("constants")) {
    if (!j["constants"].is_array()) return Status::error("program/constants: must be an array");
    for (const auto& c : j["constants"]) {
      if (!c.is_number()) return Status::error("program/constants: must be numbers");
      p.constants.push_back(c.get<float>());
    }
  }
  if (j.contains("outputs")) {
    if (!j["outputs"].is_array()) return Status::error("program/outputs: must be an array");
    for (const auto& o : j["outputs"]) {
      // As a 64-bit value: get<int>() would wrap 2^32 to 0, a register the file did not name.
      const bool in_range = o.is_number_unsigned()  ? o.get<uint64_t>() <= 255
                            : o.is_number_integer() ? o.get<int64_t>() >= 0 &&
                                                          o.get<int64_t>() <= 255
                                                    : false;
      if (!in_range)
        return Status::error("program/outputs: must be opcode indices in [0, 255] (got " +
                             o.dump() + ")");
      p.outputs.push_back(static_cast<uint8_t>(o.get<int64_t>()));
    }
  } else {
    syncOutputs(p, shape);
  }
  ProgramShape s = shape;
  s.num_constants = static_cast<int>(p.constants.size());
  s.max_length = std::max<int>(shape.max_length, static_cast<int>(p.code.size()));
  if (auto st = validate(p, s); !st) return Status::error("program: " + st.message());
  return p;
}

}  // namespace lgp
