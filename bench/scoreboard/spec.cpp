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
    for (const auto& f : t["fits"]) {
      if (!f.is_string()) die(at + "/fits: must be reference names (strings)");
      s.fits.push_back(f);
    }
    for (const auto& k : t.items())
      if (k.key() != "name" && k.key() != "title" && k.key() != "config" &&
          k.key() != "evals_per_minute" && k.key() != "fits")
        die(at + "/" + k.key() + ": unknown key");
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace lgp::board
