// The `lgp` CLI's side of lgpd: a small HTTP client for `lgp submit`, `lgp status` and
// `lgp front RUN --daemon URL`. The daemon URL comes from --daemon, else $LGP_DAEMON, else
// http://127.0.0.1:8737; a bearer token, when the daemon needs one, from $LGP_DAEMON_TOKEN.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "lgp/core/status.hpp"

namespace lgp::cli {

inline constexpr const char* kDefaultDaemonUrl = "http://127.0.0.1:8737";

// --daemon value if non-empty, else $LGP_DAEMON, else kDefaultDaemonUrl. A missing scheme
// means http://.
std::string daemonUrl(const std::string& flag);

struct DaemonReply {
  int status = 0;    // HTTP status
  std::string body;  // raw body
  // The body as JSON (null when it is not JSON).
  nlohmann::json json() const;
  // The daemon's {"error": ...} message, or the body.
  std::string errorMessage() const;
};

// One request; the error says when the daemon cannot be reached. method: GET, POST, DELETE.
Expected<DaemonReply> daemonRequest(const std::string& url, const std::string& method,
                                    const std::string& path, const std::string& body = "");

// `lgp front RUN --daemon URL`: fetches the run's front, prints it as a table
// (formatFrontTable), or as raw JSON when `json` is set; also saves it to `out_path` when
// non-empty (a front.json usable by `lgp front`/`lgp emit`). Returns the exit code
// (0 ok, 1 daemon or run error).
int daemonFront(const std::string& url, const std::string& run, const std::string& out_path = "",
                bool json = false);

// GET `path` and expect 200 with a JSON body; the error names the daemon's reason and status.
Expected<nlohmann::json> daemonGetJson(const std::string& url, const std::string& path);

}  // namespace lgp::cli
