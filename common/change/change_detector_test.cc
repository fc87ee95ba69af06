#include "common/change/change_detector.h"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace placerec {
namespace {

constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr int kThumbnailWidth = 160;

// A textured scene larger than a frame (fixed seed): smooth colour blobs.
cv::Mat Scene() {
  cv::RNG rng(7);
  cv::Mat coarse(48, 64, CV_8UC3);
  rng.fill(coarse, cv::RNG::UNIFORM, cv::Scalar::all(40), cv::Scalar::all(220));
  cv::Mat scene;
  cv::resize(coarse, scene, cv::Size(kWidth + 128, kHeight + 96), 0, 0, cv::INTER_CUBIC);
  cv::GaussianBlur(scene, scene, cv::Size(5, 5), 1.5);
  return scene;
}

cv::Mat Thumbnail(const cv::Mat& frame) {
  cv::Mat small;
  cv::resize(frame, small, cv::Size(kThumbnailWidth, kThumbnailWidth * frame.rows / frame.cols), 0,
             0, cv::INTER_AREA);
  return small;
}

// The place sees the scene from (0, 0), the frame from `offset`: a frame point p is place point
// p + offset. Point pairs on a grid, except inside `hidden` (frame pixels).
ChangeReference Reference(const cv::Mat& scene, cv::Point offset, cv::Rect hidden = cv::Rect()) {
  ChangeReference reference;
  reference.thumbnail = Thumbnail(scene(cv::Rect(0, 0, kWidth, kHeight)));
  reference.image_width = kWidth;
  for (int y = 20; y < kHeight - offset.y; y += 40) {
    for (int x = 20; x < kWidth - offset.x; x += 40) {
      if (hidden.contains(cv::Point(x, y))) continue;
      reference.point_pairs.emplace_back(cv::Point2f(x, y),
                                         cv::Point2f(x + offset.x, y + offset.y));
    }
  }
  return reference;
}

double IoU(const cv::Rect& a, const cv::Rect& b) {
  const double inter = (a & b).area();
  return inter / (a.area() + b.area() - inter);
}

const cv::Point kOffset(24, 16);

TEST(ChangeOptionsTest, DefaultsPass) {
  std::string error;
  EXPECT_TRUE(ChangeOptions().Check(&error)) << error;
  ChangeOptions bad;
  bad.sensitivity = 0;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("sensitivity"), std::string::npos);
  bad = ChangeOptions();
  bad.max_elsewhere_similarity = 0;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("elsewhere"), std::string::npos);
  bad = ChangeOptions();
  bad.reference_window_seconds = 1e13;
  EXPECT_FALSE(bad.Check(&error));
  EXPECT_NE(error.find("reference window"), std::string::npos) << error;
}

TEST(ChangeDetectorTest, UnchangedSceneRaisesNothing) {
  const cv::Mat scene = Scene();
  const cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  const ChangeResult result =
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset)}, ChangeOptions());
  EXPECT_TRUE(result.checked) << result.why_not;
  EXPECT_EQ(result.references, 1);
  EXPECT_GT(result.shared_view, 0.6);
  EXPECT_TRUE(result.changes.empty());
}

TEST(ChangeDetectorTest, ExposureChangeIsNotAChange) {
  const cv::Mat scene = Scene();
  cv::Mat frame;
  scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).convertTo(frame, -1, 0.5, 10);
  const ChangeResult result =
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset)}, ChangeOptions());
  EXPECT_TRUE(result.checked);
  EXPECT_TRUE(result.changes.empty());
}

TEST(ChangeDetectorTest, PastedObjectIsFoundWhereItIs) {
  const cv::Mat scene = Scene();
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  const cv::Rect object(300, 200, 100, 120);  // 4 % of the frame
  frame(object).setTo(cv::Scalar(20, 200, 30));
  cv::circle(frame, object.tl() + cv::Point(50, 40), 25, cv::Scalar(250, 250, 250), -1);
  const ChangeResult result = DetectChanges(Thumbnail(frame), frame.size(),
                                            {Reference(scene, kOffset, object)}, ChangeOptions());
  ASSERT_TRUE(result.checked);
  ASSERT_EQ(result.changes.size(), 1u);
  EXPECT_EQ(result.changes[0].kind, SceneChange::Kind::kAppeared);
  EXPECT_GT(IoU(result.changes[0].box, object), 0.6) << result.changes[0].box;
  EXPECT_GE(result.changes[0].confidence, 0.5f);
  EXPECT_LE(result.changes[0].confidence, 1.0f);
}

// A region under min_area is a speck, no candidate: it is not listed among the dropped regions
// ("size" there means larger than max_area), as a speck that differs weakly is not either.
TEST(ChangeDetectorTest, ASpeckIsNoDroppedRegion) {
  const cv::Mat scene = Scene();
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  const cv::Rect speck(300, 200, 24, 24);
  frame(speck).setTo(cv::Scalar(250, 250, 250));
  // The grown region around it covers about 0.5 % of the frame: a speck under 2 %.
  ChangeOptions options;
  options.min_area = 0.02;
  const ChangeResult result =
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset, speck)}, options);
  ASSERT_TRUE(result.checked);
  EXPECT_TRUE(result.changes.empty());
  for (const DroppedRegion& region : result.dropped) {
    EXPECT_EQ(IoU(region.box, speck), 0.0) << region.rule << " " << region.box;
  }
  // The same region is a candidate under the default min_area (the rules then judge it).
  const ChangeResult by_default = DetectChanges(
      Thumbnail(frame), frame.size(), {Reference(scene, kOffset, speck)}, ChangeOptions());
  bool listed = !by_default.changes.empty();
  for (const DroppedRegion& region : by_default.dropped) {
    listed = listed || IoU(region.box, speck) > 0.0;
  }
  EXPECT_TRUE(listed);
}

TEST(ChangeDetectorTest, ObjectAtTheFrameBorderIsFound) {
  // The place sees beyond the frame's top border: an object there is in the shared view, not
  // new scene brought in by the motion.
  const cv::Mat scene = Scene();
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  const cv::Rect object(260, 0, 110, 80);  // 3 % of the frame, along its top border
  frame(object).setTo(cv::Scalar(20, 200, 30));
  cv::circle(frame, object.tl() + cv::Point(55, 40), 25, cv::Scalar(250, 250, 250), -1);
  const ChangeResult result = DetectChanges(Thumbnail(frame), frame.size(),
                                            {Reference(scene, kOffset, object)}, ChangeOptions());
  ASSERT_TRUE(result.checked);
  ASSERT_EQ(result.changes.size(), 1u);
  EXPECT_GT(IoU(result.changes[0].box, object), 0.5) << result.changes[0].box;
}

// The frame with `block` (frame pixels) showing the scene moved by `shift` more than the rest:
// a near object's parallax, which no homography of the whole view models.
cv::Mat FrameWithParallax(const cv::Mat& scene, const cv::Rect& block, cv::Point shift) {
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  scene(block + kOffset + shift).copyTo(frame(block));
  return frame;
}

TEST(ChangeDetectorTest, ParallaxTheFlowFollowsIsNotAChange) {
  const cv::Mat scene = Scene();
  const cv::Rect block(280, 180, 140, 140);
  const cv::Mat frame = FrameWithParallax(scene, block, cv::Point(28, 0));
  ChangeOptions options;
  options.max_elsewhere_similarity = 1.0;  // the flow alone
  EXPECT_TRUE(
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset, block)}, options)
          .changes.empty());
  options.flow_alignment = false;
  EXPECT_FALSE(
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset, block)}, options)
          .changes.empty());
}

TEST(ChangeDetectorTest, ContentTheStoredViewShowsElsewhereIsNotAChange) {
  // Moved farther than the alignment follows, but the place shows that content nearby.
  const cv::Mat scene = Scene();
  const cv::Rect block(280, 180, 140, 140);
  const cv::Mat frame = FrameWithParallax(scene, block, cv::Point(48, 24));
  ChangeOptions options;
  options.flow_alignment = false;
  options.max_elsewhere_similarity = 1.0;
  EXPECT_FALSE(
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset, block)}, options)
          .changes.empty());
  options.max_elsewhere_similarity = ChangeOptions().max_elsewhere_similarity;
  const ChangeResult result =
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset, block)}, options);
  EXPECT_TRUE(result.changes.empty());
  // The evaluation reads which rule dropped the region, and where.
  ASSERT_FALSE(result.dropped.empty());
  EXPECT_EQ(result.dropped[0].rule, "elsewhere");
  EXPECT_GT(IoU(result.dropped[0].box, block), 0.3) << result.dropped[0].box;
}

TEST(ChangeDetectorTest, ObjectBeforeAPlainStoredAreaIsFound) {
  // Where the stored view is flat (a blown-out window), correlating with it says nothing: the
  // object pasted there is still a change.
  cv::Mat scene = Scene();
  const cv::Rect object(300, 200, 100, 120);
  scene(cv::Rect(object.tl() + kOffset - cv::Point(60, 60), object.size() + cv::Size(120, 120)))
      .setTo(cv::Scalar(255, 255, 255));
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  cv::Mat coarse(12, 10, CV_8UC3), textured;
  cv::RNG(5).fill(coarse, cv::RNG::UNIFORM, cv::Scalar::all(0), cv::Scalar::all(200));
  cv::resize(coarse, textured, object.size(), 0, 0, cv::INTER_NEAREST);
  textured.copyTo(frame(object));
  const ChangeResult result = DetectChanges(Thumbnail(frame), frame.size(),
                                            {Reference(scene, kOffset, object)}, ChangeOptions());
  ASSERT_TRUE(result.checked);
  ASSERT_EQ(result.changes.size(), 1u);
  EXPECT_GT(IoU(result.changes[0].box, object), 0.5) << result.changes[0].box;
}

// Shifts the pixels' colours by a dozen Lab units or so (less blue, more green and red).
void Tint(cv::Mat roi) {
  cv::Mat tinted;
  roi.convertTo(tinted, CV_16SC3);
  tinted += cv::Scalar(-14, 14, 14);
  tinted.convertTo(roi, CV_8UC3);
}

// A plain object before a plain wall of nearly its colour (a dozen Lab units apart): no pixel
// differs by the threshold, the object as a whole does.
struct PlainObject {
  PlainObject() {
    scene(cv::Rect(object.tl() + kOffset - cv::Point(40, 40), object.size() + cv::Size(80, 80)))
        .setTo(cv::Scalar(128, 128, 128));
    frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
    Tint(frame(object));
  }
  cv::Mat scene = Scene();
  const cv::Rect object{300, 200, 100, 120};
  cv::Mat frame;
};

TEST(ChangeDetectorTest, ASegmentThatDiffersLittlePerPixelIsFoundAsAWhole) {
  // A plain object before a plain wall of nearly its colour (a dozen Lab units apart): no pixel
  // differs by the threshold, the whole segment's mean does.
  const PlainObject plain;
  const cv::Mat& scene = plain.scene;
  const cv::Mat& frame = plain.frame;
  const cv::Rect& object = plain.object;
  // The frame's segmentation at half its resolution: the object, and the rest of the frame.
  cv::Mat segments(kHeight / 2, kWidth / 2, CV_32S, cv::Scalar(0));
  segments(cv::Rect(object.x / 2, object.y / 2, object.width / 2, object.height / 2)).setTo(1);
  const ChangeReference reference = Reference(scene, kOffset, object);
  ChangeOptions options;
  options.weak_mean = 0;  // weak regions find it too (the next test)
  const ChangeResult per_pixel =
      DetectChanges(Thumbnail(frame), frame.size(), {reference}, options, segments);
  ASSERT_TRUE(per_pixel.checked);
  EXPECT_TRUE(per_pixel.changes.empty());
  options.segment_difference = 8;
  const ChangeResult whole =
      DetectChanges(Thumbnail(frame), frame.size(), {reference}, options, segments);
  ASSERT_EQ(whole.changes.size(), 1u);
  EXPECT_EQ(whole.changes[0].kind, SceneChange::Kind::kAppeared);
  EXPECT_GT(IoU(whole.changes[0].box, object), 0.6) << whole.changes[0].box;
  // Without the frame's segments there is nothing to average over.
  EXPECT_TRUE(DetectChanges(Thumbnail(frame), frame.size(), {reference}, options).changes.empty());
  // The unchanged frame's segments match the stored view's.
  const cv::Mat unchanged = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  EXPECT_TRUE(DetectChanges(Thumbnail(unchanged), unchanged.size(), {Reference(scene, kOffset)},
                            options, segments)
                  .changes.empty());
}

TEST(ChangeDetectorTest, ALargeRegionThatDiffersLittleIsFoundWhereTheViewIsAligned) {
  // The plain object of the previous test: no pixel differs by the threshold, but the region
  // is large and stands far above the rest of a well aligned view.
  const PlainObject plain;
  const cv::Mat& scene = plain.scene;
  const cv::Mat& frame = plain.frame;
  const cv::Rect& object = plain.object;
  const ChangeReference reference = Reference(scene, kOffset, object);
  ChangeOptions options;
  options.weak_mean = 0;
  const ChangeResult off = DetectChanges(Thumbnail(frame), frame.size(), {reference}, options);
  ASSERT_TRUE(off.checked);
  EXPECT_TRUE(off.changes.empty());
  ASSERT_FALSE(off.dropped.empty());
  EXPECT_EQ(off.dropped[0].rule, "weak");
  options.weak_mean = ChangeOptions().weak_mean;
  const ChangeResult on = DetectChanges(Thumbnail(frame), frame.size(), {reference}, options);
  ASSERT_EQ(on.changes.size(), 1u);
  EXPECT_GT(IoU(on.changes[0].box, object), 0.6) << on.changes[0].box;
  // It must also stand weak_spread robust deviations above the view's median difference (where
  // the whole view differs a little, parallax makes such regions): far beyond this view's, it
  // is dropped.
  EXPECT_LT(on.median_difference + options.weak_spread * on.difference_spread, 0.5 * 25.0);
  options.weak_spread = (on.threshold - on.median_difference) / on.difference_spread;
  const ChangeResult gated = DetectChanges(Thumbnail(frame), frame.size(), {reference}, options);
  EXPECT_TRUE(gated.changes.empty());
  ASSERT_FALSE(gated.dropped.empty());
  EXPECT_EQ(gated.dropped[0].rule, "weak");
}

TEST(ChangeDetectorTest, ARegionThatDoesNotStandOutOfTheViewsSpreadIsJudgedAsWeak) {
  // A small plain object (0.8 % of the frame, under weak_min_area) that crosses the threshold,
  // in a view with some noise of its own: reported while every seeded region counts, dropped as
  // weak once its strongest pixel must stand further above the threshold, in robust deviations
  // of the view's difference, than it does.
  const cv::Mat scene = Scene();
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  // Smooth noise (a rough alignment's left-overs), which the thumbnail keeps.
  cv::Mat coarse(kHeight / 16, kWidth / 16, CV_16SC3), noise;
  cv::RNG(11).fill(coarse, cv::RNG::NORMAL, cv::Scalar::all(0), cv::Scalar::all(30));
  cv::resize(coarse, noise, frame.size(), 0, 0, cv::INTER_LINEAR);
  cv::Mat noisy;
  frame.convertTo(noisy, CV_16SC3);
  noisy += noise;
  noisy.convertTo(frame, CV_8UC3);
  const cv::Rect object(300, 200, 56, 44);
  // Plain (so not looked for elsewhere in the stored view).
  frame(object).setTo(cv::Scalar(20, 200, 30));
  const ChangeReference reference = Reference(scene, kOffset, object);
  ChangeOptions options;
  options.strong_spread = 0.0;
  const ChangeResult every = DetectChanges(Thumbnail(frame), frame.size(), {reference}, options);
  ASSERT_TRUE(every.checked) << every.why_not;
  ASSERT_EQ(every.changes.size(), 1u);
  EXPECT_GT(IoU(every.changes[0].box, object), 0.4) << every.changes[0].box;
  // Its strongest pixel above the threshold, in the view's robust deviations.
  const double to_thumb = static_cast<double>(every.difference.cols) / kWidth;
  const cv::Rect box = every.changes[0].box;
  const cv::Rect in_thumb(static_cast<int>(box.x * to_thumb), static_cast<int>(box.y * to_thumb),
                          static_cast<int>(std::ceil(box.width * to_thumb)),
                          static_cast<int>(std::ceil(box.height * to_thumb)));
  double peak = 0.0;
  cv::minMaxLoc(
      every.difference(in_thumb & cv::Rect(0, 0, every.difference.cols, every.difference.rows)),
      nullptr, &peak);
  ASSERT_GT(every.difference_spread, 0.0);
  const double deviations = (peak - every.threshold) / every.difference_spread;
  ASSERT_GT(deviations, 0.0);
  ASSERT_LT(deviations, 90.0);
  options.strong_spread = deviations * 0.95;
  EXPECT_EQ(DetectChanges(Thumbnail(frame), frame.size(), {reference}, options).changes.size(), 1u);
  options.strong_spread = deviations * 1.05;
  const ChangeResult strong = DetectChanges(Thumbnail(frame), frame.size(), {reference}, options);
  EXPECT_TRUE(strong.changes.empty());
  ASSERT_FALSE(strong.dropped.empty());
  EXPECT_EQ(strong.dropped[0].rule, "weak");
  // A value out of range is named.
  options.strong_spread = -1.0;
  std::string error;
  EXPECT_FALSE(options.Check(&error));
  EXPECT_NE(error.find("strong spread"), std::string::npos) << error;
}

TEST(ChangeDetectorTest, ConfidenceGrowsWithHowClearlyTheObjectDiffers) {
  // Two objects of one size (4 % of the frame) whose colours lie near their background's over
  // most of their area: one with a core of a colour the place never showed, one whose core only
  // just crosses the threshold. Both regions' mean difference stays under the threshold.
  const auto confidence = [](const cv::Scalar& core_shift) {
    // The plain object before a plain wall of nearly its colour (ASegmentThatDiffersLittle...).
    PlainObject plain;
    const cv::Rect& object = plain.object;
    const cv::Mat& scene = plain.scene;
    cv::Mat& frame = plain.frame;
    const cv::Rect core(object.x + 35, object.y + 40, 30, 30);
    cv::Mat shifted;
    frame(core).convertTo(shifted, CV_16SC3);
    shifted += core_shift;
    shifted.convertTo(frame(core), CV_8UC3);
    const ChangeResult result = DetectChanges(Thumbnail(frame), frame.size(),
                                              {Reference(scene, kOffset, object)}, ChangeOptions());
    EXPECT_EQ(result.changes.size(), 1u);
    if (result.changes.size() != 1) return 0.0f;
    EXPECT_GT(IoU(result.changes[0].box, object), 0.3) << result.changes[0].box;
    // The object's mean difference stays under the threshold (what the confidence must not
    // rest on).
    const double to_thumb = static_cast<double>(result.difference.cols) / kWidth;
    const cv::Rect in_thumb(
        static_cast<int>(object.x * to_thumb), static_cast<int>(object.y * to_thumb),
        static_cast<int>(object.width * to_thumb), static_cast<int>(object.height * to_thumb));
    EXPECT_LT(cv::mean(result.difference(in_thumb))[0], result.threshold);
    return result.changes[0].confidence;
  };
  const float clear = confidence(cv::Scalar(-120, 120, 120));
  const float faint = confidence(cv::Scalar(-10, 10, 10));
  EXPECT_GT(clear, faint + 0.1f) << clear << " " << faint;
  EXPECT_LE(clear, 1.0f);
  EXPECT_GE(faint, 0.5f);
}

TEST(ChangeDetectorTest, LabelsOfNoSegmentationAreNotCompared) {
  // Negative labels only, or an id far beyond one per pixel: no segment is compared, and
  // nothing throws.
  const cv::Mat scene = Scene();
  const cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  ChangeOptions options;
  options.segment_difference = 1;
  for (const int label : {-5, std::numeric_limits<int>::max()}) {
    cv::Mat segments(kHeight / 2, kWidth / 2, CV_32S, cv::Scalar(label));
    ChangeResult result;
    EXPECT_NO_THROW(result = DetectChanges(Thumbnail(frame), frame.size(),
                                           {Reference(scene, kOffset)}, options, segments));
    EXPECT_TRUE(result.checked);
    EXPECT_TRUE(result.changes.empty());
  }
}

TEST(ChangeDetectorTest, AThinSegmentIsNoChange) {
  // A segment a few pixels wide (a door frame) differs where the alignment misses by a pixel.
  const cv::Mat scene = Scene();
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  const cv::Rect thin(300, 120, 12, 240);
  Tint(frame(thin));
  cv::Mat segments(kHeight, kWidth, CV_32S, cv::Scalar(0));
  segments(thin).setTo(1);
  ChangeOptions options;
  options.segment_difference = 8;
  options.min_area = 0.001;
  const ChangeReference reference = Reference(scene, kOffset, thin);
  options.segment_min_side = 0;
  const ChangeResult kept =
      DetectChanges(Thumbnail(frame), frame.size(), {reference}, options, segments);
  options.segment_min_side = ChangeOptions().segment_min_side;
  const ChangeResult dropped =
      DetectChanges(Thumbnail(frame), frame.size(), {reference}, options, segments);
  EXPECT_EQ(kept.changes.size(), 1u);
  EXPECT_TRUE(dropped.changes.empty());
}

TEST(ChangeDetectorTest, AThinFrameIsComparedWithoutFlow) {
  // Thumbnails too small for the flow's patches: compared as the homography maps them.
  const cv::Mat scene = Scene();
  const cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, 24))).clone();
  ChangeReference reference = Reference(scene, kOffset);
  reference.thumbnail = Thumbnail(scene(cv::Rect(0, 0, kWidth, 24)));
  std::vector<std::pair<cv::Point2f, cv::Point2f>> pairs;
  for (int x = 10; x < kWidth - kOffset.x; x += 20) {
    pairs.emplace_back(cv::Point2f(x, 4 + (x / 20) % 3),
                       cv::Point2f(x + kOffset.x, 4 + (x / 20) % 3));
  }
  reference.point_pairs = pairs;
  EXPECT_NO_THROW(DetectChanges(Thumbnail(frame), frame.size(), {reference}, ChangeOptions()));
}

TEST(ChangeDetectorTest, RegionWithVerifiedMatchesIsNotAChange) {
  // The region differs but holds as many verified points as anywhere: it was seen before.
  const cv::Mat scene = Scene();
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  const cv::Rect object(300, 200, 100, 120);
  frame(object).setTo(cv::Scalar(20, 200, 30));
  const ChangeResult result =
      DetectChanges(Thumbnail(frame), frame.size(), {Reference(scene, kOffset)}, ChangeOptions());
  EXPECT_TRUE(result.changes.empty());
  ASSERT_EQ(result.dropped.size(), 1u);
  EXPECT_EQ(result.dropped[0].rule, "matched");
  EXPECT_GT(IoU(result.dropped[0].box, object), 0.6) << result.dropped[0].box;
}

TEST(ChangeDetectorTest, MissingLandmarkIsADisappearance) {
  const cv::Mat scene = Scene();
  cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  const cv::Rect gone(200, 100, 120, 100);     // frame pixels
  frame(gone).setTo(cv::Scalar(200, 60, 20));  // a plain wall where the sign was
  ChangeReference reference = Reference(scene, kOffset, gone);
  reference.landmark_boxes = {gone + kOffset, cv::Rect(0, 0, 50, 50)};
  reference.landmark_classes = {"sign", "building"};
  reference.landmark_class_confidences = {0.9f, 0.8f};
  reference.landmark_matched = {false, true};
  const ChangeResult result =
      DetectChanges(Thumbnail(frame), frame.size(), {reference}, ChangeOptions());
  ASSERT_EQ(result.changes.size(), 1u);
  EXPECT_EQ(result.changes[0].kind, SceneChange::Kind::kDisappeared);
  EXPECT_EQ(result.changes[0].object_class, "sign");
  EXPECT_FLOAT_EQ(result.changes[0].class_confidence, 0.9f);
  EXPECT_GT(IoU(result.changes[0].box, gone), 0.5);

  // A landmark whose class the classifier voted against is gone all the same, but unnamed: the
  // alarm says "object" rather than a class that is probably wrong.
  reference.landmark_class_confidences = {0.2f, 0.8f};
  const ChangeResult unsure =
      DetectChanges(Thumbnail(frame), frame.size(), {reference}, ChangeOptions());
  ASSERT_EQ(unsure.changes.size(), 1u);
  EXPECT_EQ(unsure.changes[0].kind, SceneChange::Kind::kDisappeared);
  EXPECT_EQ(unsure.changes[0].object_class, "");
  EXPECT_FLOAT_EQ(unsure.changes[0].class_confidence, 0.2f);
}

TEST(ChangeDetectorTest, ObjectSeenFromANeighbourIsNotAChange) {
  // The matched place does not show the object but its route neighbour does.
  const cv::Mat scene = Scene();
  cv::Mat changed_scene = scene.clone();
  const cv::Rect object(300, 200, 100, 120);
  changed_scene(object + kOffset).setTo(cv::Scalar(20, 200, 30));
  const cv::Mat frame = changed_scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  ChangeReference neighbour = Reference(changed_scene, kOffset, object);
  ChangeReference place = Reference(scene, kOffset, object);
  EXPECT_EQ(DetectChanges(Thumbnail(frame), frame.size(), {place}, ChangeOptions()).changes.size(),
            1u);
  const ChangeResult both =
      DetectChanges(Thumbnail(frame), frame.size(), {place, neighbour}, ChangeOptions());
  EXPECT_EQ(both.references, 2);
  EXPECT_TRUE(both.changes.empty());
}

TEST(ChangeDetectorTest, TooFewPointsOrNoThumbnailIsNotChecked) {
  const cv::Mat scene = Scene();
  const cv::Mat frame = scene(cv::Rect(kOffset, cv::Size(kWidth, kHeight))).clone();
  ChangeReference few = Reference(scene, kOffset);
  few.point_pairs.resize(5);
  ChangeResult result = DetectChanges(Thumbnail(frame), frame.size(), {few}, ChangeOptions());
  EXPECT_FALSE(result.checked);
  EXPECT_FALSE(result.why_not.empty());
  ChangeReference blank = Reference(scene, kOffset);
  blank.thumbnail.release();
  result = DetectChanges(Thumbnail(frame), frame.size(), {blank}, ChangeOptions());
  EXPECT_FALSE(result.checked);
  EXPECT_EQ(result.why_not, "the place has no thumbnail");
  result = DetectChanges(cv::Mat(), frame.size(), {Reference(scene, kOffset)}, ChangeOptions());
  EXPECT_FALSE(result.checked);
}

TEST(ChangeDetectorTest, ComparedAtLoopClosuresOrWithEnoughVerifiedPairs) {
  ChangeOptions options;
  options.min_inliers_without_loop = 0;
  EXPECT_TRUE(CompareAtRevisit(true, 0, options));
  EXPECT_FALSE(CompareAtRevisit(false, 100, options));  // 0: loop closures only
  options.min_inliers_without_loop = 15;
  EXPECT_TRUE(CompareAtRevisit(false, 15, options));
  EXPECT_FALSE(CompareAtRevisit(false, 14, options));
  EXPECT_FALSE(CompareAtRevisit(false, -1, options));  // not verified
  options.enabled = false;
  EXPECT_FALSE(CompareAtRevisit(true, 100, options));
  std::string error;
  options.enabled = true;
  options.min_inliers_without_loop = -1;
  EXPECT_FALSE(options.Check(&error));
}

TEST(ChangeDetectorTest, DrawChangesScalesToTheWidth) {
  const cv::Mat frame(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));
  SceneChange change;
  change.box = cv::Rect(100, 100, 200, 100);
  const cv::Mat picture = DrawChanges(frame, frame.size(), {change}, 320);
  EXPECT_EQ(picture.cols, 320);
  EXPECT_EQ(picture.rows, 240);
  EXPECT_NE(cv::countNonZero(picture.reshape(1)), 0);  // the box is drawn
}

}  // namespace
}  // namespace placerec
