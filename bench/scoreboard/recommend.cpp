// The member a user should ship for a table: the cheapest (measured RDNA2 ISA) that beats every
// published fit of the table on the held-out grid, else the knee of the front. Written as HLSL,
// GLSL and C++ next to the report; the shaders are run on lavapipe over the held-out grid.
#include <algorithm>
#include <cmath>
#include <fstream>

#include "board.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/vulkan_run.hpp"

namespace lgp::board {

namespace {
using nlohmann::json;

double worstRmse(const Scored& s) {
  double w = 0;
  for (const auto& c : s.channels) w = std::max(w, c.rmse);
  return w;
}

bool beatsAll(const Scored& m, const std::vector<Scored>& fits) {
  for (const auto& f : fits) {
    for (size_t c = 0; c < f.channels.size(); ++c)
      if (!(m.channels[c].rmse < f.channels[c].rmse &&
            m.channels[c].max_abs < f.channels[c].max_abs))
        return false;
  }
  return !fits.empty();
}

// The member furthest below the chord from the cheapest to the most accurate member, in
// (ISA, log10 RMS): where more instructions stop buying accuracy.
int knee(const std::vector<Scored>& ms) {
  std::vector<int> idx;
  for (size_t i = 0; i < ms.size(); ++i)
    if (std::isfinite(ms[i].isa) && worstRmse(ms[i]) > 0) idx.push_back(static_cast<int>(i));
  if (idx.empty()) return -1;
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return ms[a].isa < ms[b].isa; });
  const int lo = idx.front();
  const int hi = *std::min_element(
      idx.begin(), idx.end(), [&](int a, int b) { return worstRmse(ms[a]) < worstRmse(ms[b]); });
  const double x0 = ms[lo].isa, y0 = std::log10(worstRmse(ms[lo]));
  const double x1 = ms[hi].isa, y1 = std::log10(worstRmse(ms[hi]));
  int best = hi;
  double depth = 0;
  for (int i : idx) {
    if (ms[i].isa > x1 || x1 == x0) continue;
    const double chord = y0 + (y1 - y0) * (ms[i].isa - x0) / (x1 - x0);
    const double d = chord - std::log10(worstRmse(ms[i]));
    if (d > depth) depth = d, best = i;
  }
  return best;
}

json verify(const json& front, size_t i, const Table& t) {
  const auto st = emit::vulkanRunStatus();
  if (!st.available) return {{"unavailable", st.detail}};
  auto in = emit::emitInputFromFront(front, i);
  if (!in) return {{"error", in.error()}};
  emit::VerifyOptions vo;
  vo.fast = true;
  auto checks = emit::verifyOnVulkan(*in, t, vo);
  if (!checks) return {{"error", checks.error()}};
  json out = {{"device", st.detail}, {"rows", t.rows()}, {"checks", json::array()}};
  for (const auto& c : *checks) {
    json j = emit::toJson(c);
    j["worst_scaled_ulp"] = c.skipped ? json(nullptr) : json(c.worstScaledUlp());
    out["checks"].push_back(j);
  }
  return out;
}
}  // namespace

void recommend(TableRun& r, const std::filesystem::path& dir, const Options& o) {
  const Snapshot& fin = r.snaps.back();
  int pick = -1;
  std::string why;
  for (size_t i = 0; i < fin.members.size(); ++i)
    if (std::isfinite(fin.members[i].isa) && beatsAll(fin.members[i], r.fits) &&
        (pick < 0 || fin.members[i].isa < fin.members[pick].isa))
      pick = static_cast<int>(i);
  if (pick >= 0) {
    why =
        "the cheapest member that beats every published fit of the table (held-out RMS and "
        "max, every channel)";
  } else {
    pick = knee(fin.members);
    why =
        "no member beats every published fit: the knee of the front (furthest below the "
        "chord in measured ISA against log RMS)";
  }
  r.recommended = {{"member", pick}, {"why", why}};
  if (pick < 0) return;
  r.recommended["isa"] = fin.members[pick].isa;
  r.recommended["formula"] = fin.members[pick].formula;
  json files = json::object();
  for (const auto& language : emit::allLanguages()) {
    const emit::Language lang = language.lang;
    const std::string ext(language.name);
    emit::EmitOptions eo;
    eo.function_name = "lgp_" + r.spec.name;
    eo.fast = true;
    eo.table = &r.heldout;  // the header's errors: on the held-out grid
    eo.source = "lgp_scoreboard, " + r.spec.name + " member " + std::to_string(pick);
    auto code = emit::emitFromFront(fin.front, static_cast<size_t>(pick), lang, eo);
    const std::string name = r.spec.name + "_recommended." + ext;
    if (!code) {
      files[ext] = "emission failed: " + code.error();
      continue;
    }
    std::ofstream(dir / name) << *code;
    files[ext] = name;
  }
  r.recommended["files"] = files;
  r.recommended["lavapipe"] = o.vulkan ? verify(fin.front, static_cast<size_t>(pick), r.heldout)
                                       : json{{"unavailable", "--no-vulkan"}};
}

}  // namespace lgp::board
