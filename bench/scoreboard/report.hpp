// report.md, summary.json, timing.json and readme.md (the README's opening section) of a
// scoreboard run.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "board.hpp"

namespace lgp::board {

struct RunInfo {
  Settings settings;                        // of the unseeded board (seed_references false)
  std::string cpu;                          // the CPU model(s) of the tables' runs
  double wall_s = 0, cpu_s = 0;             // summed over the tables' runs, both boards
  std::vector<std::string> missing;         // tables of the spec without an unseeded record
  std::vector<std::string> other_settings;  // records run with other settings, left out
};

// The true median: the mean of the two middle values of an even count.
double median(std::vector<double> v);

// Writes the files from the unseeded board `runs` and, where run, the same tables seeded with
// the published fits (`seeded`, by table name); returns the one-paragraph summary.
std::string writeReport(const std::vector<TableRun>& runs,
                        const std::map<std::string, TableRun>& seeded, const RunInfo& info,
                        const std::filesystem::path& dir);

}  // namespace lgp::board
