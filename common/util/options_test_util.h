// Test helper shared by the tests of options structs (STYLE.md: every stage's options have
// `bool Check(std::string* error) const`): each spoiled copy of the defaults is refused with a
// message that names what is wrong.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace placerec {
namespace options_test {

// Changes one field of an options struct to a bad value.
template <typename Options>
using Spoiler = void (*)(Options*);

// For each (name, spoil): a default Options spoiled by `spoil` fails Check, and the error
// message contains `name` (the field or the flag).
template <typename Options>
void ExpectEachRefusedByName(const std::vector<std::pair<std::string, Spoiler<Options>>>& cases) {
  for (const auto& [name, spoil] : cases) {
    Options options;
    spoil(&options);
    std::string error;
    EXPECT_FALSE(options.Check(&error)) << name;
    EXPECT_NE(error.find(name), std::string::npos) << name << ": '" << error << "'";
  }
}

}  // namespace options_test
}  // namespace placerec
