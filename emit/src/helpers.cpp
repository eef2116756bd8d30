// Protected helpers per language. Each reproduces ops.hpp's semantics exactly, with the
// protection constants of the precision (half.hpp for half); see emit/README.md.
#include "helpers.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "lgp/emit/half.hpp"
#include "lgp/eval/semantics.hpp"
#include "syntax.hpp"

namespace lgp::emit::detail {

std::string_view opSpelling(const OpInfo& info, Language l) {
  return info.*(syntaxOf(l).spelling);
}

bool exactMath(const Ctx& c) {
  return c.exact_math && c.prec == Precision::Float;  // EmitOptions::validate: C++ only
}

std::string scalarType(const Ctx& c) {
  return std::string(syntaxOf(c.lang).scalar_type[static_cast<int>(c.prec)]);
}

std::string literal(double v, const Ctx& c) {
  // A constant beyond binary16's range is infinite in half (as lgp's half emulation has it):
  // built from its bit pattern.
  if (c.prec == Precision::Half && !std::isfinite(roundToHalf(static_cast<float>(v)))) {
    const std::string inf(syntaxOf(c.lang).half_infinity);
    return v < 0 ? "(-" + inf + ")" : inf;
  }
  std::string s;
  switch (c.prec) {
    case Precision::Float:
      s = formatFloat(static_cast<float>(v));
      break;
    case Precision::Half:
      s = formatFloat(roundToHalf(static_cast<float>(v)));
      break;
    case Precision::Double:
      s = formatDouble(v);
      break;
  }
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s + std::string(syntaxOf(c.lang).literal_suffix[static_cast<int>(c.prec)]);
}

std::string primitive(std::string_view fn, const Ctx& c) {
  if (exactMath(c) && (fn == "exp2" || fn == "log2" || fn == "sin" || fn == "cos"))
    return "lgp_vm_" + std::string(fn);
  const LanguageSyntax& syn = syntaxOf(c.lang);
  if (fn == "abs") return std::string(syn.abs);
  if (fn == "rsqrt") return std::string(syn.rsqrt);  // "": none, 1 / sqrt
  return std::string(syn.primitive_prefix) + std::string(fn);
}

std::string helperName(Helper h) {
  switch (h) {
    case Helper::Vm:
      return "lgp_vm";
    case Helper::Guard:
      return "lgp_guard";
    case Helper::Div:
      return "lgp_div";
    case Helper::Rcp:
      return "lgp_rcp";
    case Helper::Sqrt:
      return "lgp_sqrt";
    case Helper::Rsqrt:
      return "lgp_rsqrt";
    case Helper::Log2:
      return "lgp_log2";
    case Helper::Exp2:
      return "lgp_exp2";
    case Helper::Log:
      return "lgp_log";
    case Helper::Exp:
      return "lgp_exp";
    case Helper::Pow:
      return "lgp_pow";
    case Helper::Saturate:
      return "lgp_saturate";
    case Helper::Min:
      return "lgp_min";
    case Helper::Max:
      return "lgp_max";
    case Helper::Count:
      break;
  }
  return "";
}

void addWithDeps(HelperSet& set, Helper h, const Ctx& c) {
  set.set(static_cast<int>(h));
  const bool vm = exactMath(c);
  switch (h) {
    case Helper::Div:
    case Helper::Rcp:
      addWithDeps(set, Helper::Guard, c);
      break;
    case Helper::Log:
      addWithDeps(set, Helper::Log2, c);
      break;
    case Helper::Exp:
      addWithDeps(set, Helper::Exp2, c);
      break;
    case Helper::Pow:
      addWithDeps(set, Helper::Log2, c);
      addWithDeps(set, Helper::Exp2, c);
      break;
    case Helper::Log2:
    case Helper::Exp2:
      if (vm) addWithDeps(set, Helper::Vm, c);
      break;
    case Helper::Vm:
    case Helper::Guard:
    case Helper::Sqrt:
    case Helper::Rsqrt:
    case Helper::Saturate:
    case Helper::Min:
    case Helper::Max:
    case Helper::Count:
      break;
  }
}

std::string replaceAll(std::string s, std::string_view from, const std::string& to) {
  size_t pos = 0;
  while ((pos = s.find(from, pos)) != std::string::npos) {
    s.replace(pos, from.size(), to);
    pos += to.size();
  }
  return s;
}

namespace {

// Verbatim copy of lgp/include/lgp/eval/vecmath.hpp (same literals, same operation order);
// the C++ round-trip test checks that the two stay bit-identical.
constexpr const char* kVmText =
    R"(// The lgp interpreter's float32 exp2/log2/sin/cos (lgp/eval/vecmath.hpp). Compile with
// -ffp-contract=off (and FMA enabled iff the lgp build had it) for bit-identical results.
#if defined(__FMA__) || defined(__FMA4__)
inline float lgp_vm_fma(float a, float b, float c) { return __builtin_fmaf(a, b, c); }
#else
inline float lgp_vm_fma(float a, float b, float c) { return a * b + c; }
#endif
inline float lgp_vm_round(float x) { return (x + 12582912.0f) - 12582912.0f; }
inline float lgp_vm_float(std::int32_t i) { float f; std::memcpy(&f, &i, sizeof f); return f; }
inline std::int32_t lgp_vm_bits(float f) { std::int32_t i; std::memcpy(&i, &f, sizeof i); return i; }
inline float lgp_vm_exp2(float x) {
  const float n = lgp_vm_round(x);
  const float f = x - n;
  float p = 1.5252733804059840e-5f;
  p = lgp_vm_fma(p, f, 1.5403530393381609e-4f);
  p = lgp_vm_fma(p, f, 1.3333558146428443e-3f);
  p = lgp_vm_fma(p, f, 9.6181291076284772e-3f);
  p = lgp_vm_fma(p, f, 5.5504108664821580e-2f);
  p = lgp_vm_fma(p, f, 2.4022650695910071e-1f);
  p = lgp_vm_fma(p, f, 6.9314718055994531e-1f);
  p = lgp_vm_fma(p, f, 1.0f);
  return p * lgp_vm_float((static_cast<std::int32_t>(n) + 127) << 23);
}
inline float lgp_vm_log2(float x) {
  const std::int32_t i = lgp_vm_bits(x);
  std::int32_t e = ((i >> 23) & 0xff) - 127;
  float m = lgp_vm_float((i & 0x007fffff) | 0x3f800000);
  const bool hi = m > 1.41421356f;
  m = hi ? m * 0.5f : m;
  e = hi ? e + 1 : e;
  const float t = (m - 1.0f) / (m + 1.0f);
  const float t2 = t * t;
  float p = 0.26230819f;
  p = lgp_vm_fma(p, t2, 0.32059890f);
  p = lgp_vm_fma(p, t2, 0.41219858f);
  p = lgp_vm_fma(p, t2, 0.57707802f);
  p = lgp_vm_fma(p, t2, 0.96179669f);
  p = lgp_vm_fma(p, t2, 2.88539008f);
  const float r = lgp_vm_fma(p, t, static_cast<float>(e));
  return x == lgp_vm_float(0x7f800000) ? x : r;
}
inline float lgp_vm_sincos(float x, std::int32_t shift) {
  const float xc = x > 4.0e6f ? 4.0e6f : (x < -4.0e6f ? -4.0e6f : x);
  const float j = lgp_vm_round(xc * 0.63661977236758134f);
  float r = lgp_vm_fma(j, -1.5703125f, xc);
  r = lgp_vm_fma(j, -4.837512969970703125e-4f, r);
  r = lgp_vm_fma(j, -7.54978995489188216e-8f, r);
  const std::int32_t q = static_cast<std::int32_t>(j) + shift;
  const float r2 = r * r;
  float s = -2.5052108e-8f;
  s = lgp_vm_fma(s, r2, 2.7557319e-6f);
  s = lgp_vm_fma(s, r2, -1.9841270e-4f);
  s = lgp_vm_fma(s, r2, 8.3333333e-3f);
  s = lgp_vm_fma(s, r2, -1.6666667e-1f);
  s = lgp_vm_fma(s * r2, r, r);
  float c = 2.0876757e-9f;
  c = lgp_vm_fma(c, r2, -2.7557319e-7f);
  c = lgp_vm_fma(c, r2, 2.4801587e-5f);
  c = lgp_vm_fma(c, r2, -1.3888889e-3f);
  c = lgp_vm_fma(c, r2, 4.1666667e-2f);
  c = lgp_vm_fma(c, r2, -0.5f);
  c = lgp_vm_fma(c, r2, 1.0f);
  float v = (q & 1) ? c : s;
  v = (q & 2) ? -v : v;
  v = v > 1.0f ? 1.0f : (v < -1.0f ? -1.0f : v);
  return (x - x) == 0.0f ? v : (x - x);
}
inline float lgp_vm_sin(float x) { return lgp_vm_sincos(x, 0); }
inline float lgp_vm_cos(float x) { return lgp_vm_sincos(x, 1); }
)";

std::string upper(std::string s) {
  for (char& ch : s) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  return s;
}

// One helper's definition; `$T` is the scalar type, `$0`/`$1` literals 0 and 1, `$G` the
// guard, `$M` the log/rsqrt floor, `$E` the exp clamp, `$L2E`/`$LN2` the constants of
// exp/log, `$SQRT` etc. the primitives.
std::string helperDef(Helper h, const Ctx& c) {
  const bool half = c.prec == Precision::Half;
  const LanguageSyntax& syn = syntaxOf(c.lang);  // the guard, rsqrt and the qualifier
  std::string t;
  switch (h) {
    case Helper::Vm:
      return kVmText;
    case Helper::Guard:
      t = syn.guard_helper;
      break;
    case Helper::Div:
      t = "$T lgp_div($T a, $T b) { return a / lgp_guard(b); }";
      break;
    case Helper::Rcp:
      t = "$T lgp_rcp($T a) { return $1 / lgp_guard(a); }";
      break;
    case Helper::Sqrt:
      t = "$T lgp_sqrt($T a) { return $SQRT(a > $0 ? a : $0); }";
      break;
    case Helper::Rsqrt:
      t = syn.rsqrt_helper;
      break;
    case Helper::Log2:
      t = "$T lgp_log2($T a) { return $LOG2(a > $M ? a : $M); }";
      break;
    case Helper::Exp2:
      t = "$T lgp_exp2($T a) { return $EXP2(a > $E ? $E : (a < -$E ? -$E : a)); }";
      break;
    case Helper::Log:
      t = "$T lgp_log($T a) { return lgp_log2(a) * $LN2; }";
      break;
    case Helper::Exp:
      t = "$T lgp_exp($T a) { return lgp_exp2(a * $L2E); }";
      break;
    case Helper::Pow:
      t = "$T lgp_pow($T a, $T b) { return lgp_exp2(b * lgp_log2(a)); }";
      break;
    case Helper::Saturate:
      t = "$T lgp_saturate($T a) { return a > $0 ? (a < $1 ? a : $1) : $0; }";
      break;
    case Helper::Min:
      t = "$T lgp_min($T a, $T b) { return a < b ? a : b; }";
      break;
    case Helper::Max:
      t = "$T lgp_max($T a, $T b) { return a > b ? a : b; }";
      break;
    case Helper::Count:
      return "";
  }
  t = std::string(syn.helper_qualifier) + t;
  const double g =
      half ? kHalfDivGuard : (c.prec == Precision::Double ? double(kDivGuard) : kDivGuard);
  const double m = half ? kHalfMinPos : double(kMinPos);
  const double e = half ? kHalfExpClamp : kExpClamp;
  // Longest placeholders first.
  t = replaceAll(t, "$SQRT", primitive("sqrt", c));
  t = replaceAll(t, "$RSQRT", primitive("rsqrt", c));
  t = replaceAll(t, "$LOG2", primitive("log2", c));
  t = replaceAll(t, "$EXP2", primitive("exp2", c));
  t = replaceAll(
      t, "$L2E",
      literal(c.prec == Precision::Double ? sem::kLog2E : double(float(sem::kLog2E)), c));
  t = replaceAll(t, "$LN2",
                 literal(c.prec == Precision::Double ? sem::kLn2 : double(float(sem::kLn2)), c));
  t = replaceAll(t, "$T", scalarType(c));
  t = replaceAll(t, "$G", literal(g, c));
  t = replaceAll(t, "$M", literal(m, c));
  t = replaceAll(t, "$E", literal(e, c));
  t = replaceAll(t, "$0", literal(0.0, c));
  t = replaceAll(t, "$1", literal(1.0, c));
  return t + "\n";
}

}  // namespace

std::string helperBlock(const HelperSet& set, const Ctx& c) {
  std::string out;
  const std::string suffix = upper(scalarType(c)) + (exactMath(c) ? "_EXACT" : "");
  for (int i = 0; i < static_cast<int>(Helper::Count); ++i) {
    if (!set.test(i)) continue;
    const Helper h = static_cast<Helper>(i);
    const std::string key =
        "LGP_HELPER_" + upper(helperName(h).substr(4)) + (h == Helper::Vm ? "" : "_" + suffix);
    out += "#ifndef " + key + "\n#define " + key + "\n" + helperDef(h, c) + "#endif\n";
  }
  return out;
}

}  // namespace lgp::emit::detail
