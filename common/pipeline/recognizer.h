// Place recognition for a fleet (seed §5.7): for each frame of a robot, find its objects, ask
// the shared map which earlier places they were seen at, decide whether this is a loop closure,
// and store the frame's landmarks. Per-robot short-term memory (the previous frames' objects)
// lives here; the map is shared by every robot.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "common/change/change_detector.h"
#include "common/pipeline/frame_analyzer.h"
#include "common/pipeline/object_classes.h"
#include "common/pipeline/place_map.h"
#include "common/recognition/landmark_selector.h"
#include "common/recognition/loop_decision.h"
#include "common/recognition/recent_past.h"
#include "common/recognition/seed_decision.h"
#include "common/recognition/sequence_support.h"
#include "common/util/status.h"
#include "common/util/timer.h"

namespace placerec {

// Which recognition runs.
enum class RecognitionMode {
  kDefault,  // this project's: every object and keypoint looked up, geometric verification
  kSeed,     // the seed's (§5.7 steps 5-6): landmarks only, an object database with scene sets
};

// Which objects of a frame are looked up in the map.
enum class QueryObjects {
  kAll,        // every object: a revisit is found from the first frame at a place
  kLandmarks,  // only landmarks, as in seed §5.7 step 5
};

struct RecognizerOptions {
  RecognitionMode mode = RecognitionMode::kDefault;
  // The seed's loop decision (mode kSeed).
  SeedLoopOptions seed;
  AnalyzerOptions analyzer;
  LandmarkSelectorOptions landmarks;
  LandmarkIndexOptions index;
  LoopDecisionOptions loop;
  RecentPastOptions recent_past;
  // A candidate place's score averages in the robot's earlier frames that matched the same
  // route in step (sequence_support.h); a one-off query keeps its own score.
  SequenceOptions sequence;
  QueryObjects query_objects = QueryObjects::kAll;
  // Look up at most this many of the query objects' descriptors, the strongest keypoints
  // (largest DoG response) first: the cost of a lookup grows with the descriptors searched.
  // 0 searches all.
  int max_query_descriptors = 0;
  // Also look up the keypoints that fall in no object (small segments, segment borders), for
  // place-level matching only: plain frames (a corridor) have few objects but still show the
  // place.
  bool query_unassigned_keypoints = true;
  // Store only a landmark's descriptors that matched into the previous frames (its widely
  // visible features); off stores every descriptor of the landmark object.
  bool store_tracked_descriptors_only = true;
  // A place of a plain scene tracks few features; when its landmarks' tracked descriptors are
  // fewer than this, their other descriptors are stored too (strongest keypoints first) up to
  // this many, so that the place can still be recognised. 0: tracked only.
  int min_descriptors_per_place = 100;
  // The object classes of the stored landmarks (seed Ch. 4) and semantic landmarks (§7.2.3).
  ObjectClassOptions classes;
  // Scene changes at a loop closure (seed §7.2.4, common/change): the frame against the best
  // place's thumbnail and landmarks, and its route neighbours among the matches.
  ChangeOptions change;
  // JPEG quality of the place thumbnails and alarm pictures (0-100).
  int jpeg_quality = 85;

  bool Check(std::string* error) const;
};

// The options a recognizer runs with: as given for kDefault; for kSeed, the seed's choices where
// ours differ (§5.7): only landmarks are looked up, by their objects alone (no place-level votes,
// no keypoints outside objects, no geometric check, no sequence support); a new landmark is
// stored with all its descriptors; background is not an object (§3.7); nothing is left out for
// its class.
RecognizerOptions EffectiveOptions(const RecognizerOptions& options);

struct FrameRequest {
  std::string robot;     // 1..kMaxRobotIdLength bytes
  int64_t sequence = 0;  // increasing per robot for inserted frames
  int64_t utime = 0;     // capture time, microseconds since the epoch
  bool insert = true;    // false: query only, the map and the robot's state stay unchanged
};

// What scene-change detection found at a loop closure (seed §7.2.4).
struct ChangeReport {
  bool checked = false;  // the frame was compared with a stored place
  std::string why_not;   // at a loop closure that was not checked: why
  Place place;           // the place compared with (the best match); invalid id when none
  std::vector<SceneChange> changes;  // boxes in processed pixels; classes where classified
  // With changes: JPEG of the frame (AnalyzerOptions::preview_width) with the boxes drawn, and
  // the place's stored thumbnail (empty when it has none).
  std::vector<uint8_t> frame_picture;
  std::vector<uint8_t> place_picture;
  // Per pixel of the frame's thumbnail, how much it differs from the stored view (CIE Lab units,
  // ChangeResult::difference), for pictures of the evaluation.
  cv::Mat difference;
  double threshold = 0;  // the difference a change needed in this frame (ChangeResult)
  cv::Mat shared;        // where the frame was compared (ChangeResult::shared)
  std::vector<DroppedRegion> dropped;  // regions judged no change, and why (ChangeResult)
};

struct RecognitionResult {
  Status status;
  bool loop_closure = false;        // best place scored at least loop.min_score
  std::vector<PlaceMatch> matches;  // best first
  int keypoints = 0;
  int objects = 0;
  int landmarks = 0;  // this frame's landmarks (0 for query-only frames)
  // Landmarks left out of the map for their movable class (ObjectClassOptions::drop_movable).
  int movable_landmarks = 0;
  // The object class of each landmark stored (empty names for unclassified ones).
  std::vector<std::string> stored_classes;
  int stored_descriptors = 0;  // descriptors this frame added to the map
  PlaceId place;               // the place inserted for this frame, if any
  // The frame showed nothing new since the robot's last distinct frame (recent_past.h): its
  // landmarks were not stored. When the map has not changed since that frame, its answer is
  // given again (matches without the per-object pairs and points, which belong to that frame).
  bool duplicate = false;
  bool repeated_answer = false;
  ChangeReport change;       // scene changes at the best place (loop closures only)
  MapCounts map;             // map size after this frame
  double image_scale = 1.0;  // processed / original frame size (max_image_width)
  StageTimings timings;      // milliseconds
};

class Recognizer {
 public:
  // A null `segmenter` or `labeler` is made from the options (MakeSegmenter,
  // ObjectClassLabeler::Load); failing to load models is then fatal, so callers that want to
  // report it load them themselves. No labeler is used when options.classes.enabled is false.
  Recognizer(const RecognizerOptions& options, PlaceMap* map,
             std::unique_ptr<Segmenter> segmenter = nullptr,
             std::shared_ptr<const ObjectClassLabeler> labeler = nullptr);

  // Analyze + Recognize. Frames of different robots may be processed from different threads at
  // once; frames of one robot must arrive in order, one at a time.
  RecognitionResult Process(const FrameRequest& request, const cv::Mat& bgr);

  // The stateless half (thread-safe for any frames).
  FrameObservation Analyze(const cv::Mat& bgr) const { return analyzer_.Analyze(bgr); }

  // The stateful half: landmark selection, lookup, decision, insertion.
  RecognitionResult Recognize(const FrameRequest& request, const FrameObservation& observation);

  // Checks a request before any work (robot id, sequence order for inserts).
  Status Validate(const FrameRequest& request) const;

  const RecognizerOptions& options() const { return options_; }
  const Segmenter& segmenter() const { return analyzer_.segmenter(); }
  // The object classifiers (null without object classes); recognizers may share them.
  const std::shared_ptr<const ObjectClassLabeler>& labeler() const { return labeler_; }
  PlaceMap& map() { return *map_; }

 private:
  struct RobotState {
    RobotState(const LandmarkSelectorOptions& landmarks, const RecentPastOptions& recent,
               const SequenceOptions& sequence_options)
        : selector(landmarks), recent_past(recent), sequence(sequence_options) {}
    LandmarkSelector selector;
    RecentPast recent_past;
    SequenceSupport sequence;
    int64_t last_sequence = INT64_MIN;
    // Whether the robot's stored places were taken as its views (RecentPast::Resume; at its
    // first inserted frame).
    bool resumed = false;
    // The answer to the robot's last distinct frame and the map's place count after it: a
    // frame that shows nothing new while the map is unchanged gets that answer again.
    std::vector<PlaceMatch> last_matches;
    int64_t last_map_places = -1;
  };
  RobotState* StateOf(const std::string& robot);
  // The landmarks a frame stores: per selected landmark its tracked descriptors, topped up in
  // plain scenes to min_descriptors_per_place (strongest keypoints first).
  // `labels` holds one class per selected landmark.
  std::vector<Landmark> BuildLandmarks(const FrameObservation& observation,
                                       const LandmarkSelection& selection,
                                       const std::vector<ObjectLabel>& labels) const;
  // The classes of the selected landmarks (one per landmark; empty labels without a labeler),
  // and the selection without the landmarks the labeler leaves out.
  // Scene changes between the frame and the best match (and its route neighbours among the
  // matches); classes from the labeler for objects that appeared.
  ChangeReport DetectSceneChanges(const FrameObservation& observation,
                                  const std::vector<PlaceMatch>& matches) const;
  LandmarkSelection ClassifyLandmarks(const FrameObservation& observation,
                                      const LandmarkSelection& selection,
                                      std::vector<ObjectLabel>* labels) const;

  RecognizerOptions options_;
  PlaceMap* map_;
  FrameAnalyzer analyzer_;
  std::shared_ptr<const ObjectClassLabeler> labeler_;
  mutable std::mutex robots_mutex_;
  std::map<std::string, std::unique_ptr<RobotState>> robots_;
};

}  // namespace placerec
