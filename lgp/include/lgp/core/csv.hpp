// CSV as lgp reads and writes it (RFC 4180). Reading: fields are separated by ',' and
// records by LF or CRLF; a field in double quotes may hold ',', line breaks and "" (one
// quote); spaces and tabs around a field are dropped; blank records and records that start
// with '#' are skipped. Errors name the file, line and column and quote nothing of the text,
// which may be any file a path points at. Writing: a field is quoted where it needs to be,
// and a front CSV, which spreadsheets open, never starts a cell with a formula.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "lgp/core/status.hpp"

namespace lgp {

class CsvReader {
 public:
  // `file` names the text in errors ("t.csv: line 3, column 2: ...").
  CsvReader(std::string_view text, std::string file) : text_(text), file_(std::move(file)) {}

  // The next record into `fields`; false at the end of the text.
  Expected<bool> next(std::vector<std::string>& fields);
  // The line (1-based) the last record started on.
  size_t line() const { return record_line_; }
  // Whether the last record ended with a line break (not at the end of the text).
  bool terminated() const { return terminated_; }
  const std::string& file() const { return file_; }

 private:
  Status error(size_t line, size_t column, const std::string& why) const;

  std::string_view text_;
  std::string file_;
  size_t pos_ = 0;
  size_t line_ = 1;
  size_t record_line_ = 0;
  bool terminated_ = false;
};

// A plain decimal number: [+-]digits[.digits][(e|E)[+-]digits], or with digits only after
// the point. No hex, inf, nan or spaces.
bool isDecimalNumber(std::string_view s);

// A CSV cell as a finite double; the error says what is wrong ("empty cell", "a hexadecimal
// number ...") without quoting the cell.
Expected<double> parseCsvNumber(std::string_view cell);

// `s` as one RFC 4180 field: in double quotes, with " doubled, when it holds ',', '"', a
// line break or spaces at either end; as it is otherwise.
std::string csvField(std::string_view s);

// The same for a CSV that spreadsheets open: a text that starts with '=', '+', '-', '@', a
// tab or CR and is not a plain decimal number gets a leading ' so that it is shown, not
// evaluated as a formula (=HYPERLINK(...)).
std::string csvSpreadsheetField(std::string_view s);

}  // namespace lgp
