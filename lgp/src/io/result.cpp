#include "lgp/io/result.hpp"
#include "lgp/core/csv.hpp"
#include "lgp/core/text_check.hpp"

#include "lgp/config/json_reader.hpp"
#include "lgp/core/table.hpp"
#include "lgp/io/terminal_text.hpp"

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

namespace {
nlohmann::json cancellationToJson(const Cancellation& c) {
  return {{"bits_lost", c.bits_lost}, {"flagged", c.flagged}};
}

nlohmann::json memberToJson(size_t k, const FrontEntry& e, const Table& t,
                            const ErrorConfig& err_cfg) {
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
                      {"formula", e.formula},
                      {"cancellation", cancellationToJson(e.cancellation)},
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
  return m;
}
}  // namespace

nlohmann::json frontToJson(const Search& s, const std::vector<FrontEntry>& front) {
  const Table& t = s.table();
  const auto& cfg = s.config();
  const auto err_cfg = cfg.errorConfig(t.output_names);
  nlohmann::json domain = nlohmann::json::object();
  const auto dom = tableDomain(t);  // what the search and the printer used
  for (size_t i = 0; i < t.numInputs(); ++i) domain[t.input_names[i]] = {dom[i].lo, dom[i].hi};
  nlohmann::json members = nlohmann::json::array();
  for (size_t k = 0; k < front.size(); ++k)
    members.push_back(memberToJson(k, front[k], t, err_cfg));
  std::error_code ec;
  auto config_dir = cfg.base_dir;
  if (!config_dir.empty()) config_dir = std::filesystem::absolute(config_dir, ec);
  const auto p = s.progress();
  nlohmann::json progress = {{"generation", p.generation}, {"evaluations", p.evaluations},
                             {"elapsed_s", p.elapsed_s},   {"stop_reason", p.stop_reason},
                             {"threads", s.threads()},     {"islands", p.islands},
                             {"migrants", p.migrants},     {"restarts", p.restarts},
                             {"ranks", p.ranks},           {"remote_migrants", p.remote_migrants}};
  if (!s.structuredInfo().is_null()) progress["structured"] = s.structuredInfo();
  if (cfg.search.islands.adaptive > 0) progress["island_offspring"] = p.island_offspring;
  if (auto st = s.stagesInfo(); !st.is_null()) progress["stages"] = std::move(st);
  return {{"format", "lgp-front/1"},
          {"config", toJson(cfg)},
          {"config_dir", ec ? cfg.base_dir.string() : config_dir.lexically_normal().string()},
          {"table",
           {{"inputs", t.input_names},
            {"outputs", t.output_names},
            {"rows", t.rows()},
            {"domain", domain},
            {"weighted", !t.weights.empty()},
            {"meta", t.meta}}},
          {"progress", progress},
          // With measured cost in the search, members' "cost" is measured instructions.
          {"cost_model",
           cfg.objectives.measured_cost.in_search && !cfg.objectives.measured_cost.families.empty()
               ? "measured:" + std::string(toString(cfg.objectives.measured_cost.families.front()))
               : std::string(toString(cfg.objectives.cost_model))},
          {"error_metric", std::string(toString(cfg.objectives.metric))},
          {"error_channels", channelNames(err_cfg, t.output_names)},
          {"members", members},
          {"references", cfg.references}};
}

namespace {

// Writes `text` to `f` and closes it; every step's result is checked (a full disk shows at
// fwrite, fflush, fsync or fclose). The error names `path` and the reason.
Status writeAndClose(std::FILE* f, const std::string& text, const std::string& path, bool sync) {
  bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size() && std::fflush(f) == 0 &&
            (!sync || ::fsync(fileno(f)) == 0);
  int err = ok ? 0 : errno;
  if (std::fclose(f) != 0 && ok) {
    ok = false;
    err = errno;
  }
  if (!ok) return Status::error(path + ": write failed (" + std::strerror(err) + ")");
  return Status::ok();
}

}  // namespace

Status writeTextAtomic(const std::string& text, const std::filesystem::path& path) {
  // A device, FIFO or socket (/dev/stdout, /dev/full, a pipe) is written in place: a temp file
  // renamed over it would replace the device node itself.
  std::error_code sec;
  const auto st = std::filesystem::status(path, sec);
  if (!sec && std::filesystem::exists(st) && !std::filesystem::is_regular_file(st) &&
      !std::filesystem::is_directory(st)) {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return Status::error(path.string() + ": cannot write (" + std::strerror(errno) + ")");
    return writeAndClose(f, text, path.string(), false);
  }
  const auto tmp = path.string() + ".tmp";
  {
    std::FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) return Status::error(path.string() + ": cannot write (" + std::strerror(errno) + ")");
    if (auto s = writeAndClose(f, text, path.string(), true); !s) {
      std::remove(tmp.c_str());
      return s;
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::remove(tmp.c_str());
    return Status::error(path.string() + ": " + ec.message());
  }
  return Status::ok();
}

Status writeJsonAtomic(const nlohmann::json& j, const std::filesystem::path& path, int indent) {
  return writeTextAtomic(j.dump(indent) + "\n", path);
}

Status writeFrontJson(const nlohmann::json& front, const std::filesystem::path& path) {
  // A crash never leaves a half-written front.
  return writeJsonAtomic(front, path, 2);
}

Status writeCheckpointFile(const nlohmann::json& state, const std::filesystem::path& path) {
  return writeJsonAtomic(state, path, -1);
}

namespace {
// Reads a JSON document and checks its "format"; errors name the file.
Expected<nlohmann::json> readJsonDocument(const std::filesystem::path& path,
                                          const std::string& format) {
  const std::string f = path.string();
  auto text = readInputFile(path);  // a regular file only: never blocks on a FIFO
  if (!text) return text.status();
  // Fronts and checkpoints nest programs inside members inside islands: a dozen levels.
  JsonLimits limits;
  limits.max_bytes = kMaxInputFileBytes;
  auto parsed = parseJson(*text, limits);
  if (!parsed) return Status::error(f + ": " + parsed.error());
  const nlohmann::json& j = *parsed;
  if (!j.is_object() || j.value("format", "") != format)
    return Status::error(f + ": /format: expected \"" + format + "\"");
  return parsed;
}
}  // namespace

Expected<nlohmann::json> readCheckpointFile(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    return Status::error(path.string() + ": no checkpoint file there");
  return readJsonDocument(path, "lgp-checkpoint/2");
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
std::string fmt(double v) {
  if (!std::isfinite(v)) return "inf";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.9g", v);
  return buf;
}
}  // namespace

Status writeFrontCsv(const nlohmann::json& front, const std::filesystem::path& path) {
  std::ostringstream os;
  os << "index,output,error,cost,discontinuity,rmse,max_abs,mae,mean_rel,r2,bits_lost,expression,"
        "formula\n";
  for (const auto& m : front.at("members")) {
    for (const auto& o : m.at("outputs")) {
      const auto& f = o.at("float32");
      // Spreadsheets open this file: no cell may start a formula (=HYPERLINK(...)).
      os << m.at("index").get<size_t>() << ","
         << csvSpreadsheetField(o.at("name").get<std::string>()) << "," << fmt(getNum(m, "error"))
         << "," << fmt(getNum(m, "cost")) << "," << fmt(getNum(m, "discontinuity")) << ","
         << fmt(getNum(f, "rmse")) << "," << fmt(getNum(f, "max_abs")) << ","
         << fmt(getNum(f, "mae")) << "," << fmt(getNum(f, "mean_rel")) << ","
         << fmt(getNum(f, "r2")) << ","
         << fmt(m.contains("cancellation") ? getNum(m["cancellation"], "bits_lost") : INFINITY)
         << "," << csvSpreadsheetField(o.at("expression").get<std::string>()) << ","
         << csvSpreadsheetField(m.value("formula", "")) << "\n";
    }
  }
  return writeTextAtomic(os.str(), path);
}

Expected<nlohmann::json> readFrontJson(const std::filesystem::path& path) {
  auto doc = readJsonDocument(path, "lgp-front/1");
  if (!doc) return doc;
  if (auto s = checkFrontJson(*doc, path.string()); !s) return s;
  return doc;
}

Status checkFrontJson(const nlohmann::json& j, const std::string& f) {
  if (!j.is_object()) return Status::error(f + ": must be a JSON object");
  if (!j.contains("members") || !j["members"].is_array())
    return Status::error(f + ": /members: must be an array");
  if (!j.contains("table") || !j["table"].contains("inputs") || !j["table"].contains("outputs"))
    return Status::error(f + ": /table: must name inputs and outputs");
  // Names and the data path are copied into messages and the comments of emitted code.
  for (const char* key : {"inputs", "outputs"}) {
    const auto& names = j["table"][key];
    if (!names.is_array()) return Status::error(f + ": /table/" + key + ": must be an array");
    for (size_t i = 0; i < names.size(); ++i) {
      if (!names[i].is_string())
        return Status::error(f + ": /table/" + key + "/" + std::to_string(i) +
                             ": must be a string");
      if (auto s = checkNoControlCharacters(names[i].get<std::string>(),
                                            f + ": /table/" + key + "/" + std::to_string(i));
          !s)
        return s;
    }
  }
  if (j.contains("config") && j["config"].is_object() && j["config"].contains("data") &&
      j["config"]["data"].is_object())
    for (const char* key : {"path", "scene"})
      if (const auto& d = j["config"]["data"]; d.contains(key) && d[key].is_string())
        if (auto s =
                checkNoControlCharacters(d[key].get<std::string>(), f + ": /config/data/" + key);
            !s)
          return s;
  const size_t k = j["table"]["outputs"].size();
  for (size_t i = 0; i < j["members"].size(); ++i) {
    const auto& m = j["members"][i];
    const std::string at = f + ": /members/" + std::to_string(i);
    if (!m.is_object() || !m.contains("program") || !m.contains("outputs") || !m.contains("cost"))
      return Status::error(at + ": needs program, outputs and cost");
    if (!m.contains("index") || !m["index"].is_number_unsigned())
      return Status::error(at + "/index: must be an integer >= 0");
    // What the printers read (formatFrontTable, writeFrontCsv): one entry per output of the
    // table, each with its float32 metrics.
    const auto& outs = m["outputs"];
    if (!outs.is_array() || outs.size() != k)
      return Status::error(at + "/outputs: must be an array of " + std::to_string(k) +
                           " entries, one per output of /table/outputs");
    for (size_t o = 0; o < k; ++o) {
      const std::string ot = at + "/outputs/" + std::to_string(o);
      if (!outs[o].is_object() || !outs[o].contains("float32") || !outs[o]["float32"].is_object())
        return Status::error(ot + "/float32: must be an object of the output's metrics");
      for (const char* key : {"name", "expression"})
        if (outs[o].contains(key) && !outs[o][key].is_string())
          return Status::error(ot + "/" + key + ": must be a string");
    }
  }
  return Status::ok();
}

Expected<Program> memberProgram(const nlohmann::json& front, size_t index) {
  if (index >= front.at("members").size())
    return Status::error("member " + std::to_string(index) + " does not exist (front has " +
                         std::to_string(front.at("members").size()) + " members)");
  return frontEntryProgram(front, front.at("members")[index]);
}

Expected<Program> frontEntryProgram(const nlohmann::json& front, const nlohmann::json& entry) {
  if (!entry.is_object() || !entry.contains("program")) return Status::error("program: missing");
  ProgramShape shape;
  shape.num_inputs = static_cast<int>(front.at("table").at("inputs").size());
  shape.num_outputs = static_cast<int>(front.at("table").at("outputs").size());
  shape.max_length = 255;
  shape.output_mode = OutputMode::Designated;
  const auto& pj = entry.at("program");
  shape.num_constants = pj.contains("constants") ? static_cast<int>(pj["constants"].size()) : 0;
  return programFromJson(pj, shape);
}

std::vector<Interval> frontDomain(const nlohmann::json& front) {
  std::vector<Interval> d;
  const auto& t = front.at("table");
  for (const auto& n : t.at("inputs")) {
    Interval iv;
    const std::string name = n.is_string() ? n.get<std::string>() : "";
    if (t.contains("domain") && t["domain"].is_object() && t["domain"].contains(name)) {
      const auto& r = t["domain"][name];
      if (r.is_array() && r.size() == 2 && r[0].is_number() && r[1].is_number() &&
          r[0].get<double>() <= r[1].get<double>())
        iv = Interval{r[0].get<double>(), r[1].get<double>(), false};
    }
    d.push_back(iv);
  }
  return d;
}

namespace {
std::vector<std::string> names(const nlohmann::json& a) {
  std::vector<std::string> v;
  for (const auto& x : a) v.push_back(x.is_string() ? x.get<std::string>() : "");
  return v;
}
}  // namespace

Expected<Formula> memberFormulaStatements(const nlohmann::json& front, size_t index) {
  auto p = memberProgram(front, index);
  if (!p) return Status::error("/members/" + std::to_string(index) + "/program: " + p.error());
  const auto ins = names(front.at("table").at("inputs"));
  const auto outs = names(front.at("table").at("outputs"));
  return printFormula(formulaDag(*p, static_cast<int>(ins.size()), frontDomain(front)), ins, outs);
}

Expected<std::string> memberFormula(const nlohmann::json& front, size_t index) {
  auto f = memberFormulaStatements(front, index);
  if (!f) return f.status();
  return f->text();
}

std::vector<std::string> measuredFamilies(const nlohmann::json& front) {
  std::vector<std::string> out;
  if (!front.contains("cost_measured_info") || !front["cost_measured_info"].is_object()) return out;
  const auto& info = front["cost_measured_info"];
  if (info.contains("families") && info["families"].is_array())
    for (const auto& f : info["families"])
      if (f.is_string()) out.push_back(f.get<std::string>());
  return out;
}

std::string formatFrontTable(const nlohmann::json& front, const FrontTableOptions& opt) {
  std::ostringstream os;
  const size_t k = front.at("table").at("outputs").size();
  char buf[256];
  // Measured instructions (emit/gpu_cost.hpp), one figure per measured family: "14/15/14".
  const std::vector<std::string> fams = measuredFamilies(front);
  std::string isa_head;
  for (const auto& f : fams) isa_head += (isa_head.empty() ? "" : "/") + terminalSafe(f);
  const int isa_w = fams.empty() ? 0 : std::max<int>(8, static_cast<int>(isa_head.size()));
  auto isaCell = [&](const nlohmann::json& m) {
    std::string s;
    for (const auto& f : fams) {
      const auto* c = m.contains("cost_measured") && m["cost_measured"].is_object() &&
                              m["cost_measured"].contains(f)
                          ? &m["cost_measured"][f]
                          : nullptr;
      char b[32] = "-";
      if (c && c->is_object() && c->contains("instructions") && (*c)["instructions"].is_number())
        std::snprintf(b, sizeof b, "%.0f", (*c)["instructions"].get<double>());
      s += (s.empty() ? "" : "/") + std::string(b);
    }
    return s;
  };
  std::snprintf(buf, sizeof(buf), "%4s %8s %*s%s%5s %12s %12s %12s %6s  %s\n", "#", "cost", isa_w,
                isa_head.c_str(), isa_w ? " " : "", "disc", "error", "rmse", "max_abs", "lost",
                "expression");
  os << buf;
  const auto& members = front.at("members");
  for (size_t i = 0; i < members.size(); ++i) {
    const auto& m = members[i];
    // The formula as statements; a member whose program does not decode keeps its stored text.
    std::vector<FormulaStatement> st;
    if (auto f = memberFormulaStatements(front, i)) {
      st = f->statements;
    } else {
      // Text from the file, shown as text: no escape sequence reaches the terminal.
      for (size_t o = 0; o < m.at("outputs").size(); ++o)
        st.push_back({terminalSafe(m["outputs"][o].value("name", "")),
                      terminalSafe(m["outputs"][o].value("expression", "")), static_cast<int>(o)});
    }
    std::string lost = "-";
    if (m.contains("cancellation") && m["cancellation"].is_object()) {
      const double bits = getNum(m["cancellation"], "bits_lost");
      const bool flag =
          opt.cancel_bits ? bits > *opt.cancel_bits : m["cancellation"].value("flagged", false);
      std::snprintf(buf, sizeof(buf), "%.1f%s", bits, flag ? "!" : "");
      lost = buf;
    }
    auto metrics = [&](int o, bool first) {
      const bool has = o >= 0 && static_cast<size_t>(o) < m.at("outputs").size();
      const auto f = has ? m["outputs"][o].at("float32") : nlohmann::json::object();
      char rm[32] = "", mx[32] = "";
      if (has) {
        std::snprintf(rm, sizeof rm, "%.6g", getNum(f, "rmse"));
        std::snprintf(mx, sizeof mx, "%.6g", getNum(f, "max_abs"));
      }
      if (first)
        std::snprintf(buf, sizeof(buf), "%4zu %8.4g %*s%s%5.3g %12.6g %12s %12s %6s  ",
                      m.at("index").get<size_t>(), getNum(m, "cost"), isa_w, isaCell(m).c_str(),
                      isa_w ? " " : "", getNum(m, "discontinuity"), getNum(m, "error"), rm, mx,
                      lost.c_str());
      else
        std::snprintf(buf, sizeof(buf), "%4s %8s %*s%s%5s %12s %12s %12s %6s  ", "", "", isa_w, "",
                      isa_w ? " " : "", "", "", rm, mx, "");
      return std::string(buf);
    };
    if (k == 1) {
      // One line: temporaries, then the bare expression of the output.
      std::string text;
      for (const auto& s : st)
        text += (text.empty() ? "" : "; ") + (s.output >= 0 ? s.expr : s.name + " = " + s.expr);
      os << metrics(0, true) << text << "\n";
      continue;
    }
    // Several outputs: one statement per line, each output's metrics beside its own line.
    for (size_t j = 0; j < st.size(); ++j)
      os << metrics(st[j].output, j == 0) << st[j].name << " = " << st[j].expr << "\n";
  }
  // The certificate of search.exhaustive: the best error per operator count, as recorded (a
  // malformed or hostile entry is skipped, not printed).
  if (const auto it = front.find("exhaustive"); it != front.end() && it->is_object()) {
    const auto best = it->value("best", nlohmann::json::array());
    if (best.is_array() && !best.empty()) os << "exhaustive enumeration (search.exhaustive):\n";
    for (const auto& b : best) {
      if (!b.is_object() || !b.value("max_ops", nlohmann::json()).is_number_integer() ||
          !b.value("formula", nlohmann::json()).is_string())
        continue;
      const std::string formula = b["formula"].get<std::string>();
      if (!controlCharacterReason(formula).empty()) continue;
      const auto e = b.value("error", nlohmann::json());
      std::snprintf(buf, sizeof buf, "  <= %d ops: error %s%s  ", b["max_ops"].get<int>(),
                    e.is_number() ? fmt(e.get<double>()).c_str() : "-",
                    b.value("complete", false) ? "" : " (incomplete)");
      os << buf << terminalSafe(formula);
      // How many expressions of exactly that size were distinct, and fitted (older fronts
      // record only the first).
      const auto n = b.value("enumerated", nlohmann::json()),
                 m = b.value("screened", nlohmann::json());
      if (n.is_number_unsigned()) {
        os << "  [" << n.get<uint64_t>() << " distinct";
        if (m.is_number_unsigned()) os << ", " << m.get<uint64_t>() << " fitted";
        os << "]";
      }
      os << "\n";
    }
    // Why larger sizes were not done (the reasons the enumerator writes; anything else in a
    // hand-edited front is not printed).
    const auto stopped = it->value("stopped", nlohmann::json());
    const auto complete = it->value("complete_ops", nlohmann::json(-1));
    if ((stopped == "seconds" || stopped == "expression cap" || stopped == "memory") &&
        complete.is_number_integer())
      os << "  stopped by the "
         << (stopped == "seconds"          ? "time budget"
             : stopped == "expression cap" ? "expression cap"
                                           : "memory bound")
         << " after " << complete.dump() << " ops\n";
  }
  return os.str();
}

namespace {
// A front is a file anyone may hand over: its config never names where a generated table is
// cached (the user's default cache instead), and its table's columns are the columns the run
// selects, so that a scene without them is refused before it is generated.
Expected<RunConfig> parseFrontConfig(const nlohmann::json& front, nlohmann::json c,
                                     const std::filesystem::path& base) {
  if (!c.contains("data") || !c["data"].is_object())
    return Status::error("/config/data: the front records no data section");
  c["data"].erase("cache_dir");
  auto cfg = parseRunConfig(c, base);
  if (!cfg) return Status::error("/config: " + cfg.error());
  const auto& t = front.contains("table") ? front["table"] : nlohmann::json::object();
  if (cfg->data.inputs.empty() && t.contains("inputs") && t["inputs"].is_array())
    cfg->data.inputs = names(t["inputs"]);
  if (cfg->data.outputs.empty() && t.contains("outputs") && t["outputs"].is_array())
    cfg->data.outputs = names(t["outputs"]);
  return cfg;
}
}  // namespace

Expected<RunConfig> frontRunConfig(const nlohmann::json& front,
                                   const std::filesystem::path& front_path,
                                   const std::string& data_override) {
  if (!front.contains("config") || !front["config"].is_object())
    return Status::error("/config: the front records no run config");
  if (!data_override.empty()) {
    nlohmann::json c = front["config"];
    if (c.contains("data") && c["data"].is_object()) c["data"].erase("scene");
    c["data"]["path"] = std::filesystem::absolute(data_override).string();
    return parseFrontConfig(front, std::move(c), ".");
  }
  const auto& data = front["config"].value("data", nlohmann::json::object());
  const std::string rel = data.value("path", data.value("scene", std::string()));
  std::vector<std::filesystem::path> bases;
  if (front.contains("config_dir") && front["config_dir"].is_string() &&
      !front["config_dir"].get<std::string>().empty())
    bases.emplace_back(front["config_dir"].get<std::string>());
  auto dir = front_path.parent_path();
  bases.push_back(dir.empty() ? std::filesystem::path(".") : dir);
  std::string tried;
  for (const auto& b : bases) {
    std::error_code ec;
    const auto p = std::filesystem::path(rel).is_absolute() ? std::filesystem::path(rel) : b / rel;
    if (rel.empty() || !std::filesystem::exists(p, ec)) {
      tried += (tried.empty() ? "" : ", ") + p.string();
      continue;
    }
    return parseFrontConfig(front, front["config"], b);
  }
  return Status::error("/config/data: the run's table was not found (looked for " + tried +
                       "); give it with --data");
}

Expected<nlohmann::json> snapFrontMember(const nlohmann::json& front, size_t index,
                                         const RunConfig& cfg, const Table& t,
                                         const SnapOptions& o) {
  auto prog = memberProgram(front, index);
  if (!prog)
    return Status::error("/members/" + std::to_string(index) + "/program: " + prog.error());
  const auto outs = names(front.at("table").at("outputs"));
  const auto ins = names(front.at("table").at("inputs"));
  if (t.output_names != outs || t.input_names != ins)
    return Status::error("table: its columns do not match the front's /table/inputs and outputs");
  ErrorConfig ec = cfg.errorConfig(t.output_names);
  ec.linear_scaling = false;  // a member's program already applies its scales
  const Dataset ds(t, cfg.eval.block_size);
  Scorer s(ds, ec, cfg.eval.block_size);
  SnapOptions so = o;  // changes below float32 rounding of the targets count as none
  so.abs_floor = std::max(so.abs_floor, float32ErrorFloor(ec, t));
  const auto r = snapConstants(
      *prog, [&](const Program& p) { return s.error(p); }, so);
  FrontEntry e;
  e.program = r.program;
  const auto domain = tableDomain(t);
  CostModel cost = cfg.costModel();
  cost.domain = domain;
  DiscontinuityModel disc = cfg.discontinuityModel();
  disc.domain = domain;
  e.obj.error = r.error_after;
  e.obj.cost = cost.programCost(e.program) + cost.transformCost(ec.transforms);
  e.obj.discontinuity = disc.programDiscontinuity(e.program);
  e.metrics = s.metrics(e.program);
  e.metrics_ref = referenceMetrics(e.program, t, ec);
  if (!ec.channels.empty()) {
    e.channel_metrics = s.channelMetrics(e.program);
    e.channel_metrics_ref = referenceChannelMetrics(e.program, t, ec);
  }
  e.cost_by_target = costByTarget(e.program, domain, ec.transforms);
  const Dag d = formulaDag(e.program, static_cast<int>(ins.size()), domain);
  e.infix = printOutputs(d, ins);
  e.formula = printFormula(d, ins, outs).text();
  e.cancellation = cancellation(d, t, ec.transforms);
  auto j = memberToJson(index, e, t, ec);
  j["snap"] = {{"constants", r.snapped}, {"error_before", num(r.error_before)}};
  return j;
}

}  // namespace lgp
