// Emitted shaders on lavapipe (see vulkan_run.hpp).
#include "lgp/emit/vulkan_run.hpp"

#include <cmath>
#include <cstring>

#include "gpu_process.hpp"
#include "lgp/emit/compute_shader.hpp"
#include "metrics.hpp"
#include "syntax.hpp"

namespace lgp::emit {

namespace {

const detail::DriverSpec kLavapipe{"run", ""};

// Whether the language's half code is binary16 arithmetic, which a device without
// shaderFloat16 cannot run (HLSL's half is relaxed precision: it runs everywhere).
bool halfNeedsFloat16(Language l) {
  return detail::syntaxOf(l).half_needs_float16;
}

}  // namespace

VulkanStatus vulkanRunStatus() {
  auto h = detail::gpuHello(kLavapipe);
  if (!h) return {false, h.error(), false};
  return {true, h->value("device", std::string()) + ", " + h->value("driver", std::string()),
          h->value("shader_float16", false)};
}

double ulpOf(double v, Precision p) {
  const int mant = p == Precision::Half ? 10 : (p == Precision::Float ? 23 : 52);
  const int emin = p == Precision::Half ? -14 : (p == Precision::Float ? -126 : -1022);
  const double a = std::fabs(v);
  const int e = a > 0 && std::isfinite(a) ? std::max(std::ilogb(a), emin) : emin;
  return std::ldexp(1.0, e - mant);
}

Expected<std::vector<std::vector<float>>> runEmitted(const Emitted& e, Language lang,
                                                     Precision precision, const Table& t) {
  auto shader = computeShader(e, lang, precision, KernelBody::Formula);
  if (!shader) return shader.status();
  const size_t n = t.rows(), ni = t.numInputs(), k = e.output_access.size();
  if (ni != static_cast<size_t>(e.num_inputs))
    return Status::error("table: has " + std::to_string(ni) + " inputs, the function takes " +
                         std::to_string(e.num_inputs));
  if (n == 0) return Status::error("table: has no rows");
  nlohmann::json in = nlohmann::json::array();
  for (size_t r = 0; r < n; ++r)
    for (size_t i = 0; i < ni; ++i) in.push_back(static_cast<float>(t.inputs[i][r]));
  // The reply: n * k 32-bit patterns, at most 10 digits and a comma each.
  const size_t max_reply = n * k * 11 + (size_t{64} << 10);
  auto reply = detail::gpuRequest(kLavapipe,
                                  {{"op", "run"},
                                   {"lang", std::string(toString(lang))},
                                   {"source", *shader},
                                   {"rows", n},
                                   {"in_stride", ni},
                                   {"out_stride", k},
                                   {"inputs", in}},
                                  max_reply);
  if (!reply) return reply.status();
  const auto it = reply->find("output_bits");
  if (it == reply->end() || !it->is_array() || it->size() != n * k)
    return Status::error("the driver returned " +
                         std::to_string(it != reply->end() && it->is_array() ? it->size() : 0) +
                         " values, expected " + std::to_string(n * k));
  std::vector<std::vector<float>> out(k, std::vector<float>(n));
  for (size_t r = 0; r < n; ++r)
    for (size_t j = 0; j < k; ++j) {
      const auto& v = (*it)[r * k + j];
      if (!v.is_number_unsigned() || v.get<uint64_t>() > 0xFFFFFFFFu)
        return Status::error("the driver returned a value that is not a 32-bit pattern");
      const auto b = static_cast<uint32_t>(v.get<uint64_t>());
      std::memcpy(&out[j][r], &b, sizeof(float));
    }
  return out;
}

double VulkanCheck::worstScaledUlp() const {
  double w = 0;
  for (const auto& o : outputs) w = std::max(w, o.nonfinite > 0 ? INFINITY : o.max_scaled_ulp);
  return w;
}

nlohmann::json toJson(const VulkanCheck& c) {
  nlohmann::json j = {{"lang", std::string(toString(c.lang))},
                      {"precision", std::string(toString(c.precision))},
                      {"reference", c.reference}};
  if (c.skipped) {
    j["skipped"] = c.why;
    return j;
  }
  auto num = [](double v) {
    return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
  };
  nlohmann::json outs = nlohmann::json::array();
  for (const auto& o : c.outputs)
    outs.push_back(
        {{"name", o.name},
         {"max_abs_diff", num(o.max_abs_diff)},
         {"max_ulp", num(o.max_ulp)},
         {"max_scaled_ulp", num(o.max_scaled_ulp)},
         {"nonfinite_rows", o.nonfinite},
         {"driver", {{"rmse", num(o.driver.rmse)}, {"max_abs", num(o.driver.max_abs)}}},
         {"reference", {{"rmse", num(o.reference.rmse)}, {"max_abs", num(o.reference.max_abs)}}}});
  j["outputs"] = outs;
  return j;
}

std::vector<OutputAgreement> compareValues(const std::vector<std::vector<float>>& driver,
                                           const std::vector<std::vector<double>>& reference,
                                           Precision ref_precision, const Table& t,
                                           const std::vector<std::string>& names) {
  std::vector<std::vector<double>> drv(driver.size());
  for (size_t j = 0; j < driver.size(); ++j) drv[j].assign(driver[j].begin(), driver[j].end());
  const auto mdrv = detail::valueMetrics(drv, t);
  const auto mref = detail::valueMetrics(reference, t);
  std::vector<OutputAgreement> out;
  for (size_t j = 0; j < drv.size() && j < reference.size(); ++j) {
    OutputAgreement a;
    a.name = j < names.size() ? names[j] : "y" + std::to_string(j);
    double scale = 0;
    for (double v : reference[j])
      if (std::isfinite(v)) scale = std::max(scale, std::fabs(v));
    const double scale_ulp = ulpOf(scale, ref_precision);
    for (size_t r = 0; r < drv[j].size() && r < reference[j].size(); ++r) {
      const double g = drv[j][r], w = reference[j][r];
      if (std::isfinite(g) != std::isfinite(w)) {
        ++a.nonfinite;
        continue;
      }
      if (!std::isfinite(g)) continue;
      const double d = std::fabs(g - w);
      a.max_abs_diff = std::max(a.max_abs_diff, d);
      a.max_ulp = std::max(a.max_ulp, d / ulpOf(w, ref_precision));
      a.max_scaled_ulp = std::max(a.max_scaled_ulp, d / scale_ulp);
    }
    a.driver = mdrv[j];
    a.reference = mref[j];
    out.push_back(std::move(a));
  }
  return out;
}

Expected<std::vector<VulkanCheck>> verifyOnVulkan(const EmitInput& in, const Table& t,
                                                  const VerifyOptions& o) {
  const VulkanStatus st = vulkanRunStatus();
  if (!st.available) return Status::error(st.detail);
  std::vector<VulkanCheck> out;
  for (Language lang : o.langs)
    for (Precision p : o.precisions) {
      VulkanCheck c;
      c.lang = lang;
      c.precision = p;
      // What the driver computes, and so what it is compared with (vulkan_run.hpp).
      const bool half = p == Precision::Half;
      const Precision ref_p = half ? Precision::Half : Precision::Float;
      c.reference = half ? "binary16 emulation" : "float32 interpreter";
      if (half && halfNeedsFloat16(lang) && !st.float16) {
        c.skipped = true;
        c.why = "the device has no shaderFloat16";
        out.push_back(std::move(c));
        continue;
      }
      EmitOptions eo;
      eo.precision = p;
      eo.fast = o.fast;
      eo.pow_rewrites = o.pow_rewrites;
      eo.domain_rewrites = o.domain_rewrites;
      eo.header = false;
      auto e = emitProgram(in, lang, eo);
      if (!e) return e.status();
      auto got = runEmitted(*e, lang, p, t);
      if (!got)
        return Status::error(std::string(toString(lang)) + " " + std::string(toString(p)) + ": " +
                             got.error());
      // The reference: the member's DAG with exact rewrites only (no domain: the one `in`
      // claims is not evidence), evaluated as lgp does (bit-identical to the interpreter in
      // float; the binary16 emulation in half), inverse transforms applied.
      EmitInput as_scored = in;
      as_scored.domain.clear();
      EmitOptions ro;
      ro.precision = p;
      ro.pow_rewrites = false;
      ro.domain_rewrites = false;
      ro.header = false;
      auto r = emitProgram(as_scored, lang, ro);
      if (!r) return r.status();
      std::vector<TargetTransform> tr = in.transforms;
      tr.resize(r->output_access.size(), TargetTransform::None);
      auto ref = detail::dagValues(r->dag, t, tr, ref_p);
      if (!ref) return ref.status();
      c.outputs = compareValues(*got, *ref, ref_p, t, in.output_names);
      out.push_back(std::move(c));
    }
  return out;
}

}  // namespace lgp::emit
