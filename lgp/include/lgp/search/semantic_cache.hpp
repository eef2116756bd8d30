// A cache of what the search already knows about a program, keyed by its effective form.
//
// Variation makes many offspring that compute exactly what an earlier program computed:
// clones, intron-only mutants, insertions and deletions that only move opcodes. The key is
// the program with its introns dropped and its register operands renumbered by position among
// the effective opcodes; constant slots keep their index and their float bits. Two programs
// with the same key run the same float operations on the same operands, so their objectives
// are bit-identical, and so is a Levenberg-Marquardt fit of their constants.
//
// A Levenberg-Marquardt fit is kept too: whether it improved or converged, its evaluations
// and the constants it found; a second offspring fit of the key replays it.
//
// The cache is therefore invisible in results: a hit returns exactly what the work would have
// produced, and the search counts the evaluations the work would have cost. Fronts, evaluation
// counts and checkpoints are the same with the cache on or off, on any thread count, and a
// resumed run (whose cache starts empty) equals an uninterrupted one. Only time changes.
//
// Storage is direct-mapped (a newer key replaces an older one in its slot), with striped locks:
// which thread stores first changes only which later lookups hit.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/eval/objectives.hpp"

namespace lgp {

// 128 bits from two independent 64-bit hashes: a collision between distinct programs is
// negligible at the cache's scale (2^-64 per pair and hash), and a key is never trusted without
// both halves.
struct ProgramKey {
  uint64_t a = 0, b = 0;
  friend bool operator==(const ProgramKey&, const ProgramKey&) = default;
};

// The key of `p`, given its effective opcode indices (ascending, as effectiveIndices()).
ProgramKey effectiveKey(const Program& p, const std::vector<int>& effective);
ProgramKey effectiveKey(const Program& p);

class SemanticCache {
 public:
  // The outcome of an offspring Levenberg-Marquardt fit of one program: deterministic, so a
  // second fit of the same key would repeat it.
  struct LmOutcome {
    static constexpr int kMaxConstants = 16;  // fits of more effective constants are not kept
    bool improved = false, converged = false;
    uint32_t evaluations = 0;
    uint8_t count = 0;                         // effective constant slots, ascending
    std::array<float, kMaxConstants> after{};  // their values after the fit
  };
  // What is known about one effective program.
  struct Entry {
    Objectives obj;  // as Search::score() measures the program
    bool lm_known = false;
    LmOutcome lm;  // if lm_known
  };

  // `entries` is rounded up to a power of two; 0 disables the cache.
  explicit SemanticCache(size_t entries = 0);
  // What the constructor allocates for `entries`, at once (lgpd's memory bound counts it).
  static size_t bytesFor(size_t entries) {
    return entries ? std::bit_ceil(entries) * sizeof(Slot) : 0;
  }
  bool enabled() const { return !slots_.empty(); }
  size_t capacity() const { return slots_.size(); }

  bool find(const ProgramKey& key, Entry& out) const;
  // Records a program's objectives (what an LM fit found is kept if the key is already there).
  void storeObjectives(const ProgramKey& key, const Objectives& obj);
  // Records an offspring LM fit of this program (nothing if its objectives are not there).
  void storeLm(const ProgramKey& key, const LmOutcome& lm);

 private:
  struct Slot {
    ProgramKey key;
    bool used = false;
    Entry entry;
  };
  std::mutex& lockFor(size_t index) const { return locks_[index % locks_.size()]; }

  std::vector<Slot> slots_;
  size_t mask_ = 0;
  mutable std::array<std::mutex, 64> locks_;
};

}  // namespace lgp
