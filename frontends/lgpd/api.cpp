#include "api.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "http_server.hpp"
#include "lgp/config/json_reader.hpp"
#include "lgp/eval/interpreter.hpp"
#include "lgp/eval/objectives.hpp"
#include "lgp/io/result.hpp"
#include "lgpd_web.hpp"
#ifdef LGP_HAVE_EMIT
#include "lgp/emit/emit.hpp"
#include "lgp/emit/score.hpp"
#endif

namespace lgpd {

using nlohmann::json;

namespace {

constexpr size_t kDefaultResidualRows = 65536;
constexpr size_t kMaxHistoryRows = 5000;
// How long a request waits for work done on the background thread (a table being loaded,
// references being scored) before it is answered without it.
constexpr auto kTableWait = std::chrono::milliseconds(2000);
constexpr auto kReferencesWait = std::chrono::milliseconds(1000);
constexpr int kRetryAfterS = 2;

void sendJson(HttpResponse& res, int status, const json& body) {
  res.status = status;
  // Non-finite doubles print as null; invalid UTF-8 from a table name is replaced.
  res.setContent(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
}

void sendError(HttpResponse& res, int status, const std::string& msg,
               const std::string& field = "") {
  json body = {{"error", msg}, {"status", status}};
  if (!field.empty()) body["field"] = field;
  sendJson(res, status, body);
}

// An error answer after which the connection is closed: the request's body (or what the
// client sends next) is not read.
void sendErrorAndClose(HttpResponse& res, int status, const std::string& msg) {
  res.close = true;
  sendError(res, status, msg);
}

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

// The media type of a Content-Type header, without parameters, in lower case.
std::string mediaType(const std::string& content_type) {
  return lower(trim(content_type.substr(0, content_type.find(';'))));
}

bool isJsonMediaType(const std::string& type) {
  return type == "application/json" ||
         (type.size() > 5 && type.compare(type.size() - 5, 5, "+json") == 0);
}

// The credentials of an "Authorization: Bearer <token>" header; the scheme is
// case-insensitive (RFC 7235) and one or more spaces follow it. Empty for another scheme.
std::string_view bearerCredentials(std::string_view auth) {
  constexpr std::string_view kScheme = "bearer";
  if (auth.size() <= kScheme.size() || auth[kScheme.size()] != ' ') return {};
  for (size_t i = 0; i < kScheme.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(auth[i])) != kScheme[i]) return {};
  auth.remove_prefix(kScheme.size());
  while (!auth.empty() && auth.front() == ' ') auth.remove_prefix(1);
  while (!auth.empty() && (auth.back() == ' ' || auth.back() == '\t')) auth.remove_suffix(1);
  return auth;
}

// "/search/population: must be ..." -> "/search/population".
std::string fieldOf(const std::string& msg) {
  if (msg.empty() || msg[0] != '/') return "";
  auto colon = msg.find(": ");
  return colon == std::string::npos ? "" : msg.substr(0, colon);
}

// Compares without an early exit, so the time taken does not reveal a matching prefix.
bool constantTimeEqual(std::string_view a, std::string_view b) {
  if (a.size() != b.size() || b.empty()) return false;
  unsigned char diff = 0;
  for (size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
}

std::vector<std::string> splitPath(const std::string& p) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i <= p.size()) {
    size_t j = p.find('/', i);
    if (j == std::string::npos) j = p.size();
    out.push_back(p.substr(i, j - i));
    i = j + 1;
  }
  return out;
}

std::optional<size_t> parseIndex(const std::string& s) {
  if (s.empty() || s.size() > 9) return std::nullopt;
  size_t v = 0;
  auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

// Whether the front was made on a table with exactly these input and output columns.
bool sameColumns(const json& front, const lgp::Table& t) {
  const auto table = front.find("table");
  if (table == front.end() || !table->is_object()) return false;
  const auto names = [&](const char* key) {
    std::vector<std::string> out;
    const auto it = table->find(key);
    if (it == table->end() || !it->is_array()) return std::optional<std::vector<std::string>>();
    for (const auto& n : *it) {
      if (!n.is_string()) return std::optional<std::vector<std::string>>();
      out.push_back(n.get<std::string>());
    }
    return std::optional(out);
  };
  return names("inputs") == t.input_names && names("outputs") == t.output_names;
}

std::string columnList(const std::vector<std::string>& inputs,
                       const std::vector<std::string>& outputs) {
  std::string s;
  for (const auto& n : inputs) s += (s.empty() ? "" : ", ") + n;
  s += " -> ";
  for (size_t i = 0; i < outputs.size(); ++i) s += (i ? ", " : "") + outputs[i];
  return s;
}

std::string columnList(const json& front) {
  std::vector<std::string> in, out;
  const json table = front.value("table", json::object());
  for (const auto& [key, list] : {std::pair{"inputs", &in}, std::pair{"outputs", &out}})
    if (table.contains(key) && table[key].is_array())
      for (const auto& n : table[key]) list->push_back(n.is_string() ? n.get<std::string>() : "?");
  return columnList(in, out);
}

json numberOrNull(double v) {
  return std::isfinite(v) ? json(v) : json(nullptr);
}

json runSummary(const RunRecord& r, bool active) {
  const auto& c = r.counters;
  json budget = json::object();
  if (auto s = r.config.find("search"); s != r.config.end() && s->is_object()) {
    for (const char* k : {"generations", "max_evaluations", "wall_time_s"})
      if (s->contains(k)) budget[k] = (*s)[k];
  }
  json j = {
      {"id", r.id},
      {"name", r.name},
      {"status", std::string(toString(r.status))},
      {"active", active},
      {"created_at", r.created_at},
      {"started_at", r.started_at > 0 ? json(r.started_at) : json(nullptr)},
      {"finished_at", r.finished_at > 0 ? json(r.finished_at) : json(nullptr)},
      {"generation", c.generation},
      {"evaluations", c.evaluations},
      {"elapsed_s", c.elapsed_s},
      {"evals_per_s", numberOrNull(c.evals_per_s)},
      {"front_size", c.front_size},
      {"best_error", numberOrNull(c.best_error)},
      {"best", c.best},
      {"stop_reason", c.stop_reason},
      {"cancel_requested", r.cancel_requested},
      {"resumes", r.resumes},
      {"budget", budget},
      {"checkpoint", r.checkpoint_generation >= 0
                         ? json{{"generation", r.checkpoint_generation}, {"at", r.checkpoint_at}}
                         : json(nullptr)},
  };
  if (!r.error.empty()) j["error"] = r.error;
  return j;
}

class Api {
 public:
  Api(Store& store, JobManager& jobs) : store_(store), jobs_(jobs) {
    const auto& cfg = jobs_.daemonConfig();
    max_body_ = cfg.max_body_bytes;
    token_ = cfg.token;
    allowed_hosts_ = {"localhost", "127.0.0.1", "[::1]"};
    if (auto addr = parseListen(cfg.listen); addr && addr->host != "0.0.0.0" && addr->host != "::")
      allowed_hosts_.push_back(addr->host.find(':') != std::string::npos ? "[" + addr->host + "]"
                                                                         : addr->host);
    allowed_hosts_.insert(allowed_hosts_.end(), cfg.allowed_hosts.begin(), cfg.allowed_hosts.end());
    allowed_origins_ = cfg.allowed_origins;
  }

  // After the request line and headers, before any of the body is read: the framing, the
  // site, the token, and a POST's content type (none of them needs the body).
  void head(const HttpRequest& req, HttpResponse& res) {
    if (checkFraming(req, res) || checkSite(req, res)) return;
    if (!token_.empty() && req.path.rfind("/api/", 0) == 0 && req.path != "/api/v1/health" &&
        !constantTimeEqual(bearerCredentials(req.header("Authorization")), token_)) {
      res.setHeader("WWW-Authenticate", "Bearer");
      if (req.announcesBody())
        sendErrorAndClose(res, 401, "missing or wrong bearer token");
      else
        sendError(res, 401, "missing or wrong bearer token");
      return;
    }
    if (req.method != "POST") return;
    const std::string type = req.header("Content-Type");
    if (mediaType(type) == "multipart/form-data")
      return sendErrorAndClose(res, 415, "multipart bodies are not accepted");
    // Every POST, with a body or not, names a JSON type: a page on another site can send a
    // POST without a preflight only as text/plain, a form or multipart, never JSON.
    if (!isJsonMediaType(mediaType(type)))
      return sendErrorAndClose(
          res, 415,
          req.hasHeader("Content-Type")
              ? "Content-Type must be application/json (got '" + type.substr(0, 100) + "')"
              : "Content-Type: application/json is required on every POST, also one without a "
                "body");
  }

  // The whole request (its body read, at most max_body_bytes).
  void dispatch(const HttpRequest& req, HttpResponse& res) {
    const bool get = req.method == "GET" || req.method == "HEAD";
    if (get && (req.path == "/" || req.path == "/index.html")) {
      // The script comes from /app.js only: an injected inline script would not run. No site
      // may frame the page (a framing page could lure clicks onto its buttons).
      res.setHeader("Content-Security-Policy",
                    "default-src 'self'; script-src 'self'; style-src 'unsafe-inline'; "
                    "img-src 'self' data:; connect-src 'self'; frame-ancestors 'none'; "
                    "base-uri 'none'; form-action 'none'");
      res.status = 200;
      res.setContent(web::kIndexHtml, "text/html; charset=utf-8");
      return;
    }
    if (get && req.path == "/app.js") {
      res.status = 200;
      res.setContent(web::kAppJs, "text/javascript; charset=utf-8");
      return;
    }
    if (!isApi(req.path)) return sendError(res, 404, "no such route");
    route(req, res, req.body);
  }

 private:
  static bool isApi(const std::string& path) {
    return path == "/api/v1" || path.rfind("/api/v1/", 0) == 0;
  }
  // "/api/v1/runs/" -> "runs".
  static std::string apiRest(const std::string& path) {
    std::string rest = path.substr(std::string_view("/api/v1").size());
    if (!rest.empty() && rest[0] == '/') rest.erase(0, 1);
    while (!rest.empty() && rest.back() == '/') rest.pop_back();
    return rest;
  }

  // Who the request is from, checked before the token: the Host must name this daemon (a
  // DNS-rebinding page sends its own name), and a POST or DELETE that carries an Origin must
  // come from the daemon's own origin or one in allowed_origins. True when answered (403).
  bool checkSite(const HttpRequest& req, HttpResponse& res) {
    const size_t hosts = req.headerCount("Host");
    if (hosts != 1) {
      sendErrorAndClose(res, 400,
                        hosts == 0 ? "a Host header is required" : "more than one Host header");
      return true;
    }
    const std::string host_value = req.header("Host");
    const auto host = parseHostHeader(host_value);
    const bool any =
        std::find(allowed_hosts_.begin(), allowed_hosts_.end(), "*") != allowed_hosts_.end();
    if (!host || (!any && std::find(allowed_hosts_.begin(), allowed_hosts_.end(), host->host) ==
                              allowed_hosts_.end())) {
      sendErrorAndClose(res, 403,
                        "Host header '" + host_value.substr(0, 100) +
                            "' does not name this daemon (accepted: 127.0.0.1, localhost, "
                            "[::1], the listen address and allowed_hosts)");
      return true;
    }
    if (req.method != "POST" && req.method != "DELETE") return false;
    const size_t origins = req.headerCount("Origin");
    if (origins == 0) return false;
    const std::string origin_value = origins == 1 ? req.header("Origin") : "";
    const auto origin = parseOrigin(origin_value);
    const auto defaultPort = [](const std::string& scheme, int port) {
      return port >= 0 ? port : scheme == "https" ? 443 : 80;
    };
    const bool same = origin && origin->authority.host == host->host &&
                      defaultPort(origin->scheme, origin->authority.port) ==
                          defaultPort(origin->scheme, host->port);
    const bool listed = origin && std::find(allowed_origins_.begin(), allowed_origins_.end(),
                                            lower(origin_value)) != allowed_origins_.end();
    if (!same && !listed) {
      sendErrorAndClose(res, 403,
                        "a " + req.method + " from Origin '" + origin_value.substr(0, 100) +
                            "' is refused: only the daemon's own origin and allowed_origins "
                            "may change runs");
      return true;
    }
    return false;
  }

  // How the body is framed, checked before any of it is read. True when the request has
  // been answered (and the connection is to be closed).
  bool checkFraming(const HttpRequest& req, HttpResponse& res) {
    const std::string& m = req.method;
    if (m != "GET" && m != "HEAD" && m != "POST" && m != "DELETE") {
      sendErrorAndClose(res, 405, "method " + m + " is not allowed (GET, HEAD, POST, DELETE)");
      return true;
    }
    const size_t lengths = req.headerCount("Content-Length");
    const bool chunked = req.hasHeader("Transfer-Encoding");
    if (lengths > 1) {
      sendErrorAndClose(res, 400, "more than one Content-Length header");
      return true;
    }
    uint64_t length = 0;
    if (lengths == 1) {
      const std::string v = trim(req.header("Content-Length"));
      auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), length);
      if (v.empty() || v.size() > 19 || v.find_first_not_of("0123456789") != std::string::npos ||
          ec != std::errc() || ptr != v.data() + v.size()) {
        sendErrorAndClose(res, 400,
                          "invalid Content-Length '" + v.substr(0, 40) +
                              "' (expected a decimal number of bytes)");
        return true;
      }
    }
    if (chunked) {
      if (lengths) {
        sendErrorAndClose(res, 400, "both Content-Length and Transfer-Encoding are given");
        return true;
      }
      if (req.headerCount("Transfer-Encoding") != 1 ||
          lower(trim(req.header("Transfer-Encoding"))) != "chunked") {
        sendErrorAndClose(res, 501,
                          "unsupported Transfer-Encoding '" +
                              req.header("Transfer-Encoding").substr(0, 40) + "' (only chunked)");
        return true;
      }
    }
    if ((m == "GET" || m == "HEAD") && (chunked || length > 0)) {
      sendErrorAndClose(res, 400, "a " + m + " request has no body");
      return true;
    }
    if (m == "POST" && !chunked && lengths == 0) {
      sendErrorAndClose(res, 411,
                        "a POST needs a Content-Length (0 for no body) or a chunked body");
      return true;
    }
    if (length > max_body_) {
      sendErrorAndClose(res, 413,
                        "request body of " + std::to_string(length) + " bytes is larger than " +
                            "max_body_bytes (" + std::to_string(max_body_) + ")");
      return true;
    }
    return false;
  }

  // /api/v1/<segments...>, dispatched by hand so that every malformed id is a clean 400.
  void route(const HttpRequest& req, HttpResponse& res, const std::string& body) {
    auto seg = splitPath(apiRest(req.path));
    // HEAD is answered as GET (the server leaves the body out).
    const std::string m = req.method == "HEAD" ? "GET" : req.method;

    if (seg.size() == 1 && seg[0] == "health") {
      if (m != "GET") return methodNotAllowed(res);
      return sendJson(res, 200, {{"ok", true}, {"service", "lgpd"}, {"api", "v1"}});
    }
    if (seg.size() == 1 && seg[0] == "languages") {
      if (m != "GET") return methodNotAllowed(res);
      return languages(res);
    }
    if (seg.empty() || seg[0] != "runs") return sendError(res, 404, "no such route");
    if (seg.size() == 1) {
      if (m == "GET") return listRuns(res);
      if (m == "POST") return submit(body, res);
      return methodNotAllowed(res);
    }
    const std::string& id = seg[1];
    if (!isValidRunId(id))
      return sendError(res, 400, "invalid run id (expected 16 lowercase hex digits)");
    if (seg.size() == 2) {
      if (m == "GET") return getRun(id, res);
      if (m == "DELETE") return deleteRun(id, res);
      return methodNotAllowed(res);
    }
    if (seg.size() == 3 && seg[2] == "cancel") {
      if (m != "POST") return methodNotAllowed(res);
      return cancelRun(id, res);
    }
    if (seg.size() == 3 && seg[2] == "history") {
      if (m != "GET") return methodNotAllowed(res);
      return history(id, res);
    }
    if (seg.size() >= 3 && seg[2] == "front") {
      if (m != "GET") return methodNotAllowed(res);
      if (seg.size() == 3) return front(id, res);
      auto k = parseIndex(seg[3]);
      if (!k) return sendError(res, 400, "invalid member index (expected a non-negative integer)");
      if (seg.size() == 4) return member(id, *k, res);
      if (seg.size() == 5 && seg[4] == "code") return code(id, *k, req, res);
      if (seg.size() == 5 && seg[4] == "residuals") return residuals(id, *k, req, res);
    }
    return sendError(res, 404, "no such route");
  }

  void methodNotAllowed(HttpResponse& res) {
    sendError(res, 405, "method not allowed on this route");
  }

  // Loads a run or answers 404/500; nullopt means the response is already set.
  std::optional<RunRecord> loadRun(const std::string& id, HttpResponse& res) {
    auto r = store_.getRun(id);
    if (!r) {
      spdlog::error("{}", r.error());
      sendError(res, 500, "store error");
      return std::nullopt;
    }
    if (!*r) {
      sendError(res, 404, "no run " + id);
      return std::nullopt;
    }
    return std::move(**r);
  }

  std::optional<StoredFront> loadFront(const std::string& id, HttpResponse& res) {
    auto f = store_.loadFront(id);
    if (!f) {
      spdlog::error("{}", f.error());
      sendError(res, 500, "store error");
      return std::nullopt;
    }
    if (!*f) {
      sendError(res, 404, "run " + id + " has no front yet");
      return std::nullopt;
    }
    return std::move(**f);
  }

  void listRuns(HttpResponse& res) {
    std::vector<std::string> unreadable;
    auto runs = store_.listRuns(&unreadable);
    if (!runs) return sendError(res, 500, "store error: " + runs.error());
    json list = json::array();
    for (const auto& r : *runs) list.push_back(runSummary(r, jobs_.isActive(r.id)));
    json body = {{"runs", list}};
    if (!unreadable.empty()) body["unreadable"] = unreadable;
    sendJson(res, 200, body);
  }

  void submit(const std::string& text, HttpResponse& res) {
    lgp::JsonLimits limits;
    limits.max_bytes = max_body_;
    auto body = lgp::parseJson(text, limits);
    if (!body) return sendError(res, 400, "malformed JSON: " + body.error(), fieldOf(body.error()));
    lgp::Expected<PreparedRun> prepared = lgp::Status::error("not prepared");
    try {
      prepared = jobs_.prepare(*body);
    } catch (const json::exception& e) {
      // A value of a type or range the config reader did not expect: the request's fault.
      return sendError(res, 400, std::string("invalid run config: ") + e.what());
    }
    if (!prepared) return sendError(res, 400, prepared.error(), fieldOf(prepared.error()));
    bool queue_full = false;
    auto id = jobs_.submit(std::move(*prepared), &queue_full);
    if (queue_full) {
      res.setHeader("Retry-After", std::to_string(kQueueRetryAfterS));
      return sendError(res, 429, id.error());
    }
    if (!id) return sendError(res, 500, "store error: " + id.error());
    res.setHeader("Location", "/api/v1/runs/" + *id);
    sendJson(res, 201, {{"id", *id}, {"status", "queued"}, {"url", "/api/v1/runs/" + *id}});
  }

  void getRun(const std::string& id, HttpResponse& res) {
    auto r = loadRun(id, res);
    if (!r) return;
    json j = runSummary(*r, jobs_.isActive(id));
    j["config"] = r->config;
    if (r->inline_table) j["config"]["data"]["table"] = "(inline)";
    sendJson(res, 200, j);
  }

  void history(const std::string& id, HttpResponse& res) {
    if (!loadRun(id, res)) return;
    auto h = store_.history(id, kMaxHistoryRows);
    if (!h) return sendError(res, 500, "store error: " + h.error());
    json rows = json::array();
    for (const auto& p : *h)
      rows.push_back({{"t", p.t},
                      {"generation", p.generation},
                      {"evaluations", p.evaluations},
                      {"elapsed_s", p.elapsed_s},
                      {"best_error", numberOrNull(p.best_error)},
                      {"front_size", p.front_size},
                      {"event", p.event}});
    sendJson(res, 200, {{"id", id}, {"history", rows}});
  }

  void deleteRun(const std::string& id, HttpResponse& res) {
    auto r = jobs_.remove(id);
    if (!r) return sendError(res, 500, "store error: " + r.error());
    if (!*r) return sendError(res, 404, "no run " + id);
    sendJson(res, 200, {{"id", id}, {"deleted", true}});
  }

  void cancelRun(const std::string& id, HttpResponse& res) {
    auto r = loadRun(id, res);
    if (!r) return;
    if (r->status != RunStatus::Queued && r->status != RunStatus::Running)
      return sendError(res, 409, "run " + id + " is already " + std::string(toString(r->status)));
    auto cancelled = jobs_.cancel(id);
    if (!cancelled) return sendError(res, 500, "store error: " + cancelled.error());
    const bool active = *cancelled;
    auto after = loadRun(id, res);
    if (!after) return;
    std::string status(toString(after->status));
    if (active && after->status == RunStatus::Running) status = "cancelling";
    sendJson(res, 200, {{"id", id}, {"status", status}});
  }

  void front(const std::string& id, HttpResponse& res) {
    auto run = loadRun(id, res);
    if (!run) return;
    auto f = loadFront(id, res);
    if (!f) return;
    json j = std::move(f->front);
    if (auto r = j.find("references"); r != j.end()) *r = scoredReferences(*run, *r);
    j["lgpd"] = {{"run", id}, {"final", f->final}, {"generation", f->generation}};
    sendJson(res, 200, j);
  }

  // A front stored by this lgpd carries its references scored (the job scores them once, on
  // the run's table). One stored without scores (by an older lgpd, or with references as
  // given) is scored on the background thread, once per run; until that is done each
  // reference comes back with "pending": true and an "invalid" that says so.
  json scoredReferences(const RunRecord& run, const json& given) {
    if (!given.is_array() || given.empty()) return given;
    bool scored = true;  // already scored (every entry has an error or an "invalid")
    for (const auto& r : given)
      if (!r.is_object() || !(r.contains("error") || r.contains("invalid"))) scored = false;
    if (scored) return given;
    if (auto refs = jobs_.scoredReferences(run, kReferencesWait)) return *refs;
    json out = json::array();
    for (const auto& r : given) {
      json e = r.is_object() ? r : json{{"name", "(reference)"}};
      e["invalid"] = "being scored by lgpd; reload in a moment";
      e["pending"] = true;
      out.push_back(std::move(e));
    }
    return out;
  }

  // The member object of the front, or a 404.
  std::optional<json> memberOf(const json& front, size_t k, const std::string& id,
                               HttpResponse& res) {
    const auto& members = front.value("members", json::array());
    if (!members.is_array() || k >= members.size()) {
      sendError(res, 404,
                "run " + id + " has no front member " + std::to_string(k) + " (front has " +
                    std::to_string(members.is_array() ? members.size() : 0) + ")");
      return std::nullopt;
    }
    return members[k];
  }

  void member(const std::string& id, size_t k, HttpResponse& res) {
    if (!loadRun(id, res)) return;
    auto f = loadFront(id, res);
    if (!f) return;
    auto m = memberOf(f->front, k, id, res);
    if (!m) return;
    sendJson(res, 200, *m);
  }

  void code(const std::string& id, size_t k, const HttpRequest& req, HttpResponse& res) {
#ifdef LGP_HAVE_EMIT
    const std::string lang =
        req.hasParam("lang") ? req.param("lang") : std::string(lgp::emit::allLanguages()[0].name);
    const auto l = lgp::emit::languageFromString(lang);
    if (!l)
      return sendError(res, 400, "lang must be one of " + lgp::emit::languageChoices(), "lang");
    if (!loadRun(id, res)) return;
    auto f = loadFront(id, res);
    if (!f) return;
    if (!memberOf(f->front, k, id, res)) return;
    lgp::emit::EmitOptions opts;
    opts.source = "lgpd run " + id + " member " + std::to_string(k);
    auto text = lgp::emit::emitFromFront(f->front, k, *l, opts);
    if (!text)
      return sendError(res, 422, "cannot emit member " + std::to_string(k) + ": " + text.error());
    res.status = 200;
    res.setContent(*text, "text/plain; charset=utf-8");
#else
    (void)id, (void)k, (void)req;
    sendError(res, 503, "code export is not available: this lgpd was built without lgp::emit");
#endif
  }

  // GET /api/v1/languages: what the code export speaks (the page's tabs).
  void languages(HttpResponse& res) {
    json list = json::array();
#ifdef LGP_HAVE_EMIT
    for (const auto& l : lgp::emit::allLanguages())
      list.push_back({{"name", std::string(l.name)}, {"title", std::string(l.title)}});
#endif
    sendJson(res, 200, {{"languages", list}});
  }

  void residuals(const std::string& id, size_t k, const HttpRequest& req, HttpResponse& res) {
    auto run = loadRun(id, res);
    if (!run) return;
    auto f = loadFront(id, res);
    if (!f) return;
    if (!memberOf(f->front, k, id, res)) return;
    size_t max_rows = kDefaultResidualRows;
    if (req.hasParam("max_rows")) {
      auto v = parseIndex(req.param("max_rows"));
      if (!v || *v == 0)
        return sendError(res, 400, "max_rows must be a positive integer", "max_rows");
      max_rows = *v;
    }
    auto cfg = jobs_.config(*run);
    if (!cfg) return sendError(res, 500, "stored config no longer parses: " + cfg.error());
    // Loading (or generating) a table is not for an HTTP worker: the background thread does
    // it, and a client that asked too early is told to come back.
    auto loaded = jobs_.tableFor(*run, kTableWait);
    if (!loaded) {
      res.setHeader("Retry-After", std::to_string(kRetryAfterS));
      json body = {{"error", "the run's table is being loaded; retry in a moment"},
                   {"status", 503},
                   {"retry_after_s", kRetryAfterS}};
      return sendJson(res, 503, body);
    }
    auto& table = *loaded;
    if (!table) return sendError(res, 500, "cannot load the run's table: " + table.error());
    const lgp::Table& t = **table;
    // The table is read as it is now: its file may have been rewritten since the front was
    // stored, and the program would read columns that are not there (or other ones).
    if (!sameColumns(f->front, t))
      return sendError(
          res, 409,
          "the run's table no longer has the front's columns (the front: " + columnList(f->front) +
              "; the table now: " + columnList(t.input_names, t.output_names) + ")");
    auto program = lgp::memberProgram(f->front, k);
    if (!program) return sendError(res, 500, "cannot decode member: " + program.error());
    int block = cfg->eval.block_size;
    lgp::Dataset ds(t, block);
    lgp::Interpreter interp(block);
    auto out = interp.evaluate(*program, ds);

    const size_t rows = t.rows();
    const size_t stride = std::max<size_t>(1, (rows + max_rows - 1) / max_rows);
    json columns = json::object();
    for (size_t i = 0; i < t.numInputs(); ++i) {
      json col = json::array();
      for (size_t r = 0; r < rows; r += stride) col.push_back(t.inputs[i][r]);
      columns[t.input_names[i]] = std::move(col);
    }
    json outputs = json::array();
    for (size_t o = 0; o < t.numOutputs() && o < out.size(); ++o) {
      auto tr = lgp::TargetTransform::None;
      if (auto it = cfg->data.transforms.find(t.output_names[o]); it != cfg->data.transforms.end())
        tr = it->second;
      json resid = json::array();
      std::vector<double> pred(rows);
      for (size_t r = 0; r < rows; ++r) {
        pred[r] = lgp::invertTransform(tr, static_cast<double>(out[o][r]));
        if (r % stride == 0) resid.push_back(numberOrNull(pred[r] - t.outputs[o][r]));
      }
      // Every metric by its one definition (lgp/eval/metrics.hpp), the table's weights
      // included; null where a prediction is not finite.
      const lgp::OutputMetrics m =
          lgp::metricsOf(pred.data(), t.outputs[o].data(),
                         t.weights.empty() ? nullptr : t.weights.data(), rows,
                         cfg->objectives.rel_floor);
      json entry = {{"name", t.output_names[o]}, {"transform", std::string(lgp::toString(tr))}};
      for (const auto& metric : lgp::allMetrics())
        entry[std::string(metric.name)] = numberOrNull(m.*metric.field);
      entry["residual"] = std::move(resid);
      outputs.push_back(std::move(entry));
    }
    sendJson(res, 200,
             {{"id", id},
              {"member", k},
              {"rows", rows},
              {"stride", stride},
              {"precision", "float32 interpreter"},
              {"definition", "signed error = prediction - target, original scale"},
              {"inputs", t.input_names},
              {"columns", std::move(columns)},
              {"outputs", std::move(outputs)}});
  }

  Store& store_;
  JobManager& jobs_;
  std::string token_;
  std::vector<std::string> allowed_hosts_;
  std::vector<std::string> allowed_origins_;
  size_t max_body_ = 0;
};

}  // namespace

HttpHandlers makeApi(Store& store, JobManager& jobs) {
  // The handlers share the Api object and keep it alive.
  auto api = std::make_shared<Api>(store, jobs);
  HttpHandlers h;
  h.head = [api](const HttpRequest& req, HttpResponse& res) { api->head(req, res); };
  h.route = [api](const HttpRequest& req, HttpResponse& res) { api->dispatch(req, res); };
  h.default_headers = {{"X-Content-Type-Options", "nosniff"},
                       {"X-Frame-Options", "DENY"},
                       {"Cache-Control", "no-store"},
                       {"Referrer-Policy", "no-referrer"}};
  return h;
}

}  // namespace lgpd
