// Residual stages (search.stages): an accurate fit is a cheap fit plus corrections, and the
// corrections are cheap fits too. A stage island searches a correction g of an archive member
// f (the base) with the whole engine, on the base's residual table: its inputs are the run's
// plus f's value per output, its target what f leaves (additive: T(y) - f; multiplicative:
// T(y) / f, weighted by f^2 so that the squared error is the composite's). The composite
// f + g (or f * g) is one program, scored, costed and checked (the fidelity rule) like any
// other before it enters the archive, refined there jointly (every constant, LM), and may be
// the base of a later stage.
//
// Inside f (a corrected argument): the composite is f with one input x_i replaced by x_i + g.
// Its residual is not a table of anything g alone computes, so the stage searches g on the
// Gauss-Newton linearisation around f: f(x_i + g) ~ f + g df/dx_i, target (T(y) - f) / f',
// weighted by f'^2 (f' by differences of f across the table's step in x_i); every composite is
// then scored exactly on the run's table before the archive sees it.
#pragma once

#include <string_view>
#include <utility>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

enum class StageMode : uint8_t { Add, Mul, Inside };
std::string_view toString(StageMode m);

// Which archive members a stage corrects (search.stages.pick): the most accurate that leave
// room (accurate), or bases spread along the front's error-cost staircase from its cheap end
// (spread): a cheap member plus a correction may reach accuracies the accurate members' own
// refinement does not.
enum class StagePick : uint8_t { Accurate, Spread };
std::string_view toString(StagePick p);

// The bases a stage rotates over, as indices into candidates given by (error, cost), at most
// `bases`: the most accurate first (cost breaks ties), or (spread) steps of the error-cost
// staircase (each more accurate than every cheaper candidate) evenly spaced, cheapest first.
std::vector<size_t> stageBases(const std::vector<std::pair<double, double>>& error_cost, int bases,
                               StagePick pick);

// The residual table of a base whose per-output values (in program space, the outputs'
// transforms applied: what the program computes) are `f` on the rows of `t`. Inputs: t's,
// then one column per output named "f_<output>"; targets: the residual; weights: t's (mul:
// times f^2, and 0 where |f| is too small to divide by; inside: times slope^2, and 0 where
// the step (T(y) - f) / slope would leave the input's span). `slope` (inside only, one
// output): the base's derivative along the corrected input, per row.
Table residualTable(const Table& t, const std::vector<std::vector<float>>& f,
                    const std::vector<TargetTransform>& transforms, StageMode mode, int input = 0,
                    const std::vector<double>& slope = {});

// df/dx_input of a one-output base on the rows of `t`: central differences over a step of
// 1e-3 of the input's span, one-sided at the span's ends (a base may be undefined past them);
// 0 where f is not finite.
std::vector<double> inputSlope(const Program& base, const Table& t, int input, int block_size);

// The composite program: the base's opcodes, then the correction's, which reads base output
// o where it reads input num_inputs + o; then per output one add (or mul) of the two. Both
// programs final (introns pruned, any output layer applied); constants renumbered densely.
// Inside: the base's opcodes (for a correction that reads f), the correction's, x_input + g,
// then the base's opcodes again reading that sum for x_input; introns pruned. Empty when the
// composite would pass 255 opcodes.
Program composeStage(const Program& base, const Program& correction, int num_inputs, StageMode mode,
                     int input = 0);

}  // namespace lgp
