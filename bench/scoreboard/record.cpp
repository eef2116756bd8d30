#include "record.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "lgp/config/json_reader.hpp"
#include "lgp/io/result.hpp"

namespace lgp::board {

namespace {
using nlohmann::json;
constexpr const char* kFormat = "lgp-scoreboard-table/2";

// JSON has no NaN or infinity (nlohmann writes null); both read back as NaN, except an
// infinite factor, kept as the string "inf" so that a perfect member stays "beaten".
json number(double v) {
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  return v;
}
double number(const json& j) {
  if (j.is_number()) return j.get<double>();
  if (j.is_string()) return j == "inf" ? INFINITY : j == "-inf" ? -INFINITY : NAN;
  return NAN;
}

Scored scoredFrom(const json& j) {
  Scored s;
  s.name = j.at("name").get<std::string>();
  s.isa = number(j.at("isa_rdna2"));
  s.model_cost = number(j.at("model_cost"));
  for (const auto& c : j.at("heldout"))
    s.channels.push_back({number(c.at("rmse")), number(c.at("max_abs"))});
  s.formula = j.at("formula").get<std::string>();
  s.form = j.value("form", std::string());
  return s;
}

json fitJson(const FitSpec& f) {
  return {{"name", f.name},
          {"forms", f.forms},
          {"counted", f.counted},
          {"source", f.source},
          {"note", f.note}};
}
FitSpec fitFrom(const json& j) {
  FitSpec f;
  f.name = j.at("name").get<std::string>();
  f.forms = j.at("forms").get<std::vector<std::string>>();
  f.counted = j.at("counted").get<bool>();
  f.source = j.at("source").get<std::string>();
  f.note = j.at("note").get<std::string>();
  return f;
}

// A record's file stem: the table's name, with ".seeded" for a run seeded with the published
// fits (the board keeps both runs side by side).
std::string stem(const std::string& table, const Settings& s) {
  return table + (s.seed_references ? ".seeded" : "") + (s.edge_objective ? ".edges" : "");
}

std::string minutesTag(double m) {
  std::ostringstream s;
  s << m;
  return s.str();
}

// The front as committed: no path of this machine. The config's folder (where `lgp front` and
// `lgp emit` find its scene) relative to the working directory, as lgp_quality writes it; the
// front file the config would have written is not this one.
json portableFront(json f) {
  if (f.contains("config_dir") && f["config_dir"].is_string()) {
    std::error_code ec;
    const std::filesystem::path d = f["config_dir"].get<std::string>();
    if (d.is_absolute()) {
      const auto rel = std::filesystem::proximate(d, ec);
      if (!ec) f["config_dir"] = rel.generic_string();
    }
  }
  if (f.contains("config") && f["config"].contains("output"))
    for (const char* k : {"front_json", "front_csv", "checkpoint"})
      if (f["config"]["output"].contains(k)) f["config"]["output"][k] = "";
  return f;
}

Record recordFrom(const json& j) {
  if (j.value("format", std::string()) != kFormat)
    throw std::runtime_error(std::string("/format: not ") + kFormat);
  Record rec;
  const json& s = j.at("settings");
  rec.settings.quick = s.at("quick").get<bool>();
  rec.settings.threads = s.at("threads").get<int>();
  rec.settings.seed = s.at("seed").get<uint64_t>();
  rec.settings.minutes = s.at("minutes").get<std::vector<double>>();
  rec.settings.seed_references = s.at("seed_references").get<bool>();
  rec.settings.edge_objective = s.value("edge_objective", false);
  const json& t = j.at("timing");
  rec.timing.cpu = t.at("cpu").get<std::string>();
  rec.timing.wall_s = number(t.at("wall_s"));
  rec.timing.cpu_s = number(t.at("cpu_s"));
  TableRun& r = rec.run;
  const json& sp = j.at("spec");
  r.spec.name = sp.at("name").get<std::string>();
  r.spec.title = sp.at("title").get<std::string>();
  r.spec.config = sp.at("config").get<std::string>();
  r.spec.evals_per_minute = number(sp.at("evals_per_minute"));
  for (const auto& f : sp.at("fits")) r.spec.fits.push_back(fitFrom(f));
  for (const auto& [input, range] : sp.at("domain").items())
    r.spec.domain[input] = {range.at(0).get<double>(), range.at(1).get<double>()};
  r.channels = j.at("channels").get<std::vector<std::string>>();
  r.train_desc = j.at("train_grid").get<std::string>();
  r.heldout_desc = j.at("heldout_grid").get<std::string>();
  r.measured = j.at("measured").get<bool>();
  r.measure_note = j.at("measure_note").get<std::string>();
  r.table_wall_s = number(t.at("table_s"));
  r.search_wall_s = number(t.at("search_s"));
  for (const auto& sn : j.at("snapshots")) {
    Snapshot x;
    x.minutes = number(sn.at("minutes"));
    x.evaluations = sn.at("evaluations").get<uint64_t>();
    x.wall_s = number(sn.at("wall_s"));
    for (const auto& m : sn.at("members")) x.members.push_back(scoredFrom(m));
    r.snaps.push_back(std::move(x));
  }
  for (const auto& f : j.at("fits")) r.fits.push_back(scoredFrom(f));
  for (const auto& row : j.at("rows")) {
    Row x;
    x.table = r.spec.name;
    x.fit = row.at("fit").get<std::string>();
    x.counted = row.at("counted").get<bool>();
    x.source = row.at("source").get<std::string>();
    x.note = row.at("note").get<std::string>();
    x.published = scoredFrom(row.at("published"));
    for (const auto& m : row.at("lgp")) {
      Match y;
      y.member = m.at("member").get<int>();
      if (y.member >= 0) y.m = scoredFrom(m.at("scored"));
      y.rms_factor = number(m.at("rms_factor"));
      y.max_factor = number(m.at("max_factor"));
      y.beaten = m.at("beaten").get<bool>();
      x.lgp.push_back(std::move(y));
    }
    if (x.lgp.size() != r.snaps.size())
      throw std::runtime_error("/rows: a row has " + std::to_string(x.lgp.size()) +
                               " budgets, the record " + std::to_string(r.snaps.size()));
    r.rows.push_back(std::move(x));
  }
  r.recommended = j.at("recommended");
  return rec;
}
}  // namespace

nlohmann::json scoredJson(const Scored& s) {
  json ch = json::array();
  for (const auto& c : s.channels)
    ch.push_back({{"rmse", number(c.rmse)}, {"max_abs", number(c.max_abs)}});
  json j = {{"name", s.name},
            {"isa_rdna2", number(s.isa)},
            {"model_cost", number(s.model_cost)},
            {"heldout", ch},
            {"formula", s.formula}};
  if (!s.form.empty()) j["form"] = s.form;
  return j;
}
void writeRecord(const TableRun& r, const Settings& s, const RecordTiming& t,
                 const std::filesystem::path& dir) {
  const auto tables = dir / "tables";
  std::filesystem::create_directories(tables);
  json snaps = json::array();
  for (const auto& sn : r.snaps) {
    json members = json::array();
    for (const auto& m : sn.members) members.push_back(scoredJson(m));
    snaps.push_back({{"minutes", sn.minutes},
                     {"evaluations", sn.evaluations},
                     {"wall_s", sn.wall_s},
                     {"members", members}});
    std::ofstream(tables / (stem(r.spec.name, s) + ".front." + minutesTag(sn.minutes) + "min.json"))
        << portableFront(sn.front).dump(1) << "\n";
  }
  json fits = json::array();
  for (const auto& f : r.fits) fits.push_back(scoredJson(f));
  json rows = json::array();
  for (const auto& row : r.rows) {
    json lgp = json::array();
    for (const auto& m : row.lgp)
      lgp.push_back({{"member", m.member},
                     {"scored", m.member >= 0 ? scoredJson(m.m) : json(nullptr)},
                     {"rms_factor", number(m.rms_factor)},
                     {"max_factor", number(m.max_factor)},
                     {"beaten", m.beaten}});
    rows.push_back({{"fit", row.fit},
                    {"counted", row.counted},
                    {"source", row.source},
                    {"note", row.note},
                    {"published", scoredJson(row.published)},
                    {"lgp", lgp}});
  }
  const json j = {{"format", kFormat},
                  {"settings",
                   {{"quick", s.quick},
                    {"threads", s.threads},
                    {"seed", s.seed},
                    {"minutes", s.minutes},
                    {"seed_references", s.seed_references},
                    {"edge_objective", s.edge_objective}}},
                  {"spec",
                   {{"name", r.spec.name},
                    {"title", r.spec.title},
                    {"config", r.spec.config},
                    {"evals_per_minute", r.spec.evals_per_minute},
                    {"fits",
                     [&] {
                       json a = json::array();
                       for (const auto& f : r.spec.fits) a.push_back(fitJson(f));
                       return a;
                     }()},
                    {"domain",
                     [&] {
                       json d = json::object();
                       for (const auto& [input, range] : r.spec.domain)
                         d[input] = {range.first, range.second};
                       return d;
                     }()}}},
                  {"timing",
                   {{"cpu", t.cpu},
                    {"wall_s", t.wall_s},
                    {"cpu_s", t.cpu_s},
                    {"table_s", r.table_wall_s},
                    {"search_s", r.search_wall_s}}},
                  {"channels", r.channels},
                  {"train_grid", r.train_desc},
                  {"heldout_grid", r.heldout_desc},
                  {"measured", r.measured},
                  {"measure_note", r.measure_note},
                  {"snapshots", snaps},
                  {"fits", fits},
                  {"rows", rows},
                  {"recommended", r.recommended}};
  // Written beside and renamed over: a run stopped while writing leaves the old record whole.
  const auto path = tables / (stem(r.spec.name, s) + ".json");
  const auto tmp = tables / (stem(r.spec.name, s) + ".json.tmp");
  std::ofstream(tmp) << j.dump(1) << "\n";
  std::filesystem::rename(tmp, path);
}

Status readFronts(TableRun& r, const Settings& s, const std::filesystem::path& dir) {
  for (auto& sn : r.snaps) {
    const auto path =
        dir / "tables" / (stem(r.spec.name, s) + ".front." + minutesTag(sn.minutes) + "min.json");
    auto front = readFrontJson(path);  // its names reach the emitted code: checked there
    if (!front) return front.status();
    if ((*front)["members"].size() != sn.members.size())
      return Status::error(path.string() + ": its members are not the record's " +
                           std::to_string(sn.members.size()));
    sn.front = std::move(*front);
  }
  return Status::ok();
}

std::vector<Record> readRecords(const std::filesystem::path& dir,
                                std::vector<std::string>& skipped) {
  std::vector<Record> out;
  const auto tables = dir / "tables";
  std::error_code ec;
  if (!std::filesystem::is_directory(tables, ec)) return out;
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(tables, ec)) {
    const std::string n = e.path().filename().string();
    if (e.path().extension() == ".json" && n.find(".front.") == std::string::npos)
      files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    std::ifstream in(f);
    std::stringstream ss;
    ss << in.rdbuf();
    auto j = parseJson(ss.str());
    if (!j) {
      skipped.push_back(f.string() + ": " + j.error());
      continue;
    }
    try {
      Record rec = recordFrom(*j);
      if (stem(rec.run.spec.name, rec.settings) + ".json" != f.filename().string())
        throw std::runtime_error("/spec/name: '" + rec.run.spec.name + "' is not the file's name");
      out.push_back(std::move(rec));
    } catch (const std::exception& e) {
      skipped.push_back(f.string() + ": " + e.what());
    }
  }
  return out;
}

}  // namespace lgp::board
