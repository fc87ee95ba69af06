// Minimal CSV for the dataset layouts and answers files: a header row, comma-separated fields,
// no quoting (the formats placerec reads and writes never contain commas inside a field).
#pragma once

#include <string>
#include <vector>

#include "common/util/status.h"

namespace placerec {

struct CsvTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;

  // Index of a header column, or -1.
  int Column(const std::string& name) const;
};

// Reads a CSV file; every row must have as many fields as the header.
StatusOr<CsvTable> ReadCsv(const std::string& path);

std::vector<std::string> SplitString(const std::string& text, char separator);

// Parses a whole string as a number; false on trailing junk or overflow.
bool ParseInt64(const std::string& text, long long* value);
bool ParseDouble(const std::string& text, double* value);

}  // namespace placerec
