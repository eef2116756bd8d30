// The checkpoint of a search as JSON ("lgp-checkpoint/2"), written by Search::checkpoint() and
// read by Search::restore():
// { "format": "lgp-checkpoint/2",
//   "config_digest": "16 hex digits",   // configDigest: restore() rejects another config/table
//   "initialized": true, "generation": G, "evaluations": E, "elapsed_s": T,
//   "migrants": M, "remote_migrants": R, "restarts": S, "ranks": 1,
//   "island_first": 0, "island_total": K,  // the islands held: [first, first + size) of total
//   "islands": [ {"population": [member...], "rank": [...], "crowd": [...], "best": e,
//                 "stagnant": n} ],
//   "archive": [member...],
//   "parts": [checkpoint...] }          // combineCheckpoints only: each rank's own
// member: {"program": {...}, "obj": [error, cost, discontinuity], "refined": bool}. JSON has
// no infinity: a non-finite error, crowding distance or island best is null.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/config/config.hpp"
#include "lgp/core/status.hpp"
#include "lgp/core/table.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/search/search.hpp"

namespace lgp {

// [error, cost, discontinuity]; a non-finite error is null.
nlohmann::json objectivesToJson(const Objectives& o);
Expected<Objectives> objectivesFromJson(const nlohmann::json& j);

// A hash of everything that changes the search: every field of toJson(cfg) but where results
// go (output), how ranks exchange migrants (mpi), the threads, the budgets a resume may extend
// (generations, max_evaluations, wall_time_s) and the semantic cache (time, never the result);
// and the table's values. tests/core/config_roundtrip_test.cpp checks every field against it.
std::string configDigest(const RunConfig& cfg, const Table& table);

// Search::checkpoint() and Search::restore() (search.hpp says what they keep and check).
nlohmann::json checkpointToJson(const Search& s);
Status restoreFromCheckpoint(Search& s, const nlohmann::json& state, bool take_counters);

// One whole-search checkpoint from the checkpoints of disjoint island ranges covering every
// island (the ranks of an MPI run, in rank order): islands in order, archives merged in
// order (so the result is deterministic), counters summed, the lowest generation, the
// longest elapsed time. The parts are kept under "parts" so that a resume on as many ranks
// restores each rank exactly.
Expected<nlohmann::json> combineCheckpoints(const RunConfig& cfg, const ProgramShape& shape,
                                            const std::vector<nlohmann::json>& parts);

}  // namespace lgp
