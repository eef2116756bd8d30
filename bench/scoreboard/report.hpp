// report.md, summary.json and timing.json of a scoreboard run.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "board.hpp"

namespace lgp::board {

struct RunInfo {
  Settings settings;
  std::string cpu;                          // the CPU model(s) of the tables' runs
  double wall_s = 0, cpu_s = 0;             // summed over the tables' runs
  std::vector<std::string> missing;         // tables of the spec without a record yet
  std::vector<std::string> other_settings;  // records run with other settings, left out
};

// Writes the three files; returns the one-paragraph summary (also at the top of report.md).
std::string writeReport(const std::vector<TableRun>& runs, const RunInfo& info,
                        const std::filesystem::path& dir);

}  // namespace lgp::board
