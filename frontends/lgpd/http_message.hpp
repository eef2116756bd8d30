// One HTTP request and its response as lgpd's routes see them: plain data, filled in and
// sent by HttpServer (http_server.hpp), so that the routes do not depend on the library that
// does the serving.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lgpd {

struct HttpRequest {
  std::string method;                                        // as sent: "GET", "POST", ...
  std::string path;                                          // percent-decoded, without the query
  std::string remote_addr;                                   // "127.0.0.1", "::1"
  std::vector<std::pair<std::string, std::string>> headers;  // in the order sent
  std::vector<std::pair<std::string, std::string>> params;   // the query, decoded
  std::string body;  // filled only for the routes (not for the checks before the body)

  // The first header of that name (names compare case-insensitively), "" when absent.
  std::string header(std::string_view name) const;
  size_t headerCount(std::string_view name) const;
  bool hasHeader(std::string_view name) const { return headerCount(name) > 0; }
  // The first query parameter of that name, "" when absent.
  std::string param(std::string_view name) const;
  bool hasParam(std::string_view name) const;
  // A Content-Length other than 0, or a Transfer-Encoding: the request says it has a body.
  bool announcesBody() const;
};

struct HttpResponse {
  int status = 0;  // 0: not answered yet
  std::vector<std::pair<std::string, std::string>> headers;
  std::string body;
  bool close = false;  // close the connection after this response

  void setHeader(std::string name, std::string value);
  bool hasHeader(std::string_view name) const;  // names compare case-insensitively
  void setContent(std::string content, std::string content_type);
  bool answered() const { return status != 0; }
};

}  // namespace lgpd
