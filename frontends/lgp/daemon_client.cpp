#include "daemon_client.hpp"

#include <cstdio>
#include <cstdlib>
#include <fstream>

#ifdef LGP_HAVE_HTTPLIB
#include <httplib.h>
#endif

#include "lgp/config/json_reader.hpp"
#include "lgp/io/result.hpp"
#include "lgp/io/terminal_text.hpp"

namespace lgp::cli {

std::string daemonUrl(const std::string& flag) {
  std::string url = flag;
  if (url.empty())
    if (const char* env = std::getenv("LGP_DAEMON"); env && *env) url = env;
  if (url.empty()) url = kDefaultDaemonUrl;
  if (url.find("://") == std::string::npos) url = "http://" + url;
  while (url.size() > 8 && url.back() == '/') url.pop_back();
  return url;
}

nlohmann::json DaemonReply::json() const {
  // With the limits of every JSON lgp reads: a hostile daemon's 100k-deep answer would
  // overflow the stack when printed.
  auto j = parseJson(body);
  return j ? std::move(*j) : nlohmann::json();
}

std::string DaemonReply::errorMessage() const {
  auto j = json();
  // The server's text is shown as text (a hostile one may send escape sequences).
  if (j.is_object() && j.contains("error") && j["error"].is_string())
    return terminalSafe(j["error"].get<std::string>());
  return body.empty() ? "HTTP " + std::to_string(status) : terminalSafe(body.substr(0, 2000));
}

#ifdef LGP_HAVE_HTTPLIB

Expected<DaemonReply> daemonRequest(const std::string& url, const std::string& method,
                                    const std::string& path, const std::string& body) {
  httplib::Client client(url);
  if (!client.is_valid()) return Status::error("invalid daemon URL '" + url + "'");
  client.set_connection_timeout(5);
  client.set_read_timeout(60);
  httplib::Headers headers;
  if (const char* tok = std::getenv("LGP_DAEMON_TOKEN"); tok && *tok)
    headers.emplace("Authorization", std::string("Bearer ") + tok);
  if (method != "GET" && method != "POST" && method != "DELETE")
    return Status::error("unsupported method " + method);
  httplib::Result res = method == "GET"    ? client.Get(path, headers)
                        : method == "POST" ? client.Post(path, headers, body, "application/json")
                                           : client.Delete(path, headers);
  if (!res)
    return Status::error("cannot reach lgpd at " + url + " (" + httplib::to_string(res.error()) +
                         "); is it running? (--daemon URL or $LGP_DAEMON)");
  DaemonReply r;
  r.status = res->status;
  r.body = res->body;
  return r;
}

#else

Expected<DaemonReply> daemonRequest(const std::string&, const std::string&, const std::string&,
                                    const std::string&) {
  return Status::error("this lgp was built without cpp-httplib (libcpp-httplib-dev)");
}

#endif

Expected<nlohmann::json> daemonGetJson(const std::string& url, const std::string& path) {
  auto r = daemonRequest(url, "GET", path);
  if (!r) return r.status();
  if (r->status != 200)
    return Status::error(r->errorMessage() + " (HTTP " + std::to_string(r->status) + ")");
  return r->json();
}

int daemonFront(const std::string& url, const std::string& run, const std::string& out_path,
                bool json) {
  auto got = daemonGetJson(url, "/api/v1/runs/" + run + "/front");
  if (!got) {
    std::fprintf(stderr, "error: %s\n", got.error().c_str());
    return 1;
  }
  auto front = *got;
  // Checked as `lgp front` checks a file: the table's names reach the terminal.
  if (auto s = checkFrontJson(front, url + " run " + terminalSafe(run) + " front"); !s) {
    std::fprintf(stderr, "error: %s\n", terminalSafe(s.message()).c_str());
    return 1;
  }
  if (!out_path.empty()) {
    auto s = writeFrontJson(front, out_path);
    if (!s) {
      std::fprintf(stderr, "error: %s\n", s.message().c_str());
      return 1;
    }
  }
  if (json) {
    std::printf("%s\n", terminalJson(front).c_str());
  } else {
    const auto& info = front.value("lgpd", nlohmann::json::object());
    const auto final = info.find("final"), gen = info.find("generation");
    std::printf("run %s: %s front at generation %s\n", terminalSafe(run).c_str(),
                final != info.end() && *final == true ? "final" : "live",
                gen != info.end() && gen->is_number_integer() ? gen->dump().c_str() : "?");
    std::printf("%s", formatFrontTable(front).c_str());
  }
  return 0;
}

}  // namespace lgp::cli
