#include "common/eval/answers.h"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>

#include "common/eval/csv_lines.h"

namespace placerec {
namespace {

using eval_internal::CsvLines;
using eval_internal::FormatDouble;
using eval_internal::ParseFloat;
using eval_internal::ParseInt;

constexpr char kHeader[] = "frame,reference,score";
constexpr long long kMaxInt = std::numeric_limits<int>::max();

// What is wrong with one answer, or "" when it is well-formed.
std::string AnswerProblem(long long frame, long long reference, double score) {
  if (frame < 0) return "frame " + std::to_string(frame) + " is negative";
  if (reference < -1) {
    return "reference " + std::to_string(reference) + " is neither -1 (no claim) nor a frame";
  }
  if (reference >= frame) {
    return "reference " + std::to_string(reference) + " is not earlier than frame " +
           std::to_string(frame) + "; a claim names an earlier frame, -1 means no claim";
  }
  if (std::isnan(score)) return "score is NaN; give every answer a number (any value for -1)";
  return "";
}

Status NotA(const CsvLines& table, int line, const char* column, const std::string& text,
            const char* kind) {
  return Status::InvalidArgument(table.Where(line) + ": " + column + " '" + text + "' is not " +
                                 kind);
}

}  // namespace

Status WriteAnswers(const std::string& path, const std::vector<Answer>& answers) {
  for (size_t i = 0; i < answers.size(); ++i) {
    const Answer& a = answers[i];
    const std::string problem = AnswerProblem(a.frame, a.reference, a.score);
    if (!problem.empty()) {
      return Status::InvalidArgument("answer " + std::to_string(i) + " for " + path + ": " +
                                     problem);
    }
  }
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) return Status::IoError("cannot write " + path + ": " + std::strerror(errno));
  std::string text = std::string(kHeader) + "\n";
  for (const Answer& a : answers) {
    text += std::to_string(a.frame) + "," + std::to_string(a.reference) + "," +
            FormatDouble(a.score) + "\n";
  }
  out << text;
  out.close();
  if (!out) return Status::IoError("error while writing " + path + " (disk full?)");
  return Status::Ok();
}

StatusOr<std::vector<Answer>> ReadAnswers(const std::string& path) {
  StatusOr<CsvLines> table_or = eval_internal::ReadCsvLines(path);
  if (!table_or.ok()) return table_or.status();
  const CsvLines& table = *table_or;
  std::string header;
  for (const std::string& name : table.header) header += (header.empty() ? "" : ",") + name;
  if (header != kHeader) {
    return Status::InvalidArgument(table.Where(1) + ": header is '" + header + "', expected '" +
                                   kHeader + "'");
  }
  std::vector<Answer> answers;
  answers.reserve(table.rows.size());
  std::map<long long, int> line_of_frame;
  for (const eval_internal::CsvLine& row : table.rows) {
    long long frame = 0;
    long long reference = 0;
    double score = 0;
    const std::vector<std::string>& f = row.fields;
    if (!ParseInt(f[0], &frame) || frame > kMaxInt) {
      return NotA(table, row.line, "frame", f[0], "an integer frame index");
    }
    if (!ParseInt(f[1], &reference) || reference > kMaxInt) {
      return NotA(table, row.line, "reference", f[1], "an integer frame index or -1");
    }
    if (!ParseFloat(f[2], &score)) return NotA(table, row.line, "score", f[2], "a number");
    const std::string problem = AnswerProblem(frame, reference, score);
    if (!problem.empty()) return Status::InvalidArgument(table.Where(row.line) + ": " + problem);
    const auto [it, inserted] = line_of_frame.emplace(frame, row.line);
    if (!inserted) {
      return Status::InvalidArgument(table.Where(row.line) + ": frame " + std::to_string(frame) +
                                     " already has an answer on line " +
                                     std::to_string(it->second) +
                                     "; write one row per frame (its best answer)");
    }
    answers.push_back({static_cast<int>(frame), static_cast<int>(reference), score});
  }
  return answers;
}

}  // namespace placerec
