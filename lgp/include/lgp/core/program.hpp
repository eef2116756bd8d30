// Linear-GP programs (Brameier & Banzhaf 2007, "Linear Genetic Programming").
//
// A program is a string of at most `max_length` opcodes. Each opcode applies an operator to up
// to four operands (only select uses four); an operand is an input variable, a slot of the
// program's own float constant array, or the result of any *earlier* opcode. The string is
// therefore a DAG with reusable sub-expressions. Outputs are the last k opcodes (default) or
// designated opcode indices. Opcodes that no output depends on are introns; they are kept in
// the genome (they carry material for crossover) but never evaluated.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "lgp/core/ops.hpp"
#include "lgp/core/status.hpp"

namespace lgp {

enum class OperandKind : uint8_t { Var, Const, Reg };

struct Operand {
  OperandKind kind = OperandKind::Var;
  uint8_t index = 0;  // input column, constant slot, or earlier opcode position
  friend bool operator==(const Operand&, const Operand&) = default;
};

// Operand constructors, for building programs by hand (tests, parsers, examples).
constexpr Operand inputOperand(int i) {
  return {OperandKind::Var, static_cast<uint8_t>(i)};
}
constexpr Operand constOperand(int i) {
  return {OperandKind::Const, static_cast<uint8_t>(i)};
}
constexpr Operand regOperand(int i) {
  return {OperandKind::Reg, static_cast<uint8_t>(i)};
}

struct Instr {
  Op op = Op::Add;
  std::array<Operand, kMaxArity> args{};
  friend bool operator==(const Instr&, const Instr&) = default;
};

enum class OutputMode : uint8_t {
  Last,       // outputs are the last k opcodes
  Designated  // outputs are opcode indices stored in the program and mutated with it
};

// What every program of a run looks like. Shared by variation, evaluation and validation.
struct ProgramShape {
  int num_inputs = 1;     // input variables (table columns)
  int num_outputs = 1;    // k
  int max_length = 32;    // opcodes per program, 1..255
  int num_constants = 8;  // constant slots per program, 0..255
  OutputMode output_mode = OutputMode::Last;
  OpSet ops = OpSet::all();  // operators that variation may use
  int genes = 1;  // program results per model output (the output layer; num_outputs counts all)
};

struct Program {
  std::vector<Instr> code;
  std::vector<float> constants;
  std::vector<uint8_t> outputs;  // opcode index per output; kept in sync in Last mode

  friend bool operator==(const Program&, const Program&) = default;
};

// A program with a label (a parsed reference formula used as a seed, say).
struct NamedProgram {
  std::string name;
  Program program;
};

// Checks every structural invariant; the message names the first violation.
Status validate(const Program& p, const ProgramShape& shape);

// Recomputes outputs for OutputMode::Last (last k opcodes).
void syncOutputs(Program& p, const ProgramShape& shape);

// Indices of effective opcodes (those some output depends on), ascending. Backward marking
// as in Brameier & Banzhaf's intron removal, on the DAG form.
std::vector<int> effectiveIndices(const Program& p);
// The same into `out`, reusing its capacity (no allocation in steady state).
void effectiveIndices(const Program& p, std::vector<int>& out);

// Constant slots referenced by effective opcodes, ascending.
std::vector<int> effectiveConstants(const Program& p);

// A copy holding only the effective opcodes, with operands renumbered.
Program pruneIntrons(const Program& p);

// Readable infix, one self-contained text per output, over the given input names: the
// program simplified with the rewrites that hold for every input (no domain, no pow rewrites)
// and printed by the formula printer (core/formula.hpp), so each text parses back into a
// program that the interpreter evaluates bit-identically. For fronts, printFormula /
// programFormula with the table's domain is the text to show.
std::vector<std::string> toInfix(const Program& p, const std::vector<std::string>& input_names);

// Shortest decimal string that reads back as the same float.
std::string formatFloat(float v);
// Shortest %g string that reads back as the same double.
std::string formatDouble(double v);

// Compact, readable encoding: {"code": [["mad","x0","c1","r0"], ...], "constants": [...],
// "outputs": [...]}. Operands: xI input, cI constant slot, rI earlier opcode.
nlohmann::json toJson(const Program& p);
Expected<Program> programFromJson(const nlohmann::json& j, const ProgramShape& shape);

}  // namespace lgp
