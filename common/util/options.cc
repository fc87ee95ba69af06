#include "common/util/options.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

namespace po = boost::program_options;

namespace placerec {

FlagParser::FlagParser(std::string usage) : usage_(std::move(usage)), options_("Options", 100) {
  options_.add_options()("help,h", "show this help and exit");
}

void FlagParser::AddSwitch(const std::string& name, bool* field, const std::string& help) {
  options_.add_options()(name.c_str(), po::bool_switch(field), help.c_str());
}

void FlagParser::AddRepeated(const std::string& name, std::vector<std::string>* field,
                             const std::string& help) {
  options_.add_options()(name.c_str(), po::value<std::vector<std::string>>(field), help.c_str());
}

void FlagParser::AddPositional(const std::string& name, std::vector<std::string>* field,
                               const std::string& help) {
  options_.add_options()(name.c_str(), po::value<std::vector<std::string>>(field), help.c_str());
  positional_.add(name.c_str(), -1);
  positional_name_ = name;
}

Status FlagParser::Parse(int argc, const char* const* argv, int first, bool* help_requested) {
  *help_requested = false;
  std::vector<std::string> args(argv + first, argv + argc);
  po::variables_map vm;
  try {
    const po::parsed_options parsed =
        po::command_line_parser(args).options(options_).positional(positional_).run();
    for (const po::option& option : parsed.options) {
      if (unsigned_flags_.count(option.string_key) == 0) continue;
      for (const std::string& value : option.value) {
        if (!value.empty() && value.front() == '-') {
          return Status::InvalidArgument("--" + option.string_key + " must not be negative, not " +
                                         value + " (see --help)");
        }
      }
    }
    po::store(parsed, vm);
    if (vm.count("help")) {
      *help_requested = true;
      return Status::Ok();
    }
    po::notify(vm);
  } catch (const po::error& e) {
    return Status::InvalidArgument(std::string(e.what()) + " (see --help)");
  }
  return Status::Ok();
}

std::optional<int> FlagParser::ParseOrExit(int argc, const char* const* argv, int first,
                                           const std::string& program) {
  bool help = false;
  const Status parsed = Parse(argc, argv, first, &help);
  if (help) {
    std::printf("%s\n", Help().c_str());
    return 0;
  }
  if (!parsed.ok()) {
    std::fprintf(stderr, "%s: %s\n", program.c_str(), parsed.message().c_str());
    return 2;
  }
  return std::nullopt;
}

std::string ShortestText(double value, bool single) {
  // std::to_chars without a precision writes the shortest text that reads back as the value.
  char text[64];
  const std::to_chars_result written =
      single ? std::to_chars(text, text + sizeof(text), static_cast<float>(value))
             : std::to_chars(text, text + sizeof(text), value);
  return std::string(text, written.ptr);
}

std::string FlagParser::Help() const {
  std::ostringstream out;
  out << "Usage: " << usage_ << "\n\n" << options_;
  return out.str();
}

std::string CommandLine(int argc, const char* const* argv) {
  auto quoted = [](const std::string& arg) {
    const bool plain = !arg.empty() && std::all_of(arg.begin(), arg.end(), [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || std::strchr("-_./,:=+@%", c);
    });
    if (plain) return arg;
    std::string out = "'";
    for (char c : arg) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
  };
  std::string line;
  for (int i = 0; i < argc; ++i) {
    std::string arg = argv[i];
    if (i == 0) {
      const size_t slash = arg.find_last_of('/');
      if (slash != std::string::npos) arg = arg.substr(slash + 1);
    } else {
      line += ' ';
    }
    line += quoted(arg);
  }
  return line;
}

}  // namespace placerec
