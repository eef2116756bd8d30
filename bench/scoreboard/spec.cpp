// scoreboard.json: the tables of the board, their run configs, calibrated rates and the
// published fits to score.
#include <cstdio>
#include <cstdlib>

#include "board.hpp"

namespace lgp::board {

namespace {
[[noreturn]] void die(const std::string& msg) {
  std::fprintf(stderr, "lgp_scoreboard: error: %s\n", msg.c_str());
  std::exit(2);
}
// A fit: a reference name, or {"name", "forms", "counted", "source", "note"}.
FitSpec parseFit(const nlohmann::json& f, const std::string& at) {
  FitSpec fit;
  if (f.is_string()) {
    fit.name = f.get<std::string>();
    fit.forms = {fit.name};
    return fit;
  }
  if (!f.is_object() || !f.contains("name") || !f["name"].is_string())
    die(at + ": must be a reference name or an object with \"name\"");
  fit.name = f["name"];
  if (f.contains("forms")) {
    if (!f["forms"].is_array() || f["forms"].empty()) die(at + "/forms: must name references");
    for (const auto& n : f["forms"]) {
      if (!n.is_string()) die(at + "/forms: must be reference names (strings)");
      fit.forms.push_back(n);
    }
  } else {
    fit.forms = {fit.name};
  }
  if (f.contains("counted")) {
    if (!f["counted"].is_boolean()) die(at + "/counted: must be true or false");
    fit.counted = f["counted"];
  }
  for (const char* k : {"source", "note"})
    if (f.contains(k)) {
      if (!f[k].is_string()) die(at + "/" + k + ": must be a string");
      (std::string(k) == "source" ? fit.source : fit.note) = f[k];
    }
  for (const auto& k : f.items())
    if (k.key() != "name" && k.key() != "forms" && k.key() != "counted" && k.key() != "source" &&
        k.key() != "note")
      die(at + "/" + k.key() + ": unknown key");
  return fit;
}
}  // namespace

std::vector<TableSpec> parseSpec(const nlohmann::json& j, const std::string& file) {
  if (!j.is_object() || !j.contains("tables") || !j["tables"].is_array())
    die(file + ": /tables: must be an array of tables");
  std::vector<TableSpec> out;
  for (size_t i = 0; i < j["tables"].size(); ++i) {
    const auto& t = j["tables"][i];
    const std::string at = file + ": /tables/" + std::to_string(i);
    if (!t.is_object()) die(at + ": must be an object");
    TableSpec s;
    if (!t.contains("name") || !t["name"].is_string() || t["name"].get<std::string>().empty())
      die(at + "/name: must be a non-empty string");
    s.name = t["name"];
    s.title = t.value("title", s.name);
    if (!t.contains("config") || !t["config"].is_string()) die(at + "/config: must be a path");
    s.config = t["config"];
    if (!t.contains("evals_per_minute") || !t["evals_per_minute"].is_number() ||
        !(t["evals_per_minute"].get<double>() > 0))
      die(at + "/evals_per_minute: must be a number > 0");
    s.evals_per_minute = t["evals_per_minute"];
    if (!t.contains("fits") || !t["fits"].is_array() || t["fits"].empty())
      die(at + "/fits: name at least one of the config's references");
    for (size_t k = 0; k < t["fits"].size(); ++k)
      s.fits.push_back(parseFit(t["fits"][k], at + "/fits/" + std::to_string(k)));
    if (t.contains("domain")) {
      if (!t["domain"].is_object()) die(at + "/domain: must be an object of input -> [lo, hi]");
      for (const auto& [input, range] : t["domain"].items()) {
        if (!range.is_array() || range.size() != 2 || !range[0].is_number() ||
            !range[1].is_number() || !(range[0].get<double>() < range[1].get<double>()))
          die(at + "/domain/" + input + ": must be [lo, hi] with lo < hi");
        s.domain[input] = {range[0].get<double>(), range[1].get<double>()};
      }
    }
    for (const auto& k : t.items())
      if (k.key() != "name" && k.key() != "title" && k.key() != "config" &&
          k.key() != "evals_per_minute" && k.key() != "fits" && k.key() != "domain")
        die(at + "/" + k.key() + ": unknown key");
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace lgp::board
