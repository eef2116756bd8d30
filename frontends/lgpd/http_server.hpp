// lgpd's HTTP server: libmicrohttpd in its epoll mode, so that a connection holds no thread.
//
// One event thread reads and writes every connection. A request's routes run on a small pool
// of workers (`workers`) once its body has arrived; meanwhile its connection is suspended, so
// a slow route delays no other client and a slow client costs a file descriptor and a little
// memory, never a worker. Slow or greedy clients are bounded by:
//  - `max_connections` open connections in all (past it libmicrohttpd closes a new one at once)
//    and `max_connections_per_client` per client address (an IPv6 client is its /64); one
//    more from the same address gets "429 Too Many Requests" and is closed at once, before
//    anything of it is read;
//  - a request (request line, headers and body) must arrive within `request_timeout_s` of its
//    start, with no pause longer than `read_timeout_s`; a response must leave within
//    `write_timeout_s`; an idle kept-alive connection is closed after `keep_alive_timeout_s`
//    and after `keep_alive_max_requests` requests. libmicrohttpd counts pauses in whole
//    seconds (read_timeout_s and keep_alive_timeout_s are rounded up); the deadlines are ours,
//    checked every 50 ms;
//  - request line and headers may take about 80 KiB (431 past it), the request target 8 KiB
//    (414 past it), the body `max_request_bytes` (413, also for a chunked body: the
//    connection is closed once the limit is passed);
//  - stop() answers the requests being routed, then ends every connection.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "http_message.hpp"
#include "lgp/core/status.hpp"

struct MHD_Daemon;
struct MHD_Connection;

namespace lgpd {

struct HttpLimits {
  int workers = 16;
  int max_connections = 1024;
  int max_connections_per_client = 512;
  double read_timeout_s = 5;
  double request_timeout_s = 60;
  double write_timeout_s = 60;
  double keep_alive_timeout_s = 5;
  int keep_alive_max_requests = 100;
  size_t max_request_bytes = size_t{16} << 20;  // the body
};

// What the server calls:
//  - `head` with the request line and headers (no body yet), on the event thread, so it must
//    be quick: answering there (setting a status) ends the request; the body is then not
//    read and, when the request announced one, the connection is closed after the answer;
//  - `route` with the whole request, on a worker.
// An exception from either is logged and answered with 500.
struct HttpHandlers {
  using Handler = std::function<void(const HttpRequest&, HttpResponse&)>;
  Handler head;
  Handler route;
  std::vector<std::pair<std::string, std::string>> default_headers;  // on every answer
};

class HttpServer {
 public:
  HttpServer(HttpLimits limits, HttpHandlers handlers);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  // Binds and listens on `host:port` (port 0: any free port); the bound port. Connections
  // wait in the kernel's queue until serve().
  lgp::Expected<int> bind(const std::string& host, int port);
  lgp::Status serve();
  // Answers the requests being routed, then closes every connection. Idempotent.
  void stop();

  // Connections open now, for tests and logs.
  int openConnections();

  struct Connection;  // one client connection (http_server.cpp)
  struct Exchange;    // one request on it

 private:
  friend struct Callbacks;

  static void callHandler(const HttpHandlers::Handler& h, const HttpRequest& req,
                          HttpResponse& res);
  void dispatch(MHD_Connection* c, Exchange* x);
  void workerLoop();
  void sweepLoop();

  HttpLimits limits_;
  HttpHandlers handlers_;
  MHD_Daemon* daemon_ = nullptr;
  int listen_fd_ = -1;
  int family_ = 0;

  std::mutex conn_mutex_;  // guards the connection table and its deadlines
  std::map<Connection*, std::unique_ptr<Connection>> connections_;
  std::map<std::string, int> per_client_;

  std::mutex work_mutex_;
  std::condition_variable work_cv_;
  std::deque<std::function<void()>> work_;
  bool stopping_ = false;
  std::vector<std::thread> workers_;
  std::thread sweeper_;
  std::condition_variable sweep_cv_;
  bool sweep_stop_ = false;  // guarded by conn_mutex_
};

}  // namespace lgpd
