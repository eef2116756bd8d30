#include "lgp/search/semantic_cache.hpp"

#include <bit>
#include <cstring>

#include "lgp/core/ops.hpp"

namespace lgp {
namespace {

// Two hash streams over the same words: a multiply-xorshift with different constants and seeds.
struct KeyHasher {
  uint64_t a = 0x243f6a8885a308d3ull, b = 0x13198a2e03707344ull;
  void add(uint64_t w) {
    a = (a ^ w) * 0x9e3779b97f4a7c15ull;
    a ^= a >> 29;
    b = (b + w) * 0xc2b2ae3d27d4eb4full;
    b ^= b >> 31;
    b = std::rotl(b, 23);
  }
  ProgramKey finish() {
    auto mix = [](uint64_t z) {
      z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
      z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
      return z ^ (z >> 31);
    };
    return {mix(a), mix(b ^ 0x452821e638d01377ull)};
  }
};

}  // namespace

ProgramKey effectiveKey(const Program& p, const std::vector<int>& effective) {
  // Position of each effective opcode among the effective ones (introns stay -1).
  std::array<int16_t, 256> pos;
  pos.fill(-1);
  KeyHasher h;
  h.add(effective.size());
  for (size_t k = 0; k < effective.size(); ++k) {
    const Instr& in = p.code[static_cast<size_t>(effective[k])];
    pos[static_cast<size_t>(effective[k])] = static_cast<int16_t>(k);
    const int n = arity(in.op);
    h.add(static_cast<uint64_t>(in.op) | static_cast<uint64_t>(n) << 16);
    for (int i = 0; i < n; ++i) {
      const Operand& a = in.args[static_cast<size_t>(i)];
      uint64_t w = static_cast<uint64_t>(a.kind) << 56;
      if (a.kind == OperandKind::Reg) {
        w |= static_cast<uint64_t>(static_cast<uint16_t>(pos[a.index]));
      } else {
        w |= a.index;
        if (a.kind == OperandKind::Const)
          w |= static_cast<uint64_t>(std::bit_cast<uint32_t>(p.constants[a.index])) << 16;
      }
      h.add(w);
    }
  }
  h.add(0xffffffffull + p.outputs.size());
  for (uint8_t o : p.outputs) h.add(static_cast<uint64_t>(static_cast<uint16_t>(pos[o])));
  return h.finish();
}

ProgramKey effectiveKey(const Program& p) {
  // Called for every offspring, on every thread: the index list keeps its capacity.
  thread_local std::vector<int> effective;
  effectiveIndices(p, effective);
  return effectiveKey(p, effective);
}

SemanticCache::SemanticCache(size_t entries) {
  if (entries == 0) return;
  slots_.resize(std::bit_ceil(entries));
  mask_ = slots_.size() - 1;
}

bool SemanticCache::find(const ProgramKey& key, Entry& out) const {
  if (slots_.empty()) return false;
  const size_t i = key.a & mask_;
  std::lock_guard lock(lockFor(i));
  const Slot& s = slots_[i];
  if (!s.used || !(s.key == key)) return false;
  out = s.entry;
  return true;
}

void SemanticCache::storeObjectives(const ProgramKey& key, const Objectives& obj) {
  if (slots_.empty()) return;
  const size_t i = key.a & mask_;
  std::lock_guard lock(lockFor(i));
  Slot& s = slots_[i];
  if (s.used && s.key == key) return;  // the same objectives, and maybe an LM result too
  s.key = key;
  s.used = true;
  s.entry = Entry{obj, false, {}};
}

void SemanticCache::storeLm(const ProgramKey& key, const LmOutcome& lm) {
  if (slots_.empty()) return;
  const size_t i = key.a & mask_;
  std::lock_guard lock(lockFor(i));
  Slot& s = slots_[i];
  if (!s.used || !(s.key == key)) return;  // the objectives were evicted: nothing to add to
  s.entry.lm = lm;
  s.entry.lm_known = true;
}

}  // namespace lgp
