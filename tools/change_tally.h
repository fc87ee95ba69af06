// Internal to the scene-change tools (`placerec-eval change` and `placerec-eval alarms`): how
// changes made to revisits were found, counted by the object's share of the frame.
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

namespace placerec {

// Changed revisits of one kind (pasted objects, or landmarks painted over) and those found.
struct ChangeTally {
  // Size bands of the changes, as shares of the frame's area: 1-2 %, 2-5 %, 5-10 %.
  static constexpr int kBands = 3;

  int cases = 0;
  int hits = 0;
  int checked = 0;  // compared with a stored place (where that is known)
  int cases_band[kBands] = {0, 0, 0};
  int hits_band[kBands] = {0, 0, 0};
  std::vector<double> ious;  // of the hits

  // Counts one case covering `share` of the frame, found with `iou` when `found`.
  void Add(double share, bool found, double iou);
};

// {cases, found, compared, detection_recall, by_size{band: {cases, found, recall}},
// detection_recall_2pct (objects of at least 2 % of the frame), localisation_iou_median}.
nlohmann::json ChangeTallyJson(const ChangeTally& tally);

// hits / cases, 0 without cases.
double ShareOf(int hits, int cases);

}  // namespace placerec
