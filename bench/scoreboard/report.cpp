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

std::string summary(const std::vector<TableRun>& runs, const RunInfo& info) {
  size_t rows = 0, beaten = 0;
  std::vector<double> rms, mx;
  for (const auto& r : runs)
    for (const auto& row : r.rows) {
      ++rows;
      const Match& m = row.lgp.back();
      if (m.beaten) ++beaten;
      if (m.member >= 0) rms.push_back(m.rms_factor), mx.push_back(m.max_factor);
    }
  auto median = [](std::vector<double> v) {
    if (v.empty()) return static_cast<double>(NAN);
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::ostringstream s;
  s << "After " << fmt(info.settings.minutes.back()) << " nominal minutes on "
    << info.settings.threads << " threads lgp beats " << beaten << " of " << rows
    << " published fits at or below each fit's own measured RDNA2 ISA, in both RMS and max "
       "error on a held-out grid (every error channel). Median improvement at the fit's ISA: "
    << fmt(median(rms)) << "x in RMS, " << fmt(median(mx)) << "x in max error (fit / lgp, the "
    << "worst channel).";
  if (!info.missing.empty())
    s << " (" << runs.size() << " of " << runs.size() + info.missing.size()
      << " tables run so far.)";
  if (info.settings.quick) s << " (A --quick run: a structure check, not the board.)";
  return s.str();
}

void boardTable(std::ostringstream& md, const std::vector<TableRun>& runs, const RunInfo& info) {
  md << "| table | published fit | fit ISA (RDNA2) | fit RMS / max (held out) |";
  for (double m : info.settings.minutes)
    md << " lgp " << fmt(m) << " min: member, ISA, RMS / max (fit/lgp) |";
  md << " beaten | Operon RMS / max |\n|---|---|---|---|";
  for (size_t k = 0; k < info.settings.minutes.size(); ++k) md << "---|";
  md << "---|---|\n";
  for (const auto& r : runs)
    for (const auto& row : r.rows) {
      md << "| " << cell(r.spec.name) << " | " << cell(row.fit) << " | "
         << fmt(row.published.isa, "%.0f") << " | " << errors(row.published) << " |";
      for (const auto& m : row.lgp) md << " " << cell(matchCell(m)) << " |";
      md << " " << (row.lgp.back().beaten ? "yes" : "**no**") << " | " << cell(row.operon)
         << " |\n";
    }
  md << "\n";
}

void tableSection(std::ostringstream& md, const TableRun& r) {
  md << "## " << r.spec.title << " (`" << r.spec.name << "`)\n\n"
     << "- Config `" << r.spec.config << "`; error channels " << json(r.channels).dump() << "; "
     << fmt(r.spec.evals_per_minute, "%.3g") << " evaluations per nominal minute.\n"
     << "- Training grid: " << r.train_desc << ". Held-out grid (midpoints): " << r.heldout_desc
     << ".\n- Measured cost: "
     << (r.measured ? "RDNA2 instructions of the `hlsl --fast` code, " + r.measure_note
                    : "unavailable (" + r.measure_note + ")")
     << ".\n- Search: ";
  for (const auto& sn : r.snaps)
    md << fmt(sn.minutes) << " min = " << sn.evaluations << " evaluations ("
       << fmt(sn.wall_s, "%.1f") << " s), front " << sn.members.size() << "; ";
  md << "\n\n";
  const json& rec = r.recommended;
  if (rec.value("member", -1) < 0) {
    md << "No member to recommend.\n\n";
    return;
  }
  md << "**Recommended**: member #" << rec["member"].get<int>() << ", "
     << fmt(rec.value("isa", NAN), "%.0f")
     << " RDNA2 instructions: " << rec["why"].get<std::string>() << ".\n\n`"
     << cell(rec.value("formula", std::string())) << "`\n\n";
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
}  // namespace

std::string writeReport(const std::vector<TableRun>& runs, const RunInfo& info,
                        const std::filesystem::path& dir) {
  const std::string sum = summary(runs, info);
  std::ostringstream md;
  md << "# lgp scoreboard\n\n"
     << sum << "\n\n"
     << "Generated by `lgp_scoreboard" << (info.settings.quick ? " --quick" : "") << "` (seed "
     << info.settings.seed << ", " << info.settings.threads
     << " threads; budgets are evaluation counts, nominal minutes x the "
     << "table's calibrated rate, so the figures depend on the seed and thread count only). "
     << "Errors are float32-interpreter figures on the held-out grid; costs are measured RDNA2 "
     << "instructions (Mesa ACO, RADV null device). Each lgp cell is the member at or below the "
     << "fit's ISA that comes closest to beating it; (x a / x b) = fit / lgp for RMS and max, the "
     << "worst channel. Machine: " << info.cpu << "; wall " << fmt(info.wall_s, "%.0f")
     << " s, CPU " << fmt(info.cpu_s, "%.0f") << " s (summed over the tables' runs).\n\n";
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
  boardTable(md, runs, info);
  for (const auto& r : runs) tableSection(md, r);
  std::ofstream(dir / "report.md") << md.str();
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
      json lgp = json::array();
      for (size_t k = 0; k < row.lgp.size(); ++k) {
        const Match& m = row.lgp[k];
        lgp.push_back({{"minutes", r.snaps[k].minutes},
                       {"member", m.member},
                       {"scored", m.member >= 0 ? scoredJson(m.m) : json(nullptr)},
                       {"rms_factor", m.rms_factor},
                       {"max_factor", m.max_factor},
                       {"beaten", m.beaten}});
      }
      s["rows"].push_back({{"table", row.table},
                           {"fit", row.fit},
                           {"channels", r.channels},
                           {"published", scoredJson(row.published)},
                           {"lgp", lgp},
                           {"operon", row.operon}});
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
