#include "lgp/config/json_reader.hpp"

#include <cmath>
#include <utility>
#include <vector>

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

namespace {
thread_local JsonKeyRecorder* g_recorder = nullptr;
}  // namespace

JsonKeyRecorder::JsonKeyRecorder() : outer_(g_recorder) {
  g_recorder = this;
}
JsonKeyRecorder::~JsonKeyRecorder() {
  g_recorder = outer_;
}

JsonObjectReader::JsonObjectReader(const nlohmann::json& object, std::string path)
    : j_(object), path_(std::move(path)) {}

void JsonObjectReader::know(std::string_view key) {
  known_.emplace(key);
  if (g_recorder) g_recorder->keys_.insert(path(key));
}

bool JsonObjectReader::has(std::string_view key) {
  know(key);
  return j_.is_object() && j_.contains(std::string(key));
}

const nlohmann::json& JsonObjectReader::at(std::string_view key) {
  know(key);
  return j_.at(std::string(key));
}

void JsonObjectReader::allow(std::initializer_list<std::string_view> keys) {
  for (auto k : keys) know(k);
}

std::optional<std::string> JsonObjectReader::unknownKey() const {
  if (!j_.is_object()) return std::nullopt;
  for (auto it = j_.begin(); it != j_.end(); ++it)
    if (!known_.count(it.key())) return path(it.key());
  return std::nullopt;
}

namespace {

// The depth of brackets outside strings. Linear, no allocation; syntax errors are left to
// the parser, which reports them with line and column.
std::optional<size_t> firstTooDeep(std::string_view text, size_t max_depth) {
  size_t depth = 0;
  bool in_string = false, escaped = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
      continue;
    }
    if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return std::nullopt;
}

// nlohmann's message without its "[json.exception.parse_error.101] " tag and without the
// "; last read: '...'" that quotes the text: the text may be any file a path points at.
// What stays names the line and column ("parse error at line 1, column 1: syntax error
// while parsing value - invalid literal").
std::string withoutContent(std::string msg) {
  if (!msg.empty() && msg[0] == '[') {
    const auto close = msg.find("] ");
    if (close != std::string::npos) msg.erase(0, close + 2);
  }
  if (const auto last = msg.find("; last read:"); last != std::string::npos) msg.erase(last);
  return msg;
}

struct Rejected {
  std::string why;
};

}  // namespace

Expected<nlohmann::json> parseJson(std::string_view text, const JsonLimits& limits) {
  using nlohmann::json;
  if (text.size() > limits.max_bytes)
    return Status::error("JSON text of " + std::to_string(text.size()) +
                         " bytes exceeds the limit of " + std::to_string(limits.max_bytes));
  if (auto at = firstTooDeep(text, limits.max_depth))
    return Status::error("JSON nested deeper than " + std::to_string(limits.max_depth) +
                         " levels (at byte " + std::to_string(*at) + ")");
  // One frame per open container: its pointer, its keys so far (objects) or its next index
  // (arrays), and the key just read. The depth is bounded by the pre-scan.
  struct Frame {
    std::string path;
    bool object = false;
    size_t next_index = 0;
    std::set<std::string, std::less<>> keys;
    std::string key;
  };
  std::vector<Frame> stack;
  auto childPath = [&]() -> std::string {
    if (stack.empty()) return "";
    auto& f = stack.back();
    return f.object ? jsonPath(f.path, f.key) : jsonPath(f.path, f.next_index);
  };
  auto valueDone = [&] {
    if (!stack.empty() && !stack.back().object) ++stack.back().next_index;
  };
  json::parser_callback_t cb = [&](int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start: {
        Frame f;
        f.path = childPath();
        f.object = event == json::parse_event_t::object_start;
        stack.push_back(std::move(f));
        break;
      }
      case json::parse_event_t::key: {
        auto& f = stack.back();
        f.key = parsed.get<std::string>();
        if (!f.keys.insert(f.key).second)
          throw Rejected{jsonError(jsonPath(f.path, f.key), "key appears twice in one object")};
        break;
      }
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        if (!stack.empty()) stack.pop_back();
        valueDone();
        break;
      case json::parse_event_t::value:
        valueDone();
        break;
    }
    return true;
  };
  try {
    return json::parse(text, cb);
  } catch (const Rejected& r) {
    return Status::error(r.why);
  } catch (const json::out_of_range&) {
    // nlohmann's 406, "number overflow parsing '1e999'", quotes the number.
    return Status::error("number out of range: a number outside double");
  } catch (const json::parse_error& e) {
    return Status::error("invalid JSON: " + withoutContent(e.what()));
  } catch (const json::exception& e) {
    return Status::error("invalid JSON: " + withoutContent(e.what()));
  }
}

}  // namespace lgp
