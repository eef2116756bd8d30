// The emitter's intermediate form is the lgp expression DAG (lgp/core/expr.hpp): the same
// buildDag / simplify / intervals / evaluation that the front printer uses, so the emitted
// code and `lgp front` show one formula. These declarations keep the emitter's spelling.
#pragma once

#include <string>
#include <vector>

#include "lgp/core/expr.hpp"
#include "lgp/core/formula.hpp"
#include "lgp/core/interval.hpp"

namespace lgp::emit {

using lgp::applyOp;
using lgp::buildDag;
using lgp::countPiecewise;
using lgp::Dag;
using lgp::evaluateRow;
using lgp::Interval;
using lgp::isProtected;
using lgp::LinearProgram;
using lgp::Node;
using lgp::nodeIntervals;
using lgp::Precision;
using lgp::precisionFromString;
using lgp::provenUnguarded;
using lgp::simplify;
using lgp::SimplifyOptions;
using lgp::toProgram;
using lgp::toString;

// Readable infix of every output, one self-contained text each (lgp::printOutputs).
inline std::vector<std::string> dagInfix(const Dag& d, const std::vector<std::string>& names) {
  return printOutputs(d, names);
}

}  // namespace lgp::emit
