#include "lgp/io/result.hpp"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace lgp {

namespace {
nlohmann::json num(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}
double getNum(const nlohmann::json& j, const char* k) {
  return j.contains(k) && j[k].is_number() ? j[k].get<double>() : INFINITY;
}
}  // namespace

nlohmann::json metricsToJson(const OutputMetrics& m) {
  return {{"rmse", num(m.rmse)},
          {"max_abs", num(m.max_abs)},
          {"mae", num(m.mae)},
          {"mean_rel", num(m.mean_rel)},
          {"r2", num(m.r2)}};
}

nlohmann::json frontToJson(const Search& s, const std::vector<FrontEntry>& front) {
  const Table& t = s.table();
  const auto& cfg = s.config();
  const auto err_cfg = cfg.errorConfig(t.output_names);
  nlohmann::json domain = nlohmann::json::object();
  for (size_t i = 0; i < t.numInputs(); ++i) {
    double lo = INFINITY, hi = -INFINITY;
    for (double v : t.inputs[i]) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    domain[t.input_names[i]] = {lo, hi};
  }
  nlohmann::json members = nlohmann::json::array();
  for (size_t k = 0; k < front.size(); ++k) {
    const FrontEntry& e = front[k];
    nlohmann::json costs = nlohmann::json::object();
    for (int c = 0; c < kNumCostTargets; ++c)
      costs[std::string(kCostTargetNames[c])] = e.cost_by_target[c];
    nlohmann::json outs = nlohmann::json::array();
    for (size_t o = 0; o < t.numOutputs(); ++o) {
      outs.push_back({{"name", t.output_names[o]},
                      {"expression", o < e.infix.size() ? e.infix[o] : ""},
                      {"transform", std::string(toString(err_cfg.transforms[o]))},
                      {"float32", metricsToJson(e.metrics[o])},
                      {"double", metricsToJson(e.metrics_ref[o])}});
    }
    nlohmann::json m = {{"index", k},
                        {"error", num(e.obj.error)},
                        {"cost", e.obj.cost},
                        {"discontinuity", e.obj.discontinuity},
                        {"cost_by_target", costs},
                        {"outputs", outs},
                        {"program", toJson(e.program)}};
    if (!err_cfg.channels.empty()) {
      nlohmann::json chans = nlohmann::json::array();
      for (size_t c = 0; c < err_cfg.channels.size() && c < e.channel_metrics.size(); ++c)
        chans.push_back({{"name", err_cfg.channels[c].name},
                         {"float32", metricsToJson(e.channel_metrics[c])},
                         {"double", metricsToJson(e.channel_metrics_ref[c])}});
      m["channels"] = chans;
    }
    members.push_back(std::move(m));
  }
  const auto p = s.progress();
  return {{"format", "lgp-front/1"},
          {"config", toJson(cfg)},
          {"table",
           {{"inputs", t.input_names},
            {"outputs", t.output_names},
            {"rows", t.rows()},
            {"domain", domain},
            {"weighted", !t.weights.empty()},
            {"meta", t.meta}}},
          {"progress",
           {{"generation", p.generation},
            {"evaluations", p.evaluations},
            {"elapsed_s", p.elapsed_s},
            {"stop_reason", p.stop_reason},
            {"threads", s.threads()},
            {"islands", p.islands},
            {"migrants", p.migrants},
            {"restarts", p.restarts},
            {"ranks", p.ranks},
            {"remote_migrants", p.remote_migrants}}},
          {"cost_model", std::string(toString(cfg.objectives.cost_model))},
          {"error_metric", std::string(toString(cfg.objectives.metric))},
          {"error_channels", channelNames(err_cfg, t.output_names)},
          {"members", members},
          {"references", cfg.references}};
}

Status writeJsonAtomic(const nlohmann::json& j, const std::filesystem::path& path, int indent) {
  const auto tmp = path.string() + ".tmp";
  {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) return Status::error(path.string() + ": cannot write (" + std::strerror(errno) + ")");
    const std::string text = j.dump(indent) + "\n";
    const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() &&
                    std::fflush(f) == 0 && ::fsync(fileno(f)) == 0;
    const int err = errno;
    if (std::fclose(f) != 0 || !ok) {
      std::remove(tmp.c_str());
      return Status::error(path.string() + ": write failed (" + std::strerror(err) + ")");
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return Status::error(path.string() + ": " + ec.message());
  return Status::ok();
}

Status writeFrontJson(const nlohmann::json& front, const std::filesystem::path& path) {
  // A crash never leaves a half-written front.
  return writeJsonAtomic(front, path, 2);
}

Status writeCheckpointFile(const nlohmann::json& state, const std::filesystem::path& path) {
  return writeJsonAtomic(state, path, -1);
}

Expected<nlohmann::json> readCheckpointFile(const std::filesystem::path& path) {
  const std::string f = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    return Status::error(f + ": no checkpoint file there");
  std::ifstream in(path);
  if (!in) return Status::error(f + ": cannot open");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    return Status::error(f + ": invalid JSON: " + e.what());
  }
  if (!j.is_object() || j.value("format", "") != "lgp-checkpoint/2")
    return Status::error(f + ": /format: expected \"lgp-checkpoint/2\"");
  return j;
}

nlohmann::json progressToJson(const SearchProgress& p) {
  nlohmann::json levels = nlohmann::json::array();
  for (const auto& [c, e] : p.best_at_cost)
    levels.push_back({c, std::isfinite(e) ? nlohmann::json(e) : nlohmann::json(nullptr)});
  return {{"format", "lgp-status/1"},
          {"generation", p.generation},
          {"evaluations", p.evaluations},
          {"elapsed_s", p.elapsed_s},
          {"evals_per_s", p.evals_per_s},
          {"front_size", p.front_size},
          {"best_error",
           std::isfinite(p.best_error) ? nlohmann::json(p.best_error) : nlohmann::json(nullptr)},
          {"best_at_cost", levels},
          {"finished", p.finished},
          {"stop_reason", p.stop_reason},
          {"islands", p.islands},
          {"migrants", p.migrants},
          {"remote_migrants", p.remote_migrants},
          {"restarts", p.restarts},
          {"ranks", p.ranks},
          {"threads", p.threads}};
}

namespace {
std::string csvQuote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}
std::string fmt(double v) {
  if (!std::isfinite(v)) return "inf";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}
}  // namespace

Status writeFrontCsv(const nlohmann::json& front, const std::filesystem::path& path) {
  std::ostringstream os;
  os << "index,output,error,cost,discontinuity,rmse,max_abs,mae,mean_rel,r2,expression\n";
  for (const auto& m : front.at("members")) {
    for (const auto& o : m.at("outputs")) {
      const auto& f = o.at("float32");
      os << m.at("index").get<size_t>() << "," << o.at("name").get<std::string>() << ","
         << fmt(getNum(m, "error")) << "," << fmt(getNum(m, "cost")) << ","
         << fmt(getNum(m, "discontinuity")) << "," << fmt(getNum(f, "rmse")) << ","
         << fmt(getNum(f, "max_abs")) << "," << fmt(getNum(f, "mae")) << ","
         << fmt(getNum(f, "mean_rel")) << "," << fmt(getNum(f, "r2")) << ","
         << csvQuote(o.at("expression").get<std::string>()) << "\n";
    }
  }
  const auto tmp = path.string() + ".tmp";
  {
    std::ofstream out(tmp);
    if (!out) return Status::error(path.string() + ": cannot write");
    out << os.str();
    if (!out) return Status::error(path.string() + ": write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return Status::error(path.string() + ": " + ec.message());
  return Status::ok();
}

Expected<nlohmann::json> readFrontJson(const std::filesystem::path& path) {
  const std::string f = path.string();
  std::ifstream in(path);
  if (!in) return Status::error(f + ": cannot open");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    return Status::error(f + ": invalid JSON: " + e.what());
  }
  if (!j.is_object() || j.value("format", "") != "lgp-front/1")
    return Status::error(f + ": /format: expected \"lgp-front/1\"");
  if (!j.contains("members") || !j["members"].is_array())
    return Status::error(f + ": /members: must be an array");
  if (!j.contains("table") || !j["table"].contains("inputs") || !j["table"].contains("outputs"))
    return Status::error(f + ": /table: must name inputs and outputs");
  for (size_t i = 0; i < j["members"].size(); ++i) {
    const auto& m = j["members"][i];
    const std::string at = f + ": /members/" + std::to_string(i);
    if (!m.is_object() || !m.contains("program") || !m.contains("outputs") || !m.contains("cost"))
      return Status::error(at + ": needs program, outputs and cost");
  }
  return j;
}

Expected<Program> memberProgram(const nlohmann::json& front, size_t index) {
  if (index >= front.at("members").size())
    return Status::error("member " + std::to_string(index) + " does not exist (front has " +
                         std::to_string(front.at("members").size()) + " members)");
  ProgramShape shape;
  shape.num_inputs = static_cast<int>(front.at("table").at("inputs").size());
  shape.num_outputs = static_cast<int>(front.at("table").at("outputs").size());
  shape.max_length = 255;
  shape.output_mode = OutputMode::Designated;
  const auto& pj = front.at("members")[index].at("program");
  shape.num_constants = pj.contains("constants") ? static_cast<int>(pj["constants"].size()) : 0;
  return programFromJson(pj, shape);
}

std::string formatFrontTable(const nlohmann::json& front) {
  std::ostringstream os;
  const auto& outs = front.at("table").at("outputs");
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%4s %8s %5s %12s %12s %12s  %s\n", "#", "cost", "disc", "error",
                "rmse", "max_abs", "expression");
  os << buf;
  for (const auto& m : front.at("members")) {
    bool first = true;
    for (const auto& o : m.at("outputs")) {
      const auto& f = o.at("float32");
      std::string expr = o.at("expression").get<std::string>();
      if (outs.size() > 1) expr = o.at("name").get<std::string>() + " = " + expr;
      if (first) {
        std::snprintf(buf, sizeof(buf), "%4zu %8.4g %5.3g %12.6g %12.6g %12.6g  ",
                      m.at("index").get<size_t>(), getNum(m, "cost"), getNum(m, "discontinuity"),
                      getNum(m, "error"), getNum(f, "rmse"), getNum(f, "max_abs"));
      } else {
        std::snprintf(buf, sizeof(buf), "%4s %8s %5s %12s %12.6g %12.6g  ", "", "", "", "",
                      getNum(f, "rmse"), getNum(f, "max_abs"));
      }
      os << buf << expr << "\n";
      first = false;
    }
  }
  return os.str();
}

}  // namespace lgp
