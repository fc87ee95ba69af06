// Internal to the scene-change tools (`placerec-eval change` and `placerec-eval alarms`): how
// changes made to revisits were found, counted by the object's share of the frame.
#pragma once

#include <string>
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

// The classes given to the pasted objects that were found (SceneChange::object_class), against
// the class each was cut as.
struct ClassTally {
  struct Case {
    std::string pasted;  // the dataset's class (CamVid's car, pedestrian, signsymbol, ...)
    std::string given;   // the change's class ("" when it was given none)
    float confidence = 0;
  };
  std::vector<Case> cases;

  void Add(const std::string& pasted, const std::string& given, float confidence) {
    cases.push_back({pasted, given, confidence});
  }
};

// Whether `given`, a class of the object models (MSRC-21 names), names an object cut as
// `pasted`: CamVid's car is a car, pedestrian a body, bicyclist a bicycle or a body, signsymbol a
// sign; other names must be equal.
bool ClassAgrees(const std::string& pasted, const std::string& given);

// {found, labelled, agreeing, at_confidence: [{min_confidence, labelled, agreeing}, ...]}: how
// many found objects got a class and how many the right one, keeping classes of at least each
// confidence.
nlohmann::json ClassTallyJson(const ClassTally& tally);

// hits / cases, 0 without cases.
double ShareOf(int hits, int cases);

}  // namespace placerec
