// report.md, summary.json and timing.json of a scoreboard run.
#pragma once

#include <filesystem>
#include <string>

#include "board.hpp"

namespace lgp::board {

struct RunInfo {
  bool quick = false;
  int threads = 2;
  uint64_t seed = 1;
  std::vector<double> minutes;
  std::string cpu;  // the CPU model
  double wall_s = 0, cpu_s = 0;
};

// Writes the three files; returns the one-paragraph summary (also at the top of report.md).
std::string writeReport(const std::vector<TableRun>& runs, const RunInfo& info,
                        const std::filesystem::path& dir);

}  // namespace lgp::board
