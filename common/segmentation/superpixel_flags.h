// Command-line flags for SuperpixelOptions (seed §3.6, §6.1.2), one binding shared by every
// command: `<prefix>segment-width`, `<prefix>fh-sigma`, `<prefix>fh-k`, `<prefix>fh-min-size`,
// `<prefix>min-region-fraction`, `<prefix>colour-merge-distance`.
#pragma once

#include <string>

#include "common/segmentation/superpixels.h"
#include "common/util/options.h"

namespace placerec {

// `prefix` tells two partitions of one command apart ("" for superpixels used as objects,
// "po-" for Perceptual Organization's initial partition); `what` starts each help line.
void AddSuperpixelFlags(FlagParser* parser, SuperpixelOptions* options, const std::string& prefix,
                        const std::string& what);

}  // namespace placerec
