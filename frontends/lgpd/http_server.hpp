// lgpd's HTTP server: cpp-httplib's Server with its own connection loop, so that slow or
// greedy clients cannot take every worker thread.
//
// cpp-httplib 0.11 gives each accepted connection one worker of the pool for as long as the
// connection lives, and its read timeout restarts with every byte: a client that sends one
// header byte every few seconds holds a worker forever (slowloris). This class replaces the
// per-connection loop (process_and_close_socket) and keeps cpp-httplib's request parsing,
// routing and response writing (process_request):
//  - at most `max_connections_per_client` connections per client address (an IPv6 client is
//    its /64) are served at once; a connection over the bound gets "429 Too Many Requests"
//    and is closed at once, before anything of it is read;
//  - a request must arrive within `request_timeout_s` (request line, headers and body, from
//    its first byte), with no pause longer than `read_timeout_s`; the response must leave
//    within `write_timeout_s`; an idle keep-alive connection is closed after
//    `keep_alive_timeout_s` and after `keep_alive_max_requests` requests;
//  - a request may not be longer than 64 KiB of headers plus twice `max_request_bytes` (the
//    body limit itself is the API's; this bounds headers and chunk framing);
//  - stop() ends every connection within about 0.1 s, also one in the middle of a request.
// A handler that leaves a request body unread calls closeConnectionAfterResponse(): the rest
// of the body must not be taken for the next request.
#pragma once

#include <httplib.h>

#include <cstddef>
#include <map>
#include <mutex>
#include <string>

namespace lgpd {

struct HttpLimits {
  int max_connections_per_client = 8;
  double read_timeout_s = 5;
  double request_timeout_s = 60;
  double write_timeout_s = 60;
  double keep_alive_timeout_s = 5;
  int keep_alive_max_requests = 100;
  size_t max_request_bytes = size_t{16} << 20;  // the body limit (see above)
};

class HttpServer : public httplib::Server {
 public:
  explicit HttpServer(HttpLimits limits);

  // Raises the listen backlog above cpp-httplib's 5 (call after bind_to_port): a burst of
  // connections then waits in the kernel's queue instead of being dropped and retried by the
  // clients a second later.
  void widenListenBacklog();

  // Connections being served now, for tests and logs.
  int openConnections();

 private:
  bool process_and_close_socket(socket_t sock) override;
  bool acquire(const std::string& client);
  void release(const std::string& client);

  HttpLimits limits_;
  std::mutex mutex_;
  std::map<std::string, int> per_client_;  // client key -> connections being served
};

// Marks the connection of the request being handled on this thread to be closed after its
// response (the rest of its body is not read).
void closeConnectionAfterResponse();

}  // namespace lgpd
