#include "http_message.hpp"

#include <cctype>

namespace lgpd {

namespace {

bool sameName(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(a[i])) !=
        std::tolower(static_cast<unsigned char>(b[i])))
      return false;
  return true;
}

}  // namespace

std::string HttpRequest::header(std::string_view name) const {
  for (const auto& [k, v] : headers)
    if (sameName(k, name)) return v;
  return "";
}

size_t HttpRequest::headerCount(std::string_view name) const {
  size_t n = 0;
  for (const auto& [k, v] : headers) n += sameName(k, name) ? 1 : 0;
  return n;
}

std::string HttpRequest::param(std::string_view name) const {
  for (const auto& [k, v] : params)
    if (k == name) return v;
  return "";
}

bool HttpRequest::hasParam(std::string_view name) const {
  for (const auto& [k, v] : params)
    if (k == name) return true;
  return false;
}

bool HttpRequest::announcesBody() const {
  return hasHeader("Transfer-Encoding") ||
         (hasHeader("Content-Length") && header("Content-Length") != "0");
}

void HttpResponse::setHeader(std::string name, std::string value) {
  for (auto& [k, v] : headers)
    if (sameName(k, name)) {
      v = std::move(value);
      return;
    }
  headers.emplace_back(std::move(name), std::move(value));
}

bool HttpResponse::hasHeader(std::string_view name) const {
  for (const auto& [k, v] : headers)
    if (sameName(k, name)) return true;
  return false;
}

void HttpResponse::setContent(std::string content, std::string content_type) {
  body = std::move(content);
  setHeader("Content-Type", std::move(content_type));
}

}  // namespace lgpd
