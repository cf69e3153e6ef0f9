// Helpers shared by the tests.
#pragma once

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <system_error>
#include <vector>
#include <unistd.h>

#include "accura/calib/robot_io.h"

namespace accura::test {

/// Whether this test binary (and the accura it runs: the sanitizer build builds both) runs under
/// AddressSanitizer, some 4-10 times slower than the Release build. (The sanitizer build compiles
/// the test code itself uninstrumented and says so with ACCURA_UNDER_SANITIZERS: tests/CMakeLists.txt.)
#if defined(ACCURA_UNDER_SANITIZERS) || defined(__SANITIZE_ADDRESS__)
inline constexpr bool kUnderSanitizers = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kUnderSanitizers = true;
#else
inline constexpr bool kUnderSanitizers = false;
#endif
#else
inline constexpr bool kUnderSanitizers = false;
#endif

/// Pieces of a split timed motion: their durations `t_s` and TCP path lengths `len_mm`. Returns
/// the largest |t_i - total * len_i / sum(len)| (s) and sets *sum_s to the sum of the durations.
inline double durationShareError(const std::vector<double>& t_s, const std::vector<double>& len_mm, double total_s, double* sum_s) {
  double sum_len = 0;
  *sum_s = 0;
  for (size_t i = 0; i < t_s.size(); ++i) {
    *sum_s += t_s[i];
    sum_len += len_mm.at(i);
  }
  double worst = 0;
  for (size_t i = 0; i < t_s.size(); ++i) worst = std::max(worst, std::abs(t_s[i] - total_s * len_mm[i] / sum_len));
  return worst;
}

inline std::string sourcePath(const std::string& rel) { return std::string(ACCURA_SOURCE_DIR) + "/" + rel; }

inline calib::RobotModel loadBundled(const std::string& name, calib::FormPolicy policy = calib::FormPolicy::kAuto) {
  calib::RobotModel m = calib::readRobotFile(sourcePath("robots/" + name + ".xml"));
  if (policy != calib::FormPolicy::kAuto) {
    const calib::Deviations d = m.deviations;
    m = calib::RobotModel::fromDefinition(m.nominal, policy);
    m.deviations = d;
  }
  return m;
}

/// A fresh temporary directory for one test.
// Removes every directory tempDir made when the test process ends (normally or by a failed
// ASSERT, which only returns from the test), so that a test run leaves nothing in the
// system's temp folder, whichever tests forget their own remove_all.
class TempDirRegistry {
 public:
  static TempDirRegistry& instance() {
    static TempDirRegistry registry;
    return registry;
  }
  void add(const std::filesystem::path& p) { dirs_.push_back(p); }
  ~TempDirRegistry() {
    for (const auto& p : dirs_) {
      std::error_code ec;
      std::filesystem::remove_all(p, ec);
    }
  }

 private:
  std::vector<std::filesystem::path> dirs_;
};

inline std::string tempDir(const std::string& name) {
  // one directory per process: ctest runs tests in parallel processes
  const auto p = std::filesystem::temp_directory_path() /
                 ("accura_test_" + std::to_string(::getpid()) + "_" + name);
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  TempDirRegistry::instance().add(p);
  return p.string();
}

inline void writeText(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary);
  f << text;
}

/// Copies the file `from` to `to` (its directories created).
inline void copyText(const std::string& from, const std::string& to) {
  std::filesystem::create_directories(std::filesystem::path(to).parent_path());
  std::ifstream in(from, std::ios::binary);
  std::ofstream(to, std::ios::binary) << in.rdbuf();
}

/// `text` with its CRLF line ends as LF: KRL written anew has the controller's CRLF
/// (krl_writer.cpp), tests look for its lines with LF.
inline std::string lf(const std::string& text) {
  std::string out;
  for (size_t i = 0; i < text.size(); ++i)
    if (!(text[i] == '\r' && i + 1 < text.size() && text[i + 1] == '\n')) out += text[i];
  return out;
}
/// A KrlText (.src and .dat) with LF line ends (lf).
template <class Text>
Text lf(Text t) {
  t.src = lf(t.src);
  t.dat = lf(t.dat);
  return t;
}

inline std::string readText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

/// The path of a file of tests/golden/: golden("compensate/seam.src").
inline std::string golden(const std::string& rel) { return sourcePath("tests/golden/" + rel); }

/// Every regular file of a directory tree: its path relative to `dir` -> its bytes. Two snapshots
/// are equal exactly when the trees hold the same files with the same contents.
inline std::map<std::string, std::string> snapshot(const std::string& dir) {
  std::map<std::string, std::string> m;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
    if (e.is_regular_file()) m[std::filesystem::relative(e.path(), dir).generic_string()] = readText(e.path().string());
  return m;
}

/// Random joint values uniformly within the joint limits.
inline Eigen::VectorXd randomQ(const calib::RobotModel& m, std::mt19937_64& rng) {
  Eigen::VectorXd q(m.dof());
  for (int i = 0; i < m.dof(); ++i) {
    std::uniform_real_distribution<double> u(m.nominal.joints[i].lower, m.nominal.joints[i].upper);
    q[i] = u(rng);
  }
  return q;
}

/// Exit code, standard output and standard error of one run of the accura command.
struct CliRun {
  int code;
  std::string out, err;
};

/// Runs `accura ARGS` from the current directory; its output is captured in a directory of its
/// own (tempDir).
inline CliRun runAccura(const std::string& args) {
  const std::string dir = tempDir("cli_run");
  const std::string cmd = std::string(ACCURA_CLI) + " " + args + " >" + dir + "/out 2>" + dir + "/err";
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, readText(dir + "/out"), readText(dir + "/err")};
}

/// Runs `accura ARGS` in directory `dir` (relative paths in ARGS are relative to it).
inline CliRun runAccuraIn(const std::string& dir, const std::string& args) {
  const std::string cmd = "cd '" + dir + "' && " + std::string(ACCURA_CLI) + " " + args + " >.stdout 2>.stderr";
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, readText(dir + "/.stdout"), readText(dir + "/.stderr")};
}

}  // namespace accura::test
