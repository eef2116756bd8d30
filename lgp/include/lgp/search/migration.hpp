// Islands and migration.
//
// One search runs K islands (demes), each with its own NSGA-II population, all feeding one
// Pareto archive. Every `migration_interval` generations each island sends a few members of
// its first front to the next island of a ring (Cantú-Paz 1998, "A survey of parallel genetic
// algorithms"); islands that stay apart explore different structures, and migration spreads
// what works. The transport is behind a small interface so that islands can live in other
// processes or on other machines: the search only says "send these to island j" and "what has
// arrived for island i".
//
// Determinism: migration happens at a generation boundary, islands are visited in index order
// and a transport returns what arrived in the order it was sent, so a run is reproducible for a
// fixed seed, thread count and K.
#pragma once

#include <cstdint>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

struct Migrant {
  Program program;
  Objectives obj;  // as scored by the sender (same table, same objectives)
};

// Carries migrants between islands. Islands are numbered 0..K-1 across the whole search.
class MigrationTransport {
 public:
  virtual ~MigrationTransport() = default;
  // Queues migrants from island `from` for island `to`. Must not block on the receiver.
  virtual void send(int from, int to, std::vector<Migrant> migrants) = 0;
  // Takes everything that has arrived for island `to`, in the order it was sent.
  virtual std::vector<Migrant> receive(int to) = 0;
  // Migrants sent since construction (for progress reports).
  virtual uint64_t sent() const = 0;
  // Of those, migrants sent to an island in another process.
  virtual uint64_t sentRemote() const { return 0; }
};

// In-process transport: one queue per island.
class LocalTransport final : public MigrationTransport {
 public:
  explicit LocalTransport(int islands) : inbox_(islands) {}
  void send(int from, int to, std::vector<Migrant> migrants) override;
  std::vector<Migrant> receive(int to) override;
  uint64_t sent() const override { return sent_; }

 private:
  std::vector<std::vector<Migrant>> inbox_;
  uint64_t sent_ = 0;
};

// How the members of one periodic archive refinement are dealt back to the islands. Each
// member goes to one island either way.
enum class IslandDeal : uint8_t {
  Interleaved,  // in refinement order, member j to island j mod K: every island gets a sample
                // of the whole batch (cheap and accurate members alike)
  ByCost        // the batch sorted by cost and cut into K consecutive slices, island k taking
                // the k-th: each island is fed its own stretch of the front, so the islands
                // are pushed apart instead of towards the same mix
};

// The island (0..islands-1) each of `objs` goes to; deterministic for the same input.
std::vector<int> dealIslands(const std::vector<Objectives>& objs, int islands, IslandDeal deal);

// What an island's own variation may build, where it differs from the run's program shape
// (search.islands.profiles). Islands with a small profile search the cheap end as a run of small
// programs would, while the others grow long ones: an island only ever holds programs that fit
// its profile.
struct IslandProfile {
  int max_length = 0;       // opcodes per program in this island; 0 = program.max_length
  int constants = 0;        // constant slots its programs may read; 0 = program.constants
  double weight_rate = -1;  // variation.weight_rate in this island; < 0 = the run's
  // The island's population relative to the others' (search.population is split in proportion
  // to the shares), and so its part of each generation's time. Measured: a long island at 0.5
  // beside small ones lost most of the accurate end and gave the cheap end nothing
  // (docs/accurate-end.md), hence 1 in the default layout.
  double share = 1;
  // search.error_bias and search.cost_strata in this island; < 0 = the run's. Lets a long
  // island select for accuracy without steering the small ones.
  double error_bias = -1;
  int cost_strata = -1;
  friend bool operator==(const IslandProfile&, const IslandProfile&) = default;
};

// Programs per island when `population` is split over `islands` islands, island k in proportion
// to its profile's share (profiles[k % size]; none: equal shares), largest remainders first and
// ties to the lower island, so equal shares give population / islands and the remainder to the
// first islands. An island gets at least 4 (a tournament and survival need them), so the total
// can exceed `population` when a share is tiny.
std::vector<int> islandSizes(int population, int islands,
                             const std::vector<IslandProfile>& profiles);

// Offspring per island for one generation (search.islands.adaptive): the islands' total
// population, a share 1 - adaptive of it dealt as `sizes` are and the rest in proportion to
// `credit` (each island's recent front gain, FrontGain), largest remainders first and ties to
// the lower island; at least one each. No credit yet (or adaptive 0, or one island): `sizes`.
std::vector<int> offspringCounts(const std::vector<int>& sizes, const std::vector<double>& credit,
                                 double adaptive);

// The shape an island's variation works with: the run's, with the profile's smaller length and
// constant count.
ProgramShape islandShape(const ProgramShape& run, const IslandProfile& profile);

// Makes `p`, a program of the run's shape, fit `island` (at most island.max_length opcodes,
// reading only the first island.num_constants slots): unchanged where it already does, else
// with its introns pruned and the constant slots it reads renumbered from 0 (same values, so
// the same function and objectives). False, and p unchanged, where even that does not fit.
bool fitToIsland(Program& p, const ProgramShape& run, const ProgramShape& island);

// The island that island `from` sends to: the next one on a ring.
inline int migrationTarget(int from, int islands) {
  return (from + 1) % islands;
}

// Who sends to whom (search.islands.topology).
enum class MigrationTopology : uint8_t {
  Ring,      // every island to the next: with profiles, small and long islands feed each other
  ByProfile  // every island to the next island of the same profile (a ring per profile; an
             // island alone with its profile keeps its members): islands of long programs
             // grow among themselves, fed the cheap end only through the shared archive
};

// The island each island sends to (index = sender). A permutation, so that every island
// receives exactly one batch per round (the sync MPI mode relies on it); an island that is its
// own target sends nothing.
std::vector<int> migrationTargets(int islands, const std::vector<IslandProfile>& profiles,
                                  MigrationTopology topology);
// The inverse: the island each island receives from.
std::vector<int> migrationSources(const std::vector<int>& targets);

}  // namespace lgp
