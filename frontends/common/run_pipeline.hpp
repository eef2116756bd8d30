// The pipeline every search of a run config goes through, whoever runs it: `lgp run`
// (frontends/lgp/cmd_run.cpp), an lgpd job in process or over MPI (frontends/lgpd/jobs.cpp)
// and lgp.fit (frontends/python/module.cpp). Each calls these steps in this order and adds
// only what differs (the progress display, the store, the MPI launch), so that what one of
// them does to a run the others do too:
//
//   1. loadRunTable (table_source.hpp): the table, checked for the float32 evaluation.
//   2. prepareRun: the references checked on the table (before a night's work, not after),
//      the seeds, and what the mode (two_step, MPI) allows.
//   3. startSearch, on the built (or restored) Search: measured cost in the archive, the
//      seeds and, on a fresh start, the exhaustive enumeration.
//   4. The frontend's own loop: initialize() on a fresh start, then step() until done().
//   5. frontJson, then FrontExtras::addTo: the front with the enumeration's certificate, the
//      scored references and the members' measured GPU cost. emptyFrontMessage says why a
//      finished search has none.
//
// Without the emit library a config that asks for references or measured cost gets an error
// naming the field.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/table.hpp"
#include "lgp/search/search.hpp"

namespace lgp::cli {

// Step 2. The seeds of the search (search.seed_references; none when `resume`: the checkpoint
// holds the populations), once the references parse and fit the table and the mode allows
// what the config asks: no seeds under two_step, and measured cost in the archive or the
// exhaustive enumeration only in one process (`distributed`: over MPI) with one step. The
// error names the field.
Expected<std::vector<NamedProgram>> prepareRun(const RunConfig& cfg, const Table& t, bool resume,
                                               bool distributed);

// What startSearch did.
struct SearchStart {
  // The enumeration's certificate for the front JSON ("exhaustive", with "seeded"); null when
  // the config does not ask for it or the search was resumed.
  nlohmann::json exhaustive;
  // Why a seed was not taken: a reference that does not fit the program shape is reported,
  // not fatal.
  std::vector<std::string> not_seeded;
};
// Step 3, before initialize(): objectives.measured_cost.in_search, the seeds and, when
// `fresh`, search.exhaustive, whose non-dominated members seed the islands too.
Expected<SearchStart> startSearch(Search& s, const std::vector<NamedProgram>& seeds, bool fresh);

// Step 5. The front JSON of the search's front (frontToJson), with the enumeration's
// certificate when there is one.
nlohmann::json frontJson(const Search& s, const nlohmann::json& exhaustive);
// Why a finished search has no front (every program scored NaN or infinity, or none was
// scored): "the search ended with an empty front: ...".
std::string emptyFrontMessage(const Search& s);

// The extras of every front JSON of one run: the config's references scored on its table
// (once, at construction: every front gets the same scores) and each member's measured GPU
// cost (objectives.measured_cost.families; the measurements are cached, so a live snapshot
// measures only the members new since the last one).
class FrontExtras {
 public:
  FrontExtras(const RunConfig& cfg, const Table& t);
  // Adds "references" and the measured cost to a front JSON made by frontJson. Returns a line
  // for the user: what was measured in how long, or why nothing could be; empty when the
  // config asks for no measured cost.
  std::string addTo(nlohmann::json& front) const;

 private:
  nlohmann::json references_;        // null without references
  std::vector<GpuFamily> families_;  // measured; none = no measured cost
};

}  // namespace lgp::cli
