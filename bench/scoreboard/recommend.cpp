// The member a user should ship for a table: the cheapest (measured RDNA2 ISA) that beats every
// published fit of the table on the held-out grid, else the knee of the front. Written as HLSL,
// GLSL and C++ next to the report; the shaders are run on lavapipe over the held-out grid.
#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>

#include "board.hpp"
#include "lgp/emit/emit.hpp"
#include "lgp/emit/vulkan_run.hpp"
#include "lgp/io/result.hpp"

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

// The declared domain of the table's inputs (the training range where the spec gives none).
std::vector<Interval> declaredDomain(const TableRun& r) {
  std::vector<Interval> d;
  for (size_t i = 0; i < r.train.numInputs(); ++i) {
    auto it = r.spec.domain.find(r.train.input_names[i]);
    if (it != r.spec.domain.end()) {
      d.push_back(Interval{it->second.first, it->second.second, false});
    } else {
      const auto [lo, hi] = std::minmax_element(r.train.inputs[i].begin(), r.train.inputs[i].end());
      d.push_back(Interval{*lo, *hi, false});
    }
  }
  return d;
}

// The bound a member must hold on the declared domain: each output within the held-out truth's
// range widened by that range's width on either side.
std::vector<std::pair<double, double>> allowedRange(const Table& heldout) {
  std::vector<std::pair<double, double>> a;
  for (const auto& y : heldout.outputs) {
    const auto [lo, hi] = std::minmax_element(y.begin(), y.end());
    const double w = *hi - *lo;
    a.push_back({*lo - w, *hi + w});
  }
  return a;
}

std::vector<Scored> countedFits(const TableRun& r) {
  std::vector<Scored> out;
  for (const auto& row : r.rows)
    if (row.counted) out.push_back(row.published);
  return out;
}
}  // namespace

void recommend(TableRun& r, const std::filesystem::path& dir, const Options& o) {
  Snapshot& fin = r.snaps.back();
  const std::vector<Interval> domain = declaredDomain(r);
  const auto allowed = allowedRange(r.heldout);
  std::vector<TargetTransform> transforms;
  for (const auto& name : r.train.output_names) {
    auto it = r.cfg.data.transforms.find(name);
    transforms.push_back(it == r.cfg.data.transforms.end() ? TargetTransform::None : it->second);
  }
  // Only a member that holds on the whole declared domain is recommended (checked lazily,
  // cheapest first).
  std::vector<std::optional<DomainCheck>> checked(fin.members.size());
  auto safe = [&](size_t i) -> const DomainCheck& {
    if (!checked[i]) {
      auto p = memberProgram(fin.front, i);
      checked[i] = p ? checkOnDomain(*p, domain, allowed, transforms, 200)
                     : DomainCheck{false, "", NAN, NAN, p.error()};
    }
    return *checked[i];
  };
  std::vector<size_t> order;
  for (size_t i = 0; i < fin.members.size(); ++i)
    if (std::isfinite(fin.members[i].isa)) order.push_back(i);
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return fin.members[a].isa < fin.members[b].isa; });
  const std::vector<Scored> fits = countedFits(r);
  int pick = -1, unsafe = 0;
  std::string why;
  for (size_t i : order)
    if (beatsAll(fin.members[i], fits)) {
      if (safe(i).safe) {
        pick = static_cast<int>(i);
        break;
      }
      ++unsafe;
    }
  if (pick >= 0) {
    why =
        "the cheapest member that beats every counted published fit of the table (held-out RMS "
        "and max on the declared domain, every channel) and holds on the whole domain";
  } else {
    std::vector<Scored> held;
    std::vector<int> index;
    for (size_t i = 0; i < fin.members.size(); ++i)
      if (safe(i).safe) {
        held.push_back(fin.members[i]);
        index.push_back(static_cast<int>(i));
      }
    const int k = knee(held);
    pick = k < 0 ? -1 : index[static_cast<size_t>(k)];
    why = std::string(fits.empty() ? "no counted published fit"
                                   : "no member beats every counted published fit and holds on "
                                     "the domain") +
          ": the knee of the members that hold on the domain (furthest below the chord in "
          "measured ISA against log RMS)";
  }
  if (unsafe > 0)
    why += "; " + std::to_string(unsafe) + " cheaper member" + (unsafe > 1 ? "s" : "") +
           " beating the fits left out: outside the bound on the domain";
  r.recommended = {{"member", pick}, {"why", why}};
  if (pick < 0) return;
  const DomainCheck& dc = safe(static_cast<size_t>(pick));
  json dom = json::object();
  for (size_t i = 0; i < domain.size(); ++i)
    dom[r.train.input_names[i]] = {domain[i].lo, domain[i].hi};
  json bound = json::array();
  for (const auto& [lo, hi] : allowed) bound.push_back({lo, hi});
  r.recommended["domain_check"] = {
      {"domain", dom}, {"bound", bound}, {"method", dc.method}, {"range", {dc.lo, dc.hi}}};
  r.recommended["isa"] = fin.members[pick].isa;
  r.recommended["formula"] = fin.members[pick].formula;
  json heldout = json::array();
  for (const auto& c : fin.members[pick].channels)
    heldout.push_back({{"rmse", c.rmse}, {"max_abs", c.max_abs}});
  r.recommended["heldout"] = heldout;
  // The code is emitted for the declared domain: what --fast leaves unguarded is proven there.
  fin.front["table"]["domain"] = dom;
  json files = json::object();
  for (const auto& language : emit::allLanguages()) {
    const emit::Language lang = language.lang;
    const std::string ext(language.name);
    emit::EmitOptions eo;
    eo.function_name = "lgp_" + r.spec.name;
    eo.fast = true;
    eo.table = &r.heldout;  // the header's errors: on the held-out grid
    eo.table_label = "the board's held-out set (declared domain, edges included)";
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
