#include "http_server.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <optional>

namespace lgpd {

namespace {

using Clock = std::chrono::steady_clock;

thread_local bool t_close_after_response = false;

constexpr size_t kHeaderAllowance = size_t{64} << 10;  // request line and headers
constexpr auto kStopCheck = std::chrono::milliseconds(100);

Clock::duration toDuration(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

// "1.2.3.4" / "2001:db8::1" and the port of a socket's peer (or, local = true, its own end).
// IPv4-mapped IPv6 addresses are written as IPv4.
void endpointOf(int sock, bool local, std::string& ip, int& port) {
  sockaddr_storage ss{};
  socklen_t len = sizeof ss;
  ip.clear();
  port = 0;
  auto* sa = reinterpret_cast<sockaddr*>(&ss);
  if ((local ? ::getsockname(sock, sa, &len) : ::getpeername(sock, sa, &len)) != 0) return;
  char buf[INET6_ADDRSTRLEN] = {0};
  if (ss.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&ss);
    ::inet_ntop(AF_INET, &a->sin_addr, buf, sizeof buf);
    port = ntohs(a->sin_port);
  } else if (ss.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&ss);
    if (IN6_IS_ADDR_V4MAPPED(&a->sin6_addr))
      ::inet_ntop(AF_INET, &a->sin6_addr.s6_addr[12], buf, sizeof buf);
    else
      ::inet_ntop(AF_INET6, &a->sin6_addr, buf, sizeof buf);
    port = ntohs(a->sin6_port);
  }
  ip = buf;
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

// One connection as cpp-httplib's request parser and response writer see it: buffered
// reads with an inactivity timeout and a deadline per request, writes with a deadline per
// response, and a byte budget per request. Every wait wakes up every 0.1 s to see whether
// the server is stopping.
class DeadlineStream final : public httplib::Stream {
 public:
  DeadlineStream(int sock, const HttpLimits& limits, const std::atomic<socket_t>& server)
      : sock_(sock), limits_(limits), server_(server) {
    endpointOf(sock, false, remote_ip_, remote_port_);
  }

  // The next request begins (its first byte has arrived or is about to).
  void beginRequest() {
    reading_ = true;
    request_bytes_ = 0;
    read_deadline_ = Clock::now() + toDuration(limits_.request_timeout_s);
  }

  // Waits for the first byte of another request on a kept-alive connection.
  bool waitForRequest(double timeout_s) {
    if (buf_pos_ < buf_len_) return true;
    return wait(POLLIN, Clock::now() + toDuration(timeout_s)) > 0;
  }

  bool is_readable() const override {
    if (buf_pos_ < buf_len_) return true;
    return wait(POLLIN, readLimit()) > 0;
  }
  bool is_writable() const override { return wait(POLLOUT, writeLimit()) > 0; }

  ssize_t read(char* ptr, size_t size) override {
    if (size == 0) return 0;
    if (buf_pos_ < buf_len_) {
      const size_t n = std::min(size, buf_len_ - buf_pos_);
      std::memcpy(ptr, buf_ + buf_pos_, n);
      buf_pos_ += n;
      return static_cast<ssize_t>(n);
    }
    // Headers, the body and its chunk framing (twice the body allows chunks of a few bytes).
    if (request_bytes_ >= 2 * limits_.max_request_bytes + kHeaderAllowance) return -1;
    if (wait(POLLIN, readLimit()) <= 0) return -1;
    const bool direct = size >= sizeof buf_;
    ssize_t n;
    do {
      n = ::recv(sock_, direct ? ptr : buf_, direct ? size : sizeof buf_, 0);
    } while (n < 0 && errno == EINTR);
    if (n <= 0) return n < 0 ? -1 : 0;
    request_bytes_ += static_cast<size_t>(n);
    if (direct) return n;
    buf_pos_ = 0;
    buf_len_ = static_cast<size_t>(n);
    return read(ptr, size);
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (reading_) {
      reading_ = false;
      write_deadline_ = Clock::now() + toDuration(limits_.write_timeout_s);
    }
    if (wait(POLLOUT, write_deadline_) <= 0) return -1;
    ssize_t n;
    do {
      n = ::send(sock_, ptr, size, MSG_NOSIGNAL);
    } while (n < 0 && errno == EINTR);
    return n;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = remote_ip_;
    port = remote_port_;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    endpointOf(sock_, true, ip, port);
  }
  socket_t socket() const override { return sock_; }

 private:
  Clock::time_point readLimit() const {
    return std::min(Clock::now() + toDuration(limits_.read_timeout_s), read_deadline_);
  }
  Clock::time_point writeLimit() const { return write_deadline_; }

  // poll() for `events` until `until`; > 0 ready, 0 timed out or stopping, < 0 error.
  int wait(short events, Clock::time_point until) const {
    for (;;) {
      if (server_.load() == INVALID_SOCKET) return 0;
      const auto now = Clock::now();
      if (now >= until) return 0;
      const auto slice = std::min<Clock::duration>(until - now, kStopCheck);
      pollfd p{sock_, events, 0};
      const int ms = static_cast<int>(std::max<int64_t>(
          1, std::chrono::duration_cast<std::chrono::milliseconds>(slice).count()));
      const int r = ::poll(&p, 1, ms);
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) return -1;
      if (r > 0) return (p.revents & (events | POLLHUP | POLLERR)) ? 1 : -1;
    }
  }

  int sock_;
  const HttpLimits& limits_;
  const std::atomic<socket_t>& server_;
  std::string remote_ip_;
  int remote_port_ = 0;
  bool reading_ = true;
  size_t request_bytes_ = 0;
  Clock::time_point read_deadline_ = Clock::now();
  Clock::time_point write_deadline_ = Clock::now();
  char buf_[4096];
  size_t buf_pos_ = 0, buf_len_ = 0;
};

// After a response to a request whose body was left unread: stop sending, then read and
// drop what the client is still sending for a moment, so that its TCP stack does not reset
// the connection (and lose the response) when we close with unread data.
void lingeringClose(int sock) {
  ::shutdown(sock, SHUT_WR);
  const auto until = Clock::now() + std::chrono::seconds(1);
  size_t drained = 0;
  char buf[16384];
  while (drained < (size_t{4} << 20)) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    if (left.count() <= 0) break;
    pollfd p{sock, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) break;
    const ssize_t n = ::recv(sock, buf, sizeof buf, 0);
    if (n <= 0) break;
    drained += static_cast<size_t>(n);
  }
}

}  // namespace

void closeConnectionAfterResponse() {
  t_close_after_response = true;
}

HttpServer::HttpServer(HttpLimits limits) : limits_(limits) {
  limits_.max_connections_per_client = std::max(1, limits_.max_connections_per_client);
  limits_.keep_alive_max_requests = std::max(1, limits_.keep_alive_max_requests);
  // What cpp-httplib writes into its Keep-Alive response header.
  set_keep_alive_max_count(static_cast<size_t>(limits_.keep_alive_max_requests));
  set_keep_alive_timeout(static_cast<time_t>(std::max(1.0, limits_.keep_alive_timeout_s)));
  set_payload_max_length(limits_.max_request_bytes);
}

void HttpServer::widenListenBacklog() {
  const socket_t s = svr_sock_.load();
  if (s != INVALID_SOCKET) ::listen(s, SOMAXCONN);
}

int HttpServer::openConnections() {
  std::lock_guard lock(mutex_);
  int n = 0;
  for (const auto& [key, count] : per_client_) n += count;
  return n;
}

bool HttpServer::acquire(const std::string& client) {
  std::lock_guard lock(mutex_);
  int& n = per_client_[client];
  if (n >= limits_.max_connections_per_client) return false;
  ++n;
  return true;
}

void HttpServer::release(const std::string& client) {
  std::lock_guard lock(mutex_);
  auto it = per_client_.find(client);
  if (it != per_client_.end() && --it->second <= 0) per_client_.erase(it);
}

bool HttpServer::process_and_close_socket(socket_t sock) {
  std::string ip;
  int port = 0;
  endpointOf(sock, false, ip, port);
  const std::string key = clientKey(ip);
  if (!acquire(key)) {
    // Nothing of the request is read: answer and close at once, so that the rejection
    // itself costs the worker no time.
    const std::string body = "{\"error\":\"too many connections from " + ip + " (at most " +
                             std::to_string(limits_.max_connections_per_client) +
                             " at once)\",\"status\":429}";
    const std::string head =
        "HTTP/1.1 429 Too Many Requests\r\nContent-Type: application/json\r\n"
        "Connection: close\r\nRetry-After: 1\r\nContent-Length: " +
        std::to_string(body.size()) + "\r\n\r\n";
    const std::string msg = head + body;
    (void)!::send(sock, msg.data(), msg.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    ::shutdown(sock, SHUT_RDWR);
    ::close(sock);
    spdlog::debug("connection from {} refused: {} already open", ip,
                  limits_.max_connections_per_client);
    return false;
  }
  bool ret = false;
  bool linger = false;
  {
    DeadlineStream strm(sock, limits_, svr_sock_);
    for (int left = limits_.keep_alive_max_requests; left > 0; --left) {
      if (svr_sock_.load() == INVALID_SOCKET) break;
      if (!strm.waitForRequest(limits_.keep_alive_timeout_s)) break;
      strm.beginRequest();
      t_close_after_response = false;
      bool connection_closed = false;
      ret = process_request(strm, left == 1, connection_closed, {});
      linger = t_close_after_response;
      t_close_after_response = false;
      if (!ret || connection_closed || linger) break;
    }
  }
  if (linger)
    lingeringClose(sock);
  else
    ::shutdown(sock, SHUT_RDWR);
  ::close(sock);
  release(key);
  return ret;
}

}  // namespace lgpd
