// Variation operators. Every function returns a program that satisfies validate(): operand
// references always point at earlier opcodes, lengths stay within [k, max_length], and in
// OutputMode::Last the outputs are re-synchronised.
#pragma once

#include "lgp/core/program.hpp"
#include "lgp/core/rng.hpp"

namespace lgp {

struct InitConfig {
  int min_length = 2;
  int max_length = 12;
  double const_min = -2.0;
  double const_max = 2.0;
};

Program randomProgram(const ProgramShape& shape, const InitConfig& init, Rng& rng);
Instr randomInstr(const ProgramShape& shape, int position, Rng& rng);
Operand randomOperand(const ProgramShape& shape, int position, Rng& rng);

// Two-segment linear crossover: child = a[0:i) + b[k:l) + a[j:), at random points (segments of
// at most 8 opcodes; a itself when no child of a valid length results). See crossoverAt.
Program crossover(const Program& a, const Program& b, const ProgramShape& shape, Rng& rng);

// The crossover child a[0:i) + b[k:l) + a[j:), for 0 <= i < j <= |a| and 0 <= k < l <= |b|
// giving a valid length. The segment is copied blindly; references are then remapped so that
// they still point at earlier opcodes (relative offsets inside the segment are preserved).
// Constants follow the structure: the segment reads the values it read in b, and the
// effective opcodes from a read a's; where both read one slot with different values, the
// segment's copy moves to a slot neither reads (shared, with a's value, only if none is free).
Program crossoverAt(const Program& a, const Program& b, const ProgramShape& shape, int i, int j,
                    int k, int l, Rng& rng);

// Micro mutation: one operator, operand, output slot (Designated mode) or constant change.
// With probability effective_bias the target is an effective opcode. A constant change takes
// a slot that effective opcodes read (the target opcode's own, if it reads one), when any
// does; it is a relative Gaussian step of constant_sigma, or in one case out of ten a reset,
// uniform in [const_min, const_max] like the initial constants.
void microMutate(Program& p, const ProgramShape& shape, Rng& rng, double constant_sigma,
                 double effective_bias, double const_min = -2.0, double const_max = 2.0);

// Macro mutation: insert a random opcode or delete one (redirecting its users), shifting
// references. An inserted opcode is always effective and the outputs stay the same opcodes: it
// lands before the last output (in OutputMode::Last, before the last k opcodes) and a later
// effective opcode is wired to it; with one output it may instead land right after the output
// and become the output, reading the old one. With probability wrap_share an inserted opcode
// takes the operand it replaces as one of its own, so x becomes op(x, ..) and the program grows
// around what already works.
void macroMutate(Program& p, const ProgramShape& shape, Rng& rng, double wrap_share = 0.5);

// Weight mutation (Operon's weighted leaves, as opcodes): one operand x (an input or an earlier
// result) of an effective opcode becomes mul(c, x), c a constant slot that no opcode reads, set
// to 1 so the program's value is unchanged (1 * x == x in float32, NaN and -0 included);
// constant fitting then moves the new coefficient. Operands already weighted (an operand of a
// mul by a constant, or a mul by a constant itself) are left alone. False, and p unchanged,
// where no operand qualifies, the program is at max_length or every constant slot is read.
bool weightMutate(Program& p, const ProgramShape& shape, Rng& rng);

}  // namespace lgp
