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

// Every method may be called from any thread; calls on one store are serialised (the server reads
// Counts from its status thread while a worker writes). `visit` callbacks run under that lock and
// must not call back into the store.
class LandmarkStore {
 public:
  virtual ~LandmarkStore() = default;

  // Adds `place` and its `landmarks` (null for none) in one transaction; when it returns ok the
  // data is committed (for file-backed stores it survives a killed process, and power loss too
  // when the store syncs fully). Assigns place->id, and each landmark's id and place; sets
  // place->num_landmarks. Ids are valid and increase with every call. The input is validated
  // first (robot id 1..kMaxRobotIdLength bytes; descriptors CV_8U, 128 columns, continuous (or an
  // empty matrix), one keypoint each; sift_count >= 0): on any error nothing is written and the
  // inputs are left unchanged. A place whose (robot, sequence) is already stored is an
  // InvalidArgument error.
  virtual Status AddPlace(Place* place, std::vector<Landmark>* landmarks) = 0;

  // Calls `visit` for every place in increasing id order.
  virtual Status LoadPlaces(const std::function<void(const Place&)>& visit) const = 0;

  // Calls `visit` for every landmark (descriptors and keypoints included) in increasing id order.
  // Keypoints keep x, y, size and angle; response, octave and class_id come back as defaults.
  // A landmark whose stored data is damaged stops the scan with an IoError naming its id.
  virtual Status LoadLandmarks(const std::function<void(Landmark&&)>& visit) const = 0;

  // The thumbnail (JPEG bytes, Place::thumbnail) stored with a place; empty when the place has
  // none (a map written before thumbnails, or a store that keeps none: the default) or is not in
  // the map.
  virtual StatusOr<std::vector<uint8_t>> LoadThumbnail(PlaceId place) const {
    (void)place;
    return std::vector<uint8_t>();
  }

  virtual StatusOr<StoreCounts> Counts() const = 0;

  // A 64-bit digest of every stored place and landmark (ids, fields, descriptor and keypoint
  // bytes) in id order: equal digests mean equal maps.
  virtual StatusOr<uint64_t> Checksum() const = 0;

  // Where the map lives, e.g. "sqlite:/var/lib/placerec/site.db".
  virtual std::string Describe() const = 0;

  // The file that holds the snapshot of the map's descriptor index (DescriptorIndex::
  // SaveSnapshot), beside the map; empty when the store keeps none (it is then indexed from
  // scratch on every open).
  virtual std::string IndexSnapshotPath() const { return ""; }
};

}  // namespace placerec
