#include "lgp/core/csv.hpp"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>

namespace lgp {

Status CsvReader::error(size_t line, size_t column, const std::string& why) const {
  return Status::error(file_ + ": line " + std::to_string(line) + ", column " +
                       std::to_string(column) + ": " + why);
}

Expected<bool> CsvReader::next(std::vector<std::string>& fields) {
  fields.clear();
  const size_t n = text_.size();
  // Blank records and '#' comments.
  for (;;) {
    if (pos_ >= n) return false;
    size_t q = pos_;
    while (q < n && (text_[q] == ' ' || text_[q] == '\t' || text_[q] == '\r')) ++q;
    if (q < n && text_[q] != '\n' && text_[q] != '#') break;
    const size_t nl = text_.find('\n', q);
    pos_ = nl == std::string_view::npos ? n : nl + 1;
    ++line_;
  }
  record_line_ = line_;
  enum class State { Start, Unquoted, Quoted, AfterQuote } st = State::Start;
  std::string cur;
  size_t quote_line = line_;
  auto endField = [&] {
    if (st == State::Unquoted || st == State::Start) {
      size_t e = cur.size();
      while (e > 0 && (cur[e - 1] == ' ' || cur[e - 1] == '\t' || cur[e - 1] == '\r')) --e;
      cur.resize(e);
    }
    fields.push_back(std::move(cur));
    cur.clear();
  };
  while (pos_ < n) {
    const char c = text_[pos_++];
    // Outside quotes a comma ends the field and a newline the record, whatever came before.
    if (st != State::Quoted && (c == ',' || c == '\n')) {
      endField();
      st = State::Start;
      if (c == ',') continue;
      ++line_;
      terminated_ = true;
      return true;
    }
    switch (st) {
      case State::Start:
        if (c == ' ' || c == '\t') break;
        if (c == '"') {
          st = State::Quoted;
          quote_line = line_;
          break;
        }
        st = State::Unquoted;
        [[fallthrough]];
      case State::Unquoted:
        if (c == '"')
          return error(line_, fields.size() + 1,
                       "a double quote inside an unquoted field (quote the whole field and "
                       "write a quote as \"\")");
        cur += c;
        break;
      case State::Quoted:
        if (c == '"') {
          if (pos_ < n && text_[pos_] == '"') {
            cur += '"';
            ++pos_;
          } else {
            st = State::AfterQuote;
          }
        } else {
          if (c == '\n') ++line_;
          cur += c;
        }
        break;
      case State::AfterQuote:
        if (c == ' ' || c == '\t' || c == '\r') break;
        return error(line_, fields.size() + 1, "text after the closing quote of a field");
    }
  }
  if (st == State::Quoted)
    return error(quote_line, fields.size() + 1, "a quoted field is not closed");
  endField();
  terminated_ = false;
  return true;
}

bool isDecimalNumber(std::string_view s) {
  size_t i = 0;
  auto digits = [&] {
    const size_t b = i;
    while (i < s.size() && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
    return i - b;
  };
  if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
  size_t mantissa = digits();
  if (i < s.size() && s[i] == '.') {
    ++i;
    mantissa += digits();
  }
  if (mantissa == 0) return false;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  return i == s.size();
}

Expected<double> parseCsvNumber(std::string_view cell) {
  if (cell.empty()) return Status::error("empty cell (a number is needed)");
  if (!isDecimalNumber(cell)) {
    std::string_view body = cell;
    if (body[0] == '+' || body[0] == '-') body.remove_prefix(1);
    auto starts = [&](std::string_view p) {
      if (body.size() < p.size()) return false;
      for (size_t i = 0; i < p.size(); ++i)
        if (std::tolower(static_cast<unsigned char>(body[i])) != p[i]) return false;
      return true;
    };
    if (starts("0x")) return Status::error("a hexadecimal number (only decimal numbers are read)");
    if (starts("inf") || starts("nan"))
      return Status::error("inf or nan (only finite numbers are read)");
    return Status::error("not a decimal number");
  }
  const std::string s(cell);
  errno = 0;
  const double v = std::strtod(s.c_str(), nullptr);
  // ERANGE on underflow (1e-310, a subnormal, or 1e-400, which is 0) is a finite value and
  // accepted; on overflow strtod returns HUGE_VAL, which isfinite refuses.
  if (!std::isfinite(v)) return Status::error("outside the range of double");
  return v;
}

std::string csvField(std::string_view s) {
  const bool quote = s.find_first_of(",\"\r\n") != std::string_view::npos ||
                     (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.back() == ' ' ||
                                     s.back() == '\t'));
  if (!quote) return std::string(s);
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

std::string csvSpreadsheetField(std::string_view s) {
  const bool formula = !s.empty() && (s[0] == '=' || s[0] == '+' || s[0] == '-' || s[0] == '@' ||
                                      s[0] == '\t' || s[0] == '\r');
  if (formula && !isDecimalNumber(s)) {
    std::string quoted = "'";  // appended: GCC 12's -Wstringop-overflow misreads "'" + string
    quoted += s;
    return csvField(quoted);
  }
  return csvField(s);
}

}  // namespace lgp
