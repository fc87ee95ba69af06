// Command-line flags for SceneOrganizerOptions (seed Ch. 3), one binding shared by every command
// that sets them (placerec-eval run and segment, placerec-server, placerec-train), so that each
// flag has one name and means the same everywhere, and its default comes from the options the
// command starts from (SceneOrganizerOptions::ForRecognition() or ::ForSegmentation()).
#pragma once

#include "common/organization/scene_organizer.h"
#include "common/util/options.h"

namespace placerec {

// Every option of the scene organiser: --models-dir, the initial partition (--po-segment-width,
// --po-fh-k, ...), --texton-stride, the background decision, --background-smoothing, the
// learned merging and Perceptual Organization (--po-theta-complexity, ..., --po-max-rounds).
void AddOrganizerFlags(FlagParser* parser, SceneOrganizerOptions* options);

// --background-threshold and --one-per-class alone: how a region's classifier scores become its
// background class (the trainers report accuracy with them).
void AddBackgroundDecisionFlags(FlagParser* parser, SceneOrganizerOptions* options);

}  // namespace placerec
