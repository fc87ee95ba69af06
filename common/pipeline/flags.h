// Command-line flags for every field of RecognizerOptions, shared by placerec-eval and
// placerec-server so that a flag means the same everywhere and defaults live in the structs.
#pragma once

#include <iosfwd>
#include <string>

#include "common/pipeline/recognizer.h"
#include "common/util/options.h"

namespace placerec {

void AddRecognizerFlags(FlagParser* parser, RecognizerOptions* options);

std::ostream& operator<<(std::ostream& os, RecognitionMode value);
std::istream& operator>>(std::istream& is, RecognitionMode& value);
std::ostream& operator<<(std::ostream& os, QueryObjects value);
std::istream& operator>>(std::istream& is, QueryObjects& value);
std::ostream& operator<<(std::ostream& os, IndexSearch value);
std::istream& operator>>(std::istream& is, IndexSearch& value);
std::ostream& operator<<(std::ostream& os, SegmentationMethod value);
std::istream& operator>>(std::istream& is, SegmentationMethod& value);

}  // namespace placerec
