#include "common/pipeline/recognizer.h"

#include <algorithm>
#include <cstdio>
#include <functional>
#include <optional>
#include <set>
#include <tuple>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/util/logging.h"
#include "common/util/stage.h"

namespace placerec {

namespace {

bool CheckJpegQuality(int quality, std::string* error) {
  if (quality < 0 || quality > 100) {
    *error = "jpeg_quality must be in [0, 100]";
    return false;
  }
  return true;
}

std::vector<uint8_t> EncodeJpeg(const cv::Mat& image, int quality) {
  std::vector<uint8_t> bytes;
  if (!image.empty()) cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, quality});
  return bytes;
}

double Overlap(const cv::Rect& a, const cv::Rect& b) {
  const double inter = (a & b).area();
  const double uni = a.area() + b.area() - inter;
  return uni > 0 ? inter / uni : 0.0;
}

}  // namespace

bool RecognizerOptions::Check(std::string* error) const {
  return analyzer.Check(error) && landmarks.Check(error) && index.Check(error) &&
         loop.Check(error) && recent_past.Check(error) && sequence.Check(error) &&
         classes.Check(error) && seed.Check(error) && change.Check(error) &&
         CheckJpegQuality(jpeg_quality, error);
}

RecognizerOptions EffectiveOptions(const RecognizerOptions& options) {
  RecognizerOptions o = options;
  if (o.mode != RecognitionMode::kSeed) return o;
  o.query_objects = QueryObjects::kLandmarks;
  o.query_unassigned_keypoints = false;
  o.max_query_descriptors = 0;
  o.index.vote_places = 0;
  o.index.exact_places = 0;
  o.index.exact_route_neighbours = 0;
  o.loop.geometric_verification = false;
  o.sequence.frames = 0;
  o.store_tracked_descriptors_only = false;
  o.min_descriptors_per_place = 0;
  o.analyzer.objects.include_background = false;
  o.classes.drop_movable = false;
  o.change.enabled = false;  // the seed's decision keeps no verified point pairs
  return o;
}

namespace {

// The analyzer keeps the filter bank when landmarks are classified.
AnalyzerOptions AnalyzerFor(const RecognizerOptions& options) {
  AnalyzerOptions analyzer = options.analyzer;
  analyzer.keep_filter_bank = analyzer.keep_filter_bank || options.classes.enabled;
  return analyzer;
}

}  // namespace

Recognizer::Recognizer(const RecognizerOptions& options, PlaceMap* map,
                       std::unique_ptr<Segmenter> segmenter,
                       std::shared_ptr<const ObjectClassLabeler> labeler)
    : options_(EffectiveOptions(options)),
      map_(map),
      analyzer_(AnalyzerFor(options_), std::move(segmenter)),
      labeler_(std::move(labeler)) {
  CHECK(map_ != nullptr);
  options_.analyzer = analyzer_.options();
  if (!options_.classes.enabled) {
    labeler_.reset();
  } else if (!labeler_) {
    StatusOr<std::unique_ptr<ObjectClassLabeler>> loaded =
        ObjectClassLabeler::Load(options_.classes);
    CHECK(loaded.ok()) << loaded.status().message();
    labeler_ = std::move(*loaded);
  }
}

Recognizer::RobotState* Recognizer::StateOf(const std::string& robot) {
  std::lock_guard lock(robots_mutex_);
  std::unique_ptr<RobotState>& state = robots_[robot];
  if (!state) {
    state =
        std::make_unique<RobotState>(options_.landmarks, options_.recent_past, options_.sequence);
  }
  return state.get();
}

Status Recognizer::Validate(const FrameRequest& request) const {
  if (request.robot.empty()) return Status::InvalidArgument("robot id is empty");
  if (request.robot.size() > kMaxRobotIdLength) {
    return Status::InvalidArgument("robot id is " + std::to_string(request.robot.size()) +
                                   " bytes; the limit is " + std::to_string(kMaxRobotIdLength));
  }
  for (unsigned char c : request.robot) {
    if (c < 0x20 || c == 0x7f) {
      return Status::InvalidArgument("robot id contains a control character");
    }
  }
  if (Status time = CheckCaptureTime(request.utime); !time.ok()) return time;
  if (request.insert) {
    std::lock_guard lock(robots_mutex_);
    const auto it = robots_.find(request.robot);
    if (it != robots_.end() && request.sequence <= it->second->last_sequence) {
      return Status::InvalidArgument("sequence " + std::to_string(request.sequence) +
                                     " of robot '" + request.robot + "' is not after " +
                                     std::to_string(it->second->last_sequence));
    }
  }
  return Status::Ok();
}

RecognitionResult Recognizer::Process(const FrameRequest& request, const cv::Mat& bgr) {
  const Status status = Validate(request);
  if (!status.ok()) {
    RecognitionResult result;
    result.status = status;
    result.map = map_->Counts();
    return result;
  }
  return Recognize(request, analyzer_.Analyze(bgr));
}

LandmarkSelection Recognizer::ClassifyLandmarks(const FrameObservation& observation,
                                                const LandmarkSelection& selection,
                                                std::vector<ObjectLabel>* labels) const {
  labels->clear();
  if (!labeler_) {
    labels->resize(selection.landmarks.size());
    return selection;
  }
  LandmarkSelection kept;
  for (size_t i = 0; i < selection.landmarks.size(); ++i) {
    ObjectLabel label = labeler_->Classify(
        observation.filter_bank, observation.objects[selection.landmarks[i]], &observation.textons);
    if (labeler_->LeaveOut(label)) continue;
    kept.landmarks.push_back(selection.landmarks[i]);
    kept.tracked_rows.push_back(selection.tracked_rows[i]);
    labels->push_back(std::move(label));
  }
  return kept;
}

std::vector<Landmark> Recognizer::BuildLandmarks(const FrameObservation& observation,
                                                 const LandmarkSelection& selection,
                                                 const std::vector<ObjectLabel>& labels) const {
  CHECK_EQ(labels.size(), selection.landmarks.size());
  // Rows stored per landmark: the tracked ones, topped up in plain scenes.
  std::vector<std::vector<int>> stored_rows(selection.landmarks.size());
  size_t stored_total = 0;
  for (size_t i = 0; i < selection.landmarks.size(); ++i) {
    const SceneObject& object = observation.objects[selection.landmarks[i]];
    if (options_.store_tracked_descriptors_only) {
      stored_rows[i] = selection.tracked_rows[i];
    } else {
      stored_rows[i].resize(object.keypoints.size());
      for (size_t r = 0; r < stored_rows[i].size(); ++r) stored_rows[i][r] = static_cast<int>(r);
    }
    stored_total += stored_rows[i].size();
  }
  if (stored_total < static_cast<size_t>(options_.min_descriptors_per_place)) {
    // Untracked rows of every landmark, strongest keypoint first.
    std::vector<std::tuple<float, size_t, int>> extra;  // (-response, landmark, row)
    for (size_t i = 0; i < selection.landmarks.size(); ++i) {
      const SceneObject& object = observation.objects[selection.landmarks[i]];
      std::vector<bool> taken(object.keypoints.size(), false);
      for (int r : stored_rows[i]) taken[r] = true;
      for (int r = 0; r < object.sift_count(); ++r) {
        if (taken[r]) continue;
        extra.emplace_back(-observation.features.keypoints[object.keypoints[r]].response, i, r);
      }
    }
    std::sort(extra.begin(), extra.end());
    for (const auto& [negative_response, i, r] : extra) {
      if (stored_total >= static_cast<size_t>(options_.min_descriptors_per_place)) break;
      stored_rows[i].push_back(r);
      ++stored_total;
    }
  }
  std::vector<Landmark> landmarks;
  for (size_t i = 0; i < selection.landmarks.size(); ++i) {
    const SceneObject& object = observation.objects[selection.landmarks[i]];
    Landmark landmark;
    landmark.sift_count = object.sift_count();
    landmark.colour = object.colour;
    landmark.box = object.box;
    landmark.segment_class = object.segment_class;
    landmark.object_class = labels[i].name;
    landmark.class_confidence = labels[i].name.empty() ? 0.0f : labels[i].confidence;
    const std::vector<int>& rows = stored_rows[i];
    landmark.descriptors.create(static_cast<int>(rows.size()), kDescriptorSize, CV_8U);
    for (size_t r = 0; r < rows.size(); ++r) {
      object.descriptors.row(rows[r]).copyTo(landmark.descriptors.row(static_cast<int>(r)));
      landmark.keypoints.push_back(observation.features.keypoints[object.keypoints[rows[r]]]);
    }
    landmarks.push_back(std::move(landmark));
  }
  return landmarks;
}

ChangeReport Recognizer::DetectSceneChanges(const FrameObservation& observation,
                                            const std::vector<PlaceMatch>& matches) const {
  ChangeReport report;
  if (matches.empty()) return report;
  const PlaceMatch& best = matches.front();
  report.place = best.place;
  // The best place, then its route neighbours among the matches.
  const int64_t window_us = static_cast<int64_t>(options_.change.reference_window_seconds * 1e6);
  std::vector<ChangeReference> references;
  for (const PlaceMatch& match : matches) {
    if (static_cast<int>(references.size()) >= options_.change.max_references) break;
    if (&match != &best && (match.place.robot != best.place.robot ||
                            std::llabs(match.place.utime - best.place.utime) > window_us)) {
      continue;
    }
    ChangeReference reference;
    StatusOr<std::vector<uint8_t>> jpeg = map_->LoadThumbnail(match.place.id);
    if (!jpeg.ok()) {
      LOG(WARNING) << "thumbnail of place " << match.place.id.value() << ": "
                   << jpeg.status().message();
      continue;
    }
    if (!jpeg->empty()) reference.thumbnail = cv::imdecode(*jpeg, cv::IMREAD_COLOR);
    if (&match == &best) report.place_picture = std::move(*jpeg);
    reference.image_width = match.place.image_width;
    reference.point_pairs = match.point_pairs;
    std::set<LandmarkId> matched(match.point_landmarks.begin(), match.point_landmarks.end());
    for (const auto& pair : match.object_pairs) matched.insert(pair.second);
    for (const Landmark& landmark : map_->LandmarkOutlines(match.place.id)) {
      reference.landmark_boxes.push_back(landmark.box);
      reference.landmark_classes.push_back(landmark.object_class);
      reference.landmark_class_confidences.push_back(landmark.class_confidence);
      reference.landmark_matched.push_back(matched.count(landmark.id) > 0);
    }
    references.push_back(std::move(reference));
  }
  ChangeResult found = DetectChanges(observation.thumbnail, observation.processed_size, references,
                                     options_.change, observation.segmentation.labels);
  report.checked = found.checked;
  report.why_not = found.why_not;
  report.changes = std::move(found.changes);
  report.difference = found.difference;
  report.threshold = found.threshold;
  report.shared = found.shared;
  report.dropped = std::move(found.dropped);
  if (report.changes.empty()) return report;
  // The class of an object that appeared: the frame's object that covers it best.
  if (labeler_) {
    for (SceneChange& change : report.changes) {
      if (change.kind != SceneChange::Kind::kAppeared) continue;
      const SceneObject* cover = nullptr;
      double best_overlap = 0.3;
      for (const SceneObject& object : observation.objects) {
        const double overlap = Overlap(object.box, change.box);
        if (overlap >= best_overlap) {
          best_overlap = overlap;
          cover = &object;
        }
      }
      if (cover == nullptr) continue;
      const ObjectLabel label =
          labeler_->Classify(observation.filter_bank, *cover, &observation.textons);
      change.class_confidence = label.confidence;
      if (label.confidence >= options_.change.min_class_confidence) {
        change.object_class = label.name;
      }
    }
  }
  if (!observation.preview.empty()) {
    report.frame_picture = EncodeJpeg(DrawChanges(observation.preview, observation.processed_size,
                                                  report.changes, observation.preview.cols),
                                      options_.jpeg_quality);
  }
  return report;
}

namespace {

// Puts a robot's recent past back as it was unless Keep() is called: a frame that was not stored
// (a storage error, an exception) must not become the robot's last distinct frame, or the next
// frames of the same view would count as copies of it and never be stored either. RecentPast
// replaces its matrices rather than writing into them, so a shallow copy restores it.
class RecentPastGuard {
 public:
  explicit RecentPastGuard(RecentPast* past) : past_(past), saved_(*past) {}
  ~RecentPastGuard() {
    if (!kept_) *past_ = std::move(saved_);
  }
  RecentPastGuard(const RecentPastGuard&) = delete;
  RecentPastGuard& operator=(const RecentPastGuard&) = delete;

  void Keep() { kept_ = true; }

 private:
  RecentPast* past_;
  RecentPast saved_;
  bool kept_ = false;
};

}  // namespace

RecognitionResult Recognizer::Recognize(const FrameRequest& request,
                                        const FrameObservation& observation) {
  RecognitionResult result;
  result.status = Validate(request);
  result.timings = observation.timings;
  result.keypoints = observation.features.size();
  result.image_scale = observation.scale;
  result.objects = static_cast<int>(observation.objects.size());
  if (!result.status.ok()) {
    result.map = map_->Counts();
    return result;
  }
  RobotState* state = StateOf(request.robot);

  // Landmark selection (seed §5.7 step 4).
  Timer timer;
  std::optional<ScopedStage> stage(std::in_place, "landmarks");
  std::vector<cv::Mat> object_descriptors;
  object_descriptors.reserve(observation.objects.size());
  for (const SceneObject& object : observation.objects) {
    object_descriptors.push_back(object.descriptors);
  }
  const LandmarkSelection selection = state->selector.Select(object_descriptors);
  result.timings.emplace_back("landmarks", timer.ElapsedMs());

  // The robot's own recent past (seed §5.7 step 6) moves on with every inserted frame; a query
  // only reads it.
  timer.Restart();
  stage.emplace("recent_past");
  RecentPastUpdate recent;
  std::optional<RecentPastGuard> recent_guard;
  if (request.insert && !state->resumed) {
    // The robot's places stored before this recognizer knew it (a server restart, a forgotten
    // run) are its views again; a new run of the robot numbers its frames from below them.
    state->resumed = true;
    const int64_t within_us =
        static_cast<int64_t>(options_.recent_past.resume_within_seconds * 1e6);
    const int64_t away_us = static_cast<int64_t>(options_.recent_past.away_seconds * 1e6);
    state->recent_past.Resume(map_->StoredViews(
        request.robot, request.sequence, request.utime - within_us, request.utime, away_us,
        options_.recent_past.max_views, options_.recent_past.descriptors_per_frame));
  }
  if (request.insert) {
    recent_guard.emplace(&state->recent_past);
    recent =
        state->recent_past.Observe(request.sequence, request.utime, observation.features.keypoints,
                                   observation.features.descriptors);
  }
  result.timings.emplace_back("recent_past", timer.ElapsedMs());

  if (recent.duplicate && state->last_map_places == map_->Counts().places) {
    // Nothing new in the frame and nothing new in the map: the same answer, at any frame rate,
    // without a lookup.
    result.duplicate = true;
    result.repeated_answer = true;
    result.landmarks = static_cast<int>(selection.landmarks.size());  // seen, not stored
    result.matches = state->last_matches;
    result.loop_closure =
        !result.matches.empty() && result.matches.front().score >= options_.loop.min_score;
    state->last_sequence = request.sequence;
    result.map = map_->Counts();
    if (recent_guard) recent_guard->Keep();  // seen, deliberately not stored
    return result;
  }

  // Lookup (seed §5.7 step 5) and decision (step 6).
  stage.emplace("lookup");
  MapLookup lookup;
  lookup.recent = state->recent_past.Filter(request.robot, request.utime);
  lookup.image_width = observation.processed_size.width;
  std::vector<int> query_to_object;
  if (options_.query_objects == QueryObjects::kAll) {
    for (int o = 0; o < result.objects; ++o) query_to_object.push_back(o);
  } else {
    query_to_object = selection.landmarks;
  }
  // Which keypoints are searched: all, or the strongest max_query_descriptors of them.
  float min_response = -1.0f;
  if (options_.max_query_descriptors > 0) {
    std::vector<float> responses;
    for (int o : query_to_object) {
      for (int k : observation.objects[o].keypoints) {
        responses.push_back(observation.features.keypoints[k].response);
      }
    }
    if (static_cast<int>(responses.size()) > options_.max_query_descriptors) {
      std::nth_element(responses.begin(), responses.begin() + options_.max_query_descriptors - 1,
                       responses.end(), std::greater<float>());
      min_response = responses[options_.max_query_descriptors - 1];
    }
  }
  std::vector<int> searched_objects;
  for (int o : query_to_object) {
    const SceneObject& object = observation.objects[o];
    IndexQuery query{object.sift_count(), object.colour, cv::Mat()};
    std::vector<cv::KeyPoint> keypoints;
    for (int r = 0; r < object.sift_count(); ++r) {
      const cv::KeyPoint& keypoint = observation.features.keypoints[object.keypoints[r]];
      if (keypoint.response < min_response) continue;
      query.descriptors.push_back(object.descriptors.row(r));
      keypoints.push_back(keypoint);
    }
    if (keypoints.empty()) continue;
    lookup.objects.push_back(std::move(query));
    lookup.object_keypoints.push_back(std::move(keypoints));
    searched_objects.push_back(o);
  }
  if (options_.query_unassigned_keypoints) {
    std::vector<bool> in_object(observation.features.size(), false);
    for (const SceneObject& object : observation.objects) {
      for (int k : object.keypoints) in_object[k] = true;
    }
    IndexQuery rest{0, ColourSignature(), cv::Mat(), false};
    std::vector<cv::KeyPoint> keypoints;
    for (int k = 0; k < observation.features.size(); ++k) {
      const cv::KeyPoint& keypoint = observation.features.keypoints[k];
      if (in_object[k] || keypoint.response < min_response) continue;
      rest.descriptors.push_back(observation.features.descriptors.row(k));
      keypoints.push_back(keypoint);
    }
    if (!keypoints.empty()) {
      rest.sift_count = static_cast<int>(keypoints.size());
      lookup.objects.push_back(std::move(rest));
      lookup.object_keypoints.push_back(std::move(keypoints));
      searched_objects.push_back(-1);
    }
  }
  // More places than the answer holds: the robot's later frames look for its route among them.
  LoopDecisionOptions loop = options_.loop;
  if (options_.sequence.frames > 0) {
    loop.max_matches = std::max(loop.max_matches, options_.sequence.places_kept);
  }
  const bool seed = options_.mode == RecognitionMode::kSeed;
  bool seed_loop = false;
  // The map this frame's answer knows: read before the lookup, so that places other robots store
  // meanwhile are looked up again by the robot's next frame, never taken as already answered.
  const int64_t places_looked_up = map_->Counts().places;
  MapLookupResult found =
      seed ? map_->LookupSeed(lookup, options_.seed, loop.max_matches, &seed_loop)
           : map_->Lookup(lookup, loop);
  VLOG(1) << request.robot << " #" << request.sequence << ": " << lookup.objects.size()
          << " query objects, " << found.stats.candidates << " candidates, "
          << found.stats.matching.query_descriptors << " descriptors, "
          << found.stats.matching.candidate_pairs << " voted pairs, "
          << found.stats.matching.verified_pairs << " verified, "
          << found.stats.matching.matched_pairs << " matched, " << found.stats.candidate_places
          << " places; best "
          << (found.places.empty()
                  ? std::string("none")
                  : found.places[0].place.robot + " #" +
                        std::to_string(found.places[0].place.sequence) + " score " +
                        std::to_string(found.places[0].score) + " points " +
                        std::to_string(found.places[0].matched_descriptors));
  if (VLOG_IS_ON(2)) {
    std::string list;
    for (const PlaceMatch& m : found.places) {
      char text[96];
      std::snprintf(text, sizeof(text), " %lld:%.0f/%d/%d/%+.2f",
                    static_cast<long long>(m.place.sequence), m.score, m.matched_descriptors,
                    m.matched_landmarks, m.log_scale);
      list += text;
    }
    VLOG(2) << "places (sequence:score/points/landmarks/log scale):" << list;
  }
  for (PlaceMatch& match : found.places) {
    for (auto& pair : match.object_pairs) pair.first = searched_objects[pair.first];
  }
  // Sequence consistency: every frame reads the robot's earlier frames; inserted frames join
  // them once stored (a query, or a frame that fails to be stored, changes nothing).
  state->sequence.Apply(request.utime, &found.places);
  SequenceSupport::Frame sequence_frame;
  if (request.insert) sequence_frame = state->sequence.Summarise(request.utime, found.places);
  if (static_cast<int>(found.places.size()) > options_.loop.max_matches) {
    found.places.resize(options_.loop.max_matches);
  }
  result.matches = std::move(found.places);
  result.loop_closure =
      seed ? seed_loop
           : !result.matches.empty() && result.matches.front().score >= options_.loop.min_score;
  result.timings.emplace_back("index", found.index_ms);
  result.timings.emplace_back("decision", found.ranking_ms);
  if (!result.matches.empty() &&
      CompareAtRevisit(result.loop_closure, result.matches.front().inliers, options_.change)) {
    timer.Restart();
    stage.emplace("change");
    result.change = DetectSceneChanges(observation, result.matches);
    result.timings.emplace_back("change", timer.ElapsedMs());
  }

  if (!request.insert) {
    result.map = map_->Counts();
    return result;
  }

  // Store this frame's landmarks, committed before the answer goes out; a frame that shows
  // nothing new since the robot's last distinct frame is not stored.
  timer.Restart();
  stage.emplace("classes");
  result.duplicate = recent.duplicate;
  std::vector<Landmark> landmarks;
  std::set<LandmarkId> seen;  // kSeed: stored landmarks this frame saw again
  if (!result.duplicate) {
    // Classes (seed Ch. 4) of the landmarks to store; movable ones may be left out (§7.2.3).
    std::vector<ObjectLabel> labels;
    LandmarkSelection stored = ClassifyLandmarks(observation, selection, &labels);
    result.movable_landmarks =
        static_cast<int>(selection.landmarks.size() - stored.landmarks.size());
    if (seed) {
      // The seed's object database (§5.7 step 5): a landmark that matched stored objects is not
      // stored again; the place joins their scene sets.
      std::set<int> matched_objects;
      for (const auto& [query, landmark] : found.object_matches) {
        matched_objects.insert(searched_objects[query]);
        seen.insert(landmark);
      }
      LandmarkSelection unmatched;
      std::vector<ObjectLabel> unmatched_labels;
      for (size_t i = 0; i < stored.landmarks.size(); ++i) {
        if (matched_objects.count(stored.landmarks[i]) > 0) continue;
        unmatched.landmarks.push_back(stored.landmarks[i]);
        unmatched.tracked_rows.push_back(stored.tracked_rows[i]);
        unmatched_labels.push_back(labels[i]);
      }
      stored = std::move(unmatched);
      labels = std::move(unmatched_labels);
    }
    result.timings.emplace_back("classes", timer.ElapsedMs());
    timer.Restart();
    stage.emplace("insert");
    landmarks = BuildLandmarks(observation, stored, labels);
  }
  for (const Landmark& landmark : landmarks) {
    result.stored_descriptors += landmark.num_descriptors();
    result.stored_classes.push_back(landmark.object_class);
  }
  // Stored unless a duplicate or movable.
  result.landmarks = static_cast<int>(selection.landmarks.size()) - result.movable_landmarks;
  if (!landmarks.empty() || !seen.empty()) {
    Place place;
    place.robot = request.robot;
    place.sequence = request.sequence;
    place.utime = request.utime;
    place.image_width = observation.processed_size.width;
    place.seen_landmarks.assign(seen.begin(), seen.end());
    place.thumbnail = EncodeJpeg(observation.thumbnail, options_.jpeg_quality);
    const Status inserted = map_->Insert(&place, &landmarks);
    if (!inserted.ok()) {
      result.status = inserted;
      result.stored_descriptors = 0;
      result.map = map_->Counts();
      return result;
    }
    result.place = place.id;
  }
  // The landmark history holds the robot's distinct frames: copies of a view would make every
  // object "widely visible" at a high frame rate.
  if (!result.duplicate) state->selector.Remember(object_descriptors);
  // The answer a frame showing nothing new gets again: without the per-object pairs and
  // points, which belong to this frame's objects and keypoints.
  state->last_matches.clear();
  for (const PlaceMatch& match : result.matches) {
    PlaceMatch summary = match;
    summary.object_pairs.clear();
    summary.landmark_boxes.clear();
    summary.point_pairs.clear();
    summary.point_landmarks.clear();
    state->last_matches.push_back(std::move(summary));
  }
  state->last_map_places = places_looked_up + (result.place.IsValid() ? 1 : 0);
  state->last_sequence = request.sequence;
  state->sequence.Record(std::move(sequence_frame));
  result.timings.emplace_back("insert", timer.ElapsedMs());
  result.map = map_->Counts();
  if (recent_guard) recent_guard->Keep();
  return result;
}

}  // namespace placerec
