#include "server/frame_processor.h"

#include <exception>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "common/util/logging.h"
#include "common/util/stage.h"
#include "common/util/timer.h"
#include "proto/channels.h"
#include "server/protocol.h"

namespace placerec {
namespace {

// The segmenter of a robot's run: the processor's own, which the run never calls (frames are
// analyzed once, by the processor), so that a run costs no model loading (the object
// classifiers are shared too).
class SharedSegmenter : public Segmenter {
 public:
  explicit SharedSegmenter(const Segmenter* segmenter) : segmenter_(segmenter) {}
  SceneSegmentation Segment(const WorkingImage& image, cv::Mat* filter_bank = nullptr,
                            TextonMap* textons = nullptr) const override {
    return segmenter_->Segment(image, filter_bank, textons);
  }
  std::string name() const override { return segmenter_->name(); }
  int working_width() const override { return segmenter_->working_width(); }

 private:
  const Segmenter* segmenter_;
};

}  // namespace

FrameProcessor::FrameProcessor(const RecognizerOptions& options, const DecodeOptions& decode,
                               PlaceMap* map, std::unique_ptr<Segmenter> segmenter,
                               const SequenceRuleOptions& sequence_rule,
                               std::shared_ptr<const ObjectClassLabeler> labeler)
    : options_(options),
      decode_(decode),
      map_(map),
      analyzer_(options, map, std::move(segmenter), std::move(labeler)),
      gate_(sequence_rule),
      max_runs_(sequence_rule.max_robot_runs) {
  map_->ForEachPlace([this](const Place& place) { gate_.AddStored(place.robot, place.sequence); });
}

std::unique_ptr<Recognizer> FrameProcessor::NewRun() const {
  return std::make_unique<Recognizer>(options_, map_,
                                      std::make_unique<SharedSegmenter>(&analyzer_.segmenter()),
                                      analyzer_.labeler());
}

std::shared_ptr<Recognizer> FrameProcessor::FindRun(const std::string& robot) {
  std::lock_guard lock(runs_mutex_);
  const auto it = runs_.find(robot);
  if (it == runs_.end()) return nullptr;
  it->second.last_used = ++runs_clock_;
  return it->second.recognizer;
}

void FrameProcessor::KeepRun(const std::string& robot, std::shared_ptr<Recognizer> run) {
  std::lock_guard lock(runs_mutex_);
  Run& kept = runs_[robot];
  kept.recognizer = std::move(run);
  kept.last_used = ++runs_clock_;
  if (static_cast<int>(runs_.size()) <= max_runs_) return;
  auto oldest = runs_.end();
  for (auto it = runs_.begin(); it != runs_.end(); ++it) {
    if (it->first == robot) continue;
    if (oldest == runs_.end() || it->second.last_used < oldest->second.last_used) oldest = it;
  }
  LOG(WARNING) << "more than " << max_runs_ << " robots have a run (--max-robot-runs): robot '"
               << oldest->first
               << "', silent longest, loses its short-term memory; its next frame begins a new run";
  runs_.erase(oldest);
}

std::vector<std::string> FrameProcessor::RobotsWithRuns() const {
  std::lock_guard lock(runs_mutex_);
  std::vector<std::string> robots;
  robots.reserve(runs_.size());
  for (const auto& [robot, run] : runs_) robots.push_back(robot);
  return robots;
}

result_t FrameProcessor::Process(const frame_t& frame, std::vector<change_t>* alarms) {
  try {
    return ProcessOrThrow(frame, alarms);
  } catch (const std::exception& e) {
    // Where it happened: a library's exception names only the library's own function.
    const std::string stage = ScopedStage::TakeFailedStage();
    const std::string where = stage.empty() ? "" : " (in " + stage + ")";
    LOG(ERROR) << "frame " << frame.sequence << " of robot '" << frame.robot << "' failed" << where
               << ": " << e.what();
    result_t answer = AnswerTemplate(frame);
    SetError(result_t::STATUS_INTERNAL_ERROR,
             "internal error while processing the frame" + where + ": " + e.what(), &answer);
    answer.next_sequence = gate_.NextSequence(frame.robot);
    return answer;
  }
}

result_t FrameProcessor::ProcessOrThrow(const frame_t& frame, std::vector<change_t>* alarms) {
  result_t answer = AnswerTemplate(frame);
  auto fail = [&](int8_t status, const std::string& message) {
    const MapCounts counts = map_->Counts();
    answer.map_places = counts.places;
    answer.map_landmarks = counts.landmarks;
    answer.map_descriptors = counts.descriptors;
    SetError(status, message, &answer);
    answer.next_sequence = gate_.NextSequence(frame.robot);
    return answer;
  };
  std::string why;
  if (!IsValidWireRobotId(frame.robot, &why)) return fail(result_t::STATUS_BAD_REQUEST, why);
  const FrameRequest request = ToFrameRequest(frame);
  // The robot's run: its current one, or a new one when the robot has none or restarted. A new
  // run replaces the current one only once its first frame is accepted.
  bool new_run = false;
  if (request.insert) {
    const StatusOr<SequenceGate::Admission> admission =
        gate_.Admit(request.robot, request.sequence, SequenceGate::Clock::now());
    if (!admission.ok()) {
      // An insert sent again (a server killed between committing the frame and answering it lost
      // the answer; the robot sends the frame again to the restarted server) is answered with the
      // place it stored. Only refused inserts of a stored sequence look, so the pass over the
      // places costs nothing in normal running, nor for a robot sending stale sequences.
      const std::optional<Place> stored =
          gate_.IsStored(request.robot, request.sequence)
              ? map_->FindStored(request.robot, request.sequence, request.utime)
              : std::nullopt;
      if (!stored) return fail(result_t::STATUS_BAD_REQUEST, admission.status().message());
      // Answered ok with the place it stored; the loop-closure answer is not kept (the server's
      // answer record, which holds it, does not survive a restart).
      LOG(INFO) << "frame " << request.sequence << " of robot '" << request.robot
                << "' was sent again; it is stored as place " << stored->id.value();
      const MapCounts counts = map_->Counts();
      answer.map_places = counts.places;
      answer.map_landmarks = counts.landmarks;
      answer.map_descriptors = counts.descriptors;
      answer.place_id = stored->id.value();
      answer.landmarks = stored->num_landmarks;
      answer.next_sequence = gate_.NextSequence(request.robot);
      return answer;
    }
    new_run = *admission == SequenceGate::Admission::kNewRun;
  }
  std::shared_ptr<Recognizer> recognizer;
  if (!new_run) recognizer = FindRun(request.robot);
  if (recognizer == nullptr) recognizer = NewRun();
  const Status valid = recognizer->Validate(request);
  if (!valid.ok()) return fail(WireStatus(valid.code()), valid.message());
  const StatusOr<ImageEncoding> encoding = ImageEncodingFromWire(frame.encoding);
  if (!encoding.ok())
    return fail(WireStatus(encoding.status().code()), encoding.status().message());
  if (frame.size != static_cast<int32_t>(frame.data.size())) {
    return fail(result_t::STATUS_BAD_REQUEST, "size field does not match the data");
  }
  Timer timer;
  StatusOr<cv::Mat> image = [&] {
    ScopedStage stage("decode");
    return DecodeImage(frame.data.data(), frame.data.size(), *encoding, frame.width, frame.height,
                       decode_);
  }();
  if (!image.ok()) return fail(WireStatus(image.status().code()), image.status().message());
  const double decode_ms = timer.ElapsedMs();
  const FrameObservation observation = [&] {
    ScopedStage stage("analyze");
    return analyzer_.Analyze(*image);
  }();
  RecognitionResult result = [&] {
    ScopedStage stage("recognize");
    return recognizer->Recognize(request, observation);
  }();
  result.timings.insert(result.timings.begin(), {"decode", decode_ms});
  if (request.insert && result.status.ok()) {
    gate_.Accepted(request.robot, request.sequence, result.place.IsValid(),
                   SequenceGate::Clock::now());
    if (new_run) {
      LOG(INFO) << "robot '" << request.robot << "' begins a new run at sequence "
                << request.sequence;
    }
    // Kept again even when it was found: another robot's frame may have forgotten it meanwhile.
    KeepRun(request.robot, std::move(recognizer));
  }
  FillAnswer(result, &answer);
  answer.next_sequence = gate_.NextSequence(request.robot);
  if (alarms != nullptr) {
    ScopedStage stage("alarms");
    *alarms = AlarmMessages(result, frame, image->size());
  }
  if (!result.status.ok()) {
    LOG(WARNING) << "frame " << frame.sequence << " of robot '" << frame.robot
                 << "': " << result.status.ToString();
  }
  return answer;
}

}  // namespace placerec
