// Binds command-line flags to fields of the library's options structs. The default shown in
// --help is the field's value when the flag is added, so defaults live only in the structs.
#pragma once

#include <memory>
#include <optional>
#include <set>
#include <string>
#include <type_traits>
#include <vector>

#include <boost/program_options.hpp>

#include "common/util/status.h"

namespace placerec {

// The shortest decimal text that reads back as `value` (as a float when `single`): std::to_chars,
// fixed or scientific notation, whichever is shorter.
std::string ShortestText(double value, bool single = false);

class FlagParser {
 public:
  // `usage` is printed first by --help, e.g. "placerec-eval run --dataset DIR --run NAME --out
  // OUT".
  explicit FlagParser(std::string usage);

  // Adds `--name` bound to *field; `help` should give units and the seed section.
  template <typename T>
  void Add(const std::string& name, T* field, const std::string& help) {
    if constexpr (std::is_integral_v<T> && std::is_unsigned_v<T> && !std::is_same_v<T, bool>) {
      unsigned_flags_.insert(name);  // the parser reads "-1" as 2^64 - 1: Parse refuses it
    }
    if constexpr (std::is_floating_point_v<T>) {
      // Shown as the shortest text that reads back as the value (0.3, not 0.29999999999999999).
      options_.add_options()(
          name.c_str(),
          boost::program_options::value<T>(field)->default_value(
              *field, ShortestText(static_cast<double>(*field), std::is_same_v<T, float>)),
          help.c_str());
    } else {
      options_.add_options()(name.c_str(),
                             boost::program_options::value<T>(field)->default_value(*field),
                             help.c_str());
    }
  }
  // A flag without a default that must be given.
  template <typename T>
  void AddRequired(const std::string& name, T* field, const std::string& help) {
    options_.add_options()(name.c_str(), boost::program_options::value<T>(field)->required(),
                           help.c_str());
  }
  // A flag that may be given more than once; each occurrence appends to *field. No default:
  // an empty *field after parsing means the flag was not given.
  void AddRepeated(const std::string& name, std::vector<std::string>* field,
                   const std::string& help);
  // A switch: present means true.
  void AddSwitch(const std::string& name, bool* field, const std::string& help);
  // Remaining positional arguments (e.g. image paths) go into *field.
  void AddPositional(const std::string& name, std::vector<std::string>* field,
                     const std::string& help);

  // Parses argv[first..argc). Returns ok with *help_requested set when --help was given (the
  // caller prints Help() and exits 0); an InvalidArgument status with a message otherwise.
  Status Parse(int argc, const char* const* argv, int first, bool* help_requested);

  // Parse for a command's main: nullopt to go on; otherwise the exit code, after printing the
  // help to stdout (0, for --help) or "<program>: <message>" to stderr (2, for bad flags).
  std::optional<int> ParseOrExit(int argc, const char* const* argv, int first,
                                 const std::string& program);

  std::string Help() const;

 private:
  std::string usage_;
  boost::program_options::options_description options_;
  boost::program_options::positional_options_description positional_;
  std::string positional_name_;
  std::set<std::string> unsigned_flags_;  // flags of unsigned fields: no negative values
};

// The invocation as a shell would take it back: the program's file name (no directory) and
// every argument, single-quoted when it holds anything but letters, digits and -_./,:=+@%.
// Manifests record it so a model can be retrained with exactly the options it was trained with.
std::string CommandLine(int argc, const char* const* argv);

}  // namespace placerec
