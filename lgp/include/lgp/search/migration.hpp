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

// The island that island `from` sends to: the next one on a ring.
inline int migrationTarget(int from, int islands) {
  return (from + 1) % islands;
}

}  // namespace lgp
