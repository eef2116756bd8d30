#include "report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "record.hpp"

namespace lgp::board {

namespace {
using nlohmann::json;

std::string fmt(double v, const char* f = "%.3g") {
  if (!std::isfinite(v)) return "-";
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string cell(const std::string& s) {
  std::string o;
  for (char c : s)
    o += c == '|' ? std::string("\\|") : c == '\n' ? std::string(" ") : std::string(1, c);
  return o;
}

// "rms / max" per channel, joined.
std::string errors(const Scored& s) {
  std::string t;
  for (const auto& c : s.channels)
    t += (t.empty() ? "" : "; ") + fmt(c.rmse) + " / " + fmt(c.max_abs);
  return t;
}

std::string matchCell(const Match& m) {
  if (m.member < 0) return "no member at this ISA";
  return "#" + std::to_string(m.member) + ", " + fmt(m.m.isa, "%.0f") + " ISA: " + errors(m.m) +
         " (x" + fmt(m.rms_factor) + " / x" + fmt(m.max_factor) + ")";
}

// The row of the same fit in the seeded run of its table, if there is one.
const Row* seededRow(const std::map<std::string, TableRun>& seeded, const Row& row) {
  auto it = seeded.find(row.table);
  if (it == seeded.end()) return nullptr;
  for (const auto& r : it->second.rows)
    if (r.fit == row.fit) return &r;
  return nullptr;
}

struct Tally {
  size_t counted = 0, beaten = 0, seeded_runs = 0, beaten_seeded = 0, only_seeded = 0, apart = 0;
  std::vector<double> rms, mx;
  double search_s = 0;
};

Tally tally(const std::vector<TableRun>& runs, const std::map<std::string, TableRun>& seeded) {
  Tally t;
  for (const auto& r : runs) {
    if (!r.snaps.empty()) t.search_s += r.snaps.back().wall_s;
    for (const auto& row : r.rows) {
      if (!row.counted) {
        ++t.apart;
        continue;
      }
      ++t.counted;
      const Match& m = row.lgp.back();
      if (m.beaten) ++t.beaten;
      if (m.member >= 0) t.rms.push_back(m.rms_factor), t.mx.push_back(m.max_factor);
      if (const Row* s = seededRow(seeded, row)) {
        ++t.seeded_runs;
        if (s->lgp.back().beaten) ++t.beaten_seeded;
        if (s->lgp.back().beaten && !m.beaten) ++t.only_seeded;
      }
    }
  }
  return t;
}

std::string summary(const std::vector<TableRun>& runs,
                    const std::map<std::string, TableRun>& seeded, const RunInfo& info) {
  const Tally t = tally(runs, seeded);
  std::ostringstream s;
  s << "After " << fmt(info.settings.minutes.back()) << " nominal minutes of search per table ("
    << fmt(t.search_s, "%.0f") << " s of wall time in all on " << info.settings.threads
    << " threads), started without the published fits"
    << (info.settings.edge_objective
            ? " and with the edge objective (the declared domain's edge rows join the table the "
              "search fits, --edge-objective)"
            : "")
    << ", lgp beats " << t.beaten << " of " << t.counted
    << " counted published fits, each on the table it was fitted to and charged its cheapest "
       "measured form, at or below the fit's RDNA2 ISA in both RMS and max error on a held-out "
       "set that covers the declared domain to its edges (every error channel). Median "
       "improvement at the fit's ISA: "
    << fmt(median(t.rms)) << "x in RMS, " << fmt(median(t.mx))
    << "x in max error (fit / lgp, the worst channel; the true median).";
  if (t.seeded_runs > 0)
    s << " Seeded with the published fits, " << t.beaten_seeded << " of " << t.seeded_runs
      << (t.only_seeded
              ? " (" + std::to_string(t.only_seeded) + " only so: refined from the published form)"
              : "")
      << ".";
  if (t.apart > 0)
    s << " " << t.apart
      << " more rows are listed apart and not counted (a shipped clamp, a heuristic, or no "
         "located source).";
  if (!info.missing.empty())
    s << " (" << runs.size() << " of " << runs.size() + info.missing.size()
      << " tables run so far.)";
  if (info.settings.quick) s << " (A --quick run: a structure check, not the board.)";
  return s.str();
}

void boardTable(std::ostringstream& md, const std::vector<TableRun>& runs,
                const std::map<std::string, TableRun>& seeded, const RunInfo& info, bool counted) {
  md << "| table | published fit (form charged) | fit ISA (RDNA2) | fit RMS / max (held out) |";
  for (double m : info.settings.minutes)
    md << " lgp " << fmt(m) << " min: member, ISA, RMS / max (fit/lgp) |";
  md << " beaten | seeded " << fmt(info.settings.minutes.back())
     << " min | Operon RMS / max |\n|---|---|---|---|";
  for (size_t k = 0; k < info.settings.minutes.size(); ++k) md << "---|";
  md << "---|---|---|\n";
  for (const auto& r : runs)
    for (const auto& row : r.rows) {
      if (row.counted != counted) continue;
      const std::string form = row.published.form.empty() || row.published.form == row.fit
                                   ? ""
                                   : " (" + row.published.form + ")";
      md << "| " << cell(r.spec.name) << " | " << cell(row.fit + form) << " | "
         << fmt(row.published.isa, "%.0f") << " | " << errors(row.published) << " |";
      for (const auto& m : row.lgp) md << " " << cell(matchCell(m)) << " |";
      const Row* s = seededRow(seeded, row);
      md << " " << (row.lgp.back().beaten ? "yes" : "**no**") << " | "
         << (s ? cell(matchCell(s->lgp.back())) + (s->lgp.back().beaten ? ", beaten" : "")
               : std::string("not run"))
         << " | " << cell(row.operon) << " |\n";
    }
  md << "\n";
}

void tableSection(std::ostringstream& md, const TableRun& r) {
  md << "## " << r.spec.title << " (`" << r.spec.name << "`)\n\n"
     << "- Config `" << r.spec.config << "`; error channels " << json(r.channels).dump() << "; "
     << fmt(r.spec.evals_per_minute, "%.3g") << " evaluations per nominal minute.\n"
     << "- Training grid: " << r.train_desc << ". Held-out set (the declared domain";
  for (const auto& [input, range] : r.spec.domain)
    md << ", " << input << " in [" << fmt(range.first, "%.4g") << ", " << fmt(range.second, "%.4g")
       << "]";
  md << "; midpoints, edges and random values): " << r.heldout_desc << ".\n- Measured cost: "
     << (r.measured ? "RDNA2 instructions of the `hlsl --fast` code, " + r.measure_note
                    : "unavailable (" + r.measure_note + ")")
     << ".\n- Search: ";
  for (size_t i = 0; i < r.snaps.size(); ++i) {
    const auto& sn = r.snaps[i];
    md << (i ? "; " : "") << fmt(sn.minutes) << " min = " << sn.evaluations << " evaluations ("
       << fmt(sn.wall_s, "%.1f") << " s), front " << sn.members.size();
  }
  md << ".\n";
  for (const auto& row : r.rows) {
    md << "- **" << cell(row.fit) << "**" << (row.counted ? "" : " (not counted)");
    if (!row.published.form.empty())
      md << ": charged the form `" << cell(row.published.form) << "`";
    if (!row.source.empty()) md << "; source: " << cell(row.source);
    if (!row.note.empty()) md << "; " << cell(row.note);
    md << ".\n";
  }
  md << "\n";
  const json& rec = r.recommended;
  if (rec.value("member", -1) < 0) {
    md << "No member to recommend.\n\n";
    return;
  }
  md << "**Recommended**: member #" << rec["member"].get<int>() << ", "
     << fmt(rec.value("isa", NAN), "%.0f")
     << " RDNA2 instructions: " << rec["why"].get<std::string>() << ".\n\n`"
     << cell(rec.value("formula", std::string())) << "`\n\n";
  if (rec.contains("domain_check")) {
    const json& dc = rec["domain_check"];
    auto range = [](const json& p) {
      return "[" + fmt(p[0].get<double>(), "%.4g") + ", " + fmt(p[1].get<double>(), "%.4g") + "]";
    };
    md << "- Holds on the declared domain (";
    bool first = true;
    for (const auto& [input, d] : dc["domain"].items())
      md << (first ? "" : ", ") << input << " in " << range(d), first = false;
    md << "), by " << dc.value("method", std::string()) << ": its values lie in "
       << range(dc["range"]) << ", within ";
    for (size_t o = 0; o < dc["bound"].size(); ++o) md << (o ? ", " : "") << range(dc["bound"][o]);
    md << " (the truth's range on the held-out set widened by its width each side).\n";
  }
  if (rec.contains("heldout")) {
    md << "- Held-out RMS / max (declared domain):";
    for (const auto& c : rec["heldout"])
      md << " " << fmt(c.value("rmse", NAN)) << " / " << fmt(c.value("max_abs", NAN)) << ";";
    md << "\n";
  }
  if (rec.contains("files"))
    for (const auto& [lang, f] : rec["files"].items())
      md << "- " << lang << ": `" << f.get<std::string>() << "`\n";
  const json& lv = rec.value("lavapipe", json::object());
  if (lv.contains("checks")) {
    md << "- lavapipe (" << cell(lv.value("device", std::string())) << ", " << lv.value("rows", 0)
       << " held-out rows), worst difference from lgp in ulps of the output's largest |value|:";
    for (const auto& c : lv["checks"])
      md << " " << c.value("lang", std::string()) << " " << c.value("precision", std::string())
         << " "
         << (c["worst_scaled_ulp"].is_number() ? fmt(c["worst_scaled_ulp"].get<double>())
                                               : std::string("skipped"))
         << ";";
    md << "\n";
  } else {
    md << "- lavapipe: not run (" << cell(lv.dump()) << ")\n";
  }
  md << "\n";
}

// The README's opening section: the rules in one paragraph, the summary and the counted rows.
std::string readmeSection(const std::vector<TableRun>& runs,
                          const std::map<std::string, TableRun>& seeded, const RunInfo& info,
                          const std::string& sum) {
  std::ostringstream md;
  md << "**How the board counts.** Each published fit is scored on the table it was fitted to "
        "(its masking function, roughness mapping and Fresnel) and charged the measured RDNA2 "
        "instructions of its cheapest equivalent form (Horner or factored where that is "
        "cheaper; the clamp a library ships with a fit is a second row, listed apart). Errors are "
        "RMS and max on a held-out set that covers the declared domain to its edges (n.v from "
        "1e-4, roughness from 0.01, the light size from 0) with off-grid points, per error "
        "channel; lgp's member at or below the fit's ISA must beat both on every channel. The "
        "search starts without the published fits; a win that needs them is marked. Budgets "
        "are evaluation counts (nominal minutes at a calibrated rate) and the wall time is "
        "stated. Rows without a located source, heuristics and shipped clamps are listed apart "
        "and not counted. A member is recommended only if it holds on the whole declared "
        "domain (interval analysis or a dense sweep).\n\n"
     << sum << "\n\n"
     << "| table | published fit (RDNA2 ISA) | lgp member at or below it | fit / lgp, RMS and max "
        "| seeded |\n|---|---|---|---|---|\n";
  for (const auto& r : runs)
    for (const auto& row : r.rows) {
      if (!row.counted) continue;
      const Match& m = row.lgp.back();
      const Row* s = seededRow(seeded, row);
      md << "| " << cell(r.spec.name) << " | " << cell(row.fit) << " ("
         << fmt(row.published.isa, "%.0f") << ") | "
         << (m.member < 0 ? std::string("none") : fmt(m.m.isa, "%.0f") + " ISA") << " | "
         << (m.member < 0 ? std::string("-")
                          : fmt(m.rms_factor) + "x, " + fmt(m.max_factor) + "x" +
                                (m.beaten ? "" : " (**not beaten**)"))
         << " | " << (s ? (s->lgp.back().beaten ? "beaten" : "not beaten") : std::string("not run"))
         << " |\n";
    }
  (void)info;
  return md.str();
}
}  // namespace

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string writeReport(const std::vector<TableRun>& runs,
                        const std::map<std::string, TableRun>& seeded, const RunInfo& info,
                        const std::filesystem::path& dir) {
  const std::string sum = summary(runs, seeded, info);
  std::ostringstream md;
  md << "# lgp scoreboard\n\n"
     << sum << "\n\n"
     << "Generated by `lgp_scoreboard" << (info.settings.quick ? " --quick" : "") << "` (seed "
     << info.settings.seed << ", " << info.settings.threads
     << " threads; budgets are evaluation counts, nominal minutes x the "
     << "table's calibrated rate, so the figures depend on the seed and thread count only). "
     << "Errors are float32-interpreter figures on the held-out set (the declared domain, edges "
        "included); costs are measured RDNA2 instructions (Mesa ACO, RADV null device) of each "
        "fit's cheapest form. Each lgp cell is the member at or below the fit's ISA that comes "
        "closest to beating it; (x a / x b) = fit / lgp for RMS and max, the worst channel. "
        "\"seeded\" is the same search started from the published fits. Machine: "
     << info.cpu << "; wall " << fmt(info.wall_s, "%.0f") << " s, CPU " << fmt(info.cpu_s, "%.0f")
     << " s (summed over the tables' runs).\n\n";
  auto names = [](const std::vector<std::string>& v) {
    std::string t;
    for (const auto& n : v) t += (t.empty() ? "`" : ", `") + n + "`";
    return t;
  };
  if (!info.missing.empty())
    md << "**Not yet run** (no record with these settings in `tables/`): " << names(info.missing)
       << ". The summary above covers the tables below only.\n\n";
  if (!info.other_settings.empty())
    md << "Left out, run with other settings (seed, threads, budgets or --quick): "
       << names(info.other_settings) << ".\n\n";
  md << "## Counted rows\n\n";
  boardTable(md, runs, seeded, info, true);
  md << "## Listed apart (not counted)\n\n";
  boardTable(md, runs, seeded, info, false);
  for (const auto& r : runs) tableSection(md, r);
  std::ofstream(dir / "report.md") << md.str();
  std::ofstream(dir / "readme.md") << readmeSection(runs, seeded, info, sum);
  json s = {{"summary", sum},
            {"missing", info.missing},
            {"quick", info.settings.quick},
            {"seed", info.settings.seed},
            {"threads", info.settings.threads},
            {"minutes", info.settings.minutes},
            {"rows", json::array()},
            {"recommended", json::object()}};
  json timing = {{"cpu", info.cpu},
                 {"wall_s", info.wall_s},
                 {"cpu_s", info.cpu_s},
                 {"tables", json::object()}};
  for (const auto& r : runs) {
    for (const auto& row : r.rows) {
      auto matches = [&](const Row& x, const TableRun& run) {
        json lgp = json::array();
        for (size_t k = 0; k < x.lgp.size(); ++k) {
          const Match& m = x.lgp[k];
          lgp.push_back({{"minutes", run.snaps[k].minutes},
                         {"wall_s", run.snaps[k].wall_s},
                         {"member", m.member},
                         {"scored", m.member >= 0 ? scoredJson(m.m) : json(nullptr)},
                         {"rms_factor", m.rms_factor},
                         {"max_factor", m.max_factor},
                         {"beaten", m.beaten}});
        }
        return lgp;
      };
      json entry = {{"table", row.table},
                    {"fit", row.fit},
                    {"counted", row.counted},
                    {"channels", r.channels},
                    {"published", scoredJson(row.published)},
                    {"lgp", matches(row, r)},
                    {"operon", row.operon}};
      if (const Row* sr = seededRow(seeded, row))
        entry["lgp_seeded"] = matches(*sr, seeded.at(row.table));
      s["rows"].push_back(entry);
    }
    s["recommended"][r.spec.name] = r.recommended;
    json t = {{"table_s", r.table_wall_s}, {"search_s", r.search_wall_s}};
    for (const auto& sn : r.snaps)
      t[fmt(sn.minutes) + " min"] = {{"evaluations", sn.evaluations}, {"wall_s", sn.wall_s}};
    timing["tables"][r.spec.name] = t;
  }
  std::ofstream(dir / "summary.json") << s.dump(1) << "\n";
  std::ofstream(dir / "timing.json") << timing.dump(1) << "\n";
  return sum;
}

}  // namespace lgp::board
