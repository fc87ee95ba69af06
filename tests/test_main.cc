// The main() of every placerec test executable: GoogleTest's, run inside a temporary folder of
// the process's own. TEST_TMPDIR and TMPDIR point into it, so ::testing::TempDir() and the
// child processes a test starts (servers, tools, chromium and its driver) write their temporary
// files there, and the folder is removed when the process ends with every test passed; after a
// failure it is kept and its path printed for inspection. Without it each run left its key
// files, model round trips and browser profiles behind in /tmp. (A process killed by a timeout
// or a crash leaves its folder; the PostgreSQL test clusters live in /tmp folders of their own,
// which their postgres user can write.)
#include <stdlib.h>
#include <sys/stat.h>

#include <cstdio>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include <gtest/gtest.h>

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  const std::string base = ::testing::TempDir();  // TEST_TMPDIR, TMPDIR or /tmp/, with a '/'
  std::string pattern = base + "placerec_test_XXXXXX";
  std::vector<char> buffer(pattern.begin(), pattern.end());
  buffer.push_back('\0');
  const char* made = mkdtemp(buffer.data());
  std::string dir;
  if (made == nullptr) {
    std::fprintf(stderr, "cannot make a temporary folder in %s; tests write there directly\n",
                 base.c_str());
  } else {
    dir = made;
    // Enterable by other users, as /tmp is: a test's child that runs as `nobody` opens a map in
    // it (SqliteStoreTest.ReadOnlyMapIsRefusedAtOpen).
    if (chmod(made, 0755) != 0) std::perror("chmod of the temporary folder");
    setenv("TEST_TMPDIR", dir.c_str(), 1);
    setenv("TMPDIR", dir.c_str(), 1);
  }
  const int result = RUN_ALL_TESTS();
  if (!dir.empty()) {
    if (result == 0) {
      std::error_code error;
      std::filesystem::remove_all(dir, error);
      if (error) {
        std::fprintf(stderr, "could not remove %s: %s\n", dir.c_str(), error.message().c_str());
      }
    } else {
      std::fprintf(stderr, "kept %s for inspection\n", dir.c_str());
    }
  }
  return result;
}
