#include "server/frame_processor.h"

#include <exception>
#include <string>
#include <utility>

#include "common/util/logging.h"
#include "common/util/timer.h"
#include "proto/channels.h"
#include "server/protocol.h"

namespace placerec {

FrameProcessor::FrameProcessor(const RecognizerOptions& options, const DecodeOptions& decode,
                               PlaceMap* map, std::unique_ptr<Segmenter> segmenter)
    : decode_(decode), map_(map), recognizer_(options, map, std::move(segmenter)) {}

result_t FrameProcessor::Process(const frame_t& frame) {
  try {
    return ProcessOrThrow(frame);
  } catch (const std::exception& e) {
    LOG(ERROR) << "frame " << frame.sequence << " of robot '" << frame.robot
               << "' failed: " << e.what();
    result_t answer = AnswerTemplate(frame);
    SetError(result_t::STATUS_INTERNAL_ERROR,
             std::string("internal error while processing the frame: ") + e.what(), &answer);
    return answer;
  }
}

result_t FrameProcessor::ProcessOrThrow(const frame_t& frame) {
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
  const Status valid = recognizer_.Validate(request);
  if (!valid.ok()) return fail(WireStatus(valid.code()), valid.message());
  const StatusOr<ImageEncoding> encoding = ImageEncodingFromWire(frame.encoding);
  if (!encoding.ok())
    return fail(WireStatus(encoding.status().code()), encoding.status().message());
  if (frame.size != static_cast<int32_t>(frame.data.size())) {
    return fail(result_t::STATUS_BAD_REQUEST, "size field does not match the data");
  }
  Timer timer;
  StatusOr<cv::Mat> image = DecodeImage(frame.data.data(), frame.data.size(), *encoding,
                                        frame.width, frame.height, decode_);
  if (!image.ok()) return fail(WireStatus(image.status().code()), image.status().message());
  const double decode_ms = timer.ElapsedMs();
  RecognitionResult result = recognizer_.Recognize(request, recognizer_.Analyze(*image));
  result.timings.insert(result.timings.begin(), {"decode", decode_ms});
  FillAnswer(result, &answer);
  if (!result.status.ok()) {
    LOG(WARNING) << "frame " << frame.sequence << " of robot '" << frame.robot
                 << "': " << result.status.ToString();
  }
  return answer;
}

}  // namespace placerec
