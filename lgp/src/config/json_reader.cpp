#include "lgp/config/json_reader.hpp"

#include <utility>

namespace lgp {

std::string jsonPath(std::string_view parent, std::string_view key) {
  std::string p(parent);
  p += '/';
  for (char c : key) {
    if (c == '~') {
      p += "~0";
    } else if (c == '/') {
      p += "~1";
    } else {
      p += c;
    }
  }
  return p;
}

std::string jsonPath(std::string_view parent, size_t index) {
  return std::string(parent) + "/" + std::to_string(index);
}

std::string jsonError(std::string_view path, std::string_view why) {
  std::string e(path.empty() ? "/" : path);
  e += ": ";
  e += why;
  return e;
}

JsonObjectReader::JsonObjectReader(const nlohmann::json& object, std::string path)
    : j_(object), path_(std::move(path)) {}

bool JsonObjectReader::has(std::string_view key) {
  known_.emplace(key);
  return j_.is_object() && j_.contains(std::string(key));
}

const nlohmann::json& JsonObjectReader::at(std::string_view key) {
  known_.emplace(key);
  return j_.at(std::string(key));
}

void JsonObjectReader::allow(std::initializer_list<std::string_view> keys) {
  for (auto k : keys) known_.emplace(k);
}

std::optional<std::string> JsonObjectReader::unknownKey() const {
  if (!j_.is_object()) return std::nullopt;
  for (auto it = j_.begin(); it != j_.end(); ++it)
    if (!known_.count(it.key())) return path(it.key());
  return std::nullopt;
}

}  // namespace lgp
