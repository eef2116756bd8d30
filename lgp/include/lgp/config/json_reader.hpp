// How every JSON validator of the project (run config, scene, lgpd's daemon config, the
// references of `lgp score`) names the value an error is about: a JSON Pointer (RFC 6901) and
// the reason, "/search/islands/count: must be in [1, 4096] (got 0)". One helper, so that the
// four agree on the root ("/"), on array indices and on which keys count as unknown.
#pragma once

#include <cstddef>
#include <functional>
#include <initializer_list>
#include <optional>
#include <set>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgp {

// Limits of parseJson. The depth is checked by a pre-scan before any tree is built: nlohmann
// parses iteratively, but copying, dumping and destroying a value recurse, so a document
// nested 100k deep would exhaust the stack later, far from the input.
struct JsonLimits {
  size_t max_depth = 64;               // arrays and objects nested inside each other
  size_t max_bytes = size_t{1} << 28;  // 256 MiB of text
};

// Parses one JSON document (RFC 8259) and refuses what nlohmann would accept silently or
// report without a path: nesting deeper than max_depth, text longer than max_bytes, a number
// outside the range of double ("1e999", a 400-digit integer) and a key that appears twice in
// one object (nlohmann keeps the last). The error names the position or the JSON Pointer:
//   "JSON nested deeper than 64 levels (at byte 64)",
//   "/data/path: key appears twice in one object".
Expected<nlohmann::json> parseJson(std::string_view text, const JsonLimits& limits = {});

// The pointer to member `key` (or element `index`) of the value at `parent` ("" = the whole
// document). '~' and '/' in a key are written "~0" and "~1", so a path names one value.
std::string jsonPath(std::string_view parent, std::string_view key);
std::string jsonPath(std::string_view parent, size_t index);

// "<path>: <why>", the whole document shown as "/".
std::string jsonError(std::string_view path, std::string_view why);

// While it lives, records the JSON path of every key a JsonObjectReader on this thread is asked
// for or told of: the keys a parser knows (tests/core/config_roundtrip_test.cpp lists the run
// config's with it, to hold every one of them to toJson and the checkpoint digest).
class JsonKeyRecorder {
 public:
  JsonKeyRecorder();
  ~JsonKeyRecorder();
  JsonKeyRecorder(const JsonKeyRecorder&) = delete;
  JsonKeyRecorder& operator=(const JsonKeyRecorder&) = delete;
  const std::set<std::string>& keys() const { return keys_; }

 private:
  friend class JsonObjectReader;
  JsonKeyRecorder* outer_;
  std::set<std::string> keys_;
};

// One JSON object being read: remembers the keys that were asked for or declared, so that the
// rest can be reported as unknown. Keeps a reference: the object must outlive the reader.
class JsonObjectReader {
 public:
  JsonObjectReader(const nlohmann::json& object, std::string path);

  bool isObject() const { return j_.is_object(); }
  const std::string& path() const { return path_; }
  std::string path(std::string_view key) const { return jsonPath(path_, key); }

  // Whether the key is present; either way it counts as known from now on.
  bool has(std::string_view key);
  // The member (which must be present); it counts as known.
  const nlohmann::json& at(std::string_view key);
  // Keys that are valid here although nobody reads them (yet).
  void allow(std::initializer_list<std::string_view> keys);
  template <class Keys>
  void allowAll(const Keys& keys) {
    for (const auto& k : keys) know(k);
  }

  // The path of the first key, in the object's order, that is not known; none when all are
  // (or when the value is not an object).
  std::optional<std::string> unknownKey() const;

 private:
  void know(std::string_view key);
  const nlohmann::json& j_;
  std::string path_;
  std::set<std::string, std::less<>> known_;
};

}  // namespace lgp
