// The published fits as the board's configs write them (bench/scoreboard/configs and
// bench/quality/configs, parsed by lgp's formula parser and run by the float32 interpreter)
// against the formulas written here again from their sources (MaterialX pbrlib
// mx_microfacet_sheen / mx_microfacet_diffuse, Kulla and Conty 2017, Sforza and Pellacini
// 2022's coefficient files in the order of their fit script, Karis 2014), in double
// precision, at a few points of each domain: a wrong sign, digit or term ordering in a config
// fails here.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>

#include "lgp/config/config.hpp"
#include "lgp/emit/score.hpp"
#include "lgp/eval/interpreter.hpp"

namespace {
using nlohmann::json;
using Point = std::vector<double>;  // the table inputs, in the config's order

lgp::RunConfig config(const std::string& rel) {
  const std::string path = std::string(LGP_SOURCE_DIR) + "/" + rel;
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  auto c = lgp::parseRunConfig(json::parse(ss.str()), std::filesystem::path(path).parent_path());
  EXPECT_TRUE(c) << path << ": " << (c ? "" : c.error());
  return *c;
}

// Output `out` of reference `name` at the points, through the parser and the interpreter.
std::vector<double> viaConfig(const lgp::RunConfig& cfg, const std::string& name,
                              const std::vector<Point>& pts, size_t outputs = 1, size_t out = 0) {
  lgp::Table t;
  t.input_names = cfg.data.inputs;
  t.output_names = cfg.data.outputs;
  t.inputs.assign(t.input_names.size(), {});
  t.outputs.assign(outputs, std::vector<double>(pts.size(), 0.0));
  for (const auto& p : pts)
    for (size_t i = 0; i < p.size(); ++i) t.inputs[i].push_back(p[i]);
  auto progs = lgp::emit::referencePrograms(cfg, t);
  EXPECT_TRUE(progs) << (progs ? "" : progs.error());
  for (const auto& np : *progs)
    if (np.name == name) {
      const auto y = lgp::Interpreter(256).evaluate(np.program, lgp::Dataset(t, 256));
      return std::vector<double>(y[out].begin(), y[out].end());
    }
  ADD_FAILURE() << "no reference " << name;
  return {};
}

void expectClose(const std::vector<double>& got, const std::vector<Point>& pts,
                 const std::function<double(const Point&)>& f, double tol) {
  ASSERT_EQ(got.size(), pts.size());
  for (size_t i = 0; i < pts.size(); ++i) {
    const double want = f(pts[i]);
    EXPECT_NEAR(got[i], want, tol * std::max(1.0, std::abs(want))) << "point " << i;
  }
}

// sklearn's PolynomialFeatures order (Sforza and Pellacini's fit.py): degree by degree, the
// monomials as combinations with replacement of the features.
std::vector<double> features(const std::vector<double>& x, int degree) {
  std::vector<double> f = {1.0};
  std::function<void(int, size_t, double)> rec = [&](int left, size_t from, double v) {
    if (left == 0) {
      f.push_back(v);
      return;
    }
    for (size_t i = from; i < x.size(); ++i) rec(left - 1, i, v * x[i]);
  };
  for (int d = 1; d <= degree; ++d) rec(d, 0, 1.0);
  return f;
}
// fit.py's ratpoly: (num . features) / (1 + den . features[1:])
double ratpoly(const std::vector<double>& c, const std::vector<double>& x) {
  const auto f = features(x, 3);
  double num = 0, den = 1;
  for (size_t i = 0; i < f.size(); ++i) num += c[i] * f[i];
  for (size_t i = 1; i < f.size(); ++i) den += c[f.size() + i - 1] * f[i];
  return num / den;
}

const std::vector<Point> kMuR = {{0.05, 0.1}, {0.3, 0.5}, {0.7, 0.25}, {0.95, 0.9}, {0.5, 1.0}};
}  // namespace

// A fit with a clamp is on the board twice (bench/scoreboard): as shipped (clamped) and as its
// analytic rational (the row that counts), each also in Horner form; all four compute the source.
void expectFourForms(const lgp::RunConfig& cfg, const std::string& name,
                     const std::function<double(const Point&)>& rational) {
  const auto clamped = [&](const Point& p) { return std::clamp(rational(p), 0.0, 1.0); };
  expectClose(viaConfig(cfg, name + ", shipped", kMuR), kMuR, clamped, 1e-5);
  expectClose(viaConfig(cfg, name + ", shipped, Horner", kMuR), kMuR, clamped, 1e-5);
  expectClose(viaConfig(cfg, name, kMuR), kMuR, rational, 1e-5);
  expectClose(viaConfig(cfg, name + ", Horner", kMuR), kMuR, rational, 1e-5);
}

TEST(PublishedFits, MaterialXSheenAlbedo) {
  expectFourForms(
      config("bench/scoreboard/configs/sheen.json"), "MaterialX sheen albedo", [](const Point& p) {
        const double x = p[0], y = p[1];
        const std::array<double, 2> r = {13.67300 - 68.78018 * x + 799.08825 * y -
                                             905.00061 * x * y + 60.28956 * x * x +
                                             1086.96473 * y * y,
                                         1.0 + 61.57746 * x + 442.78211 * y + 2597.49308 * x * y +
                                             121.81241 * x * x + 3045.55075 * y * y};
        return r[0] / r[1];
      });
}

TEST(PublishedFits, MaterialXDiffuseAlbedo) {
  expectClose(
      viaConfig(config("bench/scoreboard/configs/burley.json"), "MaterialX Burley albedo (Hill)",
                kMuR),
      kMuR,
      [](const Point& p) {
        const double x = p[0];
        const double fit0 = 0.97619 - 0.488095 * std::pow(1.0 - x, 5.0);
        const double fit1 = 1.55754 + (-2.02221 + (2.56283 - 1.06244 * x) * x) * x;
        return fit0 + (fit1 - fit0) * p[1];
      },
      1e-5);
  expectFourForms(config("bench/scoreboard/configs/oren_nayar.json"), "MaterialX Oren-Nayar albedo",
                  [](const Point& p) {
                    const double v = p[0], r = p[1];
                    const double a = 1.0 - 0.4297 * r - 0.7632 * v * r + 1.4385 * r * r;
                    const double b = 1.0 - 0.6076 * r - 0.4993 * v * r + 2.0315 * r * r;
                    return a / b;
                  });
}

TEST(PublishedFits, KullaConty) {
  const std::vector<Point> etas = {{1.0}, {1.33}, {1.5}, {2.4}, {3.0}};
  expectClose(
      viaConfig(config("bench/scoreboard/configs/fresnel_avg.json"), "Kulla-Conty F_avg(eta)",
                etas),
      etas, [](const Point& p) { return (p[0] - 1.0) / (4.08567 + 1.00071 * p[0]); }, 1e-6);
  // E(mu) of GGX, appendix B of the 2017 course slides
  expectClose(
      viaConfig(config("bench/scoreboard/configs/energy_kc.json"), "Kulla-Conty E(mu) fit", kMuR),
      kMuR,
      [](const Point& p) {
        const double m = p[0], r = p[1];
        const double S[5] = {-0.170718, 4.07985, -11.5295, 18.4961, -9.23618};
        const double T[5] = {0.0632331, 3.1434, -7.47567, 13.0482, -7.0401};
        const double s =
            S[0] * std::sqrt(m) + S[1] * r + S[2] * r * r + S[3] * r * r * r + S[4] * r * r * r * r;
        const double t =
            T[0] * m + T[1] * r + T[2] * r * r + T[3] * r * r * r + T[4] * r * r * r * r;
        return 1.0 - std::pow(s, 6) * std::pow(m, 0.75) / (std::pow(t, 6) + m * m);
      },
      2e-5);
}

TEST(PublishedFits, SforzaPellacini) {
  const std::vector<double> conductor = {1.0247217,  -10.984229, 10.918318,  46.93353,  -54.779343,
                                         21.742077,  -30.368898, 31.919222,  -8.013965, -6.2407165,
                                         -10.218104, 10.955399,  44.08196,   -55.33452, 21.437538,
                                         -23.744568, 33.265057,  -7.9268975, -5.930959};
  // features (roughness, cos theta): their table's rows are roughness, columns cos theta
  expectClose(
      viaConfig(config("bench/scoreboard/configs/conductor_sp.json"),
                "Sforza-Pellacini conductor E", kMuR),
      kMuR,
      [&](const Point& p) {
        return ratpoly(conductor, {p[1], p[0]});
      },
      2e-5);
  const std::vector<double> dielectric = {
      0.88204753,  2.9100745,   -0.48650393, -0.6869693, -2.6111116, 1.280099,   -3.0361037,
      6.0099907,   1.5584689,   5.0413747,   0.08679456, 1.7977521,  2.4122913,  3.0965478,
      -13.059173,  6.5015526,   -5.8326087,  2.8601415,  -2.823629,  -1.9989978, 2.576616,
      -0.88472295, -0.2968001,  -1.9873656,  7.7758255,  11.823093,  11.806131,  0.77912694,
      8.370924,    -0.21419774, -3.3057156,  -7.3967423, 26.120386,  -38.740086, 18.952562,
      -7.097557,   0.06018523,  -1.6995846,  -4.2700834};
  const std::vector<Point> pts = {
      {0.1, 0.2, 1.3}, {0.5, 0.5, 1.5}, {0.9, 0.8, 2.0}, {0.3, 1.0, 2.9}, {0.7, 0.05, 1.1}};
  // features (reflectivity in [0.0125, 0.25] mapped to [0, 1], roughness, cos theta)
  expectClose(
      viaConfig(config("bench/scoreboard/configs/dielectric_sp.json"),
                "Sforza-Pellacini dielectric E", pts),
      pts,
      [&](const Point& p) {
        const double f0 = std::pow((p[2] - 1.0) / (p[2] + 1.0), 2);
        const double x = (std::clamp(f0, 0.0125, 0.25) - 0.0125) / (0.25 - 0.0125);
        return ratpoly(dielectric, {x, p[1], p[0]});
      },
      2e-5);
}

// Two of the DFG fits already listed (the configs of bench/quality): Karis's mobile
// EnvBRDFApprox with its vector constants, and Iwanicki and Pesce's.
TEST(PublishedFits, DfgFitsAlreadyListed) {
  const auto cfg = config("bench/quality/configs/dfg.json");
  auto karis = [](const Point& p, int out) {
    const double c0[4] = {-1, -0.0275, -0.572, 0.022}, c1[4] = {1, 0.0425, 1.04, -0.04};
    double q[4];
    for (int i = 0; i < 4; ++i) q[i] = p[1] * c0[i] + c1[i];
    const double a004 = std::min(q[0] * q[0], std::exp2(-9.28 * p[0])) * q[0] + q[1];
    return out == 0 ? -1.04 * a004 + q[2] : 1.04 * a004 + q[3];
  };
  for (int out : {0, 1})
    expectClose(
        viaConfig(cfg, "Karis EnvBRDFApprox", kMuR, 2, out), kMuR,
        [&](const Point& p) { return karis(p, out); }, 2e-5);
  expectClose(
      viaConfig(cfg, "Iwanicki & Pesce", kMuR, 2, 1), kMuR,
      [](const Point& p) { return std::exp2(-(7.0 * p[0] + 4.0 * p[1] * p[1])); }, 2e-5);
}
