// placerec-eval classify: region classification accuracy of the object classifiers of seed
// Ch. 4 (placerec-train objects) on a labelled dataset's ground-truth segments (seed §6.2:
// "given a ground truth segment, assign a single class label to it"), with the one-per-class
// decision (Table 6.7, Fig. 6.16) and the feature-group and selection ablation (Tables 6.5,
// 6.6). Writes OUT/classification.json and OUT/confusion.png.
#pragma once

#include <string>

namespace placerec {

// `placerec-eval classify ...`; argv[1] is "classify". Returns the process exit code: 0, 2 for
// bad flags, 1 when reading, describing or writing fails.
int ClassifyCommand(int argc, char** argv, const std::string& default_data_dir);

}  // namespace placerec
