// Calibration of the cost model (lgp/eval/cost_model.hpp) against measured ISA (gpu_cost.hpp):
// a corpus of random effective programs over every operator, their model features and their
// measured instruction counts, and a non-negative least-squares fit of the model's per-operator,
// guard and literal prices to those counts. bench/cost drives it; the fitted tables are the
// `rdna` and `gcn` columns of the operator table, and the held-out test in tests/emit checks
// that the shipped tables still predict fresh programs within the error the fit reported.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "lgp/core/interval.hpp"
#include "lgp/core/program.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/eval/cost_model.hpp"

namespace lgp::emit {

struct CalibrationSample {
  std::string name;  // "random 17", or a published formula's name
  Program program;
  int num_inputs = 0;
  std::vector<Interval> domain;  // per input
  CostFeatures features;         // of the simplified DAG on `domain`
  // Marginal ACO instruction counts per family (gpu_cost.hpp), NaN where not measured.
  std::array<double, kNumGpuFamilies> measured{};
};

struct CorpusOptions {
  int programs = 2400;  // random programs
  uint64_t seed = 1;    // the held-out test uses other seeds than the shipped fit
  int max_length = 16;  // opcodes per program before pruning
  int max_inputs = 3;   // 1..max_inputs inputs
  int max_outputs = 2;  // 1..max_outputs outputs
};
// Random programs over every operator, each with one of a few domains ([0, 1], [1/64, 1] x
// [0, 1], [-1, 1], [0.1, 10]) so that guards are sometimes proven away and sometimes not, and a
// share of constants drawn from the inline set. Programs whose simplified DAG has no operator
// are skipped. Deterministic in the seed.
std::vector<CalibrationSample> randomCorpus(const CorpusOptions& o);
// A sample for a given program (a published formula, a front member).
CalibrationSample calibrationSample(std::string name, const Program& p, int num_inputs,
                                    const std::vector<Interval>& domain);

// Measures every sample on every family in `families` (HLSL, --fast, as fronts are measured),
// with up to `threads` workers per family at once.
Status measureCorpus(std::vector<CalibrationSample>& samples,
                     const std::vector<GpuFamily>& families, int threads = 2);

struct CostFit {
  GpuFamily family = GpuFamily::Rdna2;
  CostModel model;  // the fitted prices (cost, guard, extras); domain left empty
  // On the held-out samples: coefficient of determination, RMS error, worst absolute error
  // and worst error relative to the measured count (over samples measuring >= 4).
  double r2 = 0, rmse = 0, worst_abs = 0, worst_rel = 0;
  int train = 0, test = 0;
};
// Non-negative least squares (Lawson-Hanson) of the measured counts of `family` on the
// features of `train`, evaluated on `test`. A feature no training sample has gets price 0.
CostFit fitCostModel(const std::vector<CalibrationSample>& train,
                     const std::vector<CalibrationSample>& test, GpuFamily family);

}  // namespace lgp::emit
