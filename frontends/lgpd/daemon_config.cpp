#include "daemon_config.hpp"

#include <arpa/inet.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <tuple>

#include "lgp/config/json_reader.hpp"
#include "lgp/core/program.hpp"

namespace lgpd {

using lgp::Expected;
using lgp::Status;

uint64_t DaemonConfig::runMemoryBytes() const {
  if (max_run_memory_mb > 0) return static_cast<uint64_t>(max_run_memory_mb) << 20;
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return uint64_t{1} << 32;  // unknown: 4 GiB
  return static_cast<uint64_t>(pages) * static_cast<uint64_t>(page) / 2;
}

Status DaemonConfig::validate() const {
  if (data_dir.empty()) return Status::error("/data_dir: required (--data-dir)");
  if (max_jobs < 1 || max_jobs > 256) return Status::error("/max_jobs: must be in [1, 256]");
  if (!(checkpoint_interval_s > 0))
    return Status::error("/checkpoint_interval_s: must be a number > 0");
  if (!(progress_interval_s >= 0))
    return Status::error("/progress_interval_s: must be a number >= 0");
  if (!(front_interval_s >= 0)) return Status::error("/front_interval_s: must be a number >= 0");
  if (max_body_bytes < 1024) return Status::error("/max_body_bytes: must be >= 1024");
  if (http_threads < 2 || http_threads > 256)
    return Status::error("/http_threads: must be in [2, 256]");
  if (mpi.launcher.empty()) return Status::error("/mpi/launcher: must be a non-empty string");
  if (mpi.max_np < 1 || mpi.max_np > 4096)
    return Status::error("/mpi/max_np: must be in [1, 4096]");
  if (!(mpi.stop_grace_s > 0)) return Status::error("/mpi/stop_grace_s: must be a number > 0");
  if (max_connections < 16 || max_connections > 1000000)
    return Status::error("/max_connections: must be in [16, 1000000]");
  if (max_connections_per_client != 0 &&
      (max_connections_per_client < 1 || max_connections_per_client > max_connections))
    return Status::error("/max_connections_per_client: must be in [1, max_connections] (" +
                         std::to_string(max_connections) + "), or 0 for max_connections / 2 (got " +
                         std::to_string(max_connections_per_client) + ")");
  for (auto [key, v, lo, hi] :
       {std::tuple{"read_timeout_s", read_timeout_s, 0.1, 3600.0},
        std::tuple{"request_timeout_s", request_timeout_s, 1.0, 86400.0},
        std::tuple{"write_timeout_s", write_timeout_s, 1.0, 86400.0},
        std::tuple{"keep_alive_timeout_s", keep_alive_timeout_s, 1.0, 3600.0}})
    if (!(v >= lo && v <= hi))
      return Status::error(std::string("/") + key + ": must be a number in [" +
                           lgp::formatDouble(lo) + ", " + lgp::formatDouble(hi) + "] (got " +
                           lgp::formatDouble(v) + ")");
  if (max_queued_runs < 1 || max_queued_runs > 1000000)
    return Status::error("/max_queued_runs: must be in [1, 1000000]");
  if (max_run_memory_mb < 0) return Status::error("/max_run_memory_mb: must be >= 0");
  if (keep_alive_max_requests < 1 || keep_alive_max_requests > 100000)
    return Status::error("/keep_alive_max_requests: must be in [1, 100000]");
  auto addr = parseListen(listen);
  if (!addr) return Status::error("/listen: " + addr.error());
  for (size_t n = 0; n < allowed_hosts.size(); ++n) {
    const std::string& h = allowed_hosts[n];
    auto hp = parseHostHeader(h);
    if (h != "*" && (!hp || hp->port != -1 || hp->host != h))
      return Status::error("/allowed_hosts/" + std::to_string(n) +
                           ": must be a lower-case host name or IP address without a port "
                           "(IPv6 in brackets), or \"*\" (got '" +
                           h + "')");
  }
  for (size_t n = 0; n < allowed_origins.size(); ++n) {
    const std::string& o = allowed_origins[n];
    auto parsed = parseOrigin(o);
    if (!parsed ||
        o != parsed->scheme + "://" + parsed->authority.host +
                 (parsed->authority.port >= 0 ? ":" + std::to_string(parsed->authority.port) : ""))
      return Status::error("/allowed_origins/" + std::to_string(n) +
                           ": must be a lower-case origin such as \"http://name:8080\" "
                           "(scheme http or https, no path; got '" +
                           o + "')");
  }
  if (auto s = checkToken(token); !s) return s;
  if (!isLoopbackHost(addr->host) && token.empty())
    return Status::error("/token: a non-loopback listen address (" + addr->host +
                         ") requires a bearer token of at least " +
                         std::to_string(kMinTokenCharacters) + " non-space characters");
  return Status::ok();
}

int DaemonConfig::connectionsPerClient() const {
  return max_connections_per_client > 0 ? max_connections_per_client
                                        : std::max(1, max_connections / 2);
}

Status checkToken(const std::string& token) {
  if (token.empty()) return Status::ok();
  size_t visible = 0;
  for (unsigned char c : token) {
    if (c < 0x20 || c == 0x7f)
      return Status::error("/token: control characters are not allowed in a token");
    if (c != ' ') ++visible;
  }
  if (visible < kMinTokenCharacters)
    return Status::error("/token: must have at least " + std::to_string(kMinTokenCharacters) +
                         " non-space characters (has " + std::to_string(visible) + ")");
  return Status::ok();
}

Expected<ListenAddress> parseListen(const std::string& s) {
  ListenAddress a;
  std::string port;
  if (!s.empty() && s.front() == '[') {
    auto close = s.find(']');
    if (close == std::string::npos || close + 1 >= s.size() || s[close + 1] != ':')
      return Status::error("expected [ipv6]:port, got '" + s + "'");
    a.host = s.substr(1, close - 1);
    port = s.substr(close + 2);
  } else {
    auto colon = s.rfind(':');
    if (colon == std::string::npos || colon == 0)
      return Status::error("expected host:port, got '" + s + "'");
    a.host = s.substr(0, colon);
    port = s.substr(colon + 1);
  }
  if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos)
    return Status::error("bad port in '" + s + "'");
  a.port = std::stoi(port);
  if (a.port > 65535) return Status::error("port out of range in '" + s + "'");
  return a;
}

bool isLoopbackHost(const std::string& host) {
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) {
    static const in6_addr kLoop = IN6ADDR_LOOPBACK_INIT;
    return std::memcmp(&v6, &kLoop, sizeof v6) == 0;
  }
  return false;
}

namespace {

bool isHostChar(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '_';
}

std::string toLower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

std::optional<HostPort> parseHostHeader(const std::string& value) {
  HostPort hp;
  std::string port;
  if (!value.empty() && value.front() == '[') {
    const auto close = value.find(']');
    if (close == std::string::npos) return std::nullopt;
    const std::string v6 = value.substr(1, close - 1);
    in6_addr a{};
    if (inet_pton(AF_INET6, v6.c_str(), &a) != 1) return std::nullopt;
    hp.host = toLower(value.substr(0, close + 1));
    if (close + 1 < value.size()) {
      if (value[close + 1] != ':') return std::nullopt;
      port = value.substr(close + 2);
      if (port.empty()) return std::nullopt;
    }
  } else {
    const auto colon = value.find(':');
    hp.host = toLower(value.substr(0, colon));
    if (colon != std::string::npos) {
      port = value.substr(colon + 1);
      if (port.empty()) return std::nullopt;
    }
    if (hp.host.empty() || hp.host.size() > 253 ||
        !std::all_of(hp.host.begin(), hp.host.end(), isHostChar))
      return std::nullopt;
  }
  if (!port.empty()) {
    if (port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos)
      return std::nullopt;
    hp.port = std::stoi(port);
    if (hp.port > 65535) return std::nullopt;
  }
  return hp;
}

std::optional<Origin> parseOrigin(const std::string& value) {
  const auto sep = value.find("://");
  if (sep == std::string::npos) return std::nullopt;
  Origin o;
  o.scheme = toLower(value.substr(0, sep));
  if (o.scheme != "http" && o.scheme != "https") return std::nullopt;
  auto hp = parseHostHeader(value.substr(sep + 3));
  if (!hp) return std::nullopt;
  o.authority = *hp;
  return o;
}

namespace {

template <class F>
Status field(const nlohmann::json& j, const char* key, F&& assign) {
  auto it = j.find(key);
  if (it == j.end()) return Status::ok();
  return assign(*it, lgp::jsonPath("", key));
}

Status number(const nlohmann::json& v, const std::string& path, double& out) {
  if (!v.is_number()) return Status::error(path + ": must be a number");
  out = v.get<double>();
  return Status::ok();
}

Status integer(const nlohmann::json& v, const std::string& path, int64_t lo, int64_t& out) {
  if (!v.is_number_integer() || v.get<int64_t>() < lo)
    return Status::error(path + ": must be an integer >= " + std::to_string(lo));
  out = v.get<int64_t>();
  return Status::ok();
}

Status string(const nlohmann::json& v, const std::string& path, std::string& out) {
  if (!v.is_string()) return Status::error(path + ": must be a string");
  out = v.get<std::string>();
  return Status::ok();
}

Status stringArray(const nlohmann::json& v, const std::string& path,
                   std::vector<std::string>& out) {
  if (!v.is_array()) return Status::error(path + ": must be an array of strings");
  out.clear();
  for (size_t n = 0; n < v.size(); ++n) {
    if (!v[n].is_string())
      return Status::error(lgp::jsonError(lgp::jsonPath(path, n), "must be a string"));
    out.push_back(v[n].get<std::string>());
  }
  return Status::ok();
}

Status applyMpiJson(const nlohmann::json& j, const std::string& path, MpiDaemonConfig& m) {
  if (!j.is_object()) return Status::error(path + ": must be an object");
  lgp::JsonObjectReader keys(j, path);
  keys.allow({"launcher", "hostfile", "args", "max_np", "lgp", "stop_grace_s"});
  if (auto k = keys.unknownKey()) return Status::error(lgp::jsonError(*k, "unknown key"));
  auto sub = [&](const char* key) { return lgp::jsonPath(path, key); };
  std::string str;
  int64_t i = 0;
  if (auto it = j.find("launcher"); it != j.end()) {
    if (!it->is_string() || it->get<std::string>().empty())
      return Status::error(sub("launcher") + ": must be a non-empty string");
    m.launcher = it->get<std::string>();
  }
  if (auto it = j.find("hostfile"); it != j.end()) {
    if (auto s = string(*it, sub("hostfile"), str); !s) return s;
    m.hostfile = str;
  }
  if (auto it = j.find("args"); it != j.end())
    if (auto s = stringArray(*it, sub("args"), m.args); !s) return s;
  if (auto it = j.find("max_np"); it != j.end()) {
    if (auto s = integer(*it, sub("max_np"), 1, i); !s) return s;
    m.max_np = static_cast<int>(std::min<int64_t>(i, 1 << 20));
  }
  if (auto it = j.find("lgp"); it != j.end()) {
    if (auto s = string(*it, sub("lgp"), str); !s) return s;
    m.lgp = str;
  }
  if (auto it = j.find("stop_grace_s"); it != j.end())
    if (auto s = number(*it, sub("stop_grace_s"), m.stop_grace_s); !s) return s;
  return Status::ok();
}

}  // namespace

Status applyDaemonConfigJson(const nlohmann::json& j, DaemonConfig& cfg) {
  if (!j.is_object())
    return Status::error(lgp::jsonError("", "the daemon config must be a JSON object"));
  lgp::JsonObjectReader keys(j, "");
  keys.allow({"data_dir",
              "listen",
              "max_jobs",
              "checkpoint_interval_s",
              "progress_interval_s",
              "front_interval_s",
              "token",
              "max_body_bytes",
              "data_base_dir",
              "allowed_data_dirs",
              "http_threads",
              "max_connections",
              "max_connections_per_client",
              "read_timeout_s",
              "request_timeout_s",
              "write_timeout_s",
              "keep_alive_timeout_s",
              "keep_alive_max_requests",
              "allowed_hosts",
              "allowed_origins",
              "max_queued_runs",
              "max_run_memory_mb",
              "mpi"});
  if (auto k = keys.unknownKey()) return Status::error(lgp::jsonError(*k, "unknown key"));
  Status s;
  std::string str;
  int64_t i = 0;
  if (!(s = field(j, "data_dir", [&](auto& v, auto p) {
          auto r = string(v, p, str);
          if (r) cfg.data_dir = str;
          return r;
        })))
    return s;
  if (!(s = field(j, "listen", [&](auto& v, auto p) { return string(v, p, cfg.listen); })))
    return s;
  if (!(s = field(j, "max_jobs", [&](auto& v, auto p) {
          auto r = integer(v, p, 1, i);
          if (r) cfg.max_jobs = static_cast<int>(std::min<int64_t>(i, 1 << 20));
          return r;
        })))
    return s;
  if (!(s = field(j, "max_queued_runs", [&](auto& v, auto p) {
          auto r = integer(v, p, 1, i);
          if (r) cfg.max_queued_runs = static_cast<int>(std::min<int64_t>(i, 1 << 30));
          return r;
        })))
    return s;
  if (!(s = field(j, "max_run_memory_mb", [&](auto& v, auto p) {
          auto r = integer(v, p, 0, i);
          if (r) cfg.max_run_memory_mb = i;
          return r;
        })))
    return s;
  if (!(s = field(j, "checkpoint_interval_s",
                  [&](auto& v, auto p) { return number(v, p, cfg.checkpoint_interval_s); })))
    return s;
  if (!(s = field(j, "progress_interval_s",
                  [&](auto& v, auto p) { return number(v, p, cfg.progress_interval_s); })))
    return s;
  if (!(s = field(j, "front_interval_s",
                  [&](auto& v, auto p) { return number(v, p, cfg.front_interval_s); })))
    return s;
  if (!(s = field(j, "token", [&](auto& v, auto p) { return string(v, p, cfg.token); }))) return s;
  if (!(s = field(j, "max_body_bytes", [&](auto& v, auto p) {
          auto r = integer(v, p, 1024, i);
          if (r) cfg.max_body_bytes = static_cast<size_t>(i);
          return r;
        })))
    return s;
  if (!(s = field(j, "data_base_dir", [&](auto& v, auto p) {
          auto r = string(v, p, str);
          if (r) cfg.data_base_dir = str;
          return r;
        })))
    return s;
  if (!(s = field(j, "allowed_data_dirs", [&](auto& v, auto p) {
          std::vector<std::string> dirs;
          auto r = stringArray(v, p, dirs);
          if (r) cfg.allowed_data_dirs.assign(dirs.begin(), dirs.end());
          return r;
        })))
    return s;
  if (!(s = field(j, "allowed_hosts",
                  [&](auto& v, auto p) { return stringArray(v, p, cfg.allowed_hosts); })))
    return s;
  if (!(s = field(j, "allowed_origins",
                  [&](auto& v, auto p) { return stringArray(v, p, cfg.allowed_origins); })))
    return s;
  if (!(s = field(j, "http_threads", [&](auto& v, auto p) {
          auto r = integer(v, p, 2, i);
          if (r) cfg.http_threads = static_cast<int>(std::min<int64_t>(i, 1 << 20));
          return r;
        })))
    return s;
  auto intField = [&](const char* key, int64_t lo, int& out) {
    return field(j, key, [&](auto& v, auto p) {
      auto r = integer(v, p, lo, i);
      if (r) out = static_cast<int>(std::min<int64_t>(i, 1 << 20));
      return r;
    });
  };
  if (!(s = intField("max_connections", 1, cfg.max_connections))) return s;
  if (!(s = intField("max_connections_per_client", 0, cfg.max_connections_per_client))) return s;
  if (!(s = intField("keep_alive_max_requests", 1, cfg.keep_alive_max_requests))) return s;
  for (auto [key, out] : {std::pair<const char*, double*>{"read_timeout_s", &cfg.read_timeout_s},
                          {"request_timeout_s", &cfg.request_timeout_s},
                          {"write_timeout_s", &cfg.write_timeout_s},
                          {"keep_alive_timeout_s", &cfg.keep_alive_timeout_s}})
    if (!(s = field(j, key, [&](auto& v, auto p) { return number(v, p, *out); }))) return s;
  if (!(s = field(j, "mpi", [&](auto& v, auto p) { return applyMpiJson(v, p, cfg.mpi); })))
    return s;
  return Status::ok();
}

void resolveConfigFilePaths(DaemonConfig& cfg, const std::filesystem::path& dir) {
  auto resolve = [&](std::filesystem::path& p) {
    if (!p.empty() && p.is_relative()) p = (dir / p).lexically_normal();
  };
  auto resolveIfPath = [&](auto& p) {
    if (std::filesystem::path(p).string().find('/') == std::string::npos) return;
    std::filesystem::path q(p);
    resolve(q);
    p = q.string();
  };
  resolve(cfg.data_dir);
  resolve(cfg.data_base_dir);
  for (auto& d : cfg.allowed_data_dirs) resolve(d);
  resolve(cfg.mpi.hostfile);
  resolveIfPath(cfg.mpi.launcher);
  resolveIfPath(cfg.mpi.lgp);
}

}  // namespace lgpd
