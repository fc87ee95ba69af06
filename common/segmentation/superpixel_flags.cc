#include "common/segmentation/superpixel_flags.h"

namespace placerec {

void AddSuperpixelFlags(FlagParser* parser, SuperpixelOptions* options, const std::string& prefix,
                        const std::string& what) {
  parser->Add(prefix + "segment-width", &options->working_width,
              what + ": working width in pixels (seed §6.1: about 320x240; 0: frame size)");
  parser->Add(prefix + "fh-sigma", &options->sigma,
              what + ": Felzenszwalb-Huttenlocher smoothing sigma (§6.1.2: 0.5)");
  parser->Add(prefix + "fh-k", &options->k,
              what + ": FH threshold k at 640x480, scaled by area (§6.1.2: 300)");
  parser->Add(prefix + "fh-min-size", &options->min_size,
              what + ": FH minimum component at 640x480 in pixels, scaled by area (§6.1.2: 20)");
  parser->Add(prefix + "min-region-fraction", &options->min_region_fraction,
              what +
                  ": regions below this fraction of the image merge into a neighbour "
                  "(§3.6: 0.0003)");
  parser->Add(prefix + "colour-merge-distance", &options->colour_merge_distance,
              what +
                  ": merge adjacent regions closer than this in CIE Lab (Delta E; §3.6 gives "
                  "no number; 0 disables)");
}

}  // namespace placerec
