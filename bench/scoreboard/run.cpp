// One table of the board: the published fits and lgp's search, measured (RDNA2 ISA) and scored
// on the held-out grid, and the rows that compare them.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "board.hpp"
#include "lgp/emit/gpu_cost.hpp"
#include "lgp/emit/score.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/io/result.hpp"
#include "lgp/search/search.hpp"

namespace lgp::board {

namespace {
using nlohmann::json;

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double rdna2(const json& entry) {
  if (!entry.contains("cost_measured") || !entry["cost_measured"].contains("rdna2")) return NAN;
  return entry["cost_measured"]["rdna2"].value("instructions", NAN);
}

// float32 RMS and max per error channel (or output) of `p` on `t`.
Expected<Scored> scoreOn(const Program& p, const Table& t, const RunConfig& cfg,
                         const std::string& name) {
  emit::ScoreOptions so;
  so.error = cfg.errorConfig(t.output_names);
  so.error.transforms.clear();
  auto j = emit::scoreProgram(p, t, so, {});
  if (!j) return j.status();
  Scored s;
  s.name = name;
  s.model_cost = j->value("cost", NAN);
  s.formula = j->value("formula", std::string());
  for (const auto& c : j->contains("channels") ? (*j)["channels"] : (*j)["outputs"])
    s.channels.push_back({c["float32"].value("rmse", NAN), c["float32"].value("max_abs", NAN)});
  return s;
}

// Every form of every fit named by the spec, as front entries scored on the training table
// (in the spec's order, the forms of a fit together).
Expected<json> fitEntries(const TableRun& r, std::vector<NamedProgram>& programs) {
  auto all = emit::referencePrograms(r.cfg, r.train);
  if (!all) return all.status();
  json refs = json::array();
  for (const auto& fit : r.spec.fits)
    for (const auto& name : fit.forms) {
      auto it =
          std::find_if(all->begin(), all->end(), [&](const auto& n) { return n.name == name; });
      if (it == all->end())
        return Status::error(r.spec.config + ": no reference named '" + name + "' (fits)");
      emit::ScoreOptions so;
      so.error = r.cfg.errorConfig(r.train.output_names);
      so.error.transforms.clear();
      auto j = emit::scoreProgram(it->program, r.train, so, {});
      if (!j) return Status::error(name + ": " + j.error());
      (*j)["name"] = name;
      refs.push_back(*j);
      programs.push_back(*it);
    }
  return refs;
}

// The search to the largest budget, the front kept at every budget.
void search(TableRun& r, const Options& o) {
  RunConfig cfg = r.cfg;
  cfg.search.threads = o.threads;
  cfg.search.seed = o.seed;
  cfg.search.generations = 0;
  cfg.search.wall_time_s = 0;
  std::vector<uint64_t> budgets;
  for (double m : o.minutes)
    budgets.push_back(std::max<uint64_t>(1, static_cast<uint64_t>(m * r.spec.evals_per_minute)));
  cfg.search.max_evaluations = budgets.back();
  cfg.search.seed_references = o.seed_references;
  Search s(cfg, r.train);
  if (cfg.search.seed_references)
    if (auto seeds = emit::referencePrograms(cfg, r.train))
      for (const auto& why : s.addSeeds(*seeds))
        std::fprintf(stderr, "  [%s] not seeded: %s\n", r.spec.name.c_str(), why.c_str());
  const double t0 = now();
  s.initialize();
  size_t next = 0;
  while (next < budgets.size()) {
    const auto p = s.progress();
    while (next < budgets.size() && (p.evaluations >= budgets[next] || p.finished)) {
      Snapshot sn;
      sn.minutes = o.minutes[next];
      sn.evaluations = p.evaluations;
      sn.wall_s = now() - t0;
      sn.front = frontToJson(s, s.front());
      std::fprintf(stderr, "  [%s] %g nominal min: %llu evaluations, %.1f s\n", r.spec.name.c_str(),
                   sn.minutes, static_cast<unsigned long long>(sn.evaluations), sn.wall_s);
      r.snaps.push_back(std::move(sn));
      ++next;
    }
    if (p.finished || next >= budgets.size()) break;
    s.step();
  }
  r.search_wall_s = now() - t0;
}

// Worst over channels of fit / lgp for RMS and for max.
Match compare(const Scored& fit, const Scored& m, int index) {
  Match x;
  x.member = index;
  x.m = m;
  x.rms_factor = x.max_factor = INFINITY;
  for (size_t c = 0; c < fit.channels.size() && c < m.channels.size(); ++c) {
    x.rms_factor = std::min(x.rms_factor, fit.channels[c].rmse / m.channels[c].rmse);
    x.max_factor = std::min(x.max_factor, fit.channels[c].max_abs / m.channels[c].max_abs);
  }
  x.beaten = x.rms_factor > 1 && x.max_factor > 1;
  return x;
}

Match bestMatch(const Scored& fit, const std::vector<Scored>& members) {
  Match best;
  for (size_t i = 0; i < members.size(); ++i) {
    if (!(members[i].isa <= fit.isa)) continue;
    const Match m = compare(fit, members[i], static_cast<int>(i));
    if (best.member < 0 ||
        std::min(m.rms_factor, m.max_factor) > std::min(best.rms_factor, best.max_factor))
      best = m;
  }
  return best;
}
}  // namespace

Status runTable(TableRun& r, const Options& o) {
  r.channels = channelNames(r.cfg.errorConfig(r.train.output_names), r.train.output_names);
  std::vector<NamedProgram> fit_programs;
  auto refs = fitEntries(r, fit_programs);
  if (!refs) return refs.status();
  search(r, o);
  for (size_t k = 0; k < r.snaps.size(); ++k) {
    Snapshot& sn = r.snaps[k];
    // Measured cost of the members, and (once) of the fits, in the same front.
    sn.front["references"] = k == 0 ? *refs : json::array();
    emit::addMeasuredCost(sn.front);
    const json& info = sn.front["cost_measured_info"];
    r.measured = !info.contains("unavailable");
    r.measure_note = r.measured ? info.value("compiler", std::string("ACO"))
                                : info["unavailable"].get<std::string>();
    if (k == 0) *refs = sn.front["references"];
    sn.front.erase("references");
    const json& members = sn.front["members"];
    for (size_t i = 0; i < members.size(); ++i) {
      auto p = memberProgram(sn.front, i);
      if (!p) return Status::error("member " + std::to_string(i) + ": " + p.error());
      auto s = scoreOn(*p, r.heldout, r.cfg, "#" + std::to_string(i));
      if (!s) return s.status();
      s->isa = rdna2(members[i]);
      sn.members.push_back(std::move(*s));
    }
  }
  size_t next_form = 0;
  for (const auto& fit : r.spec.fits) {
    // The fit's forms compute the same values; it is charged the cheapest one's ISA.
    std::vector<Program> forms;
    std::vector<double> isa;
    for (size_t k = 0; k < fit.forms.size(); ++k) {
      forms.push_back(fit_programs[next_form + k].program);
      isa.push_back(rdna2((*refs)[next_form + k]));
    }
    auto cheapest = cheapestForm(forms, isa, r.heldout, fit.forms);
    if (!cheapest) return Status::error(fit.name + ": " + cheapest.error());
    auto s = scoreOn(forms[*cheapest], r.heldout, r.cfg, fit.name);
    if (!s) return s.status();
    s->isa = isa[*cheapest];
    s->form = fit.forms[*cheapest];
    next_form += fit.forms.size();
    r.fits.push_back(*s);
    Row row;
    row.table = r.spec.name;
    row.fit = fit.name;
    row.counted = fit.counted;
    row.source = fit.source;
    row.note = fit.note;
    row.published = *s;
    for (const auto& sn : r.snaps) row.lgp.push_back(bestMatch(*s, sn.members));
    r.rows.push_back(std::move(row));
  }
  return Status::ok();
}

Expected<size_t> cheapestForm(const std::vector<Program>& forms, const std::vector<double>& isa,
                              const Table& t, const std::vector<std::string>& names) {
  if (forms.empty()) return Status::error("no form");
  const auto first = evaluateReference(forms[0], t);
  size_t best = 0;
  for (size_t k = 0; k < forms.size(); ++k) {
    const auto v = evaluateReference(forms[k], t);
    if (v.size() != first.size()) return Status::error("'" + names[k] + "' has other outputs");
    for (size_t o = 0; o < v.size(); ++o) {
      double scale = 0, diff = 0;
      for (size_t i = 0; i < v[o].size(); ++i) {
        scale = std::max(scale, std::fabs(first[o][i]));
        diff = std::max(diff, std::fabs(v[o][i] - first[o][i]));
      }
      if (!(diff <= 1e-4 * scale))
        return Status::error("its form '" + names[k] + "' computes other values than '" + names[0] +
                             "' (by " + std::to_string(diff) + " of " + std::to_string(scale) +
                             ")");
    }
    if (isa[k] < isa[best] || (std::isnan(isa[best]) && !std::isnan(isa[k]))) best = k;
  }
  return best;
}

void addOperon(std::vector<TableRun>& runs, const json& operon) {
  for (auto& r : runs) {
    const json* list = nullptr;
    if (operon.contains("tables") && operon["tables"].contains(r.spec.name))
      list = &operon["tables"][r.spec.name];
    if (!list || !list->is_array()) continue;  // "not run"
    for (auto& row : r.rows) {
      std::string text;
      for (size_t c = 0; c < r.channels.size(); ++c) {
        // The entry of this channel with the largest ISA bound at or below the fit's ISA.
        const json* best = nullptr;
        for (const auto& e : *list) {
          const std::string ch = e.value("channel", r.channels.size() == 1 ? r.channels[0] : "");
          const double k = e.value("isa_max", NAN);
          if (ch != r.channels[c] || !(k <= row.published.isa)) continue;
          if (!best || k > (*best)["isa_max"].get<double>()) best = &e;
        }
        char b[160];
        if (best)
          std::snprintf(b, sizeof b, "%s%.3g / %.3g (ISA <= %g)",
                        r.channels.size() > 1 ? (r.channels[c] + ": ").c_str() : "",
                        best->value("rmse", NAN), best->value("max_abs", NAN),
                        (*best)["isa_max"].get<double>());
        else
          std::snprintf(b, sizeof b, "%sno entry at this ISA",
                        r.channels.size() > 1 ? (r.channels[c] + ": ").c_str() : "");
        text += (text.empty() ? "" : "; ") + std::string(b);
      }
      row.operon = text;
    }
  }
}

}  // namespace lgp::board
