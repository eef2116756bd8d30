// How far a new archive member moves the front: the area it takes off the staircase of the
// best log10 error at cost <= c, over cost bands one cost unit wide. Island time shares follow
// it (search.islands.adaptive), so a gain counts the same at the cheap and the accurate end:
// halving the error of a 50-unit member is worth what halving a 5-unit member's is, band for
// band.
#pragma once

#include <vector>

#include "lgp/eval/objectives.hpp"

namespace lgp {

class FrontGain {
 public:
  // Bands [b, b + 1) for b < max_cost; a member costing more moves nothing.
  explicit FrontGain(int max_cost = 256);
  // The staircase of these members (the archive's, at the start of a generation).
  void reset(const std::vector<Objectives>& members);
  // The area (decades x cost units) that `o` takes off the staircase, which then includes it.
  // A band below every member counts from the worst error of the last reset, so the first
  // member there gains what it is better than that, not an infinity.
  double add(const Objectives& o);

 private:
  std::vector<double> best_;  // log10 of the lowest error at cost < b + 1
  double ceiling_ = 0;        // log10 of the worst finite error of the last reset
};

}  // namespace lgp
