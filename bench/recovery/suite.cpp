#include "suite.hpp"

#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <sstream>

namespace recovery {

namespace {

constexpr double kPi = std::numbers::pi;

double sq(double v) {
  return v * v;
}
double pow5(double v) {
  return sq(sq(v)) * v;
}

// Height-correlated Smith G2 written without tan (Heitz 2014, eq. 99 rearranged):
// 1 / (1 + L(v) + L(l)) = 2 v l / (l sqrt(a^2 + (1-a^2) v^2) + v sqrt(a^2 + (1-a^2) l^2)).
double smithG2(double v, double l, double a) {
  const double a2 = a * a;
  return 2 * v * l / (l * std::sqrt(a2 + (1 - a2) * v * v) + v * std::sqrt(a2 + (1 - a2) * l * l));
}

const std::vector<Fam> kArith = {Fam::Arith};
// Uy et al. use one function set for every Nguyen problem.
const std::vector<Fam> kNguyenOps = {Fam::Arith, Fam::Sin, Fam::Cos, Fam::Exp, Fam::Log};

const std::map<std::string, const char*> kCitations = {
    {"uy2011",
     "N. Q. Uy, N. X. Hoai, M. O'Neill, R. I. McKay, E. Galvan-Lopez, \"Semantically-based "
     "crossover in genetic programming: application to real-valued symbolic regression\", "
     "Genetic Programming and Evolvable Machines 12(2), 2011"},
    {"udrescu2020",
     "S.-M. Udrescu, M. Tegmark, \"AI Feynman: a physics-inspired method for symbolic "
     "regression\", Science Advances 6(16), 2020 (ranges from its FeynmanEquations.csv)"},
    {"walter2007",
     "B. Walter, S. R. Marschner, H. Li, K. E. Torrance, \"Microfacet models for refraction "
     "through rough surfaces\", EGSR 2007 (GGX; the same D as Trowbridge & Reitz, JOSA 1975)"},
    {"heitz2014",
     "E. Heitz, \"Understanding the masking-shadowing function in microfacet-based BRDFs\", "
     "Journal of Computer Graphics Techniques 3(2), 2014"},
    {"schlick1994",
     "C. Schlick, \"An inexpensive BRDF model for physically-based rendering\", Computer "
     "Graphics Forum 13(3) (Eurographics), 1994"},
    {"kelemen2001",
     "C. Kelemen, L. Szirmay-Kalos, \"A microfacet based coupled specular-matte BRDF model with "
     "importance sampling\", Eurographics 2001 Short Presentations"},
    {"hammon2017",
     "E. Hammon Jr., \"PBR diffuse lighting for GGX+Smith microsurfaces\", Game Developers "
     "Conference 2017"},
};

std::vector<Problem> makeSuite() {
  // Nguyen ranges as in Uy et al. (who train on 20 points; the driver's row count applies
  // here). Nguyen-9..12 take U[0,1] for both inputs, as in the DSR benchmark file (Petersen
  // et al., ICLR 2021); some later tables use U[-1,1], where x^y is not real.
  const Input x11{"x", -1, 1}, x02{"x", 0, 2}, x04{"x", 0, 4}, x01{"x", 0, 1}, y01{"y", 0, 1};
  std::vector<Problem> s = {
      {"nguyen1",
       "nguyen",
       "Nguyen-1",
       "x^3 + x^2 + x",
       "uy2011",
       {x11},
       [](const double* v) { return v[0] * (1 + v[0] * (1 + v[0])); },
       kNguyenOps},
      {"nguyen2",
       "nguyen",
       "Nguyen-2",
       "x^4 + x^3 + x^2 + x",
       "uy2011",
       {x11},
       [](const double* v) { return v[0] * (1 + v[0] * (1 + v[0] * (1 + v[0]))); },
       kNguyenOps},
      {"nguyen3",
       "nguyen",
       "Nguyen-3",
       "x^5 + x^4 + x^3 + x^2 + x",
       "uy2011",
       {x11},
       [](const double* v) {
         const double x = v[0];
         return x * (1 + x * (1 + x * (1 + x * (1 + x))));
       },
       kNguyenOps},
      {"nguyen4",
       "nguyen",
       "Nguyen-4",
       "x^6 + x^5 + x^4 + x^3 + x^2 + x",
       "uy2011",
       {x11},
       [](const double* v) {
         const double x = v[0];
         return x * (1 + x * (1 + x * (1 + x * (1 + x * (1 + x)))));
       },
       kNguyenOps},
      {"nguyen5",
       "nguyen",
       "Nguyen-5",
       "sin(x^2) cos(x) - 1",
       "uy2011",
       {x11},
       [](const double* v) { return std::sin(v[0] * v[0]) * std::cos(v[0]) - 1; },
       kNguyenOps},
      {"nguyen6",
       "nguyen",
       "Nguyen-6",
       "sin(x) + sin(x + x^2)",
       "uy2011",
       {x11},
       [](const double* v) { return std::sin(v[0]) + std::sin(v[0] + v[0] * v[0]); },
       kNguyenOps},
      {"nguyen7",
       "nguyen",
       "Nguyen-7",
       "log(x + 1) + log(x^2 + 1)",
       "uy2011",
       {x02},
       [](const double* v) { return std::log(v[0] + 1) + std::log(v[0] * v[0] + 1); },
       kNguyenOps},
      {"nguyen8",
       "nguyen",
       "Nguyen-8",
       "sqrt(x)",
       "uy2011",
       {x04},
       [](const double* v) { return std::sqrt(v[0]); },
       kNguyenOps},
      {"nguyen9",
       "nguyen",
       "Nguyen-9",
       "sin(x) + sin(y^2)",
       "uy2011",
       {x01, y01},
       [](const double* v) { return std::sin(v[0]) + std::sin(v[1] * v[1]); },
       kNguyenOps},
      {"nguyen10",
       "nguyen",
       "Nguyen-10",
       "2 sin(x) cos(y)",
       "uy2011",
       {x01, y01},
       [](const double* v) { return 2 * std::sin(v[0]) * std::cos(v[1]); },
       kNguyenOps},
      {"nguyen11",
       "nguyen",
       "Nguyen-11",
       "x^y",
       "uy2011",
       {x01, y01},
       [](const double* v) { return std::pow(v[0], v[1]); },
       kNguyenOps},
      {"nguyen12",
       "nguyen",
       "Nguyen-12",
       "x^4 - x^3 + y^2/2 - y",
       "uy2011",
       {x01, y01},
       [](const double* v) {
         const double x = v[0], y = v[1];
         return x * x * x * (x - 1) + y * (y / 2 - 1);
       },
       kNguyenOps},

      // AI Feynman equations with 1-4 inputs; operators: the families each formula uses.
      {"feynman_I_6_2a",
       "feynman",
       "Feynman I.6.2a",
       "exp(-theta^2/2) / sqrt(2 pi)",
       "udrescu2020",
       {{"theta", 1, 3}},
       [](const double* v) { return std::exp(-v[0] * v[0] / 2) / std::sqrt(2 * kPi); },
       {Fam::Arith, Fam::Exp}},
      {"feynman_I_6_2",
       "feynman",
       "Feynman I.6.2",
       "exp(-(theta/sigma)^2/2) / (sqrt(2 pi) sigma)",
       "udrescu2020",
       {{"sigma", 1, 3}, {"theta", 1, 3}},
       [](const double* v) { return std::exp(-sq(v[1] / v[0]) / 2) / (std::sqrt(2 * kPi) * v[0]); },
       {Fam::Arith, Fam::Exp}},
      {"feynman_I_10_7",
       "feynman",
       "Feynman I.10.7",
       "m_0 / sqrt(1 - v^2/c^2)",
       "udrescu2020",
       {{"m_0", 1, 5}, {"v", 1, 2}, {"c", 3, 10}},
       [](const double* v) { return v[0] / std::sqrt(1 - sq(v[1]) / sq(v[2])); },
       {Fam::Arith, Fam::Sqrt}},
      {"feynman_I_12_1",
       "feynman",
       "Feynman I.12.1",
       "mu Nn",
       "udrescu2020",
       {{"mu", 1, 5}, {"Nn", 1, 5}},
       [](const double* v) { return v[0] * v[1]; },
       kArith},
      {"feynman_I_14_4",
       "feynman",
       "Feynman I.14.4",
       "k_spring x^2 / 2",
       "udrescu2020",
       {{"k_spring", 1, 5}, {"x", 1, 5}},
       [](const double* v) { return 0.5 * v[0] * v[1] * v[1]; },
       kArith},
      {"feynman_I_25_13",
       "feynman",
       "Feynman I.25.13",
       "q / C",
       "udrescu2020",
       {{"q", 1, 5}, {"C", 1, 5}},
       [](const double* v) { return v[0] / v[1]; },
       kArith},
      {"feynman_I_27_6",
       "feynman",
       "Feynman I.27.6",
       "1 / (1/d1 + n/d2)",
       "udrescu2020",
       {{"d1", 1, 5}, {"d2", 1, 5}, {"n", 1, 5}},
       [](const double* v) { return 1 / (1 / v[0] + v[2] / v[1]); },
       kArith},
      {"feynman_I_34_8",
       "feynman",
       "Feynman I.34.8",
       "q v B / p",
       "udrescu2020",
       {{"q", 1, 5}, {"v", 1, 5}, {"B", 1, 5}, {"p", 1, 5}},
       [](const double* v) { return v[0] * v[1] * v[2] / v[3]; },
       kArith},
      {"feynman_I_39_1",
       "feynman",
       "Feynman I.39.1",
       "3/2 pr V",
       "udrescu2020",
       {{"pr", 1, 5}, {"V", 1, 5}},
       [](const double* v) { return 1.5 * v[0] * v[1]; },
       kArith},

      // Shading closed forms over the physically meaningful domain: cosines in [0, 1] (kept
      // off 0 where the term divides by them), GGX alpha = roughness^2 from near-mirror to 1.
      {"ggx_d",
       "pbr",
       "GGX / Trowbridge-Reitz D",
       "alpha^2 / (pi (NoH^2 (alpha^2 - 1) + 1)^2)",
       "walter2007",
       {{"NoH", 0, 1}, {"alpha", 0.1, 1}},
       [](const double* v) {
         const double a2 = v[1] * v[1];
         return a2 / (kPi * sq(v[0] * v[0] * (a2 - 1) + 1));
       },
       kArith},
      {"smith_g1",
       "pbr",
       "Smith G1 for GGX",
       "2 NoV / (NoV + sqrt(alpha^2 + (1 - alpha^2) NoV^2))",
       "walter2007",
       {{"NoV", 0.01, 1}, {"alpha", 0.05, 1}},
       [](const double* v) {
         const double a2 = v[1] * v[1];
         return 2 * v[0] / (v[0] + std::sqrt(a2 + (1 - a2) * v[0] * v[0]));
       },
       {Fam::Arith, Fam::Sqrt}},
      {"smith_g2",
       "pbr",
       "Height-correlated Smith G2 for GGX",
       "1 / (1 + Lambda(NoV) + Lambda(NoL))",
       "heitz2014",
       {{"NoV", 0.01, 1}, {"NoL", 0.01, 1}, {"alpha", 0.05, 1}},
       [](const double* v) { return smithG2(v[0], v[1], v[2]); },
       {Fam::Arith, Fam::Sqrt}},
      {"schlick",
       "pbr",
       "Schlick Fresnel",
       "F0 + (1 - F0) (1 - VoH)^5",
       "schlick1994",
       {{"F0", 0.02, 1}, {"VoH", 0, 1}},
       [](const double* v) { return v[0] + (1 - v[0]) * pow5(1 - v[1]); },
       kArith},
      {"kelemen",
       "pbr",
       "Kelemen visibility",
       "1 / (4 VoH^2)",
       "kelemen2001",
       {{"VoH", 0.1, 1}},
       [](const double* v) { return 1 / (4 * v[0] * v[0]); },
       kArith},
      {"hammon_rough",
       "pbr",
       "Hammon diffuse, rough term",
       "f (0.9 - 0.4 f) (0.5 + NoH) / NoH, f = 0.5 + 0.5 LoV",
       "hammon2017",
       {{"LoV", -1, 1}, {"NoH", 0.1, 1}},
       [](const double* v) {
         const double facing = 0.5 + 0.5 * v[0];
         return facing * (0.9 - 0.4 * facing) * (0.5 + v[1]) / v[1];
       },
       kArith},
      {"hammon_smooth",
       "pbr",
       "Hammon diffuse, smooth term",
       "1.05 (1 - (1 - NoL)^5) (1 - (1 - NoV)^5)",
       "hammon2017",
       {{"NoL", 0, 1}, {"NoV", 0, 1}},
       [](const double* v) { return 1.05 * (1 - pow5(1 - v[0])) * (1 - pow5(1 - v[1])); },
       kArith},
  };
  return s;
}

uint64_t fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

// SplitMix64 (Steele, Lea, Flood, OOPSLA 2014): tiny, and fixed here so that the data never
// changes with the engine's own RNG or the standard library's distributions.
struct SplitMix {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(next() >> 11) * 0x1.0p-53;
  }
};

}  // namespace

const std::vector<Problem>& suite() {
  static const std::vector<Problem> s = makeSuite();
  return s;
}

const char* citation(const std::string& key) {
  const auto it = kCitations.find(key);
  return it == kCitations.end() ? "" : it->second;
}

std::vector<const Problem*> select(const std::string& list, std::vector<std::string>& unknown) {
  std::set<std::string> want;
  std::stringstream ss(list);
  for (std::string item; std::getline(ss, item, ',');)
    if (!item.empty()) want.insert(item);
  std::set<std::string> matched;
  std::vector<const Problem*> out;
  for (const Problem& p : suite()) {
    const bool hit = want.contains("all") || want.contains(p.name) || want.contains(p.group);
    if (hit) out.push_back(&p);
    for (const char* k : {p.name, p.group})
      if (want.contains(k)) matched.insert(k);
  }
  for (const auto& w : want)
    if (w != "all" && !matched.contains(w)) unknown.push_back(w);
  return out;
}

std::vector<lgp::Op> lgpOps(const Problem& p) {
  using lgp::Op;
  std::vector<Op> ops;
  for (Fam f : p.ops) switch (f) {
      case Fam::Arith:
        // mad, neg and square are single opcodes for compositions of the four (Operon gets
        // square too; its + and * are n-ary).
        ops.insert(ops.end(), {Op::Add, Op::Sub, Op::Mul, Op::Div, Op::Mad, Op::Neg, Op::Square});
        break;
      case Fam::Sin:
        ops.push_back(Op::Sin);
        break;
      case Fam::Cos:
        ops.push_back(Op::Cos);
        break;
      case Fam::Exp:
        ops.push_back(Op::Exp);
        break;
      case Fam::Log:
        ops.push_back(Op::Log);
        break;
      case Fam::Sqrt:
        ops.push_back(Op::Sqrt);
        break;
    }
  return ops;
}

std::vector<std::string> operonSymbols(const Problem& p) {
  std::vector<std::string> s;
  for (Fam f : p.ops) switch (f) {
      case Fam::Arith:
        s.insert(s.end(), {"add", "sub", "mul", "div", "square"});
        break;
      case Fam::Sin:
        s.push_back("sin");
        break;
      case Fam::Cos:
        s.push_back("cos");
        break;
      case Fam::Exp:
        s.push_back("exp");
        break;
      case Fam::Log:
        s.push_back("log");
        break;
      case Fam::Sqrt:
        s.push_back("sqrt");
        break;
    }
  return s;
}

lgp::Table sample(const Problem& p, uint64_t seed, int stream, int rows) {
  SplitMix rng{fnv1a(p.name) ^ (seed * 0xD1B54A32D192ED03ull) ^
               (static_cast<uint64_t>(stream) * 0xA0761D6478BD642Full)};
  for (int i = 0; i < 4; ++i) rng.next();  // decorrelate nearby seeds
  lgp::Table t;
  const size_t n = p.inputs.size();
  for (const Input& in : p.inputs) t.input_names.push_back(in.name);
  t.output_names = {"target"};
  t.inputs.assign(n, {});
  t.outputs.assign(1, {});
  std::vector<double> x(n);
  for (int r = 0; r < rows; ++r) {
    for (size_t i = 0; i < n; ++i) {
      x[i] = rng.uniform(p.inputs[i].lo, p.inputs[i].hi);
      t.inputs[i].push_back(x[i]);
    }
    t.outputs[0].push_back(p.f(x.data()));
  }
  return t;
}

}  // namespace recovery
