#include "lgp/datasets/outputs.hpp"

namespace lgp::datasets {

const std::vector<std::string>& canonicalInputs() {
  static const std::vector<std::string> k = {"mu", "r", "eta"};
  return k;
}

const std::vector<OutputSpec>& outputCatalog() {
  static const std::vector<std::string> kMuR = {"mu", "r"};
  static const std::vector<OutputSpec> k = {
      {Output::A, "A", kMuR, Effect::Fresnel,
       "integral_H D G2 (1 - (1 - v.h)^5) / (4 (n.l)(n.v)) (n.l) dl  (scale on F0)"},
      {Output::B, "B", kMuR, Effect::Fresnel,
       "integral_H D G2 (1 - v.h)^5 / (4 (n.l)(n.v)) (n.l) dl  (bias, times F90)"},
      {Output::E, "E", kMuR, Effect::Specular,
       "integral_H D G2 / (4 (n.l)(n.v)) (n.l) dl  (directional albedo, F = 1)"},
      {Output::one_minus_E, "one_minus_E", kMuR, Effect::Energy, "1 - E(mu, r)"},
      {Output::E_avg, "E_avg", kMuR, Effect::Energy, "2 integral_0^1 E(mu, r) mu dmu"},
      {Output::ZH0, "ZH0", kMuR, Effect::Diffuse, "0.2820948 integral CBRDF(w) dw"},
      {Output::ZH1, "ZH1", kMuR, Effect::Diffuse,
       "0.4886025 integral CBRDF(w) (d.w) dw,  d = normalized first moment of CBRDF"},
      {Output::ZH2, "ZH2", kMuR, Effect::Diffuse, "0.3153916 integral CBRDF(w) (3 (d.w)^2 - 1) dw"},
      {Output::ZH1_over_ZH0, "ZH1_over_ZH0", kMuR, Effect::Diffuse, "ZH1 / ZH0"},
      {Output::ZH2_over_ZH0, "ZH2_over_ZH0", kMuR, Effect::Diffuse, "ZH2 / ZH0"},
      {Output::beta, "beta", kMuR, Effect::Diffuse, "d = normalize((1 - beta) n + beta v)"},
      {Output::N,
       "N",
       {"r", "size"},
       Effect::Normalization,
       "[2 integral_{cos ts}^1 E(mu) mu dmu] / [2 pi sin^2(ts) integral_0^1 f(l_rep(v), v) "
       "(n.l_rep) mu_v dmu_v]; light centred on n, l_rep = smoothed representative point, "
       "F = 1 (see datasets/README.md)"},
      {Output::ms_turquin, "ms_turquin", kMuR, Effect::Energy,
       "(1 - E) / E: f = f_ss (1 + F0 (1 - E) / E) compensates multiple scattering (Turquin 2019)"},
      {Output::ms_lobe, "ms_lobe", kMuR, Effect::Energy,
       "(1 - E(mu, r)) / sqrt(pi (1 - E_avg(r))): the Kulla-Conty lobe is "
       "f_ms(l, v) = ms_lobe(n.l) ms_lobe(n.v)"},
      {Output::E_sheen, "E_sheen", kMuR, Effect::Sheen,
       "integral_H D_charlie / (4 (n.l + n.v - (n.l)(n.v))) (n.l) dl  (Charlie sheen, "
       "Neubelt-Pettineo visibility, F = 1; also the cloth split-sum DFG term)"},
      {Output::E_burley, "E_burley", kMuR, Effect::DiffuseAlbedo,
       "integral_H f_burley(l, v) (n.l) dl  (Disney diffuse, baseColor = 1, r as is)"},
      {Output::E_oren_nayar, "E_oren_nayar", kMuR, Effect::DiffuseAlbedo,
       "integral_H (A + B max(0, s) / max(n.l, n.v)) / pi (n.l) dl,  s = l.v - (n.l)(n.v), "
       "sigma = r  (qualitative Oren-Nayar as MaterialX writes it)"},
      {Output::F_dielectric,
       "F_dielectric",
       {"mu", "eta"},
       Effect::Dielectric,
       "(r_s^2 + r_p^2) / 2 at cosine mu, relative index eta  (exact unpolarised Fresnel)"},
      {Output::F_avg,
       "F_avg",
       {"eta"},
       Effect::Dielectric,
       "2 integral_0^1 F_dielectric(mu, eta) mu dmu"},
      {Output::E_refl,
       "E_refl",
       {"mu", "r", "eta"},
       Effect::Dielectric,
       "integral_H D G2 F(v.h, eta) / (4 (n.l)(n.v)) (n.l) dl  (GGX reflection, exact Fresnel)"},
      {Output::E_trans,
       "E_trans",
       {"mu", "r", "eta"},
       Effect::Dielectric,
       "integral over the lower hemisphere of the GGX BTDF (1 - F) |n.l| dl  (Walter et al. "
       "2007; material.transmission: flux or radiance, see docs/tables.md)"},
      {Output::E_dielectric,
       "E_dielectric",
       {"mu", "r", "eta"},
       Effect::Dielectric,
       "E_refl + E_trans"},
  };
  return k;
}

const OutputSpec* findOutput(const std::string& name) {
  for (const auto& o : outputCatalog())
    if (o.name == name) return &o;
  return nullptr;
}

}  // namespace lgp::datasets
