// Round trip: emitted C++ is compiled at test time with the project's compiler and numeric
// flags, run over a table, and compared with the interpreter.
//   - exact math (float): bit-identical to the float32 interpreter (0 ulp), for random
//     programs over every operator, protected and --fast;
//   - double: bit-identical to the double reference evaluator (dyadic constants);
//   - default <cmath> math (float), real front members and the published DFG formulas:
//     within kNativeUlpBound of the interpreter (README), and finite at the domain corners
//     wherever the interpreter is finite.
#include <gtest/gtest.h>

#include <cstring>
#include <iostream>
#include <map>
#include <optional>

#include "emit_test_util.hpp"
#include "lgp/config/config.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/parser.hpp"
#include "lgp/eval/fidelity.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/semantics.hpp"
#include "lgp/search/search.hpp"

namespace lgp::emit {
namespace {

using test::randomProgram;

// Documented in emit/README.md: largest difference, in float ulps of the result, between
// the default (<cmath>) C++ float code and the float32 interpreter over the DFG table, for
// the published formulas and real front members.
constexpr int64_t kNativeUlpBound = 64;

struct Case {
  std::string fn;
  Program program;
  EmitInput input;
  EmitOptions opts;
};

struct Compiled {
  bool ok = false;
  std::string log;
  std::vector<std::vector<std::vector<double>>> out;  // [case][output][row]
};

// Emits every case into one C++ file with a main() that evaluates all of them on `rows`
// (row-major, m inputs), compiles it and runs it.
Compiled compileAndRun(const std::string& name, std::vector<Case>& cases,
                       const std::vector<std::vector<double>>& rows, Precision prec) {
  Compiled res;
  const auto dir = test::scratchDir(name);
  const std::string T = prec == Precision::Double ? "double" : "float";
  std::string src = "#include <cstdio>\n#include <vector>\n";
  for (auto& c : cases) {
    c.opts.function_name = c.fn;
    auto e = emitProgram(c.input, Language::Cpp, c.opts);
    if (!e) {
      res.log = c.fn + ": " + e.error();
      return res;
    }
    src += e->code + "\n";
  }
  const size_t m = rows.empty() ? 0 : rows[0].size();
  src +=
      "int main(int, char** argv) {\n  std::FILE* f = std::fopen(argv[1], \"rb\");\n"
      "  int n = 0, m = 0;\n  if (!f || std::fread(&n, 4, 1, f) != 1 || std::fread(&m, 4, 1, f) != "
      "1) return 3;\n"
      "  std::vector<" +
      T +
      "> x(static_cast<size_t>(n) * m);\n"
      "  if (std::fread(x.data(), sizeof(" +
      T +
      "), x.size(), f) != x.size()) return 4;\n"
      "  std::fclose(f);\n  std::FILE* o = std::fopen(argv[2], \"wb\");\n"
      "  std::vector<" +
      T + "> buf(n);\n";
  auto args = [&](const std::string& r) {
    std::string a;
    for (size_t i = 0; i < m; ++i)
      a += (i ? ", " : "") + std::string("x[") + r + " * m + " + std::to_string(i) + "]";
    return a;
  };
  for (const auto& c : cases) {
    const size_t k = c.program.outputs.size();
    for (size_t j = 0; j < k; ++j) {
      src += "  for (int r = 0; r < n; ++r) buf[r] = " + c.fn + "(" + args("r") + ")" +
             (k > 1 ? "." + c.input.output_names[j] : std::string()) + ";\n";
      src += "  std::fwrite(buf.data(), sizeof(" + T + "), n, o);\n";
    }
  }
  src += "  std::fclose(o);\n  return 0;\n}\n";
  test::writeFile(dir / "prog.cpp", src);
  {
    std::ofstream in(dir / "in.bin", std::ios::binary);
    const int32_t n = static_cast<int32_t>(rows.size()), mm = static_cast<int32_t>(m);
    in.write(reinterpret_cast<const char*>(&n), 4);
    in.write(reinterpret_cast<const char*>(&mm), 4);
    for (const auto& r : rows)
      for (double v : r) {
        if (prec == Precision::Double) {
          in.write(reinterpret_cast<const char*>(&v), sizeof v);
        } else {
          const float fv = static_cast<float>(v);
          in.write(reinterpret_cast<const char*>(&fv), sizeof fv);
        }
      }
  }
  const std::string exe = (dir / "prog").string();
  auto cc = test::runCommand(std::string(LGP_TEST_CXX) + " " + LGP_TEST_CXX_FLAGS + " -o " + exe +
                             " " + (dir / "prog.cpp").string());
  if (cc.rc != 0) {
    res.log = "compile failed:\n" + cc.output.substr(0, 4000);
    return res;
  }
  auto run =
      test::runCommand(exe + " " + (dir / "in.bin").string() + " " + (dir / "out.bin").string());
  if (run.rc != 0) {
    res.log = "run failed (rc " + std::to_string(run.rc) + "): " + run.output;
    return res;
  }
  std::ifstream out(dir / "out.bin", std::ios::binary);
  for (const auto& c : cases) {
    std::vector<std::vector<double>> per;
    for (size_t j = 0; j < c.program.outputs.size(); ++j) {
      std::vector<double> col(rows.size());
      for (auto& v : col) {
        if (prec == Precision::Double) {
          out.read(reinterpret_cast<char*>(&v), sizeof v);
        } else {
          float fv;
          out.read(reinterpret_cast<char*>(&fv), sizeof fv);
          v = fv;
        }
      }
      per.push_back(std::move(col));
    }
    res.out.push_back(std::move(per));
  }
  res.ok = static_cast<bool>(out);
  if (!res.ok) res.log = "short output file";
  return res;
}

std::vector<std::vector<double>> rowsOf(const Table& t) {
  std::vector<std::vector<double>> rows(t.rows(), std::vector<double>(t.numInputs()));
  for (size_t r = 0; r < t.rows(); ++r)
    for (size_t i = 0; i < t.numInputs(); ++i) rows[r][i] = t.inputs[i][r];
  return rows;
}

Table withRows(Table t, const std::vector<std::vector<double>>& extra) {
  for (const auto& r : extra) {
    for (size_t i = 0; i < t.numInputs(); ++i) t.inputs[i].push_back(r[i]);
    for (auto& o : t.outputs) o.push_back(o.empty() ? 0.0 : o.back());
  }
  return t;
}

std::vector<Interval> domainOf(const Table& t) {
  std::vector<Interval> d;
  for (const auto& col : t.inputs) {
    Interval iv;
    iv.lo = *std::min_element(col.begin(), col.end());
    iv.hi = *std::max_element(col.begin(), col.end());
    iv.nan = false;
    d.push_back(iv);
  }
  return d;
}

EmitInput inputFor(const Program& p, const Table& t) {
  EmitInput in;
  in.program = p;
  in.input_names = t.input_names;
  for (size_t j = 0; j < p.outputs.size(); ++j) in.output_names.push_back("o" + std::to_string(j));
  in.domain = domainOf(t);
  return in;
}

std::vector<Program> randomPrograms(uint32_t seed, int n, bool dyadic) {
  std::mt19937 rng(seed);
  std::vector<Program> ps;
  for (const auto& info : allOps())
    for (int rep = 0; rep < 3; ++rep) {
      const int len = std::uniform_int_distribution<int>(1, 8)(rng);
      ps.push_back(randomProgram(rng, 2, len, 1, dyadic, info.op));
    }
  for (int i = 0; i < n; ++i) {
    const int len = std::uniform_int_distribution<int>(3, 16)(rng);
    const int k = std::uniform_int_distribution<int>(1, 2)(rng);
    ps.push_back(randomProgram(rng, 2, len, k, dyadic));
  }
  return ps;
}

// Values of the interpreter, [output][row] (float32 path).
std::vector<std::vector<double>> interpret(const Program& p, const Table& t) {
  Interpreter interp(256);
  Dataset ds(t, 256);
  const auto v = interp.evaluate(p, ds);
  std::vector<std::vector<double>> out;
  for (const auto& col : v) out.emplace_back(col.begin(), col.begin() + t.rows());
  return out;
}

float invertFloat(TargetTransform t, float v) {
  switch (t) {
    case TargetTransform::None:
      return v;
    case TargetTransform::Log:
      return sem::apply<Op::Exp, float>(v, v, v, v);
    case TargetTransform::Sqrt:
      return v > 0.0f ? v * v : 0.0f;
    case TargetTransform::Rcp:
      return sem::apply<Op::Rcp, float>(v, v, v, v);
  }
  return v;
}

TEST(EmitRoundTrip, ExactMathCppIsBitIdenticalToTheInterpreter) {
  Table t = test::edgeTable(1);
  // Rows on a positive domain, where --fast can prove guards unreachable.
  Table pos;
  pos.input_names = {"x", "y"};
  pos.inputs.resize(2);
  for (double a : {0.25, 0.5, 1.0, 1.75, 3.0, 4.0})
    for (double b : {0.25, 0.75, 1.0, 2.5, 4.0}) {
      pos.inputs[0].push_back(a);
      pos.inputs[1].push_back(b);
    }
  pos.output_names = {"o0"};
  pos.outputs = {std::vector<double>(pos.inputs[0].size(), 0.5)};
  const Table all = withRows(t, rowsOf(pos));

  const auto programs = randomPrograms(11, 200, false);
  std::vector<Case> cases;
  for (size_t i = 0; i < programs.size(); ++i) {
    Case c;
    c.fn = "f" + std::to_string(i);
    c.program = programs[i];
    c.input = inputFor(programs[i], t);
    c.opts.exact_math = true;
    c.opts.pow_rewrites = false;
    c.opts.header = i % 7 == 0;  // the header must be valid C++ too
    // Some members were fitted on transformed targets: the function applies the inverse.
    if (i % 4 != 0)
      c.input.transforms.assign(programs[i].outputs.size(),
                                static_cast<TargetTransform>(i % 4));  // log, sqrt, rcp
    cases.push_back(c);
    Case f = c;  // --fast on the positive domain
    f.fn = "g" + std::to_string(i);
    f.input = inputFor(programs[i], pos);
    f.opts.fast = true;
    cases.push_back(f);
  }
  auto res = compileAndRun("exact_float", cases, rowsOf(all), Precision::Float);
  ASSERT_TRUE(res.ok) << res.log;
  int raw_total = 0;
  for (size_t c = 0; c < cases.size(); ++c) {
    const bool fast = cases[c].opts.fast;
    auto ref = interpret(cases[c].program, all);
    // The scorer's inverse transform, in float with the protected semantics.
    for (size_t j = 0; j < ref.size() && !cases[c].input.transforms.empty(); ++j)
      for (double& v : ref[j]) v = invertFloat(cases[c].input.transforms[j], static_cast<float>(v));
    const size_t r0 = fast ? t.rows() : 0;
    if (fast)
      raw_total += static_cast<int>(
          emitProgram(cases[c].input, Language::Cpp, cases[c].opts)->raw_ops.size());
    for (size_t j = 0; j < ref.size(); ++j)
      for (size_t r = r0; r < all.rows(); ++r) {
        const float a = static_cast<float>(ref[j][r]), b = static_cast<float>(res.out[c][j][r]);
        ASSERT_EQ(test::ulpDistance(a, b), 0)
            << cases[c].fn << " output " << j << " row " << r << " (x=" << all.inputs[0][r]
            << ", y=" << all.inputs[1][r] << "): interpreter " << a << " emitted " << b
            << "\nprogram: " << toInfix(cases[c].program, {"x", "y"})[j] << "\n"
            << emitProgram(cases[c].input, Language::Cpp, cases[c].opts)->function;
      }
  }
  EXPECT_GT(raw_total, 20) << "--fast proved too few ops unguarded to be a meaningful test";
}

TEST(EmitRoundTrip, DoubleCppIsBitIdenticalToTheReference) {
  const Table t = test::edgeTable(1);
  const auto programs = randomPrograms(23, 150, true);
  std::vector<Case> cases;
  for (size_t i = 0; i < programs.size(); ++i) {
    Case c;
    c.fn = "d" + std::to_string(i);
    c.program = programs[i];
    c.input = inputFor(programs[i], t);
    c.opts.precision = Precision::Double;
    c.opts.pow_rewrites = false;
    cases.push_back(c);
  }
  auto res = compileAndRun("double", cases, rowsOf(t), Precision::Double);
  ASSERT_TRUE(res.ok) << res.log;
  for (size_t c = 0; c < cases.size(); ++c) {
    const auto ref = evaluateReference(cases[c].program, t);
    for (size_t j = 0; j < ref.size(); ++j)
      for (size_t r = 0; r < t.rows(); ++r) {
        const double a = ref[j][r], b = res.out[c][j][r];
        const bool same = (a == b) || (std::isnan(a) && std::isnan(b));
        ASSERT_TRUE(same) << cases[c].fn << " output " << j << " row " << r << ": reference " << a
                          << " emitted " << b << "\n"
                          << emitProgram(cases[c].input, Language::Cpp, cases[c].opts)->function;
      }
  }
}

// Published DFG formulas (Karis 2014; Iwanicki & Pesce 2015) in the parser's syntax.
std::vector<std::pair<std::string, std::vector<std::string>>> publishedDfg() {
  return {
      {"karis",
       {"qx = 1 - r; qy = -0.0275*r + 0.0425; qz = -0.572*r + 1.04; qw = 0.022*r - 0.04;"
        "a004 = min(qx*qx, exp2(-9.28*NoV))*qx + qy; A = -1.04*a004 + qz; B = 1.04*a004 + qw"}},
      {"iwanicki",
       {"m = r*r; B = exp2(-(7*NoV + 4*m)); A = 1 - B - m*max(B, min(r, 0.739 + 0.323*NoV) - "
        "0.434)"}},
      {"narkowicz",
       {"x = (1 - r)*(1 - r); y = NoV;"
        "B = saturate(min(-0.1688*x + 1.895*x*x, 0.9903 - 4.853*y + 8.404*y*y - 5.069*y*y*y));"
        "delta = saturate(0.6045 + 1.699*x - 0.5228*y - 3.603*x*x + 1.404*x*y + 0.1939*y*y + "
        "2.661*x*x*x); A = delta - B"}},
      {"materialx",
       {"x = NoV; y = r*r; x2 = x*x; y2 = y*y;"
        "r0 = 0.1003 - 0.6303*x + 9.748*y - 2.038*x*y + 29.34*x2 - 8.245*y2 - 26.44*x2*y + "
        "19.99*x*y2 - 5.448*x2*y2;"
        "r1 = 0.9345 - 2.323*x + 2.229*y - 3.748*x*y + 1.424*x2 - 0.7684*y2 + 1.436*x2*y + "
        "0.2913*x*y2 + 0.6286*x2*y2;"
        "r2 = 1.0 - 1.765*x + 8.263*y + 11.53*x*y + 28.96*x2 - 7.507*y2 - 36.11*x2*y + 15.86*x*y2 "
        "+ 33.37*x2*y2;"
        "r3 = 1.0 + 0.2281*x + 15.94*y - 55.83*x*y + 13.08*x2 + 41.26*y2 + 54.9*x2*y + 300.2*x*y2 "
        "- 285.1*x2*y2;"
        "A = saturate(r0/r2); B = saturate(r1/r3)"}},
      {"rtg",
       {"m = r*r;"
        "B = ((0.99044 - 1.28514*NoV) + m*(1.29678 - 0.755907*NoV)) /"
        "  ((1 + 2.92338*NoV + 59.4188*NoV^3) + m*(20.3225 - 27.0302*NoV + 222.592*NoV^3) +"
        "   m^3*(121.563 + 626.13*NoV + 316.627*NoV^3));"
        "A = ((0.0365463 + 3.32707*NoV) + m*(9.0632 - 9.04756*NoV)) /"
        "  ((1 + 3.59685*NoV^2 - 1.36772*NoV^3) + m*(9.04401 - 16.3174*NoV^2 + 9.22949*NoV^3) +"
        "   m^3*(5.56589 + 19.7886*NoV^2 - 20.2123*NoV^3))"}},
  };
}

// A few real front members: a short, seeded search on the DFG table.
std::vector<Program> frontMembers(const Table& t) {
  // At this budget about 4 seeds in 5 give a front of 3 or more (31 of 1..40 with double error
  // sums, 32 with float ones); seed 7 gives 7 members with both.
  nlohmann::json cj = {
      {"data", {{"path", (test::dataDir() / "dfg_16x16.json").string()}}},
      {"program", {{"max_length", 20}}},
      {"search", {{"population", 64}, {"generations", 12}, {"seed", 7}, {"threads", 1}}}};
  auto cfg = parseRunConfig(cj, test::dataDir());
  EXPECT_TRUE(cfg.hasValue()) << cfg.error();
  if (!cfg) return {};
  Search s(*cfg, t);
  s.run();
  std::vector<Program> out;
  for (const auto& e : s.front()) out.push_back(e.program);
  return out;
}

TEST(EmitRoundTrip, NativeMathCppOfRealMembersAgreesWithinTheUlpBound) {
  const Table dfg = test::loadDfg();
  std::vector<std::pair<std::string, Program>> progs;
  for (const auto& [name, texts] : publishedDfg()) {
    ParseOptions po;
    po.input_names = dfg.input_names;
    po.output_names = dfg.output_names;
    auto pf = parseFormula(texts, po);
    ASSERT_TRUE(pf.hasValue()) << name << ": " << pf.error();
    progs.emplace_back(name, pf->program);
  }
  const auto members = frontMembers(dfg);
  EXPECT_GE(members.size(), 3u);
  for (size_t i = 0; i < members.size(); ++i)
    progs.emplace_back("member" + std::to_string(i), members[i]);

  // Domain corners and centre, appended to the table's rows.
  const auto dom = domainOf(dfg);
  std::vector<std::vector<double>> corners;
  for (double a : {dom[0].lo, 0.5 * (dom[0].lo + dom[0].hi), dom[0].hi})
    for (double b : {dom[1].lo, 0.5 * (dom[1].lo + dom[1].hi), dom[1].hi})
      corners.push_back({a, b});
  const Table all = withRows(dfg, corners);

  std::vector<Case> cases;
  for (const auto& [name, p] : progs)
    for (bool fast : {false, true}) {
      Case c;
      c.fn = name + (fast ? "_fast" : "");
      c.program = p;
      c.input = inputFor(p, dfg);
      c.input.output_names = dfg.output_names;
      c.opts.fast = fast;
      cases.push_back(c);
    }
  auto res = compileAndRun("native_float", cases, rowsOf(all), Precision::Float);
  ASSERT_TRUE(res.ok) << res.log;
  int64_t worst = 0;
  std::string worst_at;
  for (size_t c = 0; c < cases.size(); ++c) {
    const auto ref = interpret(cases[c].program, all);
    for (size_t j = 0; j < ref.size(); ++j)
      for (size_t r = 0; r < all.rows(); ++r) {
        const float a = static_cast<float>(ref[j][r]), b = static_cast<float>(res.out[c][j][r]);
        if (std::isfinite(a)) {
          ASSERT_TRUE(std::isfinite(b)) << cases[c].fn << " row " << r << ": interpreter " << a
                                        << " is finite but the emitted code gives " << b;
        }
        const int64_t u = test::ulpDistance(a, b);
        if (u > worst) {
          worst = u;
          worst_at = cases[c].fn + " output " + std::to_string(j) + " row " + std::to_string(r) +
                     " (" + std::to_string(a) + " vs " + std::to_string(b) + ")";
        }
      }
  }
  std::cout << "native C++ vs interpreter: max " << worst << " ulp at " << worst_at << "\n";
  EXPECT_LE(worst, kNativeUlpBound) << worst_at;
}

TEST(EmitRoundTrip, RandomProgramsStayFiniteAtTheDomainEdges) {
  // Native math and --fast on the edge table's own domain: wherever the interpreter is
  // finite at a domain corner, the emitted code is too.
  const Table t = test::edgeTable(1);
  const auto dom = domainOf(t);
  std::vector<std::vector<double>> corners;
  for (double a : {dom[0].lo, dom[0].hi, 0.0, 1e-30})
    for (double b : {dom[1].lo, dom[1].hi, 0.0, -1e-30}) corners.push_back({a, b});
  const auto programs = randomPrograms(37, 120, false);
  std::vector<Case> cases;
  for (size_t i = 0; i < programs.size(); ++i)
    for (bool fast : {false, true}) {
      Case c;
      c.fn = std::string(fast ? "e" : "n") + std::to_string(i);
      c.program = programs[i];
      c.input = inputFor(programs[i], t);
      c.opts.fast = fast;
      cases.push_back(c);
    }
  Table ct = t;
  for (auto& col : ct.inputs) col.clear();
  for (auto& col : ct.outputs) col.clear();
  ct = withRows(ct, corners);
  for (auto& o : ct.outputs) std::fill(o.begin(), o.end(), 0.5);
  auto res = compileAndRun("edges", cases, corners, Precision::Float);
  ASSERT_TRUE(res.ok) << res.log;
  for (size_t c = 0; c < cases.size(); ++c) {
    const auto ref = interpret(cases[c].program, ct);
    for (size_t j = 0; j < ref.size(); ++j)
      for (size_t r = 0; r < corners.size(); ++r)
        if (std::isfinite(ref[j][r])) {
          ASSERT_TRUE(std::isfinite(res.out[c][j][r]))
              << cases[c].fn << " at (" << corners[r][0] << ", " << corners[r][1]
              << "): interpreter " << ref[j][r] << ", emitted " << res.out[c][j][r] << "\n"
              << emitProgram(cases[c].input, Language::Cpp, cases[c].opts)->function;
        }
  }
}

// What is exported is what was scored (search-4): on tables and seeds under linear scaling,
// the C++ `lgp emit` writes for each front member, compiled and run over the table, has the
// member's scored float32 error within the fidelity bound (2^-14 of the target's RMS), and
// the double reference error agrees with it.
TEST(EmitRoundTrip, EmittedCppReproducesTheScoredErrorAcrossTablesAndSeeds) {
  Table step;
  step.input_names = {"x", "z"};
  step.output_names = {"y"};
  step.inputs.resize(2);
  step.outputs.resize(1);
  for (int i = 0; i < 32; ++i)
    for (int j = 0; j < 8; ++j) {
      const double x = (i + 0.5) / 32, z = (j + 0.5) / 8;
      step.inputs[0].push_back(x);
      step.inputs[1].push_back(z);
      step.outputs[0].push_back(std::sqrt(x) * (1 + z * z) + (x > 0.6 ? 0.3 : 0.0));
    }
  const std::vector<std::pair<std::string, Table>> tables = {{"dfg", test::loadDfg()},
                                                             {"bumpy", step}};
  int members = 0;
  for (const auto& [tname, t] : tables) {
    const auto tol = fidelityTolerances(t);
    for (int seed : {1, 2}) {
      nlohmann::json cj = {{"data", {{"path", "t.csv"}}},
                           {"program", {{"max_length", 16}}},
                           {"search",
                            {{"population", 96},
                             {"generations", 25},
                             {"seed", seed},
                             {"threads", 1},
                             {"linear_scaling", true}}}};
      auto cfg = parseRunConfig(cj, test::dataDir());
      ASSERT_TRUE(cfg.hasValue()) << cfg.error();
      Search s(*cfg, t);
      s.run();
      const auto& front = s.front();
      ASSERT_FALSE(front.empty());
      std::vector<Case> cases;
      for (size_t i = 0; i < front.size(); ++i) {
        Case c;
        c.fn = tname + "_s" + std::to_string(seed) + "_m" + std::to_string(i);
        c.program = front[i].program;
        c.input = inputFor(front[i].program, t);
        c.input.output_names = t.output_names;
        cases.push_back(c);
      }
      auto res = compileAndRun("scored_" + tname + std::to_string(seed), cases, rowsOf(t),
                               Precision::Float);
      ASSERT_TRUE(res.ok) << res.log;
      for (size_t i = 0; i < front.size(); ++i) {
        const auto& e = front[i];
        for (size_t o = 0; o < t.outputs.size(); ++o) {
          double sse = 0;
          for (size_t r = 0; r < t.rows(); ++r) {
            const double d = res.out[i][o][r] - t.outputs[o][r];
            sse += d * d;
          }
          const double rmse = std::sqrt(sse / static_cast<double>(t.rows()));
          EXPECT_NEAR(rmse, e.metrics[o].rmse, tol[o])
              << cases[i].fn << " output " << o << ": " << e.formula;
          EXPECT_NEAR(e.metrics_ref[o].rmse, e.metrics[o].rmse, tol[o])
              << cases[i].fn << " output " << o << ": " << e.formula;
        }
        ++members;
      }
    }
  }
  std::cout << members << " members: emitted C++ error = scored error within the bound\n";
  EXPECT_GE(members, 12);
}

}  // namespace
}  // namespace lgp::emit
