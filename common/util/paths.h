// Where the evaluation data and trained models are: a flag wins, then the environment
// (PLACEREC_DATA, PLACEREC_MODELS), then the build's defaults (../shared/data, models/).
#pragma once

#include <string>

namespace placerec {

std::string DataDir(const std::string& flag_value, const std::string& build_default);
std::string ModelsDir(const std::string& flag_value, const std::string& build_default);
bool PathExists(const std::string& path);
// Creates a directory and its parents; false when it could not be created, or exists but cannot
// be written in.
bool MakeDirectories(const std::string& path);

}  // namespace placerec
