// Tests of the Perceptual Organization model (perceptual_organization.h; seed §3.5, §3.7) on
// small synthetic partitions: boundary complexity, the boundary energy, Algorithm 1
// (DetectObject) and Algorithm 2 with the final merges (OrganizeScene).

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "common/organization/perceptual_organization.h"

namespace placerec {
namespace {

// ---- Synthetic partitions ----

// A labels image of `size` filled with part 0 (the background around the parts).
cv::Mat Canvas(cv::Size size) { return cv::Mat(size, CV_32S, cv::Scalar(0)); }

void Fill(cv::Mat* labels, const cv::Rect& rect, int id) { (*labels)(rect).setTo(cv::Scalar(id)); }

// A comb-edged block: rows [y0, y1) and columns [x0, x1), its right edge and its bottom edge
// cut into teeth `tooth` pixels wide, so that its boundary is jagged (many notches).
void FillJagged(cv::Mat* labels, int x0, int y0, int x1, int y1, int tooth, int id) {
  for (int y = y0; y < y1; ++y) {
    const int right = x1 + (((y - y0) / tooth) % 2 == 0 ? tooth : 0);
    for (int x = x0; x < right; ++x) labels->at<int>(y, x) = id;
  }
  for (int x = x0; x < x1; x += 2 * tooth) {
    for (int y = y1; y < y1 + tooth; ++y) {
      for (int dx = 0; dx < tooth && x + dx < x1; ++dx) labels->at<int>(y, x + dx) = id;
    }
  }
}

// Classes: part 0 is sky (background), every other part structured.
std::vector<SegmentClass> SkyAndStructured(int parts) {
  std::vector<SegmentClass> classes(static_cast<size_t>(parts), SegmentClass::kStructured);
  classes[0] = SegmentClass::kSky;
  return classes;
}

// A CIE Lab picture giving every part its own, clearly different colour (so no colour merge
// hides what the model decides).
cv::Mat PartColours(const cv::Mat& labels) {
  static const cv::Vec3f kColours[] = {{80, 0, -30},  {40, 60, 40}, {55, -50, 30},
                                       {30, 20, -60}, {70, 10, 70}, {20, 0, 0}};
  cv::Mat lab(labels.size(), CV_32FC3);
  for (int y = 0; y < labels.rows; ++y) {
    for (int x = 0; x < labels.cols; ++x) lab.at<cv::Vec3f>(y, x) = kColours[labels.at<int>(y, x)];
  }
  return lab;
}

std::vector<char> StructuredAvailable(const PartGraph& graph) {
  std::vector<char> available(static_cast<size_t>(graph.size()), 0);
  for (int i = 0; i < graph.size(); ++i) {
    available[i] = graph.parts[i].segment_class == SegmentClass::kStructured;
  }
  return available;
}

TEST(OrganizationOptionsTest, DefaultsPassAndBadValuesAreRejected) {
  std::string error;
  EXPECT_TRUE(OrganizationOptions().Check(&error)) << error;
  // The seed's parameters (§3.5) are the defaults.
  const OrganizationOptions defaults;
  EXPECT_EQ(defaults.theta_complexity, 18.0);
  EXPECT_EQ(defaults.theta_cohesion, 3.5);
  EXPECT_EQ(defaults.alpha, 20.0);
  EXPECT_EQ(defaults.beta, 3.0);

  OrganizationOptions bad;
  bad.beta = -1.0;
  error.clear();
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_FALSE(error.empty());
  bad = OrganizationOptions();
  bad.max_subset = 0;
  EXPECT_FALSE(bad.Check(&error));
  bad = OrganizationOptions();
  bad.background_merge_colour_distance = -1.0;
  EXPECT_FALSE(bad.Check(&error));
}

// ---- Boundary complexity (eq. 3.7-3.9) ----

TEST(BoundaryComplexityTest, SquareIsSimplerThanJaggedShapeOfEqualArea) {
  cv::Mat square(60, 60, CV_8U, cv::Scalar(0));
  square(cv::Rect(10, 10, 40, 40)).setTo(255);
  // Same area (1600 pixels): rows alternate 44 and 36 pixels wide in bands of 4, teeth on
  // both sides.
  cv::Mat jagged(60, 60, CV_8U, cv::Scalar(0));
  for (int y = 0; y < 40; ++y) {
    const bool wide = (y / 4) % 2 == 0;
    jagged(cv::Rect(wide ? 6 : 10, 10 + y, wide ? 44 : 36, 1)).setTo(255);
  }
  ASSERT_EQ(cv::countNonZero(square), cv::countNonZero(jagged));
  const OrganizationOptions options;
  const double b_square =
      MaskBoundaryComplexity(square, options.complexity_step, options.complexity_window);
  const double b_jagged =
      MaskBoundaryComplexity(jagged, options.complexity_step, options.complexity_window);
  // A convex polygon has no notches, so F = 0 in every window (eq. 3.9).
  EXPECT_NEAR(b_square, 0.0, 1e-12);
  EXPECT_GT(b_jagged, b_square + 0.03);
}

TEST(BoundaryComplexityTest, ConvexContourIsZeroAndNotchedContourIsNot) {
  // A convex octagon, listed point by point along its outline.
  const std::vector<cv::Point> corners = {{10, 0},  {20, 0},  {30, 10}, {30, 20},
                                          {20, 30}, {10, 30}, {0, 20},  {0, 10}};
  std::vector<cv::Point> octagon;
  for (size_t i = 0; i < corners.size(); ++i) {
    const cv::Point a = corners[i];
    const cv::Point b = corners[(i + 1) % corners.size()];
    const int steps = std::max(std::abs(b.x - a.x), std::abs(b.y - a.y));
    for (int s = 0; s < steps; ++s) {
      octagon.emplace_back(a.x + (b.x - a.x) * s / steps, a.y + (b.y - a.y) * s / steps);
    }
  }
  EXPECT_NEAR(BoundaryComplexity(octagon, 2, 5), 0.0, 1e-12);
  // Fewer than three points: 0 by definition.
  EXPECT_EQ(BoundaryComplexity({{0, 0}, {1, 1}}, 2, 5), 0.0);
  // A zig-zag (saw-tooth) outline has notches in most windows.
  std::vector<cv::Point> saw;
  for (int x = 0; x < 40; ++x) saw.emplace_back(x, (x / 2) % 2 == 0 ? 0 : 2);
  saw.emplace_back(40, 20);
  saw.emplace_back(0, 20);
  EXPECT_GT(BoundaryComplexity(saw, 1, 4), 0.1);
}

// ---- Energy (eq. 3.4, 3.6, 3.10-3.13) ----

// Parts: 0 background (sky); 1 reference a (20 x 30); 2 beside a, the same size and height
// (symmetric about a vertical axis, aligned: its common boundary continues a's outline);
// 3 a smaller part touching a's right side along 5 pixels only, lower down (weakly attached).
TEST(BoundaryEnergyTest, SymmetricAlignedPartLowersEnergyWeakPartRaisesIt) {
  for (const int weak_x : {60, 20}) {  // the weak part on the free side of a
    cv::Mat labels = Canvas({120, 100});
    Fill(&labels, {40, 20, 20, 30}, 1);
    if (weak_x == 60) {
      Fill(&labels, {20, 20, 20, 30}, 2);  // partner on the left
      Fill(&labels, {60, 45, 15, 15}, 3);  // weak part on the right
    } else {
      Fill(&labels, {60, 20, 20, 30}, 2);  // partner on the right
      Fill(&labels, {25, 45, 15, 15}, 3);  // weak part on the left
    }
    const OrganizationOptions options;
    const PartGraph graph =
        BuildPartGraph(labels, 4, PartColours(labels), SkyAndStructured(4), options);
    const PartLink* partner = graph.Link(1, 2);
    const PartLink* weak = graph.Link(1, 3);
    ASSERT_NE(partner, nullptr);
    ASSERT_NE(weak, nullptr);
    EXPECT_TRUE(partner->symmetric);
    EXPECT_TRUE(partner->aligned);
    EXPECT_DOUBLE_EQ(partner->strength, 1.0);
    EXPECT_EQ(weak->shared, 5);
    EXPECT_FALSE(weak->symmetric);
    EXPECT_FALSE(weak->aligned);
    EXPECT_LT(weak->strength, 0.2);

    const double alone = BoundaryEnergy(graph, 1, {1}, options);
    // E of a single part is -area / perimeter (f = 1 at the reference).
    EXPECT_NEAR(alone, -600.0 / 100.0, 1e-9);
    const double with_partner = BoundaryEnergy(graph, 1, {1, 2}, options);
    const double with_weak = BoundaryEnergy(graph, 1, {1, 3}, options);
    EXPECT_LT(with_partner, alone);
    EXPECT_GT(with_weak, alone);
    // Cohesiveness spreads through the links: 1 through the symmetric link, weak otherwise.
    const std::vector<double> c = Cohesiveness(graph, 1, {1, 2, 3});
    EXPECT_DOUBLE_EQ(c[1], 1.0);
    EXPECT_DOUBLE_EQ(c[2], 1.0);
    EXPECT_NEAR(c[3], weak->strength, 1e-12);
    EXPECT_EQ(c[0], 0.0);
  }
}

// ---- Seed Figure 3.1 ----

// Parts: 0 background; a (1) and b (2) side by side, the same size and height (symmetric and
// aligned); c (3) below b along b's whole bottom edge (strongly attached) but jagged; d (4) a
// small part touching a's left side along a few pixels (weakly attached).
struct Figure31 {
  cv::Mat labels;
  cv::Mat lab;
  std::vector<SegmentClass> classes;
};

Figure31 MakeFigure31() {
  Figure31 f;
  f.labels = Canvas({140, 120});
  Fill(&f.labels, {40, 20, 20, 30}, 1);         // a
  Fill(&f.labels, {60, 20, 20, 30}, 2);         // b
  FillJagged(&f.labels, 60, 50, 80, 76, 3, 3);  // c
  Fill(&f.labels, {25, 44, 15, 14}, 4);         // d
  f.lab = PartColours(f.labels);
  f.classes = SkyAndStructured(5);
  return f;
}

TEST(PerceptualOrganizationTest, Figure31PartsAAndBGroupButCAndDDoNot) {
  const Figure31 f = MakeFigure31();
  const OrganizationOptions options;
  const PartGraph graph = BuildPartGraph(f.labels, 5, f.lab, f.classes, options);
  ASSERT_NE(graph.Link(1, 2), nullptr);
  ASSERT_NE(graph.Link(2, 3), nullptr);
  ASSERT_NE(graph.Link(1, 4), nullptr);
  EXPECT_EQ(graph.Link(3, 4), nullptr);  // c and d are not connected
  // c is the jagged one.
  EXPECT_GT(graph.parts[3].complexity, graph.parts[1].complexity + 0.05);
  EXPECT_GT(graph.parts[3].complexity, graph.parts[2].complexity + 0.05);

  // The energies the seed's walk-through compares (§3.5, Figure 3.1 b).
  const double e_a = BoundaryEnergy(graph, 1, {1}, options);
  const double e_ab = BoundaryEnergy(graph, 1, {1, 2}, options);
  const double e_abc = BoundaryEnergy(graph, 1, {1, 2, 3}, options);
  const double e_abd = BoundaryEnergy(graph, 1, {1, 2, 4}, options);
  const double e_abcd = BoundaryEnergy(graph, 1, {1, 2, 3, 4}, options);
  EXPECT_LT(e_ab, e_a);
  EXPECT_GT(e_abc, e_ab);
  EXPECT_GT(e_abd, e_ab);
  EXPECT_GT(e_abcd, e_ab);

  // Algorithm 1 from a, and from b, returns exactly a u b.
  const std::vector<char> available = StructuredAvailable(graph);
  EXPECT_EQ(DetectObject(graph, 1, available, options), (std::vector<int>{1, 2}));
  EXPECT_EQ(DetectObject(graph, 2, available, options), (std::vector<int>{1, 2}));
  // The background part is never taken, even when it is the reference's largest neighbour.
  for (const int member : DetectObject(graph, 3, available, options)) EXPECT_NE(member, 0);
}

TEST(PerceptualOrganizationTest, Figure31SceneKeepsEveryPixelAndGroupsOnlyAAndB) {
  const Figure31 f = MakeFigure31();
  OrganizationSummary summary;
  const SceneSegmentation scene =
      OrganizeScene(f.labels, f.classes, f.lab, OrganizationOptions(), &summary);
  ASSERT_EQ(scene.labels.size(), f.labels.size());
  // One segment per object: background, a u b, c, d.
  EXPECT_EQ(scene.size(), 4);
  EXPECT_EQ(summary.segments, 4);
  ASSERT_GE(summary.rounds, 1);
  EXPECT_EQ(summary.parts[0], 4);
  auto segment_at = [&scene](int x, int y) { return scene.labels.at<int>(y, x); };
  const int background = segment_at(0, 0);
  const int a = segment_at(45, 30);
  const int b = segment_at(70, 30);
  const int c = segment_at(65, 60);
  const int d = segment_at(30, 50);
  EXPECT_EQ(a, b);
  EXPECT_NE(c, a);
  EXPECT_NE(d, a);
  EXPECT_NE(c, d);
  EXPECT_EQ(scene.classes[background], SegmentClass::kSky);
  EXPECT_EQ(scene.classes[a], SegmentClass::kStructured);
  EXPECT_EQ(scene.classes[c], SegmentClass::kStructured);
  // Every pixel of an input part lands in one output segment.
  for (int y = 0; y < f.labels.rows; ++y) {
    for (int x = 0; x < f.labels.cols; ++x) {
      const int part = f.labels.at<int>(y, x);
      const int expected = part == 0 ? background : part <= 2 ? a : part == 3 ? c : d;
      ASSERT_EQ(scene.labels.at<int>(y, x), expected) << "at " << x << "," << y;
    }
  }
}

TEST(PerceptualOrganizationTest, AdjacentBackgroundRegionsOfOneClassAndColourMerge) {
  cv::Mat labels = Canvas({60, 40});
  Fill(&labels, {0, 20, 60, 20}, 1);   // a second sky region under the first
  Fill(&labels, {20, 10, 20, 10}, 2);  // a structured part inside
  const std::vector<SegmentClass> classes = {SegmentClass::kSky, SegmentClass::kSky,
                                             SegmentClass::kStructured};
  // The two sky regions in one colour merge; in clearly different colours (Delta E about 100,
  // e.g. a building part the classifiers called sky) they do not, unless the gate is off.
  cv::Mat same_sky = PartColours(labels);
  same_sky.setTo(cv::Scalar(80, 0, -30), labels == 1);
  EXPECT_EQ(OrganizeScene(labels, classes, same_sky, OrganizationOptions()).size(), 2);
  EXPECT_EQ(OrganizeScene(labels, classes, PartColours(labels), OrganizationOptions()).size(), 3);
  OrganizationOptions any_colour;
  any_colour.background_merge_colour_distance = 0;
  EXPECT_EQ(OrganizeScene(labels, classes, PartColours(labels), any_colour).size(), 2);
  OrganizationOptions keep;
  keep.merge_background = false;
  EXPECT_EQ(OrganizeScene(labels, classes, same_sky, keep).size(), 3);
}

}  // namespace
}  // namespace placerec
