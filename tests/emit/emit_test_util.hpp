// Shared helpers of the emit tests: random programs over every operator, the DFG test
// table, and compiling/running emitted C++ with the system compiler.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "lgp/core/program.hpp"
#include "lgp/core/table.hpp"

namespace lgp::emit::test {

inline std::filesystem::path dataDir() {
  return std::filesystem::path(LGP_SOURCE_DIR) / "tests" / "emit" / "data";
}

inline std::filesystem::path scratchDir(const std::string& name) {
  auto p = std::filesystem::path(LGP_BINARY_DIR) / "tests" / "emit" / "scratch" / name;
  std::filesystem::create_directories(p);
  return p;
}

inline Table loadDfg() {
  auto raw = readTableFile(dataDir() / "dfg_16x16.json");
  EXPECT_TRUE(raw.hasValue()) << raw.error();
  auto t = selectColumns(*raw, {}, {}, "", "dfg_16x16.json");
  EXPECT_TRUE(t.hasValue()) << t.error();
  return *t;
}

// A table over two inputs that exercises every protected branch: zeros, tiny and huge
// magnitudes, negatives. Outputs are unused placeholders.
inline Table edgeTable(int k_outputs) {
  const std::vector<double> vals = {0.0,  1e-30, -1e-30, 1e-20, -1e-20, 1e-10, -3.5,
                                    -1.0, -0.25, 0.125,  0.5,   0.75,   1.0,   1.5,
                                    2.0,  3.75,  10.0,   -20.0, 100.0,  300.0};
  Table t;
  t.input_names = {"x", "y"};
  t.inputs.resize(2);
  for (double a : vals)
    for (double b : vals) {
      t.inputs[0].push_back(a);
      t.inputs[1].push_back(b);
    }
  for (int k = 0; k < k_outputs; ++k) {
    t.output_names.push_back("o" + std::to_string(k));
    t.outputs.push_back(std::vector<double>(t.inputs[0].size(), 0.5));
  }
  return t;
}

// A random program: `len` opcodes, operands drawn from inputs, constants and earlier
// opcodes; outputs are the last k opcodes. `dyadic` draws constants k/16 (exact in float
// and double); zero constants are avoided (x + 0 -> x may flip the sign of a zero).
inline Program randomProgram(std::mt19937& rng, int num_inputs, int len, int k, bool dyadic,
                             std::optional<Op> force_first = std::nullopt) {
  Program p;
  std::uniform_int_distribution<int> nconst(1, 4);
  const int nc = nconst(rng);
  std::uniform_int_distribution<int> dy(-64, 64);
  std::uniform_real_distribution<float> real(-3.0f, 3.0f);
  for (int c = 0; c < nc; ++c) {
    float v = dyadic ? static_cast<float>(dy(rng)) / 16.0f : real(rng);
    if (v == 0.0f) v = 0.5f;
    p.constants.push_back(v);
  }
  std::uniform_int_distribution<int> opd(0, kNumOps - 1);
  for (int i = 0; i < len; ++i) {
    Instr in;
    in.op = (i == 0 && force_first) ? *force_first : static_cast<Op>(opd(rng));
    for (int a = 0; a < arity(in.op); ++a) {
      std::uniform_int_distribution<int> kind(0, i > 0 ? 4 : 1);
      const int kd = kind(rng);
      Operand o;
      if (kd == 0) {
        o = {OperandKind::Var,
             static_cast<uint8_t>(std::uniform_int_distribution<int>(0, num_inputs - 1)(rng))};
      } else if (kd == 1) {
        o = {OperandKind::Const,
             static_cast<uint8_t>(std::uniform_int_distribution<int>(0, nc - 1)(rng))};
      } else {
        // Prefer recent opcodes so programs are deep rather than flat.
        const int lo = std::max(0, i - 4);
        o = {OperandKind::Reg,
             static_cast<uint8_t>(std::uniform_int_distribution<int>(lo, i - 1)(rng))};
      }
      in.args[a] = o;
    }
    p.code.push_back(in);
  }
  for (int j = 0; j < k; ++j) p.outputs.push_back(static_cast<uint8_t>(len - k + j));
  return p;
}

struct RunResult {
  int rc = -1;
  std::string output;
};

inline RunResult runCommand(const std::string& cmd) {
  RunResult r;
  const std::string full = cmd + " 2>&1";
  FILE* f = popen(full.c_str(), "r");
  if (!f) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, f)) > 0) r.output.append(buf, n);
  const int st = pclose(f);
  r.rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

inline void writeFile(const std::filesystem::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
}

// Distance in units in the last place between two floats (0 if bit-identical or both NaN,
// +0 and -0 count as equal).
inline int64_t ulpDistance(float a, float b) {
  if (std::isnan(a) && std::isnan(b)) return 0;
  if (std::isnan(a) || std::isnan(b)) return INT64_MAX;
  auto ord = [](float x) {
    int32_t i;
    std::memcpy(&i, &x, sizeof i);
    return i < 0 ? static_cast<int64_t>(INT32_MIN) - i : static_cast<int64_t>(i);
  };
  return std::llabs(ord(a) - ord(b));
}

}  // namespace lgp::emit::test
