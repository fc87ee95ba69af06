#include "common/organization/region_merging.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <queue>
#include <tuple>

#include <glog/logging.h>
#include <opencv2/core/persistence.hpp>
#include <opencv2/imgproc.hpp>

#include "common/organization/filter_bank.h"
#include "common/organization/textons.h"

namespace placerec {
namespace {

// A crack whose two pixels differ by more than this (Delta E) counts as a strong edge.
constexpr double kStrongContrast = 10.0;

double DeltaE(const cv::Vec3f& p, const cv::Vec3f& q) {
  const double dl = p[0] - q[0];
  const double da = p[1] - q[1];
  const double db = p[2] - q[2];
  return std::sqrt(dl * dl + da * da + db * db);
}

}  // namespace

bool RegionMergeOptions::Check(std::string* error) const {
  if (!std::isfinite(threshold)) {
    *error = "region merge threshold must be finite";
    return false;
  }
  return true;
}

MergeState::MergeState(const cv::Mat& labels, int num_regions, const cv::Mat& lab,
                       const cv::Mat& appearance, int texton_stride, const cv::Mat& feature_inv_std,
                       const BackgroundClassifier& classifier, double background_threshold,
                       bool one_per_class, const cv::Mat& boundary_scores)
    : labels_(labels.clone()),
      size_(labels.size()),
      classifier_(classifier),
      background_threshold_(background_threshold),
      one_per_class_(one_per_class) {
  CHECK_EQ(labels.type(), CV_32S);
  CHECK_EQ(lab.type(), CV_32FC3);
  CHECK(lab.size() == labels.size());
  CHECK_EQ(appearance.rows, num_regions);
  CHECK_EQ(appearance.type(), CV_32F);
  CHECK_GE(texton_stride, 1);
  have_boundary_ = !boundary_scores.empty();
  if (have_boundary_) {
    CHECK_EQ(boundary_scores.type(), CV_32F);
    CHECK(boundary_scores.size() == labels.size());
  }
  k_ = appearance.cols - 1 - kAppearanceExtras;
  CHECK_GT(k_, 0);
  CHECK_EQ(feature_inv_std.total(), static_cast<size_t>(kTextonFeatureSize));
  inv_std_.assign(feature_inv_std.ptr<float>(), feature_inv_std.ptr<float>() + kTextonFeatureSize);
  regions_.resize(static_cast<size_t>(num_regions));
  parent_.resize(static_cast<size_t>(num_regions));
  for (int i = 0; i < num_regions; ++i) {
    parent_[i] = i;
    Region& r = regions_[i];
    r.min_x = size_.width;
    r.min_y = size_.height;
    r.max_x = -1;
    r.max_y = -1;
    r.appearance.assign(appearance.ptr<float>(i), appearance.ptr<float>(i) + appearance.cols);
  }
  // Contrast across the boundary on a smoothed image, between the pixels one step beyond each
  // side of the crack: an edge measure less disturbed by texture than adjacent pixels.
  cv::Mat smooth;
  cv::GaussianBlur(lab, smooth, cv::Size(0, 0), 1.0);
  auto wide = [&](int x0, int y0, int x1, int y1) {
    const int xa = std::clamp(2 * x0 - x1, 0, size_.width - 1);
    const int ya = std::clamp(2 * y0 - y1, 0, size_.height - 1);
    const int xb = std::clamp(2 * x1 - x0, 0, size_.width - 1);
    const int yb = std::clamp(2 * y1 - y0, 0, size_.height - 1);
    return DeltaE(smooth.at<cv::Vec3f>(ya, xa), smooth.at<cv::Vec3f>(yb, xb));
  };
  std::map<std::pair<int, int>, int> edge_of;
  auto crack = [&](int a, int b, double contrast, double wide_contrast, bool horizontal,
                   double boundary) {
    const std::pair<int, int> key(std::min(a, b), std::max(a, b));
    auto it = edge_of.find(key);
    if (it == edge_of.end()) {
      it = edge_of.emplace(key, static_cast<int>(edges_.size())).first;
      edges_.emplace_back();
      regions_[a].neighbours[b] = it->second;
      regions_[b].neighbours[a] = it->second;
    }
    Edge& e = edges_[it->second];
    e.shared += 1;
    e.contrast_sum += contrast;
    e.strong += contrast > kStrongContrast;
    e.wide_sum += wide_contrast;
    e.horizontal += horizontal;
    e.boundary_sum += boundary;
    e.boundary_positive += boundary > 0;
    e.boundary_strong += boundary > kStrongBoundary;
    e.boundary_weak += boundary < kWeakBoundary;
  };
  for (int y = 0; y < size_.height; ++y) {
    const int* row = labels.ptr<int>(y);
    const int* below = y + 1 < size_.height ? labels.ptr<int>(y + 1) : nullptr;
    const cv::Vec3f* lab_row = lab.ptr<cv::Vec3f>(y);
    const cv::Vec3f* lab_below = below != nullptr ? lab.ptr<cv::Vec3f>(y + 1) : nullptr;
    const float* boundary_row = have_boundary_ ? boundary_scores.ptr<float>(y) : nullptr;
    const float* boundary_below =
        have_boundary_ && below != nullptr ? boundary_scores.ptr<float>(y + 1) : nullptr;
    for (int x = 0; x < size_.width; ++x) {
      const int l = row[x];
      CHECK(l >= 0 && l < num_regions) << "label " << l << " outside 0.." << num_regions - 1;
      Region& r = regions_[l];
      r.area += 1;
      r.sum_x += x;
      r.sum_y += y;
      const cv::Vec3d c(lab_row[x]);
      r.lab_sum += c;
      r.lab_squares += c.mul(c);
      r.min_x = std::min(r.min_x, x);
      r.min_y = std::min(r.min_y, y);
      r.max_x = std::max(r.max_x, x);
      r.max_y = std::max(r.max_y, y);
      if (x == 0 || x + 1 == size_.width) r.perimeter += 1;
      if (y == 0 || y + 1 == size_.height) r.perimeter += 1;
      if (x + 1 < size_.width && row[x + 1] != l) {
        r.perimeter += 1;
        regions_[row[x + 1]].perimeter += 1;
        crack(l, row[x + 1], DeltaE(lab_row[x], lab_row[x + 1]), wide(x, y, x + 1, y), false,
              have_boundary_ ? 0.5 * (boundary_row[x] + boundary_row[x + 1]) : 0.0);
      }
      if (below != nullptr && below[x] != l) {
        r.perimeter += 1;
        regions_[below[x]].perimeter += 1;
        crack(l, below[x], DeltaE(lab_row[x], lab_below[x]), wide(x, y, x, y + 1), true,
              have_boundary_ ? 0.5 * (boundary_row[x] + boundary_below[x]) : 0.0);
      }
      if (y % texton_stride == 0 && x % texton_stride == 0) r.samples += 1;
    }
  }
  for (Region& r : regions_) {
    if (r.samples == 0) r.samples = r.area;  // RegionAppearance used all its pixels
    if (r.area == 0) r.alive = false;
  }
  // Background scores of the initial regions in one batch.
  const cv::Mat scores = classifier_.Scores(appearance);
  const cv::Mat structured = classifier_.StructuredScores(appearance);
  for (int i = 0; i < num_regions; ++i) {
    Region& r = regions_[i];
    std::copy(scores.ptr<float>(i), scores.ptr<float>(i) + kBackgroundClasses, r.scores.begin());
    r.structured_scores.assign(structured.ptr<float>(i),
                               structured.ptr<float>(i) + structured.cols);
    Decide(&r);
  }
}

std::vector<std::pair<int, int>> MergeState::Pairs() const {
  std::vector<std::pair<int, int>> pairs;
  for (int a = 0; a < capacity(); ++a) {
    if (!regions_[a].alive) continue;
    for (const auto& [b, edge] : regions_[a].neighbours) {
      if (b > a) pairs.emplace_back(a, b);
    }
  }
  return pairs;
}

const std::map<int, int>& MergeState::NeighboursOf(int region) const {
  return regions_[region].neighbours;
}

void MergeState::PairFeatures(int a, int b, float* out) const {
  const Region& ra = regions_[a];
  const Region& rb = regions_[b];
  const auto it = ra.neighbours.find(b);
  CHECK(it != ra.neighbours.end()) << "regions " << a << " and " << b << " are not adjacent";
  const Edge& e = edges_[it->second];
  const cv::Vec3d mean_a = ra.lab_sum * (1.0 / ra.area);
  const cv::Vec3d mean_b = rb.lab_sum * (1.0 / rb.area);
  const cv::Vec3d d = mean_a - mean_b;
  auto lab_std = [](const Region& r, const cv::Vec3d& mean) {
    double var = 0;
    for (int c = 0; c < 3; ++c) var += std::max(0.0, r.lab_squares[c] / r.area - mean[c] * mean[c]);
    return std::sqrt(var);
  };
  double chi2 = 0;
  for (int t = 0; t < k_; ++t) {
    const double s = ra.appearance[t] + rb.appearance[t];
    if (s > 0) {
      const double diff = ra.appearance[t] - rb.appearance[t];
      chi2 += diff * diff / s;
    }
  }
  double mean_diff = 0;
  double std_diff = 0;
  for (int f = 0; f < kTextonFeatureSize; ++f) {
    const int m = k_ + 1 + f;
    const int s = k_ + 1 + kTextonFeatureSize + f;
    mean_diff += std::abs(ra.appearance[m] - rb.appearance[m]) * inv_std_[f];
    std_diff += std::abs(ra.appearance[s] - rb.appearance[s]) * inv_std_[f];
  }
  const double image_area = static_cast<double>(size_.area());
  const double small = std::min(ra.area, rb.area);
  const double large = std::max(ra.area, rb.area);
  const double ya = ra.sum_y / ra.area / size_.height;
  const double yb = rb.sum_y / rb.area / size_.height;
  const int box_w = std::max(ra.max_x, rb.max_x) - std::min(ra.min_x, rb.min_x) + 1;
  const int box_h = std::max(ra.max_y, rb.max_y) - std::min(ra.min_y, rb.min_y) + 1;
  const double contrast = e.contrast_sum / std::max(1.0, e.shared);
  int i = 0;
  out[i++] = static_cast<float>(std::sqrt(d.dot(d)));
  out[i++] = static_cast<float>(std::abs(d[0]));
  out[i++] = static_cast<float>(std::hypot(d[1], d[2]));
  out[i++] = static_cast<float>(0.5 * chi2);
  out[i++] = static_cast<float>(mean_diff / kTextonFeatureSize);
  out[i++] = static_cast<float>(std_diff / kTextonFeatureSize);
  out[i++] = static_cast<float>(contrast);
  out[i++] = static_cast<float>(e.strong / std::max(1.0, e.shared));
  out[i++] =
      static_cast<float>(contrast / (1.0 + 0.5 * (lab_std(ra, mean_a) + lab_std(rb, mean_b))));
  out[i++] = static_cast<float>(e.shared / std::max(1.0, std::min(ra.perimeter, rb.perimeter)));
  out[i++] = static_cast<float>(e.shared / std::max(1.0, std::max(ra.perimeter, rb.perimeter)));
  out[i++] = static_cast<float>(std::log(small / image_area));
  out[i++] = static_cast<float>(std::log(large / image_area));
  out[i++] = static_cast<float>(std::min(ya, yb));
  out[i++] = static_cast<float>(std::max(ya, yb));
  out[i++] = static_cast<float>(std::abs(ra.sum_x / ra.area - rb.sum_x / rb.area) / size_.width);
  out[i++] = static_cast<float>((ra.area + rb.area) / (static_cast<double>(box_w) * box_h));
  out[i++] = static_cast<float>(small / large);
  out[i++] = ra.segment_class == rb.segment_class ? 1.0f : 0.0f;
  out[i++] =
      ra.segment_class == SegmentClass::kStructured && rb.segment_class == SegmentClass::kStructured
          ? 1.0f
          : 0.0f;
  for (int c = 0; c < kBackgroundClasses; ++c) out[i++] = std::min(ra.scores[c], rb.scores[c]);
  for (int c = 0; c < kBackgroundClasses; ++c) out[i++] = std::max(ra.scores[c], rb.scores[c]);
  const double shared = std::max(1.0, e.shared);
  out[i++] = static_cast<float>(e.wide_sum / shared);
  out[i++] = static_cast<float>(e.horizontal / shared);
  // How much of the smaller region's height the larger one spans: 1 beside it, 0 above/below.
  const Region& s_region = ra.area <= rb.area ? ra : rb;
  const Region& l_region = ra.area <= rb.area ? rb : ra;
  const int overlap =
      std::min(s_region.max_y, l_region.max_y) - std::max(s_region.min_y, l_region.min_y) + 1;
  out[i++] = static_cast<float>(std::max(0, overlap)) / (s_region.max_y - s_region.min_y + 1);
  CHECK_EQ(i, kMergeRelationFeatures);
  // Semantic features (zeros without structured classifiers).
  const int structured = static_cast<int>(ra.structured_scores.size());
  for (int j = 0; j < kMergeStructuredScores; ++j) {
    const bool have = j < structured;
    out[i++] = have ? std::min(ra.structured_scores[j], rb.structured_scores[j]) : 0.0f;
    out[i++] = have ? std::max(ra.structured_scores[j], rb.structured_scores[j]) : 0.0f;
  }
  out[i++] = std::min(ra.margin, rb.margin);
  out[i++] = std::max(ra.margin, rb.margin);
  out[i++] = structured > 0 && ra.best_class == rb.best_class ? 1.0f : 0.0f;
  CHECK_EQ(i, kMergeBoundaryOffset);
  if (have_boundary_) {
    out[i++] = static_cast<float>(e.boundary_sum / shared);
    out[i++] = static_cast<float>(e.boundary_positive / shared);
    out[i++] = static_cast<float>(e.boundary_strong / shared);
    out[i++] = static_cast<float>(e.boundary_weak / shared);
    auto internal = [](const Region& r) {
      return r.internal_cracks > 0 ? static_cast<float>(r.internal_boundary_sum / r.internal_cracks)
                                   : kNoInternalBoundary;
    };
    out[i++] = std::min(internal(ra), internal(rb));
    out[i++] = std::max(internal(ra), internal(rb));
  } else {
    for (int f = 0; f < kMergeBoundaryFeatures; ++f) out[i++] = 0.0f;
  }
  CHECK_EQ(i, kMergeAppearanceOffset);
  for (int f = 0; f < kTextonFeatureSize; ++f) {
    const float ma = ra.appearance[k_ + 1 + f];
    const float mb = rb.appearance[k_ + 1 + f];
    out[i++] = std::min(ma, mb);
    out[i++] = std::max(ma, mb);
  }
  CHECK_EQ(i, kMergeFeatures);
}

void MergeState::Describe(Region* r) const {
  CHECK_GE(static_cast<int>(r->appearance.size()), classifier_.feature_size());
  r->structured_scores.resize(static_cast<size_t>(classifier_.structured_classes()));
  classifier_.RowScores(r->appearance.data(), r->scores.data(), r->structured_scores.data());
  Decide(r);
}

void MergeState::Decide(Region* r) const {
  const auto background = std::max_element(r->scores.begin(), r->scores.end());
  const auto structured =
      std::max_element(r->structured_scores.begin(), r->structured_scores.end());
  const bool has_structured = structured != r->structured_scores.end();
  r->best_class =
      has_structured && *structured > *background
          ? kBackgroundClasses + static_cast<int>(structured - r->structured_scores.begin())
          : static_cast<int>(background - r->scores.begin());
  r->margin = has_structured ? *background - *structured : 0.0f;
  const float rival =
      one_per_class_ && has_structured ? *structured : -std::numeric_limits<float>::infinity();
  r->segment_class = BackgroundClassifier::Decide(r->scores.data(), background_threshold_, rival);
}

void MergeState::Merge(int a, int b) {
  CHECK_NE(a, b);
  Region& ra = regions_[a];
  Region& rb = regions_[b];
  CHECK(ra.alive && rb.alive);
  const auto ab = ra.neighbours.find(b);
  CHECK(ab != ra.neighbours.end()) << "merging regions that are not adjacent";
  const double shared = edges_[ab->second].shared;
  // The common boundary's cracks are inside the union from now on.
  ra.internal_boundary_sum += rb.internal_boundary_sum + edges_[ab->second].boundary_sum;
  ra.internal_cracks += rb.internal_cracks + shared;
  // Appearance: sample-weighted histograms and feature moments; height from the pixels.
  const double wa = ra.samples / (ra.samples + rb.samples);
  const double wb = 1.0 - wa;
  for (int t = 0; t < k_; ++t) {
    ra.appearance[t] = static_cast<float>(wa * ra.appearance[t] + wb * rb.appearance[t]);
  }
  for (int f = 0; f < kTextonFeatureSize; ++f) {
    const int m = k_ + 1 + f;
    const int s = k_ + 1 + kTextonFeatureSize + f;
    const double mean = wa * ra.appearance[m] + wb * rb.appearance[m];
    const double second = wa * (static_cast<double>(ra.appearance[s]) * ra.appearance[s] +
                                static_cast<double>(ra.appearance[m]) * ra.appearance[m]) +
                          wb * (static_cast<double>(rb.appearance[s]) * rb.appearance[s] +
                                static_cast<double>(rb.appearance[m]) * rb.appearance[m]);
    ra.appearance[m] = static_cast<float>(mean);
    ra.appearance[s] = static_cast<float>(std::sqrt(std::max(0.0, second - mean * mean)));
  }
  ra.area += rb.area;
  ra.sum_x += rb.sum_x;
  ra.sum_y += rb.sum_y;
  ra.lab_sum += rb.lab_sum;
  ra.lab_squares += rb.lab_squares;
  ra.min_x = std::min(ra.min_x, rb.min_x);
  ra.min_y = std::min(ra.min_y, rb.min_y);
  ra.max_x = std::max(ra.max_x, rb.max_x);
  ra.max_y = std::max(ra.max_y, rb.max_y);
  ra.perimeter = ra.perimeter + rb.perimeter - 2 * shared;  // seed Lemma 1
  ra.samples += rb.samples;
  ra.appearance[k_] = static_cast<float>((ra.sum_y / ra.area + 0.5) / size_.height);
  // Boundaries: b's edges move to a, joining a's edge to the same neighbour.
  ra.neighbours.erase(ab);
  for (const auto& [n, edge] : rb.neighbours) {
    if (n == a) continue;
    Region& rn = regions_[n];
    rn.neighbours.erase(b);
    const auto existing = ra.neighbours.find(n);
    if (existing != ra.neighbours.end()) {
      Edge& target = edges_[existing->second];
      const Edge& source = edges_[edge];
      target.shared += source.shared;
      target.contrast_sum += source.contrast_sum;
      target.strong += source.strong;
      target.wide_sum += source.wide_sum;
      target.horizontal += source.horizontal;
      target.boundary_sum += source.boundary_sum;
      target.boundary_positive += source.boundary_positive;
      target.boundary_strong += source.boundary_strong;
      target.boundary_weak += source.boundary_weak;
    } else {
      ra.neighbours[n] = edge;
      rn.neighbours[a] = edge;
    }
  }
  rb.neighbours.clear();
  rb.alive = false;
  rb.appearance.clear();
  parent_[b] = a;
  Describe(&ra);
}

int MergeState::Find(int region) const {
  int root = region;
  while (parent_[root] != root) root = parent_[root];
  while (parent_[region] != root) {
    const int next = parent_[region];
    parent_[region] = root;
    region = next;
  }
  return root;
}

SceneSegmentation MergeState::Result() const {
  SceneSegmentation result;
  result.labels.create(size_, CV_32S);
  std::vector<int> compact(regions_.size(), -1);
  for (int y = 0; y < size_.height; ++y) {
    const int* in = labels_.ptr<int>(y);
    int* out = result.labels.ptr<int>(y);
    for (int x = 0; x < size_.width; ++x) {
      const int root = Find(in[x]);
      if (compact[root] < 0) {
        compact[root] = static_cast<int>(result.classes.size());
        result.classes.push_back(regions_[root].segment_class);
      }
      out[x] = compact[root];
    }
  }
  return result;
}

// ---- The model ----

bool RegionMergeModel::TrainingOptions::Check(std::string* error) const {
  if (weak_count < 1 || max_depth < 1 || max_depth > BoostedForest::kMaxTrainingDepth ||
      !(weight_trim_rate >= 0 && weight_trim_rate <= 1)) {
    *error = "grouping training: weak_count >= 1, max_depth in [1, " +
             std::to_string(BoostedForest::kMaxTrainingDepth) + "], weight_trim_rate in [0, 1]";
    return false;
  }
  return true;
}

RegionMergeModel RegionMergeModel::Train(const cv::Mat& features, const std::vector<int>& labels,
                                         const std::vector<float>& weights,
                                         const TrainingOptions& options) {
  CHECK_EQ(features.type(), CV_32F);
  CHECK(features.cols >= 1 && features.cols <= kMergeFeatures);
  CHECK_EQ(features.rows, static_cast<int>(labels.size()));
  CHECK(weights.empty() || weights.size() == labels.size());
  cv::Mat responses(features.rows, 1, CV_32S);
  cv::Mat sample_weights(features.rows, 1, CV_32F, cv::Scalar(1.0f));
  for (int r = 0; r < features.rows; ++r) {
    responses.at<int>(r) = labels[r] != 0 ? 1 : 0;
    if (!weights.empty()) sample_weights.at<float>(r) = weights[r];
  }
  RegionMergeModel model;
  model.AddMember(TrainGentleBoost(features, responses, sample_weights, options.weak_count,
                                   options.max_depth, options.weight_trim_rate));
  return model;
}

RegionMergeModel RegionMergeModel::Ensemble(const std::vector<RegionMergeModel>& models) {
  RegionMergeModel ensemble;
  for (const RegionMergeModel& m : models) {
    CHECK(!m.empty()) << "an ensemble member is empty";
    for (const auto& member : m.members_) ensemble.AddMember(member);
  }
  return ensemble;
}

int RegionMergeModel::feature_size() const {
  int size = 0;
  for (const auto& m : members_) size = std::max(size, m->getVarCount());
  return size;
}

Status RegionMergeModel::Save(const std::string& directory) const {
  if (empty()) return Status::InvalidArgument("no grouping model to save");
  const std::string path = directory + "/" + kFileName;
  // Written aside and moved into place whole: training writes into the models folder a server
  // loads, and a file cut short there stops the server (the temporary name keeps the .gz
  // ending: FileStorage compresses by the name).
  const std::string temporary = directory + "/.writing." + kFileName;
  try {
    cv::FileStorage fs(temporary, cv::FileStorage::WRITE);
    if (!fs.isOpened()) return Status::IoError("cannot write " + temporary);
    fs << "format_version" << kFormatVersion;
    fs << "features" << feature_size();
    fs << "members" << members();
    for (int i = 0; i < members(); ++i) {
      fs << "member_" + std::to_string(i) << "{";
      members_[i]->write(fs);
      fs << "}";
    }
    fs.release();
  } catch (const cv::Exception& e) {
    return Status::IoError("cannot write " + temporary + ": " + e.what());
  }
  std::error_code ec;
  std::filesystem::rename(temporary, path, ec);
  if (ec) return Status::IoError("cannot move " + temporary + " to " + path + ": " + ec.message());
  return Status::Ok();
}

StatusOr<RegionMergeModel> RegionMergeModel::Load(const std::string& directory) {
  const std::string path = directory + "/" + kFileName;
  RegionMergeModel model;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Status::NotFound("no " + path);
  try {
    cv::FileStorage fs(path, cv::FileStorage::READ);
    if (!fs.isOpened()) return Status::NotFound("cannot read " + path);
    int version = 0;
    int features = 0;
    int members = 1;
    fs["format_version"] >> version;
    fs["features"] >> features;
    if (version >= 2) fs["members"] >> members;
    // Versions 1 and 2 put the appearance-space features right after the relational ones,
    // version 3 right after the semantic ones.
    const int most = version == kFormatVersion ? kMergeFeatures
                     : version == 3            ? kMergeBoundaryOffset
                                               : kMergeRelationFeatures;
    if (version < 1 || version > kFormatVersion || features < 1 || features > most || members < 1) {
      return Status::InvalidArgument(
          path + ": format version " + std::to_string(version) + " with " +
          std::to_string(features) + " features; this build reads version " +
          std::to_string(kFormatVersion) + " with at most " + std::to_string(kMergeFeatures) +
          ", version 3 with at most " + std::to_string(kMergeBoundaryOffset) +
          " and versions 1 and 2 with at most " + std::to_string(kMergeRelationFeatures) +
          " (retrain with placerec-train grouping)");
    }
    for (int i = 0; i < members; ++i) {
      cv::Ptr<cv::ml::Boost> boost = cv::ml::Boost::create();
      boost->read(fs[version == 1 ? std::string("boost") : "member_" + std::to_string(i)]);
      if (!boost->isTrained() || boost->getVarCount() < 1 || boost->getVarCount() > features ||
          BoostedForest::Depth(*boost) > BoostedForest::kMaxDepth ||
          !BoostedForest::Intact(*boost)) {
        return Status::InvalidArgument(
            path + ": member " + std::to_string(i) +
            " is not a trained grouping classifier (or has trees "
            "deeper than " +
            std::to_string(BoostedForest::kMaxDepth) +
            ", or values that are not finite numbers or splits on variables it does not have)");
      }
      model.AddMember(boost);
    }
    if (model.feature_size() != features) {
      return Status::InvalidArgument(path + ": members read " +
                                     std::to_string(model.feature_size()) + " features, not " +
                                     std::to_string(features));
    }
  } catch (const cv::Exception& e) {
    return Status::InvalidArgument("cannot load " + path + ": " + e.what());
  }
  return model;
}

void RegionMergeModel::AddMember(cv::Ptr<cv::ml::Boost> boost) {
  forests_.emplace_back(*boost);
  members_.push_back(std::move(boost));
}

cv::Mat RegionMergeModel::Scores(const cv::Mat& features) const {
  CHECK(!empty()) << "grouping model not loaded";
  CHECK_EQ(features.type(), CV_32F);
  CHECK_GE(features.cols, feature_size());
  cv::Mat scores(features.rows, 1, CV_32F);
  if (features.rows == 0) return scores;
  const double scale = 1.0 / members();
  // The members' sums rounded to float and added in member order, as ml::Boost::predict
  // returns them.
  std::vector<float> total(static_cast<size_t>(features.rows), 0.0f);
  std::vector<double> sums(static_cast<size_t>(features.rows));
  const size_t stride = features.step1();
  for (const BoostedForest& forest : forests_) {
    forest.Sums(features.ptr<float>(0), stride, features.rows, sums.data());
    for (int r = 0; r < features.rows; ++r) total[r] += static_cast<float>(sums[r]);
  }
  for (int r = 0; r < features.rows; ++r) {
    scores.at<float>(r) = static_cast<float>(total[r] * scale);
  }
  return scores;
}

// ---- Agglomeration ----

int MergeRegions(const RegionMergeModel& model, const RegionMergeOptions& options,
                 MergeState* state, const std::function<void(int, int)>& after_merge) {
  std::string error;
  CHECK(options.Check(&error)) << error;
  std::vector<int> stamp(static_cast<size_t>(state->capacity()), 0);
  using Entry = std::tuple<float, int, int, int, int>;  // score, a, b, stamp a, stamp b
  std::priority_queue<Entry> queue;
  auto score_pairs = [&](const std::vector<std::pair<int, int>>& pairs) {
    if (pairs.empty()) return;
    cv::Mat features(static_cast<int>(pairs.size()), kMergeFeatures, CV_32F);
    for (size_t p = 0; p < pairs.size(); ++p) {
      state->PairFeatures(pairs[p].first, pairs[p].second,
                          features.ptr<float>(static_cast<int>(p)));
    }
    const cv::Mat scores = model.Scores(features);
    for (size_t p = 0; p < pairs.size(); ++p) {
      const float s = scores.at<float>(static_cast<int>(p));
      if (s <= options.threshold) continue;
      const auto [a, b] = pairs[p];
      queue.emplace(s, a, b, stamp[a], stamp[b]);
    }
  };
  score_pairs(state->Pairs());
  int merges = 0;
  std::vector<std::pair<int, int>> pairs;
  while (!queue.empty()) {
    const auto [score, a, b, sa, sb] = queue.top();
    queue.pop();
    if (!state->alive(a) || !state->alive(b) || stamp[a] != sa || stamp[b] != sb) continue;
    state->Merge(a, b);
    ++merges;
    ++stamp[a];
    if (after_merge) after_merge(a, b);
    pairs.clear();
    for (const auto& [n, edge] : state->NeighboursOf(a)) pairs.emplace_back(a, n);
    score_pairs(pairs);
  }
  return merges;
}

}  // namespace placerec
