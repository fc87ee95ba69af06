#include "server/frame_processor.h"

#include <exception>
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
      gate_(sequence_rule) {
  map_->ForEachPlace([this](const Place& place) { gate_.AddStored(place.robot, place.sequence); });
}

std::unique_ptr<Recognizer> FrameProcessor::NewRun() const {
  return std::make_unique<Recognizer>(options_, map_,
                                      std::make_unique<SharedSegmenter>(&analyzer_.segmenter()),
                                      analyzer_.labeler());
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
      // place it stored. Only refused inserts look, so the pass over the places costs nothing in
      // normal running.
      const std::optional<Place> stored =
          map_->FindStored(request.robot, request.sequence, request.utime);
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
      return answer;
    }
    new_run = *admission == SequenceGate::Admission::kNewRun;
  }
  Recognizer* recognizer = nullptr;
  std::unique_ptr<Recognizer> fresh;
  if (!new_run) {
    std::lock_guard lock(runs_mutex_);
    const auto it = runs_.find(request.robot);
    if (it != runs_.end()) recognizer = it->second.get();
  }
  if (recognizer == nullptr) {
    fresh = NewRun();
    recognizer = fresh.get();
  }
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
    if (fresh) {
      if (new_run) {
        LOG(INFO) << "robot '" << request.robot << "' begins a new run at sequence "
                  << request.sequence;
      }
      std::lock_guard lock(runs_mutex_);
      runs_[request.robot] = std::move(fresh);
    }
  }
  FillAnswer(result, &answer);
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
