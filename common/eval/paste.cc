#include "common/eval/paste.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

namespace placerec {

StatusOr<std::vector<CutObject>> CutTestObjects(const std::string& dataset_dir,
                                                const CutOptions& options) {
  std::ifstream names(dataset_dir + "/classes.txt");
  std::ifstream split(dataset_dir + "/test.txt");
  if (!names || !split) {
    return Status::NotFound("no labelled dataset with classes.txt and test.txt at " + dataset_dir);
  }
  std::map<int, std::string> class_of_id;
  for (std::string line; std::getline(names, line);) {
    std::istringstream fields(line);
    int id = -1;
    std::string name;
    if (fields >> id >> name) class_of_id[id] = name;
  }
  const std::string dataset = dataset_dir.substr(dataset_dir.find_last_of('/') + 1);
  std::vector<CutObject> cut;
  for (std::string id;
       std::getline(split, id) && static_cast<int>(cut.size()) < options.max_objects;) {
    if (id.empty()) continue;
    const cv::Mat image = cv::imread(dataset_dir + "/images/" + id + ".jpg", cv::IMREAD_COLOR);
    const cv::Mat classes =
        cv::imread(dataset_dir + "/classes/" + id + ".png", cv::IMREAD_GRAYSCALE);
    const cv::Mat objects =
        cv::imread(dataset_dir + "/objects/" + id + ".png", cv::IMREAD_GRAYSCALE);
    if (image.empty() || classes.size() != image.size() || objects.size() != image.size()) continue;
    double max_object = 0;
    cv::minMaxLoc(objects, nullptr, &max_object);
    for (int object = 1; object <= static_cast<int>(max_object); ++object) {
      const cv::Mat mask = objects == object;
      const int pixels = cv::countNonZero(mask);
      if (pixels < options.min_pixels) continue;
      // The object's majority class.
      std::map<int, int> votes;
      for (int y = 0; y < mask.rows; ++y) {
        for (int x = 0; x < mask.cols; ++x) {
          if (mask.at<uint8_t>(y, x) != 0) ++votes[classes.at<uint8_t>(y, x)];
        }
      }
      const auto best =
          std::max_element(votes.begin(), votes.end(),
                           [](const auto& a, const auto& b) { return a.second < b.second; });
      const auto name = class_of_id.find(best->first);
      if (name == class_of_id.end() || std::find(options.classes.begin(), options.classes.end(),
                                                 name->second) == options.classes.end()) {
        continue;
      }
      const cv::Rect box = cv::boundingRect(mask);
      if (pixels < options.min_fill * box.area()) continue;
      CutObject piece;
      image(box).copyTo(piece.bgr);
      mask(box).copyTo(piece.mask);
      piece.class_name = name->second;
      piece.source = dataset + "/" + id + "#" + std::to_string(object);
      cut.push_back(std::move(piece));
      if (static_cast<int>(cut.size()) >= options.max_objects) break;
    }
  }
  return cut;
}

cv::Rect PasteObject(const CutObject& object, double area_share, double x, double y,
                     double colour_shift, cv::Mat* frame, double* covered_share) {
  const double mask_pixels = cv::countNonZero(object.mask);
  if (mask_pixels <= 0 || frame->empty()) return cv::Rect();
  const double scale = std::sqrt(area_share * frame->total() / mask_pixels);
  const cv::Size size(static_cast<int>(std::lround(object.bgr.cols * scale)),
                      static_cast<int>(std::lround(object.bgr.rows * scale)));
  if (size.width < 2 || size.height < 2 || size.width > frame->cols || size.height > frame->rows) {
    return cv::Rect();
  }
  cv::Mat pixels, mask;
  cv::resize(object.bgr, pixels, size, 0, 0, cv::INTER_AREA);
  cv::resize(object.mask, mask, size, 0, 0, cv::INTER_LINEAR);
  const cv::Point at(static_cast<int>(x * (frame->cols - size.width)),
                     static_cast<int>(y * (frame->rows - size.height)));
  const cv::Rect box(at, size);
  cv::Mat region = (*frame)(box);
  // Colour matched: the object's Lab mean moved `colour_shift` of the way to the region's.
  cv::Mat object_lab, region_lab;
  pixels.convertTo(object_lab, CV_32FC3, 1.0 / 255.0);
  cv::cvtColor(object_lab, object_lab, cv::COLOR_BGR2Lab);
  region.convertTo(region_lab, CV_32FC3, 1.0 / 255.0);
  cv::cvtColor(region_lab, region_lab, cv::COLOR_BGR2Lab);
  const cv::Scalar shift = (cv::mean(region_lab) - cv::mean(object_lab, mask > 127)) * colour_shift;
  object_lab += shift;
  cv::cvtColor(object_lab, object_lab, cv::COLOR_Lab2BGR);
  // Feathered edges: the mask blurred over about 1 % of the object's size.
  cv::Mat alpha;
  mask.convertTo(alpha, CV_32F, 1.0 / 255.0);
  const int feather = std::max(1, std::min(size.width, size.height) / 40) * 2 + 1;
  cv::GaussianBlur(alpha, alpha, cv::Size(feather, feather), 0);
  cv::Mat base;
  region.convertTo(base, CV_32FC3, 1.0 / 255.0);
  cv::Mat alpha3;
  cv::merge(std::vector<cv::Mat>{alpha, alpha, alpha}, alpha3);
  cv::Mat blended = object_lab.mul(alpha3) + base.mul(cv::Scalar::all(1.0) - alpha3);
  blended.convertTo(region, CV_8UC3, 255.0);
  const cv::Mat covered = mask > 127;
  if (covered_share != nullptr) {
    *covered_share = static_cast<double>(cv::countNonZero(covered)) / frame->total();
  }
  const cv::Rect on = cv::boundingRect(covered);
  return on + at;
}

cv::Rect PaintOver(const cv::Rect& box, cv::Mat* frame) {
  const cv::Rect clipped = box & cv::Rect(0, 0, frame->cols, frame->rows);
  if (clipped.area() <= 0) return cv::Rect();
  cv::Mat mask = cv::Mat::zeros(frame->size(), CV_8U);
  mask(clipped).setTo(255);
  cv::Mat painted;
  cv::inpaint(*frame, mask, painted, 5, cv::INPAINT_TELEA);
  painted.copyTo(*frame);
  return clipped;
}

double BoxIoU(const cv::Rect& a, const cv::Rect& b) {
  const double inter = (a & b).area();
  const double uni = static_cast<double>(a.area()) + b.area() - inter;
  return uni > 0 ? inter / uni : 0.0;
}

}  // namespace placerec
