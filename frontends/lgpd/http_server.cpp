#include "http_server.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <microhttpd.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace lgpd {

namespace {

using Clock = std::chrono::steady_clock;

constexpr size_t kMaxTarget = 8192;                     // request target (414 past it)
constexpr size_t kConnectionMemory = size_t{80} << 10;  // request line, headers, buffers
constexpr auto kSweepEvery = std::chrono::milliseconds(50);
constexpr int kReservedDescriptors = 64;  // the store, jobs, logs: not for connections

Clock::duration toDuration(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// libmicrohttpd's timeouts are whole seconds.
unsigned wholeSeconds(double s) {
  return static_cast<unsigned>(std::max(1.0, std::ceil(s)));
}

// "1.2.3.4" / "2001:db8::1"; an IPv4-mapped IPv6 address is written as IPv4.
std::string addressText(const sockaddr* sa) {
  char buf[INET6_ADDRSTRLEN] = {0};
  if (sa == nullptr) return "";
  if (sa->sa_family == AF_INET) {
    ::inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(sa)->sin_addr, buf, sizeof buf);
  } else if (sa->sa_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(sa);
    if (IN6_IS_ADDR_V4MAPPED(&a->sin6_addr))
      ::inet_ntop(AF_INET, &a->sin6_addr.s6_addr[12], buf, sizeof buf);
    else
      ::inet_ntop(AF_INET6, &a->sin6_addr, buf, sizeof buf);
  }
  return buf;
}

// The unit the per-client bound counts: an IPv4 address, or the /64 of an IPv6 address (one
// host usually holds a whole /64).
std::string clientKey(const std::string& ip) {
  in6_addr v6{};
  if (ip.find(':') == std::string::npos || ::inet_pton(AF_INET6, ip.c_str(), &v6) != 1) return ip;
  char buf[40];
  std::snprintf(buf, sizeof buf, "%02x%02x:%02x%02x:%02x%02x:%02x%02x::/64", v6.s6_addr[0],
                v6.s6_addr[1], v6.s6_addr[2], v6.s6_addr[3], v6.s6_addr[4], v6.s6_addr[5],
                v6.s6_addr[6], v6.s6_addr[7]);
  return buf;
}

std::string errorJson(int status, const std::string& msg) {
  // `msg` is ours (no quotes or backslashes), so no escaping is needed.
  return "{\"error\":\"" + msg + "\",\"status\":" + std::to_string(status) + "}";
}

// A whole response written straight to the socket, for the two answers that libmicrohttpd
// cannot send itself: before it has read a request (429) and in the middle of a body (413).
// Both end the connection; the answer is small enough for the socket's buffer.
void sendRawAnswer(int fd, int status, const char* reason, const std::string& body,
                   const std::string& extra_headers) {
  const std::string msg = "HTTP/1.1 " + std::to_string(status) + " " + reason +
                          "\r\nContent-Type: application/json\r\nConnection: close\r\n" +
                          extra_headers + "Content-Length: " + std::to_string(body.size()) +
                          "\r\n\r\n" + body;
  (void)!::send(fd, msg.data(), msg.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

}  // namespace

struct HttpServer::Connection {
  enum class Phase { Reading, Routing, Writing, Idle };
  int fd = -1;
  std::string ip, key;
  Phase phase = Phase::Reading;
  Clock::time_point deadline;  // of the phase (none while routing)
  int requests = 0;            // answered on this connection
  bool refused = false;        // over the per-client bound: answered 429 at once
  bool ended = false;          // shut down by the sweeper
  uint64_t events = 0;         // callbacks seen, to tell a stuck connection from a busy one
  uint64_t hangup_events = ~uint64_t{0};  // `events` when the client was seen half-closed
};

struct HttpServer::Exchange {
  Connection* conn = nullptr;
  size_t target_length = 0;
  bool headers_seen = false;
  bool dispatched = false;
  HttpRequest req;
  HttpResponse res;
};

// libmicrohttpd's callbacks (C function pointers); `cls` is the server.
struct Callbacks {
  static HttpServer::Connection* connectionOf(MHD_Connection* c) {
    const MHD_ConnectionInfo* info = MHD_get_connection_info(c, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    return info ? static_cast<HttpServer::Connection*>(info->socket_context) : nullptr;
  }

  static void log(void*, const char* fmt, va_list ap) {
    char buf[512];
    std::vsnprintf(buf, sizeof buf, fmt, ap);
    std::string s = buf;
    while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
    spdlog::debug("http: {}", s);
  }

  static void connection(void* cls, MHD_Connection* c, void** socket_context,
                         MHD_ConnectionNotificationCode code) {
    auto* server = static_cast<HttpServer*>(cls);
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
      auto conn = std::make_unique<HttpServer::Connection>();
      if (const auto* fd = MHD_get_connection_info(c, MHD_CONNECTION_INFO_CONNECTION_FD))
        conn->fd = fd->connect_fd;
      if (const auto* a = MHD_get_connection_info(c, MHD_CONNECTION_INFO_CLIENT_ADDRESS))
        conn->ip = addressText(a->client_addr);
      conn->key = clientKey(conn->ip);
      conn->deadline = Clock::now() + toDuration(server->limits_.request_timeout_s);
      std::lock_guard lock(server->conn_mutex_);
      int& open = server->per_client_[conn->key];
      if (open >= server->limits_.max_connections_per_client) {
        // Nothing of the request is read: answer and end it at once (libmicrohttpd then
        // reads the end of the stream and closes), so the rejection costs nothing.
        conn->refused = true;
        sendRawAnswer(
            conn->fd, 429, "Too Many Requests",
            errorJson(429, "too many connections from " + conn->ip + " (at most " +
                               std::to_string(server->limits_.max_connections_per_client) +
                               " at once)"),
            "Retry-After: 1\r\n");
        ::shutdown(conn->fd, SHUT_RDWR);
        spdlog::debug("connection from {} refused: {} already open", conn->ip, open);
      } else {
        ++open;
      }
      *socket_context = conn.get();
      server->connections_.emplace(conn.get(), std::move(conn));
    } else if (code == MHD_CONNECTION_NOTIFY_CLOSED) {
      // Called before libmicrohttpd closes the descriptor: once the entry is gone the sweeper
      // can no longer shut down a descriptor number that a new connection may reuse.
      auto* conn = static_cast<HttpServer::Connection*>(*socket_context);
      std::lock_guard lock(server->conn_mutex_);
      auto it = server->connections_.find(conn);
      if (it == server->connections_.end()) return;
      if (!conn->refused) {
        auto pc = server->per_client_.find(conn->key);
        if (pc != server->per_client_.end() && --pc->second <= 0) server->per_client_.erase(pc);
      }
      server->connections_.erase(it);
      *socket_context = nullptr;
    }
  }

  // The request line has arrived: the request's state begins here.
  static void* uriLog(void* cls, const char* uri, MHD_Connection* c) {
    auto* server = static_cast<HttpServer*>(cls);
    auto* x = new HttpServer::Exchange();
    x->conn = connectionOf(c);
    x->target_length = uri ? std::strlen(uri) : 0;
    if (x->conn) {
      std::lock_guard lock(server->conn_mutex_);
      x->conn->phase = HttpServer::Connection::Phase::Reading;
      ++x->conn->events;
      x->conn->deadline =
          std::min(x->conn->deadline, Clock::now() + toDuration(server->limits_.request_timeout_s));
    }
    MHD_set_connection_option(c, MHD_CONNECTION_OPTION_TIMEOUT,
                              wholeSeconds(server->limits_.read_timeout_s));
    return x;
  }

  static void completed(void* cls, MHD_Connection* c, void** con_cls,
                        MHD_RequestTerminationCode toe) {
    auto* server = static_cast<HttpServer*>(cls);
    auto* x = static_cast<HttpServer::Exchange*>(*con_cls);
    *con_cls = nullptr;
    if (x && x->conn) {
      std::lock_guard lock(server->conn_mutex_);
      x->conn->phase = HttpServer::Connection::Phase::Idle;
      ++x->conn->events;
      // An idle connection has keep_alive_timeout_s for the next request to start (counted
      // by libmicrohttpd) and request_timeout_s for it to arrive.
      x->conn->deadline = Clock::now() + toDuration(server->limits_.keep_alive_timeout_s) +
                          toDuration(server->limits_.request_timeout_s);
    }
    delete x;
    if (toe == MHD_REQUEST_TERMINATED_COMPLETED_OK)
      MHD_set_connection_option(c, MHD_CONNECTION_OPTION_TIMEOUT,
                                wholeSeconds(server->limits_.keep_alive_timeout_s));
  }

  static MHD_Result collect(void* cls, MHD_ValueKind, const char* key, const char* value) {
    auto* out = static_cast<std::vector<std::pair<std::string, std::string>>*>(cls);
    out->emplace_back(key ? key : "", value ? value : "");
    return MHD_YES;
  }

  static MHD_Result queue(HttpServer* server, MHD_Connection* c, HttpServer::Exchange* x) {
    HttpResponse& res = x->res;
    {
      std::lock_guard lock(server->conn_mutex_);
      if (x->conn) {
        ++x->conn->requests;
        if (x->conn->requests >= server->limits_.keep_alive_max_requests) res.close = true;
        x->conn->phase = HttpServer::Connection::Phase::Writing;
        x->conn->deadline = Clock::now() + toDuration(server->limits_.write_timeout_s);
      }
    }
    MHD_Response* r = MHD_create_response_from_buffer(
        res.body.size(), const_cast<char*>(res.body.data()), MHD_RESPMEM_MUST_COPY);
    if (r == nullptr) return MHD_NO;
    for (const auto& [k, v] : server->handlers_.default_headers)
      if (!res.hasHeader(k)) MHD_add_response_header(r, k.c_str(), v.c_str());
    for (const auto& [k, v] : res.headers)
      if (strcasecmp(k.c_str(), "Connection") != 0)
        MHD_add_response_header(r, k.c_str(), v.c_str());
    if (res.close) MHD_add_response_header(r, "Connection", "close");
    const MHD_Result ok = MHD_queue_response(c, static_cast<unsigned>(res.status), r);
    MHD_destroy_response(r);
    spdlog::debug("{} {} {} -> {}", x->req.remote_addr, x->req.method, x->req.path.substr(0, 200),
                  res.status);
    return ok;
  }

  static MHD_Result access(void* cls, MHD_Connection* c, const char* url, const char* method,
                           const char*, const char* upload_data, size_t* upload_size,
                           void** con_cls) {
    auto* server = static_cast<HttpServer*>(cls);
    auto* x = static_cast<HttpServer::Exchange*>(*con_cls);
    if (x == nullptr || x->conn == nullptr || x->conn->refused) return MHD_NO;
    if (!x->headers_seen) {
      x->headers_seen = true;
      x->req.method = method ? method : "";
      x->req.path = url ? url : "";
      x->req.remote_addr = x->conn->ip;
      MHD_get_connection_values(c, MHD_HEADER_KIND, &collect, &x->req.headers);
      MHD_get_connection_values(c, MHD_GET_ARGUMENT_KIND, &collect, &x->req.params);
      if (x->target_length > kMaxTarget) {
        x->res.status = 414;
        x->res.setContent(errorJson(414, "request target longer than 8192 bytes"),
                          "application/json");
        x->res.close = true;
      } else {
        server->callHandler(server->handlers_.head, x->req, x->res);
      }
      // An answer before the body: with a body announced it goes now, libmicrohttpd then
      // reads none of it and closes the connection; without one it waits for the end of the
      // request, and the connection may be kept.
      if (x->res.answered() && x->req.announcesBody()) return queue(server, c, x);
      return MHD_YES;
    }
    if (*upload_size != 0) {
      if (x->req.body.size() + *upload_size > server->limits_.max_request_bytes) {
        // libmicrohttpd queues no answer in the middle of a body: write it and close.
        sendRawAnswer(x->conn->fd, 413, "Content Too Large",
                      errorJson(413, "request body larger than max_body_bytes (" +
                                         std::to_string(server->limits_.max_request_bytes) + ")"),
                      "");
        spdlog::debug("{} {} {} -> 413 (body over the limit)", x->req.remote_addr, x->req.method,
                      x->req.path);
        return MHD_NO;
      }
      x->req.body.append(upload_data, *upload_size);
      *upload_size = 0;
      return MHD_YES;
    }
    if (x->res.answered()) return queue(server, c, x);
    if (x->dispatched) return MHD_YES;
    x->dispatched = true;
    {
      std::lock_guard lock(server->conn_mutex_);
      x->conn->phase = HttpServer::Connection::Phase::Routing;
      ++x->conn->events;
    }
    // The connection waits, without the event thread, until a worker has the answer.
    MHD_suspend_connection(c);
    server->dispatch(c, x);
    return MHD_YES;
  }
};

HttpServer::HttpServer(HttpLimits limits, HttpHandlers handlers)
    : limits_(limits), handlers_(std::move(handlers)) {
  limits_.workers = std::max(1, limits_.workers);
  limits_.max_connections = std::max(1, limits_.max_connections);
  limits_.max_connections_per_client = std::max(1, limits_.max_connections_per_client);
  limits_.keep_alive_max_requests = std::max(1, limits_.keep_alive_max_requests);
}

HttpServer::~HttpServer() {
  stop();
}

void HttpServer::callHandler(const HttpHandlers::Handler& h, const HttpRequest& req,
                             HttpResponse& res) {
  if (!h) return;
  try {
    h(req, res);
  } catch (const std::exception& e) {
    spdlog::error("{} {}: {}", req.method, req.path, e.what());
    res = HttpResponse{};
    res.status = 500;
    res.setContent(errorJson(500, "internal error"), "application/json");
  } catch (...) {
    spdlog::error("{} {}: unknown exception", req.method, req.path);
    res = HttpResponse{};
    res.status = 500;
    res.setContent(errorJson(500, "internal error"), "application/json");
  }
}

void HttpServer::dispatch(MHD_Connection* c, Exchange* x) {
  {
    std::lock_guard lock(work_mutex_);
    if (!stopping_) {
      work_.push_back([this, c, x] {
        callHandler(handlers_.route, x->req, x->res);
        if (!x->res.answered()) {
          x->res.status = 500;
          x->res.setContent(errorJson(500, "internal error (no answer)"), "application/json");
        }
        MHD_resume_connection(c);
      });
      work_cv_.notify_one();
      return;
    }
  }
  x->res.status = 503;
  x->res.setContent(errorJson(503, "lgpd is stopping"), "application/json");
  x->res.close = true;
  MHD_resume_connection(c);
}

void HttpServer::workerLoop() {
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock lock(work_mutex_);
      work_cv_.wait(lock, [this] { return stopping_ || !work_.empty(); });
      if (work_.empty()) return;  // stopping, and every queued request answered
      job = std::move(work_.front());
      work_.pop_front();
    }
    job();
  }
}

// True when the client has closed its sending side and nothing it sent is left unread.
static bool clientHalfClosed(int fd) {
  pollfd p{fd, POLLRDHUP, 0};
  if (::poll(&p, 1, 0) <= 0 || !(p.revents & (POLLRDHUP | POLLHUP | POLLERR))) return false;
  int unread = 0;
  return ::ioctl(fd, FIONREAD, &unread) == 0 && unread == 0;
}

void HttpServer::sweepLoop() {
  std::unique_lock lock(conn_mutex_);
  while (!sweep_stop_) {
    sweep_cv_.wait_for(lock, kSweepEvery);
    const auto now = Clock::now();
    for (auto& [ptr, conn] : connections_) {
      if (conn->ended || conn->refused || conn->phase == Connection::Phase::Routing) continue;
      const char* why = nullptr;
      if (now >= conn->deadline) {
        why = conn->phase == Connection::Phase::Writing ? "response deadline passed"
                                                        : "request deadline passed";
      } else if (conn->phase != Connection::Phase::Writing && clientHalfClosed(conn->fd)) {
        // The client can send no more, and what it sent is not a whole request: it never will
        // be. libmicrohttpd's edge-triggered loop may not read the end of the stream until
        // its timeout, so end it here, once two sweeps saw no progress.
        if (conn->hangup_events == conn->events) why = "client closed before a whole request";
        conn->hangup_events = conn->events;
      }
      if (why == nullptr) continue;
      // libmicrohttpd sees the end of the stream and closes the connection itself.
      ::shutdown(conn->fd, SHUT_RDWR);
      conn->ended = true;
      spdlog::debug("connection from {} closed: {}", conn->ip, why);
    }
  }
}

int HttpServer::openConnections() {
  std::lock_guard lock(conn_mutex_);
  return static_cast<int>(connections_.size());
}

lgp::Expected<int> HttpServer::bind(const std::string& host, int port) {
  // Each connection is a descriptor: take what the hard limit allows, and keep a reserve.
  rlimit rl{};
  if (::getrlimit(RLIMIT_NOFILE, &rl) == 0) {
    if (rl.rlim_cur < rl.rlim_max) {
      rl.rlim_cur = rl.rlim_max;
      ::setrlimit(RLIMIT_NOFILE, &rl);
      ::getrlimit(RLIMIT_NOFILE, &rl);
    }
    const auto room = static_cast<long long>(rl.rlim_cur) - kReservedDescriptors;
    if (rl.rlim_cur != RLIM_INFINITY && room < limits_.max_connections) {
      spdlog::warn("max_connections lowered from {} to {}: this process may open {} descriptors",
                   limits_.max_connections, std::max(1LL, room), rl.rlim_cur);
      limits_.max_connections = static_cast<int>(std::max(1LL, room));
    }
  }

  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  if (const int rc = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found); rc != 0)
    return lgp::Status::error("cannot resolve '" + host + "': " + ::gai_strerror(rc));
  std::string why = "no address";
  for (addrinfo* a = found; a != nullptr && listen_fd_ < 0; a = a->ai_next) {
    const int fd =
        ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
    if (fd < 0) continue;
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, SOMAXCONN) == 0) {
      listen_fd_ = fd;
    } else {
      why = std::strerror(errno);
      ::close(fd);
    }
  }
  ::freeaddrinfo(found);
  if (listen_fd_ < 0)
    return lgp::Status::error("cannot listen on " + host + ":" + service + ": " + why);
  sockaddr_storage ss{};
  socklen_t len = sizeof ss;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&ss), &len);
  family_ = ss.ss_family;
  return static_cast<int>(ntohs(ss.ss_family == AF_INET6
                                    ? reinterpret_cast<sockaddr_in6*>(&ss)->sin6_port
                                    : reinterpret_cast<sockaddr_in*>(&ss)->sin_port));
}

lgp::Status HttpServer::serve() {
  if (listen_fd_ < 0 || daemon_ != nullptr) return lgp::Status::error("not bound, or serving");

  for (int i = 0; i < limits_.workers; ++i) workers_.emplace_back([this] { workerLoop(); });
  sweeper_ = std::thread([this] { sweepLoop(); });

  unsigned flags = MHD_USE_EPOLL_INTERNAL_THREAD | MHD_ALLOW_SUSPEND_RESUME | MHD_USE_ERROR_LOG;
  if (family_ == AF_INET6) flags |= MHD_USE_IPv6;
  daemon_ =
      MHD_start_daemon(flags, 0, nullptr, nullptr, &Callbacks::access, this,  //
                       MHD_OPTION_EXTERNAL_LOGGER, &Callbacks::log, this,     //
                       MHD_OPTION_LISTEN_SOCKET, listen_fd_,                  //
                       MHD_OPTION_CONNECTION_LIMIT, static_cast<unsigned>(limits_.max_connections),
                       MHD_OPTION_CONNECTION_TIMEOUT, wholeSeconds(limits_.keep_alive_timeout_s),
                       MHD_OPTION_CONNECTION_MEMORY_LIMIT, kConnectionMemory,       //
                       MHD_OPTION_NOTIFY_CONNECTION, &Callbacks::connection, this,  //
                       MHD_OPTION_NOTIFY_COMPLETED, &Callbacks::completed, this,    //
                       MHD_OPTION_URI_LOG_CALLBACK, &Callbacks::uriLog, this,       //
                       MHD_OPTION_END);
  if (daemon_ == nullptr) {
    stop();
    return lgp::Status::error("cannot start the HTTP server (libmicrohttpd)");
  }
  return lgp::Status::ok();
}

void HttpServer::stop() {
  {
    std::lock_guard lock(work_mutex_);
    stopping_ = true;
  }
  work_cv_.notify_all();
  // Every request being routed is answered and its connection resumed first:
  // libmicrohttpd cannot stop with a connection suspended.
  for (auto& t : workers_) t.join();
  workers_.clear();
  if (daemon_ != nullptr) {
    MHD_stop_daemon(daemon_);  // closes every connection and the listening socket
    daemon_ = nullptr;
    listen_fd_ = -1;
  } else if (listen_fd_ >= 0) {
    ::close(listen_fd_);
    listen_fd_ = -1;
  }
  {
    std::lock_guard lock(conn_mutex_);
    sweep_stop_ = true;
  }
  sweep_cv_.notify_all();
  if (sweeper_.joinable()) sweeper_.join();
}

}  // namespace lgpd
