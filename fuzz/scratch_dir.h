// A scratch folder of the fuzzing process's own (in TMPDIR, else /tmp), removed when the process
// exits: the readers under test take file names, and every run used to leave its files in /tmp.
#pragma once

#include <stdlib.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

inline const std::string& fuzzScratchDir() {
  // Never destroyed: the exit handler below runs after static objects made before it are gone.
  static const std::string* dir = [] {
    const char* parent = std::getenv("TMPDIR");
    std::string path = std::string(parent && *parent ? parent : "/tmp") + "/mrslam_fuzz_XXXXXX";
    if (!mkdtemp(path.data())) {
      std::perror(("cannot make a scratch folder " + path).c_str());
      std::abort();
    }
    return new std::string(path);
  }();
  static const bool cleaned_at_exit = std::atexit([] {
    std::error_code ignored;
    std::filesystem::remove_all(*dir, ignored);
  }) == 0;
  (void)cleaned_at_exit;
  return *dir;
}
