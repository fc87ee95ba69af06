#include "tools/change_tally.h"

#include "common/eval/stats.h"

namespace placerec {
namespace {

struct Band {
  const char* name;
  double high;  // upper end (share of the frame); the last band takes everything above
};
constexpr Band kBandLimits[ChangeTally::kBands] = {{"<2%", 0.02}, {"2-5%", 0.05}, {">=5%", 1.0}};

int BandOf(double share) {
  for (int b = 0; b < ChangeTally::kBands; ++b) {
    if (share < kBandLimits[b].high) return b;
  }
  return ChangeTally::kBands - 1;
}

}  // namespace

void ChangeTally::Add(double share, bool found, double iou) {
  const int band = BandOf(share);
  ++cases;
  ++cases_band[band];
  if (!found) return;
  ++hits;
  ++hits_band[band];
  ious.push_back(iou);
}

bool ClassAgrees(const std::string& pasted, const std::string& given) {
  if (given.empty()) return false;
  if (pasted == "pedestrian") return given == "body";
  if (pasted == "bicyclist") return given == "bicycle" || given == "body";
  if (pasted == "signsymbol") return given == "sign";
  return pasted == given;
}

nlohmann::json ClassTallyJson(const ClassTally& tally) {
  const auto count = [&](float min_confidence, bool agreeing) {
    int n = 0;
    for (const ClassTally::Case& c : tally.cases) {
      if (c.given.empty() || c.confidence < min_confidence) continue;
      n += !agreeing || ClassAgrees(c.pasted, c.given) ? 1 : 0;
    }
    return n;
  };
  nlohmann::json j;
  j["found"] = tally.cases.size();
  j["labelled"] = count(0.f, false);
  j["agreeing"] = count(0.f, true);
  j["at_confidence"] = nlohmann::json::array();
  for (const float at : {0.5f, 0.6f, 0.7f, 0.8f, 0.9f}) {
    j["at_confidence"].push_back(
        {{"min_confidence", at}, {"labelled", count(at, false)}, {"agreeing", count(at, true)}});
  }
  return j;
}

double ShareOf(int hits, int cases) { return cases > 0 ? static_cast<double>(hits) / cases : 0.0; }

nlohmann::json ChangeTallyJson(const ChangeTally& t) {
  nlohmann::json j;
  j["cases"] = t.cases;
  j["found"] = t.hits;
  j["compared"] = t.checked;
  j["detection_recall"] = ShareOf(t.hits, t.cases);
  int cases2 = 0, hits2 = 0;
  for (int b = 0; b < ChangeTally::kBands; ++b) {
    j["by_size"][kBandLimits[b].name] = {{"cases", t.cases_band[b]},
                                         {"found", t.hits_band[b]},
                                         {"recall", ShareOf(t.hits_band[b], t.cases_band[b])}};
    if (b >= 1) {
      cases2 += t.cases_band[b];
      hits2 += t.hits_band[b];
    }
  }
  j["detection_recall_2pct"] = ShareOf(hits2, cases2);
  j["localisation_iou_median"] = t.ious.empty() ? 0.0 : Percentile(t.ious, 50);
  return j;
}

}  // namespace placerec
