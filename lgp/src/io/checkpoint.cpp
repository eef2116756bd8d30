#include "lgp/io/checkpoint.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include "lgp/core/program.hpp"

namespace lgp {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

uint64_t fnv1a(const void* data, size_t n, uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

// A member of a checkpoint, held to the run's own shape: programFromJson takes the constant
// count and the length from the program itself, and a checkpoint is a file anyone can edit (a
// program without its constants, or longer than max_length, would be evaluated out of bounds).
Expected<Program> checkpointProgram(const nlohmann::json& member, const ProgramShape& shape) {
  auto p = programFromJson(member.at("program"), shape);
  if (!p) return p;
  if (auto st = validate(*p, shape); !st)
    return Status::error("program: " + st.message() + " (this run's shape)");
  return p;
}

// A member's recorded error is a claim: its program is scored again on the run's table, and
// the two must agree (to 1e-4 relative: the same code gives the same float32 sums), else the
// checkpoint is refused. What the search selects and the front reports is then never a
// number the file made up.
Status checkClaimedError(Scorer& scorer, const Program& p, const Objectives& claimed,
                         const std::string& what) {
  const double e = scorer.error(p);
  const bool both_worst = !std::isfinite(e) && !claimed.finite();
  if (both_worst || (std::isfinite(e) && claimed.finite() &&
                     std::abs(e - claimed.error) <= 1e-4 * std::max(std::abs(e), 1e-30)))
    return Status::ok();
  return Status::error("checkpoint: " + what + " claims error " + formatDouble(claimed.error) +
                       ", its program scores " + formatDouble(e) + " on this table");
}

// A counter that must be a non-negative integer of the given type.
template <class T>
Expected<T> counter(const nlohmann::json& st, const char* key) {
  const auto& v = st.at(key);
  if (!v.is_number_integer() ||
      (v.is_number_integer() && !v.is_number_unsigned() && v.get<int64_t>() < 0))
    return Status::error(std::string("checkpoint: /") + key + ": must be an integer >= 0");
  if (v.is_number_unsigned() &&
      v.get<uint64_t>() > static_cast<uint64_t>(std::numeric_limits<T>::max()))
    return Status::error(std::string("checkpoint: /") + key + ": out of range");
  return v.get<T>();
}
}  // namespace

nlohmann::json objectivesToJson(const Objectives& o) {
  return nlohmann::json::array(
      {o.finite() ? nlohmann::json(o.error) : nlohmann::json(nullptr), o.cost, o.discontinuity});
}

Expected<Objectives> objectivesFromJson(const nlohmann::json& j) {
  if (!j.is_array() || j.size() != 3 || !j[1].is_number() || !j[2].is_number())
    return Status::error("bad objectives");
  Objectives o;
  o.error = j[0].is_number() ? j[0].get<double>() : kInf;
  o.cost = j[1].get<double>();
  o.discontinuity = j[2].get<double>();
  return o;
}

std::string configDigest(const RunConfig& cfg, const Table& table) {
  nlohmann::json c = toJson(cfg);
  c.erase("output");  // where results go does not change the search
  c.erase("mpi");     // nor how ranks exchange migrants: a checkpoint resumes either way
  c["search"].erase("threads");
  c["search"].erase("generations");  // budgets may be extended on resume
  c["search"].erase("max_evaluations");
  c["search"].erase("wall_time_s");
  c["search"].erase("semantic_cache");  // changes time, never the result
  const std::string s = c.dump();
  uint64_t h = fnv1a(s.data(), s.size());
  for (const auto& col : table.inputs) h = fnv1a(col.data(), col.size() * sizeof(double), h);
  for (const auto& col : table.outputs) h = fnv1a(col.data(), col.size() * sizeof(double), h);
  h = fnv1a(table.weights.data(), table.weights.size() * sizeof(double), h);
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

nlohmann::json islandToJson(const Search::Island& isl) {
  nlohmann::json pop = nlohmann::json::array();
  for (const auto& ind : isl.pop)
    pop.push_back({{"program", toJson(ind.program)},
                   {"obj", objectivesToJson(ind.obj)},
                   {"refined", ind.refined}});
  // Ranks and crowding come from the last survival's pool (see Search::survive()), which a
  // resumed run cannot recompute: they are stored. JSON has no infinity: boundary points are
  // null.
  nlohmann::json crowd = nlohmann::json::array();
  for (double c : isl.crowd) crowd.push_back(std::isfinite(c) ? nlohmann::json(c) : nullptr);
  return {{"population", pop},
          {"rank", isl.rank},
          {"crowd", crowd},
          {"best", std::isfinite(isl.best) ? nlohmann::json(isl.best) : nullptr},
          {"stagnant", isl.stagnant},
          {"credit", isl.credit}};
}

// An island from its JSON: every program held to `shape` and its claimed error scored again
// by `scorer`.
Status islandFromJson(const nlohmann::json& ji, const ProgramShape& shape, Scorer& scorer,
                      const std::string& at, Search::Island& isl) {
  for (const auto& j : ji.at("population")) {
    auto p = checkpointProgram(j, shape);
    if (!p) return Status::error("checkpoint: population: " + p.error());
    auto o = objectivesFromJson(j.at("obj"));
    if (!o) return Status::error("checkpoint: population: " + o.error());
    const std::string who = at + " member " + std::to_string(isl.pop.size());
    if (auto c = checkClaimedError(scorer, *p, *o, who); !c) return c;
    isl.pop.push_back({*p, *o, j.value("refined", false)});
  }
  isl.rank = ji.at("rank").get<std::vector<int>>();
  for (int r : isl.rank)
    if (r < 0) return Status::error("checkpoint: " + at + ": a rank below 0");
  for (const auto& c : ji.at("crowd")) isl.crowd.push_back(c.is_number() ? c.get<double>() : kInf);
  if (isl.rank.size() != isl.pop.size() || isl.crowd.size() != isl.pop.size())
    return Status::error("checkpoint: island ranks do not match its population");
  isl.best = ji.at("best").is_number() ? ji.at("best").get<double>() : kInf;
  auto stagnant = counter<int>(ji, "stagnant");
  if (!stagnant) return Status::error(stagnant.error() + " (" + at + ")");
  isl.stagnant = *stagnant;
  // Absent from checkpoints written before search.islands.adaptive: no credit yet.
  isl.credit =
      ji.contains("credit") && ji.at("credit").is_number() ? ji.at("credit").get<double>() : 0;
  if (!(std::isfinite(isl.credit) && isl.credit >= 0))
    return Status::error("checkpoint: " + at + ": credit must be a finite number >= 0");
  return Status::ok();
}

nlohmann::json checkpointToJson(const Search& s) {
  nlohmann::json islands = nlohmann::json::array();
  for (const auto& isl : s.islands_) islands.push_back(islandToJson(isl));
  nlohmann::json arch = nlohmann::json::array();
  for (const auto& m : s.archive_.members())
    arch.push_back(
        {{"program", toJson(m.program)}, {"obj", objectivesToJson(m.obj)}, {"refined", m.refined}});
  // Residual stages: the base each corrects (its residual table is computed again from it)
  // and its island, like the others.
  nlohmann::json stages = nlohmann::json::array();
  for (const auto& st : s.stages_) {
    nlohmann::json j = islandToJson(st->isl);
    j["base"] = st->base.code.empty() ? nlohmann::json(nullptr) : toJson(st->base);
    j["mode"] = std::string(toString(st->mode));
    if (st->mode == StageMode::Inside) j["input"] = st->input;
    j["base_error"] = st->base_error;
    j["since"] = st->since;
    j["picks"] = st->picks;
    j["composites"] = st->composites;
    stages.push_back(std::move(j));
  }
  const int total = s.island_total_ > 0 ? s.island_total_ : static_cast<int>(s.islands_.size());
  return {{"format", "lgp-checkpoint/2"},
          {"config_digest", configDigest(s.cfg_, s.table_)},
          {"initialized", s.initialized_},
          {"generation", s.generation_},
          {"evaluations", s.evaluations_},
          {"elapsed_s", s.elapsed()},
          {"migrants", s.migrants_before_ + (s.transport_ ? s.transport_->sent() : 0)},
          {"remote_migrants",
           s.remote_migrants_before_ + (s.transport_ ? s.transport_->sentRemote() : 0)},
          {"restarts", s.restarts_},
          {"ranks", s.ranks_},
          {"island_first", s.island_first_},
          {"island_total", total},
          {"islands", islands},
          {"archive", arch},
          {"stages", stages}};
}

Status restoreFromCheckpoint(Search& s, const nlohmann::json& st, bool take_counters) {
  try {
    if (!st.is_object() || st.value("format", "") != "lgp-checkpoint/2")
      return Status::error("checkpoint: unknown format");
    if (st.at("config_digest").get<std::string>() != configDigest(s.cfg_, s.table_))
      return Status::error("checkpoint: made with a different config or table");
    const auto& jislands = st.at("islands");
    const int held = static_cast<int>(jislands.size());
    const int ck_first = st.value("island_first", 0);
    const int ck_total = st.value("island_total", held);
    // Which of the checkpoint's islands this search takes: all of them, or its range.
    int take_first = 0, take_count = held;
    if (s.range_set_) {
      if (ck_total != s.island_total_)
        return Status::error("checkpoint: made with " + std::to_string(ck_total) +
                             " islands, this run has " + std::to_string(s.island_total_));
      take_first = s.island_first_ - ck_first;
      take_count = static_cast<int>(s.islands_.size());
      if (take_first < 0 || take_first + take_count > held)
        return Status::error("checkpoint: holds islands " + std::to_string(ck_first) + ".." +
                             std::to_string(ck_first + held - 1) + ", not this rank's " +
                             std::to_string(s.island_first_) + ".." +
                             std::to_string(s.island_first_ + take_count - 1));
    } else if (ck_first != 0 || ck_total != held) {
      return Status::error("checkpoint: holds islands " + std::to_string(ck_first) + ".." +
                           std::to_string(ck_first + held - 1) + " of " + std::to_string(ck_total) +
                           " (one rank of an MPI run); resume from the run's combined checkpoint");
    }
    auto generation = counter<int>(st, "generation");
    if (!generation) return generation.status();
    auto evaluations = counter<uint64_t>(st, "evaluations");
    if (!evaluations) return evaluations.status();
    const double elapsed = st.at("elapsed_s").get<double>();
    if (!(elapsed >= 0.0) || !std::isfinite(elapsed))
      return Status::error("checkpoint: /elapsed_s: must be a finite number >= 0");
    Scorer& scorer = s.scorer(0);
    std::vector<Search::Island> islands;
    for (int k = take_first; k < take_first + take_count; ++k) {
      Search::Island isl;
      if (auto c = islandFromJson(jislands.at(static_cast<size_t>(k)), s.shape_, scorer,
                                  "island " + std::to_string(k), isl);
          !c)
        return c;
      islands.push_back(std::move(isl));
    }
    Archive arch(s.cfg_.search.archive);
    auto& members = arch.mutableMembers();
    for (const auto& j : st.at("archive")) {
      auto p = checkpointProgram(j, s.shape_);
      if (!p) return Status::error("checkpoint: archive: " + p.error());
      auto o = objectivesFromJson(j.at("obj"));
      if (!o) return Status::error("checkpoint: archive: " + o.error());
      if (!std::isfinite(o->cost) || o->cost < 0 || !std::isfinite(o->discontinuity) ||
          o->discontinuity < 0)
        return Status::error("checkpoint: archive member " + std::to_string(members.size()) +
                             ": cost and discontinuity must be finite and >= 0");
      const std::string who = "archive member " + std::to_string(members.size());
      if (auto c = checkClaimedError(scorer, *p, *o, who); !c) return c;
      members.push_back({*p, *o, j.value("refined", false)});
    }
    if (st.at("initialized").get<bool>()) {
      if (islands.empty()) return Status::error("checkpoint: no islands");
      // Every island holds its share of the population, as survival leaves it: an empty or
      // resized island would be bred from out of bounds.
      const int total = s.range_set_ ? s.island_total_ : held;
      const int n = s.cfg_.search.population;
      if (total < 1 || total > n)
        return Status::error("checkpoint: " + std::to_string(total) +
                             " islands for a population of " + std::to_string(n));
      const std::vector<int> sizes = islandSizes(n, total, s.cfg_.search.islands.profiles);
      for (int k = 0; k < take_count; ++k) {
        const int global = s.range_set_ ? s.island_first_ + k : k;
        const int want = sizes[static_cast<size_t>(global)];
        const size_t got = islands[static_cast<size_t>(k)].pop.size();
        if (got != static_cast<size_t>(want))
          return Status::error("checkpoint: island " + std::to_string(global) + " holds " +
                               std::to_string(got) + " programs, this run's population gives it " +
                               std::to_string(want));
      }
    }
    if (static_cast<int>(members.size()) > s.cfg_.search.archive.max_size)
      return Status::error("checkpoint: the archive holds " + std::to_string(members.size()) +
                           " members, more than search.archive.max_size (" +
                           std::to_string(s.cfg_.search.archive.max_size) + ")");
    // The stages of this rank (a combined checkpoint keeps each rank's in its part).
    std::vector<std::unique_ptr<Search::Stage>> stages;
    if (st.contains("stages")) {
      const nlohmann::json* js = &st.at("stages");
      if (s.range_set_ && st.contains("parts"))
        for (const auto& part : st.at("parts"))
          if (part.value("island_first", -1) == s.island_first_ && part.contains("stages"))
            js = &part.at("stages");
      for (size_t k = 0; k < js->size(); ++k) {
        const auto& j = js->at(k);
        const std::string at = "stage " + std::to_string(k);
        auto stage = std::make_unique<Search::Stage>();
        if (!j.at("base").is_null()) {
          ProgramShape loose = s.shape_;
          loose.num_outputs = static_cast<int>(s.table_.numOutputs());
          loose.genes = 1;
          loose.max_length = 255;
          // A final program keeps only the slots it reads: its own count, within the bound.
          const auto& bc = j.at("base");
          const size_t slots =
              bc.is_object() && bc.contains("constants") && bc.at("constants").is_array()
                  ? bc.at("constants").size()
                  : 0;
          loose.num_constants = static_cast<int>(std::min<size_t>(slots, 255));
          loose.output_mode = OutputMode::Designated;
          auto base = checkpointProgram(nlohmann::json{{"program", j.at("base")}}, loose);
          if (!base) return Status::error("checkpoint: " + at + " base: " + base.error());
          stage->base = std::move(*base);
          const std::string mode = j.at("mode").get<std::string>();
          if (mode != "add" && mode != "mul" && mode != "inside")
            return Status::error("checkpoint: " + at + ": mode must be add, mul or inside");
          stage->mode = mode == "mul"      ? StageMode::Mul
                        : mode == "inside" ? StageMode::Inside
                                           : StageMode::Add;
          if (stage->mode == StageMode::Inside) {
            const int input = j.value("input", -1);
            if (input < 0 || input >= s.shape_.num_inputs)
              return Status::error("checkpoint: " + at + ": input must be an input index, 0 to " +
                                   std::to_string(s.shape_.num_inputs - 1));
            stage->input = input;
          }
          stage->base_error = j.at("base_error").get<double>();
          s.bindStage(*stage);
          if (auto c = islandFromJson(j, stage->shape, s.stageScorer(*stage, 0), at, stage->isl);
              !c)
            return c;
        }
        auto since = counter<int>(j, "since");
        auto picks = counter<int>(j, "picks");
        auto composites = counter<uint64_t>(j, "composites");
        if (!since || !picks || !composites)
          return Status::error("checkpoint: " + at +
                               ": since, picks and composites must be counts");
        stage->since = *since;
        stage->picks = *picks;
        stage->composites = *composites;
        stages.push_back(std::move(stage));
      }
      if (!stages.empty() && static_cast<int>(stages.size()) != s.cfg_.search.stages.islands)
        return Status::error("checkpoint: holds " + std::to_string(stages.size()) +
                             " stages, search.stages.islands is " +
                             std::to_string(s.cfg_.search.stages.islands));
    }
    s.islands_ = std::move(islands);
    s.stages_ = std::move(stages);
    if (!s.range_set_) {
      s.island_first_ = 0;
      s.island_total_ = held;
    }
    if (!s.transport_ || dynamic_cast<LocalTransport*>(s.transport_.get()))
      s.transport_ = std::make_unique<LocalTransport>(s.island_total_);
    s.migrants_before_ = take_counters ? st.at("migrants").get<uint64_t>() : 0;
    s.remote_migrants_before_ = take_counters ? st.value("remote_migrants", uint64_t{0}) : 0;
    s.restarts_ = take_counters ? st.at("restarts").get<uint64_t>() : 0;
    s.archive_ = std::move(arch);
    s.initialized_ = st.at("initialized").get<bool>();
    s.generation_ = *generation;
    s.evaluations_ = take_counters ? *evaluations : 0;
    s.elapsed_before_ = elapsed;
    s.start_ = std::chrono::steady_clock::now();
    s.session_evals_ = 0;
  } catch (const nlohmann::json::exception& e) {
    return Status::error(std::string("checkpoint: ") + e.what());
  }
  return Status::ok();
}

Expected<nlohmann::json> combineCheckpoints(const RunConfig& cfg, const ProgramShape& shape,
                                            const std::vector<nlohmann::json>& parts) {
  if (parts.empty()) return Status::error("checkpoint: no parts to combine");
  try {
    nlohmann::json out = parts[0];
    out.erase("parts");
    nlohmann::json islands = nlohmann::json::array();
    Archive arch(cfg.search.archive);
    uint64_t evaluations = 0, migrants = 0, remote = 0, restarts = 0;
    int generation = std::numeric_limits<int>::max();
    double elapsed = 0;
    bool initialized = true;
    int next_island = 0;
    const int total = parts[0].at("island_total").get<int>();
    for (const auto& part : parts) {
      if (part.at("config_digest") != parts[0].at("config_digest"))
        return Status::error("checkpoint: parts were made with different configs");
      if (part.at("island_first").get<int>() != next_island ||
          part.at("island_total").get<int>() != total)
        return Status::error("checkpoint: parts do not cover the islands in order");
      for (const auto& isl : part.at("islands")) islands.push_back(isl);
      next_island += static_cast<int>(part.at("islands").size());
      for (const auto& j : part.at("archive")) {
        auto p = checkpointProgram(j, shape);
        if (!p) return Status::error("checkpoint: archive: " + p.error());
        auto o = objectivesFromJson(j.at("obj"));
        if (!o) return Status::error("checkpoint: archive: " + o.error());
        arch.insert(*p, *o, j.value("refined", false));
      }
      evaluations += part.at("evaluations").get<uint64_t>();
      migrants += part.at("migrants").get<uint64_t>();
      remote += part.value("remote_migrants", uint64_t{0});
      restarts += part.at("restarts").get<uint64_t>();
      generation = std::min(generation, part.at("generation").get<int>());
      elapsed = std::max(elapsed, part.at("elapsed_s").get<double>());
      initialized = initialized && part.at("initialized").get<bool>();
    }
    if (next_island != total)
      return Status::error("checkpoint: parts hold " + std::to_string(next_island) + " of " +
                           std::to_string(total) + " islands");
    nlohmann::json jarch = nlohmann::json::array();
    for (const auto& m : arch.members())
      jarch.push_back({{"program", toJson(m.program)},
                       {"obj", objectivesToJson(m.obj)},
                       {"refined", m.refined}});
    out["islands"] = std::move(islands);
    out["archive"] = std::move(jarch);
    out["island_first"] = 0;
    out["island_total"] = total;
    out["ranks"] = static_cast<int>(parts.size());
    out["evaluations"] = evaluations;
    out["migrants"] = migrants;
    out["remote_migrants"] = remote;
    out["restarts"] = restarts;
    out["generation"] = generation;
    out["elapsed_s"] = elapsed;
    out["initialized"] = initialized;
    out["parts"] = parts;
    return out;
  } catch (const nlohmann::json::exception& e) {
    return Status::error(std::string("checkpoint: ") + e.what());
  }
}

}  // namespace lgp
