// Multi-objective selection over (error, cost, discontinuity), all minimised.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "lgp/core/program.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

// a dominates b: no worse in every objective and better in one. Non-finite error never
// dominates and is dominated by every finite individual.
bool dominates(const Objectives& a, const Objectives& b);

// Non-dominated sorting (ENS-BS, Zhang et al. 2015). Returns the front rank per individual
// (0 = best): 1 + the highest rank among those that dominate it, as NSGA-II defines it.
std::vector<int> nondominatedRanks(const std::vector<Objectives>& objs);

// Crowding distance of each member of `front` (indices into objs); boundary points +inf.
std::vector<double> crowdingDistance(const std::vector<Objectives>& objs,
                                     const std::vector<int>& front);

struct ArchiveConfig {
  int max_size = 256;              // hard bound on members
  double eps_log10_error = 0.01;   // error box width in decades (0.01: 2.3 % relative)
  double eps_cost = 0.0;           // cost box width (0 = exact)
  double eps_discontinuity = 0.0;  // discontinuity box width (0 = exact)
  Status validate() const;
};

struct ArchiveMember {
  Program program;
  Objectives obj;
  bool refined = false;  // constants already polished by Nelder-Mead
};

// The Pareto archive kept across the whole run.
//
// Bound: epsilon-box dominance (Laumanns et al. 2002). Objectives map to boxes
// (floor(log10(error)/eps_e), floor(cost/eps_c), floor(disc/eps_d)); a box holds at most one
// member (the one that dominates, else the lower error), and a candidate whose box is
// dominated by a member's box is rejected. With eps_c = eps_d = 0 every distinct cost keeps
// its own trade-off, and errors within one 2.3 % box (default) collapse to one member. If the
// archive still exceeds max_size, the member with the smallest crowding distance is removed
// (never the lowest-error or lowest-cost member). Non-finite members are never inserted.
class Archive {
 public:
  explicit Archive(ArchiveConfig cfg = {});
  // Returns true if the candidate entered the archive.
  bool insert(const Program& p, const Objectives& o, bool refined = false);
  // Whether insert would turn a candidate with these objectives away.
  bool rejects(const Objectives& o) const;
  const std::vector<ArchiveMember>& members() const { return members_; }
  std::vector<ArchiveMember>& mutableMembers() { return members_; }
  void clear() { members_.clear(); }
  // Re-establishes the invariants after members' objectives changed (e.g. after refinement).
  void rebuild();
  // Members sorted by cost, then error (for printing and output).
  std::vector<ArchiveMember> sorted() const;

 private:
  struct Box {
    long long e, c, d;
  };
  Box box(const Objectives& o) const;
  void enforceSize();
  ArchiveConfig cfg_;
  std::vector<ArchiveMember> members_;
};

// Which unrefined archive members a periodic full refinement serves first.
enum class ArchiveRefineOrder : uint8_t {
  Oldest,   // storage order: the longest-lived first (long-lived cheap members, mostly)
  Accurate  // lowest error first: the accurate end, whose members are replaced fastest and so
            // would otherwise rarely reach the head of the queue
};

// Indices of at most `max` unrefined members of `members`, in the order they are refined.
// Deterministic: ties in error go to the lower cost, then the lower discontinuity, then the
// earlier member.
std::vector<int> refineQueue(const std::vector<ArchiveMember>& members, int max,
                             ArchiveRefineOrder order);

// Survival stratified by cost (search.cost_strata): the indices of `keep` survivors of a pool
// of objective vectors. The finite members' cost range is cut into `strata` equal slices; the
// lowest-error members of each slice (keep / (4 strata), at least 1; a member equal in every
// objective to the one kept before it is skipped) survive first, then the rest in `order` (the
// pool in NSGA-II order). strata <= 0 keeps the first `keep` of `order`.
std::vector<int> stratifiedSurvivors(const std::vector<Objectives>& pool,
                                     const std::vector<int>& order, int keep, int strata);

}  // namespace lgp
