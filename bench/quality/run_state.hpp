// What a quality run has collected, kept so that a run of many hours can stop and resume
// (lgp_quality --state): the search's checkpoint (lgp/io/checkpoint.hpp), the front at each
// budget reached so far and the accuracy curve. A resumed run restores the search exactly, so
// its report equals an uninterrupted run's (same seed, threads and budgets); only the wall
// times differ, and they add up over the sessions.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgpq {

struct Snapshot {
  double minutes = 0;
  uint64_t evaluations = 0;
  int generation = 0;
  double wall_s = 0;     // since the run started, over every session
  nlohmann::json front;  // lgp-front/1
};

struct CurvePoint {
  double minutes;
  std::vector<double> best;  // per cost level
};

struct RunState {
  std::string table;
  uint64_t seed = 0;
  int threads = 0;
  std::vector<double> minutes;  // the budgets, ascending
  std::vector<Snapshot> snaps;  // one per budget reached
  std::vector<CurvePoint> curve;
  double next_curve = 0;  // the nominal minute of the next curve point
  double wall_s = 0;      // wall time of the sessions before this one
  int sessions = 0;       // sessions that wrote this state
  bool finished = false;  // every budget reached (the search is not needed any more)
  nlohmann::json search;  // Search::checkpoint(), null once finished
};

// "lgp-quality-state/1". Non-finite curve errors are null.
nlohmann::json stateToJson(const RunState& s);
// Reads a state file; errors name the file and the field.
lgp::Expected<RunState> readState(const std::filesystem::path& path);
lgp::Status writeState(const RunState& s, const std::filesystem::path& path);
// A state belongs to a run when its table, seed, threads and budgets are the run's; the error
// names the first that differs, with both values.
lgp::Status checkStateMatches(const RunState& saved, const RunState& run);

}  // namespace lgpq
