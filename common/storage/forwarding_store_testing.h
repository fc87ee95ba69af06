// A LandmarkStore that passes the calls every store must have to another one, for tests that
// change one call (hold a write, fail the next one) and keep the rest real; thumbnails and the
// index snapshot keep LandmarkStore's defaults (none). Tests only.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "common/storage/landmark_store.h"

namespace placerec {
namespace testing_storage {

class ForwardingStore : public LandmarkStore {
 public:
  explicit ForwardingStore(std::unique_ptr<LandmarkStore> inner) : inner_(std::move(inner)) {}

  Status AddPlace(Place* place, std::vector<Landmark>* landmarks) override {
    return inner_->AddPlace(place, landmarks);
  }
  Status LoadPlaces(const std::function<void(const Place&)>& visit) const override {
    return inner_->LoadPlaces(visit);
  }
  Status LoadLandmarks(const std::function<void(Landmark&&)>& visit) const override {
    return inner_->LoadLandmarks(visit);
  }
  StatusOr<StoreCounts> Counts() const override { return inner_->Counts(); }
  StatusOr<uint64_t> Checksum() const override { return inner_->Checksum(); }
  std::string Describe() const override { return inner_->Describe(); }

 private:
  std::unique_ptr<LandmarkStore> inner_;
};

}  // namespace testing_storage
}  // namespace placerec
