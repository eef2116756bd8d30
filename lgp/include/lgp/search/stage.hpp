// Residual stages (search.stages): an accurate fit is a cheap fit plus corrections, and the
// corrections are cheap fits too. A stage island searches a correction g of an archive member
// f (the base) with the whole engine, on the base's residual table: its inputs are the run's
// plus f's value per output, its target what f leaves (additive: T(y) - f; multiplicative:
// T(y) / f, weighted by f^2 so that the squared error is the composite's). The composite
// f + g (or f * g) is one program, scored, costed and checked (the fidelity rule) like any
// other before it enters the archive, refined there jointly (every constant, LM), and may be
// the base of a later stage.
#pragma once

#include <string_view>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

enum class StageMode : uint8_t { Add, Mul };
std::string_view toString(StageMode m);

// The residual table of a base whose per-output values (in program space, the outputs'
// transforms applied: what the program computes) are `f` on the rows of `t`. Inputs: t's,
// then one column per output named "f_<output>"; targets: the residual; weights: t's (mul:
// times f^2, and 0 where |f| is too small to divide by).
Table residualTable(const Table& t, const std::vector<std::vector<float>>& f,
                    const std::vector<TargetTransform>& transforms, StageMode mode);

// The composite program: the base's opcodes, then the correction's, which reads base output
// o where it reads input num_inputs + o; then per output one add (or mul) of the two. Both
// programs final (introns pruned, any output layer applied); constants renumbered densely.
Program composeStage(const Program& base, const Program& correction, int num_inputs,
                     StageMode mode);

}  // namespace lgp
