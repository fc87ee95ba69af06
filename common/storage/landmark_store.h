// Persistence of the landmark map (DESIGN.md "Architecture"): places and their landmarks with
// descriptors and keypoints. Stores sit behind this interface; SQLite is the embedded default.
// Opening a map means streaming everything back with LoadPlaces / LoadLandmarks into the index.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/recognition/types.h"
#include "common/util/status.h"

namespace placerec {

struct StoreCounts {
  int64_t places = 0;
  int64_t landmarks = 0;
  int64_t descriptors = 0;
};

class LandmarkStore {
 public:
  virtual ~LandmarkStore() = default;

  // Adds `place` and its `landmarks` in one transaction; when it returns ok the data is durable
  // (committed to disk for file-backed stores). Assigns place->id, and each landmark's id and
  // place; sets place->num_landmarks. On error nothing is written and the inputs' ids are left
  // invalid. A place whose (robot, sequence) is already stored is an InvalidArgument error.
  virtual Status AddPlace(Place* place, std::vector<Landmark>* landmarks) = 0;

  // Calls `visit` for every place in increasing id order.
  virtual Status LoadPlaces(const std::function<void(const Place&)>& visit) const = 0;

  // Calls `visit` for every landmark (descriptors and keypoints included) in increasing id order.
  virtual Status LoadLandmarks(const std::function<void(Landmark&&)>& visit) const = 0;

  virtual StatusOr<StoreCounts> Counts() const = 0;

  // A 64-bit digest of every stored place and landmark (ids, fields, descriptor and keypoint
  // bytes) in id order: equal digests mean equal maps.
  virtual StatusOr<uint64_t> Checksum() const = 0;

  // Where the map lives, e.g. "sqlite:/var/lib/placerec/site.db".
  virtual std::string Describe() const = 0;
};

}  // namespace placerec
