// accura batch on a terminal: the progress bar (stderr is a pseudo-terminal here, as in an
// interactive shell). Each finished program redraws one line: a 30-character bar filled in
// proportion to the programs done, done/total and the program's name; a failed program gets
// its own line first; the last redraw ends the line.
#include <gtest/gtest.h>
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <string>
#include <vector>

#include "test_util.h"

namespace fs = std::filesystem;

namespace accura::calib {
namespace {

/// Runs accura with `args` in `dir` with stdout and stderr on a new pseudo-terminal; returns
/// the exit code and everything written to the terminal.
std::pair<int, std::string> runOnTerminal(const std::string& dir, const std::vector<std::string>& args) {
  int master = -1;
  const pid_t pid = forkpty(&master, nullptr, nullptr, nullptr);
  if (pid < 0) return {-1, "forkpty failed"};
  if (pid == 0) {
    if (chdir(dir.c_str()) != 0) _exit(127);
    std::vector<char*> argv;
    std::string cli = ACCURA_CLI;
    argv.push_back(cli.data());
    std::vector<std::string> copy = args;
    for (std::string& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(cli.c_str(), argv.data());
    _exit(127);
  }
  std::string out;
  char buf[4096];
  for (;;) {
    const ssize_t n = read(master, buf, sizeof buf);
    if (n > 0) {
      out.append(buf, static_cast<size_t>(n));
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      break;  // EOF, or EIO once the child closed the terminal
    }
  }
  close(master);
  int status = 0;
  waitpid(pid, &status, 0);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

void copyFile(const std::string& from, const std::string& to) {
  fs::create_directories(fs::path(to).parent_path());
  test::writeText(to, test::readText(from));
}

TEST(BatchTerminal, ProgressBarRedrawsOneLinePerProgram) {
  const std::string root = test::tempDir("batch_tty");
  const std::string g = test::sourcePath("tests/golden/compensate/");
  for (const char* sub : {"a", "b", "c"}) {
    copyFile(g + "seam.src", root + "/in/" + sub + "/seam.src");
    copyFile(g + "seam.dat", root + "/in/" + sub + "/seam.dat");
  }
  test::writeText(root + "/in/bad.src", "DEF bad( )\nLIN {X 1000,Y 0,Z 800,A 0,B 90,Q 0}\nEND\n");
  copyFile(g + "kr16_real.xml", root + "/model.xml");
  copyFile(g + "$config.dat", root + "/$config.dat");
  const auto [code, text] = runOnTerminal(
      root, {"batch", "--robot", "model.xml", "--config", "$config.dat", "--in", "in", "--out", "out", "--tol", "0.02", "--jobs", "1"});
  EXPECT_EQ(code, 2) << text;  // one program failed
  // the terminal turns \n into \r\n; the bar is redrawn with \r ESC[K
  const std::string redraw = "\r\033[K[";
  std::vector<std::string> bars;
  for (size_t p = text.find(redraw); p != std::string::npos; p = text.find(redraw, p + 1)) {
    const size_t end = text.find_first_of("\r\n", p + redraw.size());
    bars.push_back(text.substr(p + redraw.size() - 1, end - p - redraw.size() + 1));
  }
  ASSERT_EQ(bars.size(), 4u) << text;
  // programs in sorted order: a/seam.src, b/seam.src, bad.src, c/seam.src; the bar filled to
  // done * 30 / total characters
  const std::vector<std::string> names = {"a/seam.src", "b/seam.src", "bad.src", "c/seam.src"};
  for (int k = 0; k < 4; ++k) {
    const int filled = (k + 1) * 30 / 4;
    const std::string expected = "[" + std::string(static_cast<size_t>(filled), '#') + std::string(static_cast<size_t>(30 - filled), '.') +
                                 "] " + std::to_string(k + 1) + "/4 " + names[static_cast<size_t>(k)];
    EXPECT_EQ(bars[static_cast<size_t>(k)], expected) << k;
  }
  // the failure on its own line before the bar that counts it, naming the place
  const size_t failed = text.find("\r\033[KFAILED bad.src: in/bad.src:2:");
  ASSERT_NE(failed, std::string::npos) << text;
  EXPECT_LT(text.find("2/4 b/seam.src"), failed);
  EXPECT_GT(text.find("3/4 bad.src"), failed);
  // the last redraw ends its line, and the summary follows on its own line
  const size_t last = text.find("4/4 c/seam.src");
  EXPECT_EQ(text.substr(last + 14, 2), "\r\n");
  EXPECT_NE(text.find("accura batch: 3 converted, 1 failed, 0 skipped, 4 programs in in"), std::string::npos) << text;
  // the plain-log form (one "accura batch: [k/n]" line per program) is not used on a terminal
  EXPECT_EQ(text.find("accura batch: [1/4]"), std::string::npos);
}

}  // namespace
}  // namespace accura::calib
