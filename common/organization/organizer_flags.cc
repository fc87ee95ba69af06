#include "common/organization/organizer_flags.h"

namespace placerec {

void AddBackgroundDecisionFlags(FlagParser* parser, SceneOrganizerOptions* options) {
  parser->Add("background-threshold", &options->background_threshold,
              "a region is background when its best background classifier's score exceeds "
              "this (0: the boosted decision)");
  parser->Add("one-per-class", &options->one_per_class,
              "a region is background only when its best background classifier also beats "
              "every structured class's (seed §6.2.1; models with structured classifiers)");
}

void AddLearnedMergeFlags(FlagParser* parser, SceneOrganizerOptions* options) {
  parser->Add("learned-merge", &options->learned_merge,
              "merge the classified superpixels with the learned region-merge classifier "
              "(models/grouping.yml.gz) before Perceptual Organization");
  parser->Add("merge-threshold", &options->merge.threshold,
              "learned merging goes on while the best pair's boosted score exceeds this");
}

}  // namespace placerec
