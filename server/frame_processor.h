// Answers one frame message (DESIGN.md "LCM protocol"): checks the request, decodes the image and
// runs the recognizer, whose map commits the frame's landmarks before it returns, then builds the
// answer. Every failure becomes an error answer that says what was wrong; nothing throws.
#pragma once

#include "common/image/image.h"
#include "common/pipeline/place_map.h"
#include "common/pipeline/recognizer.h"
#include "placerec/frame_t.hpp"
#include "placerec/result_t.hpp"

namespace placerec {

class FrameProcessor {
 public:
  // `map` must outlive the processor; a null `segmenter` is made from the options.
  FrameProcessor(const RecognizerOptions& options, const DecodeOptions& decode, PlaceMap* map,
                 std::unique_ptr<Segmenter> segmenter = nullptr);

  // Frames of one robot must come one at a time and in order; frames of different robots may be
  // processed from different threads at once (Recognizer's contract).
  result_t Process(const frame_t& frame);

  PlaceMap& map() { return *map_; }

 private:
  result_t ProcessOrThrow(const frame_t& frame);

  DecodeOptions decode_;
  PlaceMap* map_;
  Recognizer recognizer_;
};

}  // namespace placerec
