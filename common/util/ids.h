// Typed identifiers, so that a landmark id cannot be passed where a place id is expected.
#pragma once

#include <cstdint>
#include <functional>
#include <ostream>

namespace placerec {

template <typename Tag>
class TypedId {
 public:
  static constexpr int64_t kInvalidValue = -1;

  constexpr TypedId() = default;
  constexpr explicit TypedId(int64_t value) : value_(value) {}

  static constexpr TypedId Invalid() { return TypedId(); }
  constexpr bool IsValid() const { return value_ >= 0; }
  constexpr int64_t value() const { return value_; }

  friend constexpr bool operator==(TypedId a, TypedId b) { return a.value_ == b.value_; }
  friend constexpr bool operator!=(TypedId a, TypedId b) { return a.value_ != b.value_; }
  friend constexpr bool operator<(TypedId a, TypedId b) { return a.value_ < b.value_; }
  friend std::ostream& operator<<(std::ostream& os, TypedId id) { return os << id.value_; }

 private:
  int64_t value_ = kInvalidValue;
};

struct LandmarkIdTag {};
struct PlaceIdTag {};

// A landmark object stored in the map (seed §5.3).
using LandmarkId = TypedId<LandmarkIdTag>;
// A place: one frame of one robot whose landmarks are in the map (seed §5.7).
using PlaceId = TypedId<PlaceIdTag>;

}  // namespace placerec

template <typename Tag>
struct std::hash<placerec::TypedId<Tag>> {
  size_t operator()(placerec::TypedId<Tag> id) const noexcept {
    return std::hash<int64_t>()(id.value());
  }
};
