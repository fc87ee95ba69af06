// Tests of the Perceptual Organization model (perceptual_organization.h; seed §3.5, §3.7) on
// small synthetic partitions: boundary complexity, the part graph, link strengths, the boundary
// energy, Algorithm 1 (DetectObject) and Algorithm 2 with the final merges (OrganizeScene).

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "common/organization/perceptual_organization.h"
#include "common/util/options_test_util.h"

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

// Every out-of-range field is refused with a message that names it.
TEST(OrganizationOptionsTest, EachBadValueIsNamedInTheError) {
  options_test::ExpectEachRefusedByName<OrganizationOptions>({
      {"theta_complexity", [](OrganizationOptions* o) { o->theta_complexity = -0.5; }},
      // Not finite is not a weight either.
      {"theta_complexity",
       [](OrganizationOptions* o) {
         o->theta_complexity = std::numeric_limits<double>::quiet_NaN();
       }},
      {"theta_cohesion",
       [](OrganizationOptions* o) { o->theta_cohesion = std::numeric_limits<double>::infinity(); }},
      {"theta_cohesion", [](OrganizationOptions* o) { o->theta_cohesion = -1; }},
      {"alpha", [](OrganizationOptions* o) { o->alpha = -20; }},
      {"symmetry_tolerance", [](OrganizationOptions* o) { o->symmetry_tolerance = -0.1; }},
      {"alignment_extension", [](OrganizationOptions* o) { o->alignment_extension = -1; }},
      {"round_colour_merge_distance",
       [](OrganizationOptions* o) { o->round_colour_merge_distance = -5; }},
      {"complexity_step", [](OrganizationOptions* o) { o->complexity_step = 0; }},
      {"complexity_window", [](OrganizationOptions* o) { o->complexity_window = 1; }},
      {"alignment_tolerance", [](OrganizationOptions* o) { o->alignment_tolerance = 1.5; }},
      {"enclosed_fraction", [](OrganizationOptions* o) { o->enclosed_fraction = 0; }},
      {"max_subset", [](OrganizationOptions* o) { o->max_subset = 3; }},
      {"max_rounds", [](OrganizationOptions* o) { o->max_rounds = -1; }},
  });
  // The edges of the ranges are allowed.
  OrganizationOptions edges;
  edges.alpha = 0;
  edges.alignment_tolerance = 1;
  edges.enclosed_fraction = 1;
  edges.max_subset = 1;
  edges.max_rounds = 0;
  std::string error;
  EXPECT_TRUE(edges.Check(&error)) << error;
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

// ---- Part graph and link strength (eq. 3.10-3.13, Lemma 1) ----

// A 10 x 6 partition: part 0 the left 4 columns, part 1 the right 6.
TEST(PartGraphTest, TwoRectanglesHaveExactAreasPerimetersAndCommonBoundary) {
  cv::Mat labels = Canvas({10, 6});
  Fill(&labels, {4, 0, 6, 6}, 1);
  const OrganizationOptions options;
  const PartGraph graph =
      BuildPartGraph(labels, 2, PartColours(labels),
                     {SegmentClass::kStructured, SegmentClass::kStructured}, options);
  ASSERT_EQ(graph.size(), 2);
  EXPECT_EQ(graph.image_size, cv::Size(10, 6));
  EXPECT_EQ(graph.parts[0].area, 24);
  EXPECT_EQ(graph.parts[1].area, 36);
  // Crack edges, the image border included.
  EXPECT_EQ(graph.parts[0].perimeter, 20);
  EXPECT_EQ(graph.parts[1].perimeter, 24);
  EXPECT_EQ(graph.parts[0].box, cv::Rect(0, 0, 4, 6));
  EXPECT_EQ(graph.parts[1].box, cv::Rect(4, 0, 6, 6));
  EXPECT_DOUBLE_EQ(graph.parts[0].centroid.x, 1.5);
  EXPECT_DOUBLE_EQ(graph.parts[0].centroid.y, 2.5);
  EXPECT_DOUBLE_EQ(graph.parts[1].centroid.x, 6.5);
  // Rectangles are convex: no boundary complexity.
  EXPECT_NEAR(graph.parts[0].complexity, 0.0, 1e-12);
  EXPECT_NEAR(graph.parts[1].complexity, 0.0, 1e-12);

  ASSERT_EQ(graph.links[0].size(), 1u);
  ASSERT_EQ(graph.links[1].size(), 1u);
  const PartLink* link = graph.Link(0, 1);
  ASSERT_NE(link, nullptr);
  EXPECT_EQ(link->other, 1);
  EXPECT_EQ(graph.Link(1, 0)->other, 0);
  EXPECT_EQ(link->shared, 6);
  EXPECT_EQ(graph.Link(1, 0)->shared, 6);
  EXPECT_DOUBLE_EQ(link->cos_omega, 0.0);  // a vertical common boundary
  EXPECT_TRUE(link->symmetric);            // centroids at the same height
  EXPECT_DOUBLE_EQ(link->strength, 1.0);
  EXPECT_EQ(graph.Link(0, 0), nullptr);

  // E = -sum f |i| / L(dR) with L(d(A u B)) = L(dA) + L(dB) - 2 L(dAB) (seed Lemma 1): the
  // whole 10 x 6 image, -60 / 32.
  EXPECT_DOUBLE_EQ(BoundaryEnergy(graph, 0, {0}, options), -24.0 / 20.0);
  EXPECT_DOUBLE_EQ(BoundaryEnergy(graph, 1, {1}, options), -36.0 / 24.0);
  EXPECT_DOUBLE_EQ(BoundaryEnergy(graph, 0, {0, 1}, options), -60.0 / 32.0);
  // Outside the region, no cohesiveness.
  EXPECT_EQ(Cohesiveness(graph, 0, {0}), (std::vector<double>{1.0, 0.0}));
  EXPECT_EQ(Cohesiveness(graph, 0, {0, 1}), (std::vector<double>{1.0, 1.0}));
}

// exp(-phi psi lambda) with lambda = beta exp(-alpha cos(omega) L(dij) / (L(di) + L(dj))).
TEST(LinkStrengthTest, FollowsEquation313) {
  const OrganizationOptions options;  // alpha 20, beta 3
  PartLink link;
  link.shared = 10;
  // A vertical common boundary (cos 0) is no attachment at all: lambda = beta.
  link.cos_omega = 0.0;
  EXPECT_NEAR(LinkStrength(link, 40, 60, options), std::exp(-3.0), 1e-12);
  // A horizontal one sharing a tenth of the two boundaries: lambda = 3 exp(-2).
  link.cos_omega = 1.0;
  EXPECT_NEAR(LinkStrength(link, 40, 60, options), std::exp(-3.0 * std::exp(-2.0)), 1e-12);
  // Sharing more attaches more strongly.
  link.shared = 30;
  EXPECT_GT(LinkStrength(link, 40, 60, options), std::exp(-3.0 * std::exp(-2.0)));
  // Symmetric (phi = 0) or aligned (psi = 0) parts are fully cohesive.
  link.cos_omega = 0.0;
  link.symmetric = true;
  EXPECT_EQ(LinkStrength(link, 40, 60, options), 1.0);
  link.symmetric = false;
  link.aligned = true;
  EXPECT_EQ(LinkStrength(link, 40, 60, options), 1.0);
}

// ---- Algorithm 1 and Algorithm 2 ----

// Parts the caller marks unavailable (taken by an earlier object, or background) are never
// added; the reference itself always is.
TEST(DetectObjectTest, UnavailablePartsAreNeverTaken) {
  const Figure31 f = MakeFigure31();
  const OrganizationOptions options;
  const PartGraph graph = BuildPartGraph(f.labels, 5, f.lab, f.classes, options);
  std::vector<char> available = StructuredAvailable(graph);
  available[2] = 0;  // b already belongs to another object
  EXPECT_EQ(DetectObject(graph, 1, available, options), (std::vector<int>{1}));
  // Nothing available: the reference alone, even an unavailable one.
  const std::vector<char> none(5, 0);
  for (int part = 0; part < 5; ++part) {
    EXPECT_EQ(DetectObject(graph, part, none, options), (std::vector<int>{part})) << part;
  }
}

// Without grouping rounds every part stays a segment of its own, classes kept; the summary
// counts what happened.
TEST(OrganizeSceneTest, ZeroRoundsKeepEveryPartAsItsOwnSegment) {
  const Figure31 f = MakeFigure31();
  OrganizationOptions options;
  options.max_rounds = 0;
  OrganizationSummary summary;
  const SceneSegmentation scene = OrganizeScene(f.labels, f.classes, f.lab, options, &summary);
  EXPECT_EQ(scene.size(), 5);
  EXPECT_EQ(summary.rounds, 0);
  EXPECT_TRUE(summary.parts.empty());
  EXPECT_EQ(summary.background_parts, 1);
  EXPECT_EQ(summary.segments, 5);
  // One segment per input part, and one part per segment.
  std::vector<std::set<int>> segments_of(5);
  for (int y = 0; y < f.labels.rows; ++y) {
    for (int x = 0; x < f.labels.cols; ++x) {
      segments_of[f.labels.at<int>(y, x)].insert(scene.labels.at<int>(y, x));
    }
  }
  std::set<int> all;
  for (int part = 0; part < 5; ++part) {
    ASSERT_EQ(segments_of[part].size(), 1u) << part;
    const int segment = *segments_of[part].begin();
    all.insert(segment);
    EXPECT_EQ(scene.classes[segment], f.classes[part]) << part;
  }
  EXPECT_EQ(all.size(), 5u);
}

// A scene of background alone groups nothing: one round finds no structured part, and the
// final merge joins the two sky regions of one colour.
TEST(OrganizeSceneTest, BackgroundAloneIsOneSegmentAfterOneEmptyRound) {
  cv::Mat labels = Canvas({40, 30});
  Fill(&labels, {0, 15, 40, 15}, 1);
  cv::Mat lab(labels.size(), CV_32FC3, cv::Scalar(80, 0, -30));
  OrganizationSummary summary;
  const SceneSegmentation scene = OrganizeScene(labels, {SegmentClass::kSky, SegmentClass::kSky},
                                                lab, OrganizationOptions(), &summary);
  EXPECT_EQ(scene.size(), 1);
  EXPECT_EQ(scene.classes, std::vector<SegmentClass>{SegmentClass::kSky});
  EXPECT_EQ(cv::countNonZero(scene.labels), 0);
  EXPECT_EQ(summary.rounds, 1);
  EXPECT_EQ(summary.parts, std::vector<int>{0});
  EXPECT_EQ(summary.background_parts, 2);
  EXPECT_EQ(summary.segments, 1);
}

}  // namespace
}  // namespace placerec
