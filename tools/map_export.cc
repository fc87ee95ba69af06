// `placerec-map export`: places.csv, route.png, the place thumbnails and their contact sheet
// (map_tools.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/util/paths.h"
#include "tools/map_tools.h"

namespace placerec {
namespace {

constexpr char kCsvHeader[] = "id,robot,sequence,utime,landmarks,descriptors,classes,thumbnail";

// Whether `file` is a thumbnail as places.csv names it: thumbnails/<place id>.jpg.
bool IsThumbnailName(const std::string& file) {
  const std::string prefix = "thumbnails/", suffix = ".jpg";
  if (file.size() <= prefix.size() + suffix.size() || file.compare(0, prefix.size(), prefix) != 0 ||
      file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0) {
    return false;
  }
  return std::all_of(file.begin() + static_cast<std::ptrdiff_t>(prefix.size()),
                     file.end() - static_cast<std::ptrdiff_t>(suffix.size()),
                     [](char c) { return c >= '0' && c <= '9'; });
}

// A CSV field, quoted when it holds a separator, a quote or a line break.
std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string quoted = "\"";
  for (const char c : text) {
    quoted += c;
    if (c == '"') quoted += '"';
  }
  return quoted + "\"";
}

// Colours (BGR) of the object classes in the picture, by their order of name; unclassified grey.
// Hues a golden angle apart, with alternating saturation and value, stay apart for the 21
// classes of MSRC and more.
cv::Scalar ClassColour(size_t index) {
  const double hue = std::fmod(static_cast<double>(index) * 0.6180339887, 1.0) * 180.0;
  const double saturation = index % 2 == 0 ? 220 : 140;
  const double value = index % 3 == 0 ? 170 : 230;
  cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(hue, saturation, value)), bgr;
  cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
  const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
  return cv::Scalar(c[0], c[1], c[2]);
}
const cv::Scalar kUnclassified(200, 200, 200);

void Text(cv::Mat* image, const std::string& text, int x, int y, double scale = 0.45) {
  cv::putText(*image, text, {x, y}, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(20, 20, 20), 1,
              cv::LINE_AA);
}

// The picture: per robot (in order of first place) a caption, a strip of its places in time
// order coloured by landmark count (viridis, one scale for the whole map), a strip of the class
// shares of their landmarks, and the robot's class counts; a legend at the bottom.
cv::Mat DrawRoute(const std::vector<PlaceSummary>& places) {
  constexpr int kLeft = 10, kWidth = 1200, kCaption = 22, kCountStrip = 36, kClassStrip = 18;
  constexpr int kClassLine = 20, kGap = 14, kLegend = 60;
  std::vector<std::string> robots;
  std::map<std::string, std::vector<const PlaceSummary*>> by_robot;
  std::map<std::string, int64_t> class_totals;
  int64_t max_landmarks = 1;
  for (const PlaceSummary& place : places) {
    if (by_robot.find(place.robot) == by_robot.end()) robots.push_back(place.robot);
    by_robot[place.robot].push_back(&place);
    max_landmarks = std::max(max_landmarks, place.landmarks);
    for (const auto& [name, count] : place.classes) class_totals[name] += count;
  }
  std::map<std::string, cv::Scalar> colours;
  size_t next_colour = 0;
  for (const auto& [name, count] : class_totals) {
    colours[name] = name.empty() ? kUnclassified : ClassColour(next_colour++);
  }
  // The legend's class entries, row by row after the count scale (every class is listed).
  constexpr int kLegendX = kLeft + 340, kLegendRow = 18;
  std::vector<std::pair<cv::Point, std::string>> legend;  // offset from the legend's top, class
  {
    int x = kLegendX, row = 0;
    for (const auto& [name, colour] : colours) {
      const std::string label = name.empty() ? "unclassified" : name;
      const int width = 24 + 8 * static_cast<int>(label.size());
      if (x + width > kLeft + kWidth && x > kLegendX) {
        x = kLegendX;
        ++row;
      }
      legend.emplace_back(cv::Point(x, row * kLegendRow), name);
      x += width;
    }
  }
  const int legend_rows = legend.empty() ? 1 : legend.back().first.y / kLegendRow + 1;
  const int block = kCaption + kCountStrip + kClassStrip + kClassLine + kGap;
  const int height = 30 + block * static_cast<int>(robots.size()) +
                     std::max(kLegend, (legend_rows + 1) * kLegendRow);
  cv::Mat image(height, kLeft * 2 + kWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  Text(&image,
       std::to_string(places.size()) + " places of " + std::to_string(robots.size()) +
           (robots.size() == 1 ? " robot" : " robots") + "; colour: landmarks per place (0 .. " +
           std::to_string(max_landmarks) + ")",
       kLeft, 20, 0.5);
  cv::Mat scale(1, 256, CV_8UC1);
  for (int i = 0; i < 256; ++i) scale.at<uint8_t>(0, i) = static_cast<uint8_t>(i);
  cv::Mat scale_colours;
  cv::applyColorMap(scale, scale_colours, cv::COLORMAP_VIRIDIS);
  const auto count_colour = [&](double landmarks) {
    const int level = std::clamp(static_cast<int>(255.0 * landmarks / max_landmarks), 0, 255);
    const cv::Vec3b c = scale_colours.at<cv::Vec3b>(0, level);
    return cv::Scalar(c[0], c[1], c[2]);
  };

  int y = 30;
  for (const std::string& robot : robots) {
    std::vector<const PlaceSummary*> list = by_robot[robot];
    std::stable_sort(list.begin(), list.end(), [](const PlaceSummary* l, const PlaceSummary* r) {
      return l->utime != r->utime ? l->utime < r->utime : l->sequence < r->sequence;
    });
    int64_t landmarks = 0;
    std::map<std::string, int64_t> classes;
    for (const PlaceSummary* place : list) {
      landmarks += place->landmarks;
      for (const auto& [name, count] : place->classes) classes[name] += count;
    }
    char caption[256];
    std::snprintf(caption, sizeof(caption), "%s: %zu places, %lld landmarks, %.1f s", robot.c_str(),
                  list.size(), static_cast<long long>(landmarks),
                  (list.back()->utime - list.front()->utime) / 1e6);
    Text(&image, caption, kLeft, y + 16);
    y += kCaption;
    // Pixel column x shows places [x n / W, (x + 1) n / W): several places share a column on a
    // long run (their mean count and summed classes), a short run's places span several columns.
    const int n = static_cast<int>(list.size());
    for (int x = 0; x < kWidth; ++x) {
      const int first = static_cast<int>(static_cast<int64_t>(x) * n / kWidth);
      const int last =
          std::max(first + 1, static_cast<int>(static_cast<int64_t>(x + 1) * n / kWidth));
      double sum = 0;
      std::map<std::string, int64_t> shares;
      int64_t share_total = 0;
      for (int i = first; i < last && i < n; ++i) {
        sum += static_cast<double>(list[i]->landmarks);
        for (const auto& [name, count] : list[i]->classes) {
          shares[name] += count;
          share_total += count;
        }
      }
      const cv::Scalar colour =
          sum > 0 ? count_colour(sum / (last - first)) : cv::Scalar(60, 60, 60);
      cv::line(image, {kLeft + x, y}, {kLeft + x, y + kCountStrip - 3}, colour);
      int top = y + kCountStrip;
      int64_t done = 0;
      for (const auto& [name, count] : shares) {
        const int from = top + static_cast<int>(done * (kClassStrip - 2) / share_total);
        done += count;
        const int to = top + static_cast<int>(done * (kClassStrip - 2) / share_total);
        if (to > from) cv::line(image, {kLeft + x, from}, {kLeft + x, to - 1}, colours[name]);
      }
    }
    y += kCountStrip + kClassStrip;
    const std::string counts = FormatClassCounts(classes);
    Text(&image, counts.empty() ? "no landmarks" : "classes " + counts, kLeft, y + 14, 0.4);
    y += kClassLine + kGap;
  }
  // Legend: the count scale, then the class colours.
  for (int x = 0; x < 256; ++x) {
    cv::line(image, {kLeft + x, y}, {kLeft + x, y + 12}, count_colour(max_landmarks * x / 255.0));
  }
  Text(&image, "0", kLeft, y + 28, 0.4);
  Text(&image, std::to_string(max_landmarks) + " landmarks", kLeft + 220, y + 28, 0.4);
  for (const auto& [at, name] : legend) {
    cv::rectangle(image, cv::Rect(at.x, y + at.y, 12, 12), colours[name], cv::FILLED);
    Text(&image, name.empty() ? "unclassified" : name, at.x + 16, y + at.y + 11, 0.4);
  }
  return image;
}

// Contact sheet tiles: thumbnails scaled to kTileWidth pixels with a caption, kSheetColumns a row.
constexpr int kTileWidth = 160;
constexpr int kTileHeight = 120;
constexpr int kCaption = 14;
constexpr int kSheetColumns = 10;
constexpr int64_t kSheetTiles = 120;

cv::Mat Tile(const cv::Mat& image, const std::string& caption) {
  cv::Mat tile(kTileHeight + kCaption, kTileWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  const double scale = std::min(static_cast<double>(kTileWidth) / image.cols,
                                static_cast<double>(kTileHeight) / image.rows);
  cv::Mat scaled;
  cv::resize(image, scaled,
             cv::Size(std::max(1, static_cast<int>(image.cols * scale)),
                      std::max(1, static_cast<int>(image.rows * scale))),
             0, 0, cv::INTER_AREA);
  scaled.copyTo(tile(cv::Rect(0, 0, scaled.cols, scaled.rows)));
  cv::putText(tile, caption, cv::Point(2, kTileHeight + kCaption - 3), cv::FONT_HERSHEY_SIMPLEX,
              0.35, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  return tile;
}

cv::Mat ContactSheet(const std::vector<cv::Mat>& tiles) {
  const int columns = std::min<int>(kSheetColumns, static_cast<int>(tiles.size()));
  const int rows = (static_cast<int>(tiles.size()) + columns - 1) / columns;
  const int tile_height = kTileHeight + kCaption;
  cv::Mat sheet(rows * (tile_height + 2), columns * (kTileWidth + 2), CV_8UC3,
                cv::Scalar(200, 200, 200));
  for (size_t i = 0; i < tiles.size(); ++i) {
    const int r = static_cast<int>(i) / columns;
    const int c = static_cast<int>(i) % columns;
    tiles[i].copyTo(
        sheet(cv::Rect(c * (kTileWidth + 2), r * (tile_height + 2), kTileWidth, tile_height)));
  }
  return sheet;
}

}  // namespace

StatusOr<ExportReport> ExportMap(const std::string& path, const std::string& out_dir) {
  StatusOr<std::vector<PlaceSummary>> places = ReadPlaceSummaries(path);
  if (!places.ok()) return places.status();
  if (!MakeDirectories(out_dir)) {
    return Status::IoError("cannot create or write in " + out_dir +
                           ": choose a folder you can write");
  }
  // What an earlier export into this folder listed in its places.csv (this export's own format):
  // its thumbnails, removed below when this export does not write them again.
  std::set<std::string> earlier_thumbnails;
  bool earlier_export = false;
  {
    std::ifstream earlier(out_dir + "/places.csv");
    std::string line;
    if (std::getline(earlier, line) && line == kCsvHeader) {
      earlier_export = true;
      while (std::getline(earlier, line)) {
        const size_t comma = line.find_last_of(',');
        const std::string file = comma == std::string::npos ? "" : line.substr(comma + 1);
        if (IsThumbnailName(file)) earlier_thumbnails.insert(file);
      }
    }
  }
  ExportReport report;
  report.csv_path = out_dir + "/places.csv";
  report.picture_path = out_dir + "/route.png";
  // Thumbnails: every one as a file, an even sample of them on the contact sheet.
  std::map<int64_t, const PlaceSummary*> by_id;
  int64_t with_thumbnail = 0;
  for (const PlaceSummary& place : *places) {
    by_id[place.id] = &place;
    with_thumbnail += place.thumbnail ? 1 : 0;
  }
  const int64_t every = std::max<int64_t>(1, (with_thumbnail + kSheetTiles - 1) / kSheetTiles);
  std::vector<cv::Mat> tiles;
  int64_t seen = 0;
  if (with_thumbnail > 0 && !MakeDirectories(out_dir + "/thumbnails")) {
    return Status::IoError("cannot create or write in " + out_dir + "/thumbnails");
  }
  Status written = Status::Ok();
  PLACEREC_RETURN_IF_ERROR(
      ForEachThumbnail(path, [&](int64_t id, const std::vector<uint8_t>& jpeg) {
        if (!written.ok()) return;
        // Only the places read above: a server writing beside the export may have committed a
        // place (and its thumbnail) since, which places.csv does not list.
        const auto place = by_id.find(id);
        if (place == by_id.end() || !place->second->thumbnail) return;
        const std::string file = out_dir + "/thumbnails/" + std::to_string(id) + ".jpg";
        std::ofstream out(file, std::ios::binary);
        out.write(reinterpret_cast<const char*>(jpeg.data()),
                  static_cast<std::streamsize>(jpeg.size()));
        if (!out.flush()) {
          written = Status::IoError("cannot write " + file);
          return;
        }
        ++report.thumbnails;
        if (seen++ % every != 0) return;
        const cv::Mat image = cv::imdecode(jpeg, cv::IMREAD_COLOR);
        if (image.empty()) return;
        tiles.push_back(
            Tile(image, place->second->robot + " #" + std::to_string(place->second->sequence)));
      }));
  PLACEREC_RETURN_IF_ERROR(written);
  if (!tiles.empty()) {
    report.contact_sheet_path = out_dir + "/contact_sheet.jpg";
    if (!cv::imwrite(report.contact_sheet_path, ContactSheet(tiles))) {
      return Status::IoError("cannot write " + report.contact_sheet_path);
    }
  }
  {
    std::ofstream csv(report.csv_path);
    csv << kCsvHeader << '\n';
    std::map<std::string, int> robots;
    for (const PlaceSummary& place : *places) {
      csv << place.id << ',' << CsvField(place.robot) << ',' << place.sequence << ',' << place.utime
          << ',' << place.landmarks << ',' << place.descriptors << ','
          << CsvField(FormatClassCounts(place.classes)) << ','
          << (place.thumbnail ? "thumbnails/" + std::to_string(place.id) + ".jpg" : "") << '\n';
      robots[place.robot] = 1;
    }
    report.robots = static_cast<int64_t>(robots.size());
    if (!csv.flush()) return Status::IoError("cannot write " + report.csv_path);
  }
  report.places = static_cast<int64_t>(places->size());
  const cv::Mat picture = DrawRoute(*places);
  if (!cv::imwrite(report.picture_path, picture)) {
    return Status::IoError("cannot write " + report.picture_path);
  }
  // Written whole: what the earlier export had and this one has not goes (a pruned map's places,
  // an old map's pictures), and nothing that no export listed.
  for (const PlaceSummary& place : *places) {
    if (place.thumbnail)
      earlier_thumbnails.erase("thumbnails/" + std::to_string(place.id) + ".jpg");
  }
  std::error_code ignored;
  for (const std::string& file : earlier_thumbnails) {
    std::filesystem::remove(out_dir + "/" + file, ignored);
  }
  if (earlier_export && report.contact_sheet_path.empty()) {
    std::filesystem::remove(out_dir + "/contact_sheet.jpg", ignored);
  }
  return report;
}

}  // namespace placerec
