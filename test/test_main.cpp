#include <gtest/gtest.h>
#include <stdlib.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

// Every test process writes its scratch files into a folder of its own. gtest's TempDir() is
// the same /tmp/ for every process, and the shards of one binary run side by side
// (CMakeLists.txt, scripts/sanitize): two shards once wrote and read the same
// intel_200.log at once, and one of them died under AddressSanitizer. TempDir() returns
// TEST_TMPDIR when it is set, so this points it at a fresh folder (inside the one the caller
// set, if any) and removes the folder at the end.
int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  const char* parent = std::getenv("TEST_TMPDIR");
  std::string folder = ((parent && *parent) ? std::filesystem::path(parent) : std::filesystem::temp_directory_path()) /
                       "mrslam_test_XXXXXX";
  if (!mkdtemp(folder.data())) {
    std::perror(("cannot make a scratch folder " + folder).c_str());
    return 1;
  }
  setenv("TEST_TMPDIR", folder.c_str(), 1);
  const int status = RUN_ALL_TESTS();
  std::error_code ignored;
  std::filesystem::remove_all(folder, ignored);
  return status;
}
