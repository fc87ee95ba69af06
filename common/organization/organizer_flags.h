// Command-line flags for the SceneOrganizerOptions that several commands set (placerec-eval
// segment and run, placerec-server, placerec-train), so that each means the same everywhere and
// its default comes from the struct.
#pragma once

#include "common/organization/scene_organizer.h"
#include "common/util/options.h"

namespace placerec {

// --background-threshold and --one-per-class: how a region's classifier scores become its
// background class.
void AddBackgroundDecisionFlags(FlagParser* parser, SceneOrganizerOptions* options);

// --learned-merge and --merge-threshold: the learned region merging before Perceptual
// Organization.
void AddLearnedMergeFlags(FlagParser* parser, SceneOrganizerOptions* options);

}  // namespace placerec
