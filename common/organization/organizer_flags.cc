#include "common/organization/organizer_flags.h"

#include "common/segmentation/superpixel_flags.h"

namespace placerec {
namespace {

void AddPerceptualOrganizationFlags(FlagParser* parser, OrganizationOptions* po) {
  parser->Add("po-theta-complexity", &po->theta_complexity,
              "structure potential weight theta_B of boundary complexity (eq. 3.6: 18)");
  parser->Add("po-theta-cohesion", &po->theta_cohesion,
              "structure potential weight theta_C of cohesiveness (eq. 3.6: 3.5)");
  parser->Add("po-alpha", &po->alpha, "attachment alpha (eq. 3.13: 20)");
  parser->Add("po-beta", &po->beta, "attachment beta (eq. 3.13: 3)");
  parser->Add("po-complexity-step", &po->complexity_step, "s of eq. 3.8 (contour pixels)");
  parser->Add("po-complexity-window", &po->complexity_window, "k of eq. 3.8 (steps)");
  parser->Add("po-symmetry-tolerance", &po->symmetry_tolerance,
              "eq. 3.11: centroid heights equal within this fraction of the shorter part");
  parser->Add("po-alignment-extension", &po->alignment_extension,
              "eq. 3.12: extension beyond each end, fraction of the common boundary's chord");
  parser->Add("po-alignment-tolerance", &po->alignment_tolerance,
              "eq. 3.12: aligned when at most this share of the extension touches either part");
  parser->Add("po-enclosed-fraction", &po->enclosed_fraction,
              "a part sharing this much of its boundary with a neighbour is enclosed by it");
  parser->Add("po-max-subset", &po->max_subset,
              "Algorithm 1: neighbours tested together (1, 2; §3.5)");
  parser->Add("po-max-rounds", &po->max_rounds,
              "Algorithm 2: at most this many rounds (§3.5; the seed: 2)");
  parser->Add("po-round-colour-merge", &po->round_colour_merge_distance,
              "Algorithm 2: similar-colour merge between rounds (Delta E; 0: none)");
  parser->Add("po-background-merge-colour", &po->background_merge_colour_distance,
              "the final background merge joins only regions closer than this in CIE Lab "
              "(Delta E; 0: any two of one class, as the seed)");
  parser->Add("po-merge-background", &po->merge_background,
              "merge adjacent background regions of one class at the end (§3.7; the seed: true)");
}

}  // namespace

void AddBackgroundDecisionFlags(FlagParser* parser, SceneOrganizerOptions* options) {
  parser->Add("background-threshold", &options->background_threshold,
              "a region is background when its best background classifier's score exceeds "
              "this (0: the boosted decision, as the seed)");
  parser->Add("one-per-class", &options->one_per_class,
              "a region is background only when its best background classifier also beats "
              "every structured class's (seed §6.2.1; models with structured classifiers)");
}

void AddOrganizerFlags(FlagParser* parser, SceneOrganizerOptions* options) {
  parser->Add("models-dir", &options->models_dir,
              "trained textons and classifiers (default: PLACEREC_MODELS or models/)");
  AddSuperpixelFlags(parser, &options->superpixels, "po-", "initial partition");
  parser->Add("texton-stride", &options->texton_stride,
              "textons on every N-th pixel in x and y (1: every pixel, as the seed)");
  AddBackgroundDecisionFlags(parser, options);
  parser->Add("background-smoothing", &options->background_smoothing,
              "weight of the neighbours' mean classifier scores in each superpixel's decision "
              "(0: independent decisions, as in the seed)");
  parser->Add("learned-merge", &options->learned_merge,
              "merge the classified superpixels with the learned region-merge classifier "
              "(models/grouping.yml.gz) before Perceptual Organization (not in the seed)");
  parser->Add("merge-threshold", &options->merge.threshold,
              "learned merging goes on while the best pair's boosted score exceeds this");
  AddPerceptualOrganizationFlags(parser, &options->organization);
}

}  // namespace placerec
