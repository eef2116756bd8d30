// IEEE binary16 emulation for `--precision half` lives in lgp/core/half.hpp (the DAG folds
// and evaluates in half there); these names keep the emitter's spelling.
#pragma once

#include "lgp/core/half.hpp"

namespace lgp::emit {

using lgp::applyHalf;
using lgp::kHalfDivGuard;
using lgp::kHalfExpClamp;
using lgp::kHalfMax;
using lgp::kHalfMinPos;
using lgp::roundToHalf;

}  // namespace lgp::emit
