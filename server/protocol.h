// The server's message adapter (DESIGN.md "LCM protocol"): frame_t bytes in, domain types
// (FrameRequest, ImageEncoding) out, and RecognitionResult back into a result_t answer. The
// generated LCM types stop here; common/ sees only domain types.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "common/image/image.h"
#include "common/pipeline/recognizer.h"
#include "common/util/status.h"
#include "placerec/change_t.hpp"
#include "placerec/frame_t.hpp"
#include "placerec/result_t.hpp"
#include "placerec/status_t.hpp"

namespace placerec {

// Longest robot id an answer echoes (bytes); longer ids are cut (they are errors anyway).
constexpr size_t kMaxEchoedRobotIdLength = 256;

// Decodes the bytes of one LCM message as a frame_t. InvalidArgument, saying why, when they are
// not a well-formed frame_t (wrong fingerprint, truncated, negative or oversized lengths,
// trailing bytes). Never throws and never allocates more than the message size.
StatusOr<frame_t> DecodeFrameMessage(const void* data, size_t size);

// For a message DecodeFrameMessage refused: the fields before the image (utime, sequence,
// request_id, insert, encoding, width, height, robot; `size` and `data` left empty) when the
// fingerprint is frame_t's and those fields are whole, so that the sender can be answered (a
// `size` that does not match the bytes, trailing bytes). InvalidArgument otherwise.
StatusOr<frame_t> DecodeFrameHead(const void* data, size_t size);

// The image encoding a frame_t declares; BadImage for values the protocol does not define.
StatusOr<ImageEncoding> ImageEncodingFromWire(int8_t encoding);

// The library's view of a frame.
FrameRequest ToFrameRequest(const frame_t& frame);

// The result_t status code for a library status code.
int8_t WireStatus(StatusCode code);
// "ok", "bad request", ... for a result_t status code.
const char* WireStatusName(int8_t status);

// An answer to `frame` with the request's fields echoed, status OK and nothing found yet.
result_t AnswerTemplate(const frame_t& frame);

// Fills `answer` from what the recognizer returned (status, decision, matches, counts, timings).
void FillAnswer(const RecognitionResult& result, result_t* answer);

// The scene-change alarms (change_t, PLACEREC_CHANGE) of a processed frame: one per change in
// result.change, boxes in pixels of the frame as sent (`frame_size`); utime is left 0 for the
// publisher. None for a failed frame.
std::vector<change_t> AlarmMessages(const RecognitionResult& result, const frame_t& frame,
                                    const cv::Size& frame_size);

// Turns `answer` into an error answer with `status` (a result_t::STATUS_* value) and `message`;
// matches and what the frame stored are cleared; counts and timings are kept.
void SetError(int8_t status, const std::string& message, result_t* answer);

}  // namespace placerec
