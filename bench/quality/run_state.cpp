#include "run_state.hpp"

#include <cmath>
#include <fstream>

#include "lgp/io/result.hpp"

namespace lgpq {

using json = nlohmann::json;

namespace {

constexpr const char* kFormat = "lgp-quality-state/1";

// Reads `key` of `j` as T; the error names the field.
template <class T>
lgp::Status field(const json& j, const char* key, T& out, const std::string& at) {
  if (!j.contains(key)) return lgp::Status::error(at + "/" + key + ": missing");
  try {
    out = j.at(key).get<T>();
  } catch (const json::exception&) {
    return lgp::Status::error(at + "/" + key + ": wrong type");
  }
  return lgp::Status::ok();
}

}  // namespace

json stateToJson(const RunState& s) {
  json snaps = json::array();
  for (const auto& sn : s.snaps)
    snaps.push_back({{"minutes", sn.minutes},
                     {"evaluations", sn.evaluations},
                     {"generation", sn.generation},
                     {"wall_s", sn.wall_s},
                     {"front", sn.front}});
  json curve = json::array();
  for (const auto& cp : s.curve) {
    json best = json::array();
    for (double e : cp.best) best.push_back(std::isfinite(e) ? json(e) : json());
    curve.push_back({{"minutes", cp.minutes}, {"best", best}});
  }
  return {{"format", kFormat},      {"table", s.table},           {"seed", s.seed},
          {"threads", s.threads},   {"minutes", s.minutes},       {"snapshots", snaps},
          {"curve", curve},         {"next_curve", s.next_curve}, {"wall_s", s.wall_s},
          {"sessions", s.sessions}, {"finished", s.finished},     {"search", s.search}};
}

lgp::Expected<RunState> readState(const std::filesystem::path& path) {
  const std::string at = path.string() + ": ";
  std::ifstream in(path);
  if (!in) return lgp::Status::error(at + "cannot open");
  json j;
  try {
    in >> j;
  } catch (const json::exception& e) {
    return lgp::Status::error(at + "invalid JSON: " + e.what());
  }
  if (!j.is_object() || j.value("format", "") != kFormat)
    return lgp::Status::error(at + "/format: not " + std::string(kFormat));
  RunState s;
  const std::string root = at;
  for (auto st : {field(j, "table", s.table, root), field(j, "seed", s.seed, root),
                  field(j, "threads", s.threads, root), field(j, "minutes", s.minutes, root),
                  field(j, "next_curve", s.next_curve, root), field(j, "wall_s", s.wall_s, root),
                  field(j, "sessions", s.sessions, root), field(j, "finished", s.finished, root)})
    if (!st) return st;
  s.search = j.value("search", json());
  if (!s.finished && !s.search.is_object())
    return lgp::Status::error(at + "/search: an unfinished run needs its search checkpoint");
  if (!j.contains("snapshots") || !j["snapshots"].is_array())
    return lgp::Status::error(at + "/snapshots: must be an array");
  for (size_t i = 0; i < j["snapshots"].size(); ++i) {
    const json& e = j["snapshots"][i];
    const std::string sat = at + "/snapshots/" + std::to_string(i);
    Snapshot sn;
    for (auto st :
         {field(e, "minutes", sn.minutes, sat), field(e, "evaluations", sn.evaluations, sat),
          field(e, "generation", sn.generation, sat), field(e, "wall_s", sn.wall_s, sat)})
      if (!st) return st;
    if (!e.contains("front") || !e["front"].is_object())
      return lgp::Status::error(sat + "/front: must be a front object");
    sn.front = e["front"];
    s.snaps.push_back(std::move(sn));
  }
  if (s.snaps.size() > s.minutes.size())
    return lgp::Status::error(at + "/snapshots: more than the budgets");
  if (!j.contains("curve") || !j["curve"].is_array())
    return lgp::Status::error(at + "/curve: must be an array");
  for (size_t i = 0; i < j["curve"].size(); ++i) {
    const json& e = j["curve"][i];
    const std::string cat = at + "/curve/" + std::to_string(i);
    CurvePoint cp{0, {}};
    if (auto st = field(e, "minutes", cp.minutes, cat); !st) return st;
    if (!e.contains("best") || !e["best"].is_array())
      return lgp::Status::error(cat + "/best: must be an array");
    for (const auto& b : e["best"]) {
      if (!b.is_null() && !b.is_number()) return lgp::Status::error(cat + "/best: numbers or null");
      cp.best.push_back(b.is_null() ? INFINITY : b.get<double>());
    }
    s.curve.push_back(std::move(cp));
  }
  return s;
}

lgp::Status writeState(const RunState& s, const std::filesystem::path& path) {
  return lgp::writeJsonAtomic(stateToJson(s), path, -1);
}

lgp::Status checkStateMatches(const RunState& saved, const RunState& run) {
  auto differs = [](const char* what, const std::string& a, const std::string& b) {
    return lgp::Status::error(std::string("the state is of another run: ") + what + " " + a +
                              " there, " + b + " here");
  };
  if (saved.table != run.table) return differs("table", saved.table, run.table);
  if (saved.seed != run.seed)
    return differs("seed", std::to_string(saved.seed), std::to_string(run.seed));
  if (saved.threads != run.threads)
    return differs("threads", std::to_string(saved.threads), std::to_string(run.threads));
  if (saved.minutes != run.minutes)
    return differs("budgets", json(saved.minutes).dump(), json(run.minutes).dump());
  return lgp::Status::ok();
}

}  // namespace lgpq
