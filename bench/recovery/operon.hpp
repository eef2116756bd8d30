// Runs Operon's `operon_gp` (a peer engine, never a build dependency) on one CSV and reads
// its per-generation rows. The binary is given by path; nothing here assumes where it lives.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace recovery {

struct OperonJob {
  std::string exe;  // path of operon_gp
  std::string csv;  // training rows, then held-out rows
  std::string target;
  std::vector<std::string> inputs;
  int train_rows = 0, test_rows = 0;
  int budget_s = 60;
  int threads = 1;
  uint64_t seed = 1;
  std::vector<std::string> symbols;  // --enable-symbols
  double r2_threshold = 0.99999;
  bool stop_at_recovery = true;  // end the process once a row shows recovery
};

struct OperonResult {
  std::string error;  // empty = ran and produced rows
  bool recovered = false;
  double time_s = 0;     // `elapsed` of the first recovered row
  double test_r2 = 0;    // at recovery, else of the last row
  double train_r2 = 0;   // same row
  double elapsed_s = 0;  // of the last row read
  int generations = 0;   // rows read
  std::string model;     // the best model line (absent when stopped at recovery)
  bool stopped = false;  // ended by us at recovery
};

// The argument vector of a job (argv[0] = exe), for running and for the report.
std::vector<std::string> operonArgs(const OperonJob& job);
OperonResult runOperon(const OperonJob& job);

}  // namespace recovery
