// Helpers shared by the tests.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "accura/calib/robot_io.h"

namespace accura::test {

inline std::string sourcePath(const std::string& rel) { return std::string(ACCURA_SOURCE_DIR) + "/" + rel; }

inline RobotModel loadBundled(const std::string& name, FormPolicy policy = FormPolicy::kAuto) {
  RobotModel m = readRobotFile(sourcePath("robots/" + name + ".xml"));
  if (policy != FormPolicy::kAuto) {
    const Deviations d = m.deviations;
    m = RobotModel::fromDefinition(m.nominal, policy);
    m.deviations = d;
  }
  return m;
}

/// A fresh temporary directory for one test.
inline std::string tempDir(const std::string& name) {
  // one directory per process: ctest runs tests in parallel processes
  const auto p = std::filesystem::temp_directory_path() /
                 ("accura_test_" + std::to_string(::getpid()) + "_" + name);
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p.string();
}

inline void writeText(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

inline std::string readText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace accura::test
