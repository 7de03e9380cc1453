// Helpers for tests that run the real `shoal` executable.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace shoal::testing {

inline std::string ShoalBinary() { return std::string(SHOAL_BINARY_DIR) + "/tools/shoal"; }
inline std::string SourcePath(const std::string& rel) {
  return std::string(SHOAL_SOURCE_DIR) + "/" + rel;
}

inline std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct RunResult {
  int status = -1;  // exit status, or 128 + signal
  std::string out;
  std::string err;
};

/// Runs `args` (a shell-quoted argument string) with the shoal binary.
inline RunResult RunShoal(const std::string& args, const std::string& tag) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  const std::string out = dir + "/" + tag + ".out", err = dir + "/" + tag + ".err";
  const std::string cmd = ShoalBinary() + " " + args + " >" + out + " 2>" + err + " </dev/null";
  const int raw = std::system(cmd.c_str());
  RunResult r;
  if (WIFEXITED(raw)) {
    r.status = WEXITSTATUS(raw);
  } else if (WIFSIGNALED(raw)) {
    r.status = 128 + WTERMSIG(raw);
  }
  r.out = ReadFile(out);
  r.err = ReadFile(err);
  return r;
}

inline std::string TmpPath(const std::string& name) {
  const std::string dir = std::string(SHOAL_BINARY_DIR) + "/test_tmp";
  std::system(("mkdir -p " + dir).c_str());
  return dir + "/" + name;
}

}  // namespace shoal::testing
