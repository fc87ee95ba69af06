// libFuzzer target: the server's frame decoder (server/protocol.h) on arbitrary message bytes,
// as anything on PLACEREC_FRAME reaches it. A decoded frame goes on through what the receive loop
// and the frame processor do with it before the image: the robot-id rule, the encoding, the
// answer template. Crashes, leaks and sanitizer reports are the findings; scripts/fuzz.sh runs it.
#include <cstddef>
#include <cstdint>
#include <string>

#include "proto/channels.h"
#include "server/protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace placerec;
  StatusOr<frame_t> frame = DecodeFrameMessage(data, size);
  if (!frame.ok()) {
    StatusOr<frame_t> head = DecodeFrameHead(data, size);
    if (head.ok()) {
      result_t answer = AnswerTemplate(*head);
      SetError(result_t::STATUS_BAD_REQUEST, frame.status().message(), &answer);
    }
    return 0;
  }
  std::string why;
  if (!IsValidWireRobotId(frame->robot, &why)) return 0;
  (void)ResultChannel(frame->robot);
  (void)ImageEncodingFromWire(frame->encoding);
  (void)ToFrameRequest(*frame);
  result_t answer = AnswerTemplate(*frame);
  // The answer is encoded as the server publishes it.
  std::string bytes(static_cast<size_t>(answer.getEncodedSize()), '\0');
  answer.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return 0;
}
