#include "common/eval/csv_lines.h"

#include <cerrno>
#include <charconv>
#include <cstring>
#include <fstream>
#include <system_error>

#include "common/util/csv.h"
#include "common/util/paths.h"

namespace placerec {
namespace eval_internal {

int CsvLines::Column(const std::string& name) const {
  for (size_t i = 0; i < header.size(); ++i) {
    if (header[i] == name) return static_cast<int>(i);
  }
  return -1;
}

std::string CsvLines::Where(int line) const { return path + ":" + std::to_string(line); }

StatusOr<CsvLines> ReadCsvLines(const std::string& path) {
  if (!PathExists(path)) return Status::NotFound(path + " does not exist");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IoError("cannot open " + path + ": " + std::strerror(errno));
  CsvLines table;
  table.path = path;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line_number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    std::vector<std::string> fields = SplitString(line, ',');
    if (table.header.empty()) {
      table.header = std::move(fields);
      continue;
    }
    if (fields.size() != table.header.size()) {
      std::string header_text;
      for (size_t i = 0; i < table.header.size(); ++i) {
        header_text += (i > 0 ? "," : "") + table.header[i];
      }
      return Status::InvalidArgument(table.Where(line_number) + ": expected " +
                                     std::to_string(table.header.size()) + " fields (" +
                                     header_text + "), found " + std::to_string(fields.size()) +
                                     "; fields are separated by commas and may not contain one");
    }
    table.rows.push_back({line_number, std::move(fields)});
  }
  if (in.bad()) return Status::IoError("error while reading " + path);
  if (table.header.empty()) {
    return Status::InvalidArgument(path + " is empty; it needs at least a header row");
  }
  return table;
}

bool ParseInt(const std::string& text, long long* value) {
  const char* begin = text.data();
  const char* end = begin + text.size();
  long long v = 0;
  const std::from_chars_result result = std::from_chars(begin, end, v);
  if (text.empty() || result.ec != std::errc() || result.ptr != end) return false;
  *value = v;
  return true;
}

bool ParseFloat(const std::string& text, double* value) {
  const char* begin = text.data();
  const char* end = begin + text.size();
  double v = 0;
  const std::from_chars_result result = std::from_chars(begin, end, v);
  if (text.empty() || result.ec != std::errc() || result.ptr != end) return false;
  *value = v;
  return true;
}

std::string FormatDouble(double value) {
  char buffer[64];
  const std::to_chars_result result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  CHECK(result.ec == std::errc()) << "to_chars failed on a 64-byte buffer";
  return std::string(buffer, result.ptr);
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string text;
  for (size_t i = 0; i < names.size(); ++i) text += (i > 0 ? ", " : "") + names[i];
  return text;
}

}  // namespace eval_internal
}  // namespace placerec
