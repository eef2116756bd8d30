// The metadata a generated table records (datasets/README.md): definition per output, the
// canonical scene, grid and row order, integrator, evaluation counts, largest estimated error
// overall and per output, accuracy target, convergence, limits and generator version.
// Private to the datasets library.
#pragma once

#include <nlohmann/json.hpp>

#include "lgp/datasets/generate.hpp"

namespace lgp::datasets::detail {

nlohmann::json tableMeta(const Scene& s, const IntegratorOptions& io, const GeneratedTable& g,
                         const nlohmann::json& max_by_output);

}  // namespace lgp::datasets::detail
