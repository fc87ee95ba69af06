#include "common/training/labelled_dataset.h"

#include <fstream>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/image/image.h"
#include "common/util/paths.h"

namespace placerec {

std::string ClassTable::Name(int id) const {
  const auto it = names.find(id);
  return it != names.end() ? it->second : "class" + std::to_string(id);
}

bool ClassTable::IsUnlabelled(int id) const {
  const auto it = names.find(id);
  if (it == names.end()) return false;
  return it->second == "unknown" || it->second == "void" || it->second == "unlabelled";
}

SegmentClass BackgroundClassOfName(const std::string& name) {
  for (const SegmentClass c : {SegmentClass::kSky, SegmentClass::kTree, SegmentClass::kRoad,
                               SegmentClass::kGrass, SegmentClass::kWater}) {
    if (name == SegmentClassName(c)) return c;
  }
  // Names that mean a background class under another word.
  static const std::map<std::string, SegmentClass> kAliases = {
      {"pavement", SegmentClass::kRoad},  // camvid: sidewalks, ground like road
  };
  const auto alias = kAliases.find(name);
  return alias != kAliases.end() ? alias->second : SegmentClass::kStructured;
}

SegmentClass ClassTable::BackgroundClass(int id) const {
  const auto it = names.find(id);
  return it == names.end() ? SegmentClass::kStructured : BackgroundClassOfName(it->second);
}

StatusOr<ClassTable> ReadClassTable(const std::string& dir) {
  ClassTable table;
  const std::string path = dir + "/classes.txt";
  if (!PathExists(path)) return table;
  std::ifstream in(path);
  if (!in) return Status::IoError("cannot read " + path);
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty()) continue;
    std::istringstream fields(line);
    int id = 0;
    std::string name;
    if (!(fields >> id >> name)) {
      return Status::InvalidArgument(path + ":" + std::to_string(line_number) +
                                     ": expected 'id name'");
    }
    table.names[id] = name;
  }
  return table;
}

StatusOr<std::vector<std::string>> ReadSplit(const std::string& dir, const std::string& split) {
  const std::string path = dir + "/" + split + ".txt";
  std::ifstream in(path);
  if (!in) return Status::NotFound("cannot read split list " + path);
  std::vector<std::string> ids;
  std::string line;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (!line.empty()) ids.push_back(line);
  }
  if (ids.empty()) return Status::InvalidArgument(path + " lists no images");
  return ids;
}

StatusOr<LabelledImage> ReadLabelledImage(const std::string& dir, const std::string& id) {
  LabelledImage image;
  image.id = id;
  std::string path = dir + "/images/" + id + ".jpg";
  if (!PathExists(path) && PathExists(dir + "/images/" + id + ".png")) {
    path = dir + "/images/" + id + ".png";
  }
  StatusOr<cv::Mat> bgr = ReadImageFile(path);
  if (!bgr.ok()) return bgr.status();
  image.bgr = *bgr;
  auto read_layer = [&](const std::string& layer, cv::Mat* out) -> Status {
    const std::string file = dir + "/" + layer + "/" + id + ".png";
    if (!PathExists(file)) return Status::Ok();
    *out = cv::imread(file, cv::IMREAD_UNCHANGED);
    if (out->empty() || out->channels() != 1 || (out->depth() != CV_8U && out->depth() != CV_16U)) {
      return Status::InvalidArgument(file + ": expected a one-channel 8- or 16-bit PNG");
    }
    if (out->size() != image.bgr.size()) {
      return Status::InvalidArgument(file + ": size differs from the image's");
    }
    return Status::Ok();
  };
  PLACEREC_RETURN_IF_ERROR(read_layer("classes", &image.classes));
  PLACEREC_RETURN_IF_ERROR(read_layer("objects", &image.objects));
  return image;
}

cv::Mat LayerAtSize(const cv::Mat& layer, cv::Size size) {
  cv::Mat out;
  layer.convertTo(out, CV_32S);
  if (out.size() != size) cv::resize(out, out, size, 0, 0, cv::INTER_NEAREST);
  return out;
}

std::string Fold::ToString() const {
  return empty() ? std::string() : std::to_string(index) + "/" + std::to_string(count);
}

bool Fold::Check(std::string* error) const {
  if (empty() || (count >= 2 && index >= 0 && index < count)) return true;
  *error = "leave_out_fold must be empty or I/K with 0 <= I < K and K >= 2, got index " +
           std::to_string(index) + " of " + std::to_string(count);
  return false;
}

StatusOr<Fold> ParseFold(const std::string& text) {
  Fold fold;
  if (text.empty()) return fold;
  const size_t slash = text.find('/');
  const std::string help =
      "a fold is written I/K (0 <= I < K, K >= 2), e.g. 0/2; got '" + text + "'";
  if (slash == std::string::npos) return Status::InvalidArgument(help);
  try {
    size_t used_index = 0;
    size_t used_count = 0;
    fold.index = std::stoi(text.substr(0, slash), &used_index);
    fold.count = std::stoi(text.substr(slash + 1), &used_count);
    if (used_index != slash || used_count != text.size() - slash - 1) {
      return Status::InvalidArgument(help);
    }
  } catch (const std::exception&) {
    return Status::InvalidArgument(help);
  }
  if (fold.count < 2 || fold.index < 0 || fold.index >= fold.count) {
    return Status::InvalidArgument(help);
  }
  return fold;
}

int FoldOf(size_t position, size_t total, int count) {
  return static_cast<int>(position * static_cast<size_t>(count) / total);
}

}  // namespace placerec
