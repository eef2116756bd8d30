// What `lgp run` and the Python module do around a search, so that both write the same front:
// the config's reference formulas (checked, seeded, scored), measured cost in the archive, and
// the members' measured GPU cost in the front JSON. Without the emit library, a config that
// asks for these gets an error naming the field.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/search.hpp"

namespace lgp::cli {

// Before the search: the references parse and fit the table (not after a night's work).
Status checkRunReferences(const RunConfig& cfg, const Table& t);
// The references that seed the search (search.seed_references); none when it is off.
Expected<std::vector<NamedProgram>> referenceSeeds(const RunConfig& cfg, const Table& t);
// What a two-step or MPI run cannot do: seeds under two_step, and measured cost in the
// archive or the exhaustive enumeration outside one process with one step. The error names
// the field.
Status checkRunMode(const RunConfig& cfg, bool has_seeds, bool distributed);
// objectives.measured_cost.in_search on `s` (a no-op when off).
Status enableArchiveMeasuredCost(Search& s);
// search.exhaustive on `s` (before initialize()): the enumeration's non-dominated members
// seed the islands; returns the certificate for the front JSON ("exhaustive"), with
// "seeded", or null when the config does not ask for it.
Expected<nlohmann::json> runExhaustive(Search& s);
// Why a finished search has no front (every program scored NaN or infinity, or none was
// scored): "the search ended with an empty front: ...".
std::string emptyFrontMessage(const Search& s);
// Adds "references" (scored on the run's table) and each member's measured GPU cost to a
// front JSON made by frontToJson. Returns a line for the user: what was measured in how long,
// or why nothing could be; empty when the config asks for no measured cost.
std::string addFrontExtras(nlohmann::json& front, const Search& s);

}  // namespace lgp::cli
