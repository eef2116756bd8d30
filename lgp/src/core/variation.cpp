#include "lgp/core/variation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace lgp {

namespace {

std::vector<Op> allowedOps(const ProgramShape& shape) {
  std::vector<Op> ops;
  for (const auto& i : allOps())
    if (shape.ops.contains(i.op)) ops.push_back(i.op);
  if (ops.empty()) ops.push_back(Op::Add);
  return ops;
}

Op randomOp(const ProgramShape& shape, Rng& rng) {
  // Rebuilt per call would allocate; cache per distinct op set (bits) in a tiny table.
  thread_local uint32_t cached_bits = 0xffffffffu;
  thread_local std::vector<Op> cached;
  if (cached_bits != shape.ops.bits()) {
    cached = allowedOps(shape);
    cached_bits = shape.ops.bits();
  }
  return cached[rng.below(static_cast<uint32_t>(cached.size()))];
}

// Remaps a reference that became invalid at `pos` (points at or after itself).
Operand fixOperand(Operand o, int pos, const ProgramShape& shape, Rng& rng) {
  if (o.kind != OperandKind::Reg || o.index < pos) return o;
  if (pos == 0) return randomOperand(shape, 0, rng);
  o.index = static_cast<uint8_t>(o.index % pos);
  return o;
}

void repairAll(Program& p, const ProgramShape& shape, Rng& rng) {
  for (int i = 0; i < static_cast<int>(p.code.size()); ++i)
    for (int a = 0; a < kMaxArity; ++a)
      p.code[i].args[a] = fixOperand(p.code[i].args[a], i, shape, rng);
  syncOutputs(p, shape);
}

// Constants of a crossover child c = a[0:i) + b-segment [s0, s1) + a[j:): the segment reads
// the values it read in b, and the effective opcodes from a keep a's. A slot both read with
// different values moves, for the segment, to a slot neither reads; only when there is none
// do they share it (with a's value, which constant refinement then fits for both).
void shareSegmentConstants(Program& c, const Program& a, const Program& b, int s0, int s1) {
  const int nc = static_cast<int>(std::min(c.constants.size(), b.constants.size()));
  if (nc == 0) return;
  std::vector<uint8_t> a_reads(nc, 0), seg_reads(nc, 0);
  const auto reads = [&](const Instr& ins, std::vector<uint8_t>& mark) {
    for (int q = 0; q < arity(ins.op); ++q)
      if (ins.args[q].kind == OperandKind::Const && ins.args[q].index < nc)
        mark[ins.args[q].index] = 1;
  };
  for (int e : effectiveIndices(c))
    if (e < s0 || e >= s1) reads(c.code[e], a_reads);
  for (int p = s0; p < s1; ++p) reads(c.code[p], seg_reads);
  std::vector<int> remap(nc, -1);
  std::vector<uint8_t> taken = a_reads;
  for (int s = 0; s < nc; ++s)
    if (seg_reads[s]) taken[s] = 1;
  for (int s = 0; s < nc; ++s) {
    if (!seg_reads[s]) continue;
    remap[s] = s;
    if (!a_reads[s] || a.constants[s] == b.constants[s]) {
      c.constants[s] = b.constants[s];
      continue;
    }
    const auto free = std::find(taken.begin(), taken.end(), uint8_t{0});
    if (free == taken.end()) continue;  // shared, with a's value
    const int t = static_cast<int>(free - taken.begin());
    taken[t] = 1;
    c.constants[t] = b.constants[s];
    remap[s] = t;
  }
  for (int p = s0; p < s1; ++p)
    for (int q = 0; q < arity(c.code[p].op); ++q) {
      Operand& o = c.code[p].args[q];
      if (o.kind == OperandKind::Const && o.index < nc)
        o.index = static_cast<uint8_t>(remap[o.index]);
    }
}

// Inserts `ins` at `pos`: register operands and outputs at or after pos shift by one, so
// every opcode keeps reading (and every output keeps naming) the value it did.
void insertAt(Program& p, int pos, const Instr& ins) {
  for (size_t i = pos; i < p.code.size(); ++i)
    for (int a = 0; a < arity(p.code[i].op); ++a) {
      Operand& o = p.code[i].args[a];
      if (o.kind == OperandKind::Reg && o.index >= pos) ++o.index;
    }
  for (auto& o : p.outputs)  // both output modes: the same opcodes, shifted
    if (o >= pos) ++o;
  p.code.insert(p.code.begin() + pos, ins);
}

}  // namespace

Operand randomOperand(const ProgramShape& shape, int position, Rng& rng) {
  Operand o;
  const double u = rng.uniform();
  // Prefer wiring to earlier opcodes (builds deep DAGs), then inputs, then constants.
  const bool can_reg = position > 0;
  const bool can_const = shape.num_constants > 0;
  if (can_reg && u < 0.5) {
    o.kind = OperandKind::Reg;
    // Bias towards recent opcodes, which keeps more of the program effective.
    const int back = std::min(position, 1 + static_cast<int>(rng.below(std::min(position, 8))));
    o.index = static_cast<uint8_t>(rng.chance(0.7) ? position - back : rng.below(position));
  } else if (can_const && u > (can_reg ? 0.8 : 0.7)) {
    o.kind = OperandKind::Const;
    o.index = static_cast<uint8_t>(rng.below(shape.num_constants));
  } else {
    o.kind = OperandKind::Var;
    o.index = static_cast<uint8_t>(rng.below(std::max(1, shape.num_inputs)));
  }
  return o;
}

Instr randomInstr(const ProgramShape& shape, int position, Rng& rng) {
  Instr ins;
  ins.op = randomOp(shape, rng);
  for (int a = 0; a < arity(ins.op); ++a) ins.args[a] = randomOperand(shape, position, rng);
  return ins;
}

Program randomProgram(const ProgramShape& shape, const InitConfig& init, Rng& rng) {
  Program p;
  const int lo = std::clamp(init.min_length, std::max(1, shape.num_outputs), shape.max_length);
  const int hi = std::clamp(init.max_length, lo, shape.max_length);
  const int len = rng.range(lo, hi);
  for (int i = 0; i < len; ++i) p.code.push_back(randomInstr(shape, i, rng));
  p.constants.resize(shape.num_constants);
  for (auto& c : p.constants) {
    // A few exact small constants help the search find 1 - x, 2^x, x/2 and the like.
    if (rng.chance(0.25)) {
      static constexpr float kNice[] = {0.5f, 1.0f, 2.0f, -1.0f, 0.25f, 3.0f};
      c = kNice[rng.below(6)];
    } else {
      c = static_cast<float>(rng.uniform(init.const_min, init.const_max));
    }
  }
  syncOutputs(p, shape);
  if (shape.output_mode == OutputMode::Designated) {
    const int n = static_cast<int>(p.code.size());
    for (size_t k = 0; k < p.outputs.size(); ++k)
      p.outputs[k] =
          static_cast<uint8_t>(n - static_cast<int>(p.outputs.size()) + static_cast<int>(k));
  }
  return p;
}

Program crossover(const Program& a, const Program& b, const ProgramShape& shape, Rng& rng) {
  const int na = static_cast<int>(a.code.size());
  const int nb = static_cast<int>(b.code.size());
  // Segment [i, j) of a is replaced by segment [k, l) of b.
  int i = rng.below(na);
  int j = i + 1 + static_cast<int>(rng.below(std::min(na - i, 8)));
  int k = rng.below(nb);
  int l = k + 1 + static_cast<int>(rng.below(std::min(nb - k, 8)));
  const int min_len = std::max(1, shape.num_outputs);
  int new_len = na - (j - i) + (l - k);
  if (new_len > shape.max_length) l -= new_len - shape.max_length;
  if (l <= k) l = k + 1;
  new_len = na - (j - i) + (l - k);
  if (new_len > shape.max_length || new_len < min_len) return a;
  return crossoverAt(a, b, shape, i, j, k, l, rng);
}

Program crossoverAt(const Program& a, const Program& b, const ProgramShape& shape, int i, int j,
                    int k, int l, Rng& rng) {
  const int na = static_cast<int>(a.code.size());
  const int new_len = na - (j - i) + (l - k);
  const int delta = (l - k) - (j - i);

  Program c;
  c.constants = a.constants;
  c.code.reserve(new_len);
  for (int p = 0; p < i; ++p) c.code.push_back(a.code[p]);
  for (int p = k; p < l; ++p) {
    Instr ins = b.code[p];
    for (int q = 0; q < arity(ins.op); ++q) {
      Operand& o = ins.args[q];
      if (o.kind == OperandKind::Reg && o.index >= k)
        o.index = static_cast<uint8_t>(o.index - k + i);
    }
    c.code.push_back(ins);
  }
  for (int p = j; p < na; ++p) {
    Instr ins = a.code[p];
    for (int q = 0; q < arity(ins.op); ++q) {
      Operand& o = ins.args[q];
      if (o.kind != OperandKind::Reg) continue;
      if (o.index >= j) {
        o.index = static_cast<uint8_t>(o.index + delta);
      } else if (o.index >= i) {
        // Pointed into the replaced segment: point at the same relative place in the new one.
        const int seg = l - k;
        o.index = static_cast<uint8_t>(i + (o.index - i) % seg);
      }
    }
    c.code.push_back(ins);
  }
  c.outputs = a.outputs;
  if (shape.output_mode == OutputMode::Designated)
    for (auto& o : c.outputs)
      if (o >= j) o = static_cast<uint8_t>(o + delta);
  repairAll(c, shape, rng);
  shareSegmentConstants(c, a, b, i, i + (l - k));
  return c;
}

void microMutate(Program& p, const ProgramShape& shape, Rng& rng, double constant_sigma,
                 double effective_bias, double const_min, double const_max) {
  const int n = static_cast<int>(p.code.size());
  int pos;
  if (rng.chance(effective_bias)) {
    const auto eff = effectiveIndices(p);
    pos = eff.empty() ? n - 1 : eff[rng.below(static_cast<uint32_t>(eff.size()))];
  } else {
    pos = static_cast<int>(rng.below(n));
  }
  Instr& ins = p.code[pos];
  const double u = rng.uniform();
  if (u < 0.3) {
    // Operator change; keep the operands that still apply, fill new ones randomly.
    const int old_arity = arity(ins.op);
    ins.op = randomOp(shape, rng);
    for (int a = old_arity; a < arity(ins.op); ++a) ins.args[a] = randomOperand(shape, pos, rng);
    for (int a = arity(ins.op); a < kMaxArity; ++a) ins.args[a] = Operand{};  // canonical
  } else if (u < 0.7 || shape.num_constants == 0) {
    const int a = static_cast<int>(rng.below(arity(ins.op)));
    ins.args[a] = randomOperand(shape, pos, rng);
  } else if (u < 0.95 || shape.output_mode != OutputMode::Designated) {
    // Constant change, on a constant that changes the program's value where there is one: one
    // this opcode reads (if effective opcodes read it too), else any one effective opcodes read.
    const auto live = effectiveConstants(p);
    const auto is_live = [&](int c) {
      return live.empty() || std::binary_search(live.begin(), live.end(), c);
    };
    std::array<int, kMaxArity> own{};
    int owned = 0;
    for (int a = 0; a < arity(ins.op); ++a)
      if (ins.args[a].kind == OperandKind::Const && is_live(ins.args[a].index))
        own[owned++] = ins.args[a].index;
    int slot;
    if (owned > 0)
      slot = own[rng.below(owned)];
    else if (!live.empty())
      slot = live[rng.below(static_cast<uint32_t>(live.size()))];
    else
      slot = static_cast<int>(rng.below(shape.num_constants));
    float& c = p.constants[slot];
    if (rng.chance(0.1)) {
      c = static_cast<float>(rng.uniform(const_min, const_max));  // a reset, as at initialisation
    } else {
      const double scale = std::max(std::fabs(static_cast<double>(c)), 0.1);
      c = static_cast<float>(c + constant_sigma * scale * rng.normal());
    }
    if (!std::isfinite(c)) c = 1.0f;
  } else {
    const int k = static_cast<int>(rng.below(static_cast<uint32_t>(p.outputs.size())));
    p.outputs[k] = static_cast<uint8_t>(rng.below(n));
  }
  syncOutputs(p, shape);
}

void macroMutate(Program& p, const ProgramShape& shape, Rng& rng, double wrap_share) {
  const int n = static_cast<int>(p.code.size());
  const int min_len = std::max(1, shape.num_outputs);
  const bool insert = (n < shape.max_length) && (n <= min_len || rng.chance(0.5));
  if (insert) {
    // Effective insertion (Brameier & Banzhaf): the new opcode lands before the last effective
    // opcode and feeds a later effective one, so it is never an intron. In "last" mode the
    // outputs are the last k opcodes: landing among them would make the new opcode an output
    // and drop one, so it lands before them. With one output it may also land right after
    // it ("top"): it becomes the output and reads the old one, so y grows into op(y, ..).
    const int k = static_cast<int>(p.outputs.size());
    const int last_eff = *std::max_element(p.outputs.begin(), p.outputs.end());
    const int inner = shape.output_mode == OutputMode::Last ? n - k : last_eff;
    const int pos = static_cast<int>(rng.below(inner + (k == 1 ? 2 : 1)));
    const bool top = pos > inner;  // only with one output: pos == last_eff + 1
    insertAt(p, pos, randomInstr(shape, pos, rng));
    Instr& ins = p.code[pos];
    if (top) {
      ins.args[rng.below(arity(ins.op))] = Operand{OperandKind::Reg, static_cast<uint8_t>(pos - 1)};
      p.outputs[0] = static_cast<uint8_t>(pos);
    } else {
      // Rewire one operand of a later effective opcode (there is one: an output) to it.
      const auto eff = effectiveIndices(p);
      std::vector<int> later;
      for (int e : eff)
        if (e > pos) later.push_back(e);
      Instr& user = p.code[later[rng.below(static_cast<uint32_t>(later.size()))]];
      const int a = static_cast<int>(rng.below(arity(user.op)));
      // Wrapping keeps the operand it replaces (x becomes op(x, ..)) instead of losing it.
      const Operand old = user.args[a];
      const bool fits = old.kind != OperandKind::Reg || old.index < pos;
      if (fits && rng.chance(wrap_share)) ins.args[rng.below(arity(ins.op))] = old;
      user.args[a] = Operand{OperandKind::Reg, static_cast<uint8_t>(pos)};
    }
  } else if (n > min_len) {
    const int pos = static_cast<int>(rng.below(n));
    // Users of the deleted opcode take its first register operand, else a random operand.
    const Instr del = p.code[pos];
    Operand repl{OperandKind::Var, 0};
    bool have = false;
    for (int a = 0; a < arity(del.op); ++a)
      if (del.args[a].kind == OperandKind::Reg) {
        repl = del.args[a];
        have = true;
        break;
      }
    if (!have) repl = arity(del.op) > 0 ? del.args[0] : Operand{};
    p.code.erase(p.code.begin() + pos);
    for (int i = pos; i < n - 1; ++i)
      for (int a = 0; a < arity(p.code[i].op); ++a) {
        Operand& o = p.code[i].args[a];
        if (o.kind != OperandKind::Reg) continue;
        if (o.index == pos)
          o = repl;
        else if (o.index > pos)
          --o.index;
      }
    if (shape.output_mode == OutputMode::Designated)
      for (auto& o : p.outputs)
        if (o >= pos && o > 0) --o;
  }
  repairAll(p, shape, rng);
}

bool weightMutate(Program& p, const ProgramShape& shape, Rng& rng) {
  const int n = static_cast<int>(p.code.size());
  const int nc = static_cast<int>(p.constants.size());
  if (n >= shape.max_length || n >= 255 || nc == 0) return false;
  // A slot no opcode reads, introns included: an intron that became effective later would
  // otherwise read the new coefficient instead of its own value.
  std::vector<uint8_t> read(nc, 0);
  for (const Instr& ins : p.code)
    for (int a = 0; a < arity(ins.op); ++a)
      if (ins.args[a].kind == OperandKind::Const && ins.args[a].index < nc)
        read[ins.args[a].index] = 1;
  std::vector<int> free;
  for (int c = 0; c < nc; ++c)
    if (!read[c]) free.push_back(c);
  if (free.empty()) return false;
  const auto scaled = [&](const Instr& ins) {  // a mul by a constant: a weight already
    return ins.op == Op::Mul &&
           (ins.args[0].kind == OperandKind::Const || ins.args[1].kind == OperandKind::Const);
  };
  // The new opcode lands right before its reader; in "last" mode not inside the block of the
  // last k opcodes (that would make it an output), so there it lands before the block.
  const int k = static_cast<int>(p.outputs.size());
  const int limit = shape.output_mode == OutputMode::Last ? n - k : n;
  struct Site {
    int reader, arg, pos;
  };
  std::vector<Site> sites;
  for (int e : effectiveIndices(p)) {
    const Instr& ins = p.code[e];
    if (scaled(ins)) continue;
    const int pos = std::min(e, limit);
    for (int a = 0; a < arity(ins.op); ++a) {
      const Operand& o = ins.args[a];
      if (o.kind == OperandKind::Const) continue;
      if (o.kind == OperandKind::Reg && (o.index >= pos || scaled(p.code[o.index]))) continue;
      sites.push_back({e, a, pos});
    }
  }
  if (sites.empty()) return false;
  const Site s = sites[rng.below(static_cast<uint32_t>(sites.size()))];
  const int slot = free[rng.below(static_cast<uint32_t>(free.size()))];
  const Operand x = p.code[s.reader].args[s.arg];
  Instr w;
  w.op = Op::Mul;
  w.args[0] = constOperand(slot);
  w.args[1] = x;
  insertAt(p, s.pos, w);
  p.code[s.reader + 1].args[s.arg] = regOperand(s.pos);
  p.constants[slot] = 1.0f;
  syncOutputs(p, shape);
  return true;
}

}  // namespace lgp
