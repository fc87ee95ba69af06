// Internal to common/eval: a CSV reader that remembers the line number of every row, so that
// the run and answers loaders can say "file:line: what is wrong". Same dialect as
// common/util/csv.h (header row, comma-separated, no quoting, blank lines skipped, CRLF and a
// UTF-8 byte-order mark tolerated), plus locale-independent number parsing.
#pragma once

#include <string>
#include <vector>

#include "common/util/status.h"

namespace placerec {
namespace eval_internal {

struct CsvLine {
  int line = 0;  // 1-based line number in the file
  std::vector<std::string> fields;
};

struct CsvLines {
  std::string path;
  std::vector<std::string> header;
  std::vector<CsvLine> rows;

  // Index of a header column, or -1.
  int Column(const std::string& name) const;
  // "path:line" for messages.
  std::string Where(int line) const;
};

// Reads a CSV file whose rows all have as many fields as the header. A missing file is
// NotFound, an unreadable one IoError, an empty or ragged one InvalidArgument.
StatusOr<CsvLines> ReadCsvLines(const std::string& path);

// Whole-string, locale-independent number parsing (no leading '+' or spaces); false on junk,
// an empty string or a value out of range.
bool ParseInt(const std::string& text, long long* value);
bool ParseFloat(const std::string& text, double* value);

// Shortest decimal text that reads back as exactly `value` ("0.1", "1e-07", "12345.678").
std::string FormatDouble(double value);

// "a, b, c".
std::string JoinNames(const std::vector<std::string>& names);

}  // namespace eval_internal
}  // namespace placerec
