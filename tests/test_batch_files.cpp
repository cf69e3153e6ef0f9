// accura batch / compensate / convert against the file system: an output directory that leads
// back into the input tree through a symbolic link, a directory of the tree that cannot be
// listed, symbolic links to nothing and to directories, an output that is a stream (a FIFO,
// /dev/fd/1) rather than a file to replace, an earlier run's outputs of a program that fails
// now, an output directory that cannot be created.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <grp.h>
#include <poll.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <map>
#include <thread>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/postproc/batch.h"
#include "test_util.h"

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

using test::CliRun;
CliRun accura(const std::string& dir, const std::string& args) { return test::runAccuraIn(dir, args); }

void seam(const std::string& src_path) {  // the golden seam (.src and .dat) under another name
  test::copyText(test::golden("compensate/seam.src"), src_path);
  test::copyText(test::golden("compensate/seam.dat"), fs::path(src_path).replace_extension(".dat").string());
}

std::string job() {
  return "--robot " + test::golden("compensate/kr16_real.xml") + " --config '" + test::golden("compensate/$config.dat") + "' ";
}

// A directory under --out that is a symbolic link back into the input tree: writing through it
// replaced the input programs with their compensated versions (exit 0). Now each program whose
// output directory resolves inside the input tree fails, named, and the tree keeps its bytes.
TEST(BatchFiles, AnOutputDirectoryLinkedBackIntoTheInputTreeNeverReplacesAnInput) {
  const std::string root = test::tempDir("batchfiles_outlink");
  seam(root + "/in/cell1/a.src");
  seam(root + "/in/cell1/sub/b.src");
  seam(root + "/in/cell2/c.src");
  fs::create_directories(root + "/out");
  fs::create_directory_symlink("../in/cell1", root + "/out/cell1");
  const auto before = test::snapshot(root + "/in");
  for (const char* jobs : {"1", "2"}) {
    SCOPED_TRACE(jobs);
    const CliRun r = accura(root, "batch " + job() + "--in in --out out --jobs " + jobs);
    EXPECT_EQ(r.code, 2) << r.out << r.err;
    EXPECT_NE(r.out.find("FAILED cell1/a.src: out/cell1: the output directory is"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("FAILED cell1/sub/b.src: out/cell1/sub: the output directory is"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("inside the input tree in, which is never modified: not written"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("1 compensated, 2 failed"), std::string::npos) << r.out;
    EXPECT_TRUE(fs::is_regular_file(root + "/out/cell2/c.src"));
    EXPECT_EQ(test::snapshot(root + "/in"), before);
  }
}

// Runs `accura ARGS` in `dir` as the user nobody when this process is root (root reads a
// directory whatever its mode: the run must not be root for a directory it cannot list).
CliRun accuraUnprivileged(const std::string& dir, const std::string& args) {
  if (::geteuid() != 0) return accura(dir, args);
  const pid_t pid = fork();
  if (pid == 0) {
    if (::setgroups(0, nullptr) != 0 || ::setgid(65534) != 0 || ::setuid(65534) != 0) _exit(97);
    const std::string cmd = "cd '" + dir + "' && " + std::string(ACCURA_CLI) + " " + args + " >.stdout 2>.stderr";
    execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    _exit(98);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, test::readText(dir + "/.stdout"), test::readText(dir + "/.stderr")};
}

// A directory of the tree that cannot be listed ended the walk there, silently: every program
// listed after it was left out of the run and of its report (exit 0 when those before it were
// fine). Now it is a failed entry of the report and the walk goes on; a program name that is a
// symbolic link to nothing is a failed entry, a symbolic link to a directory a skipped one.
TEST(BatchFiles, ADirectoryThatCannotBeListedIsReportedAndTheOthersAreCompensated) {
  const std::string root = test::tempDir("batchfiles_unlisted");
  for (const char* d : {"a", "b", "c", "d", "e", "f"}) seam(root + "/in/" + d + "/seam.src");
  seam(root + "/in/locked/seam.src");
  fs::create_directory_symlink("a", root + "/in/link_to_a");
  fs::create_symlink("nowhere.src", root + "/in/gone.src");
  fs::create_directories(root + "/out");
  for (const char* d : {"", "/out"}) fs::permissions(root + d, fs::perms::all);  // nobody writes there
  fs::permissions(root + "/in/locked", fs::perms::none);
  const CliRun r = accuraUnprivileged(root, "batch " + job() + "--in in --out out --jobs 2 --json out/report.json");
  fs::permissions(root + "/in/locked", fs::perms::owner_all);
  ASSERT_NE(r.code, 97) << "could not become the user nobody";
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.out.find("FAILED locked: cannot list the directory: Permission denied"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("FAILED gone.src: cannot read the program: a symbolic link that leads to no file"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("skipped link_to_a: a symbolic link to a directory: not followed"), std::string::npos) << r.out;
  // 6 programs read, and 3 other entries of the tree (the directory not listed, the link to
  // nothing, the link not followed): counted in failed / skipped, not as programs
  EXPECT_NE(r.out.find("accura batch: 6 compensated, 2 failed, 1 skipped, 6 programs and 3 other entries of the tree in in"),
            std::string::npos)
      << r.out;
  for (const char* d : {"a", "b", "c", "d", "e", "f"}) EXPECT_TRUE(fs::is_regular_file(root + "/out/" + std::string(d) + "/seam.src")) << d;
  const std::string report = test::readText(root + "/out/report.json");
  EXPECT_NE(report.find("\"input\": \"locked\""), std::string::npos) << report;
  EXPECT_NE(report.find("\"programs\": 6,"), std::string::npos) << report;
  // the library call: the problems listed, the walk complete; without a list, an error
  if (::geteuid() != 0) {
    fs::permissions(root + "/in/locked", fs::perms::none);
    std::vector<TreeProblem> problems;
    EXPECT_EQ(findPrograms(root + "/in", &problems).size(), 6u);
    EXPECT_EQ(problems.size(), 3u);
    EXPECT_THROW(findPrograms(root + "/in"), calib::InputError);
    fs::permissions(root + "/in/locked", fs::perms::owner_all);
  }
}

// What a FIFO's writer sends until it closes, or nothing after 60 s without one (a FIFO
// replaced by a file: no writer comes).
std::string readFifo(const std::string& path) {
  std::string got;
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK);
  char buf[4096];
  for (struct pollfd p{fd, POLLIN, 0}; fd >= 0 && ::poll(&p, 1, 60000) > 0;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n > 0) got.append(buf, static_cast<size_t>(n));
    else if (n == 0 || errno != EAGAIN) break;
  }
  if (fd >= 0) ::close(fd);
  return got;
}

// An output that is a stream, not a file to replace: a FIFO was replaced by a regular file (its
// reader got nothing), /dev/stdout and /dev/null too (as root, the system's /dev/null). Now the
// FIFO stays a FIFO and its reader gets the report; /dev/fd/1 is the standard output.
TEST(BatchFiles, AnOutputThatIsAStreamIsWrittenIntoNotReplaced) {
  const std::string root = test::tempDir("batchfiles_stream");
  seam(root + "/in/seam.src");
  const std::string fifo = root + "/report.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  std::string got;
  std::thread reader([&] { got = readFifo(fifo); });
  const CliRun r = accura(root, "compensate " + job() + "--in in/seam.src --out out --json report.fifo");
  reader.join();
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  struct stat st;
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  EXPECT_EQ(got.rfind("{\n  \"program\": \"in/seam.src\"", 0), 0u) << got.substr(0, 200);
  EXPECT_TRUE(fs::is_regular_file(root + "/out/seam.src"));
  // the standard output by its descriptor's name: the report goes there
  const CliRun s = accura(root, "compensate " + job() + "--in in/seam.src --out out2 --json /dev/fd/1");
  EXPECT_EQ(s.code, 0) << s.err;
  EXPECT_EQ(s.out.rfind("{\n  \"program\": \"in/seam.src\"", 0), 0u) << s.out.substr(0, 200);
  EXPECT_NE(s.out.find("wrote /dev/fd/1"), std::string::npos);
  // the writer on its own: a FIFO written into along with a regular file
  ASSERT_EQ(::mkfifo((root + "/b.fifo").c_str(), 0644), 0);
  std::string got2;
  std::thread reader2([&] { got2 = readFifo(root + "/b.fifo"); });
  calib::writeFilesAtomically({{root + "/plain.txt", "plain"}, {root + "/b.fifo", "streamed"}});
  reader2.join();
  EXPECT_EQ(got2, "streamed");
  EXPECT_EQ(test::readText(root + "/plain.txt"), "plain");
  ASSERT_EQ(::lstat((root + "/b.fifo").c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
}

// A program that fails now, in an --out that holds its output of an earlier run: the report said
// only FAILED while the tree still held a compensated program by its name. Now the failure says
// that the file there is an earlier run's (and leaves it: accura removes nothing).
TEST(BatchFiles, AFailedProgramWhoseEarlierOutputIsInTheOutputTreeSaysSo) {
  const std::string root = test::tempDir("batchfiles_stale");
  seam(root + "/in/seam.src");
  seam(root + "/in/ok.src");
  ASSERT_EQ(accura(root, "batch " + job() + "--in in --out out --jobs 1").code, 0);
  const std::string earlier = test::readText(root + "/out/seam.src");
  test::writeText(root + "/in/seam.src", "DEF seam( )\nPTP {X 5000,Y 0,Z 800,A 0,B 90,C 0}\nEND\n");
  const CliRun r = accura(root, "batch " + job() + "--in in --out out --jobs 1 --json report.json");
  EXPECT_EQ(r.code, 2) << r.out << r.err;
  EXPECT_NE(r.out.find("FAILED seam.src: "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("not written, but out/seam.src, out/seam.dat exist from an earlier run: not this run's output"), std::string::npos)
      << r.out;
  EXPECT_NE(test::readText(root + "/report.json").find("exist from an earlier run"), std::string::npos);
  EXPECT_EQ(test::readText(root + "/out/seam.src"), earlier);
  // a fresh --out: nothing to say
  const CliRun f = accura(root, "batch " + job() + "--in in --out fresh --jobs 1");
  EXPECT_EQ(f.code, 2);
  EXPECT_EQ(f.out.find("earlier run"), std::string::npos) << f.out;
}

// convert --out under a file: an "internal error" (exit 4) from std::filesystem; now the
// command's own error, exit 1.
TEST(BatchFiles, ConvertIntoADirectoryThatCannotBeCreatedIsAnInputError) {
  const std::string root = test::tempDir("batchfiles_convert_dir");
  seam(root + "/in/seam.src");
  test::writeText(root + "/afile", "x");
  const CliRun r = accura(root, "convert --in in/seam.src --out afile/x.xml");
  EXPECT_EQ(r.code, 1) << r.err;
  EXPECT_NE(r.err.find("afile: cannot create the directory: Not a directory"), std::string::npos) << r.err;
  EXPECT_EQ(test::readText(root + "/afile"), "x");
}

}  // namespace
}  // namespace accura::postproc

namespace accura::postproc {
namespace {

// An --out that cannot be resolved (a symbolic link in a loop) and a batch --json /dev/stdout
// whose standard output is a pipe (/proc/self/fd/1 -> "pipe:[N]", no path) threw
// std::filesystem's exception: "internal error", exit 4, nothing written. Now the first is the
// command's own error (exit 1) and the second writes the report into the pipe.
TEST(BatchFiles, AnOutputThatDoesNotResolveIsAnInputErrorAndTheReportGoesIntoAPipe) {
  const std::string root = test::tempDir("batchfiles_resolve");
  seam(root + "/in/seam.src");
  fs::create_symlink("loop", root + "/loop");
  for (const char* out : {"loop", "loop/x"}) {
    SCOPED_TRACE(out);
    const CliRun r = accura(root, "batch " + job() + "--in in --out " + out);
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_NE(r.err.find(std::string(out) + ": cannot resolve the output directory (--out): Too many levels of symbolic links"),
              std::string::npos)
        << r.err;
  }
  const std::string cmd = "cd '" + root + "' && { " + std::string(ACCURA_CLI) + " batch " + job() +
                          "--in in --out out --json /dev/stdout 2>err.txt; echo $? >rc.txt; } | cat >piped.txt";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_EQ(test::readText(root + "/rc.txt"), "0\n") << test::readText(root + "/err.txt");
  const std::string piped = test::readText(root + "/piped.txt");
  EXPECT_NE(piped.find("\"compensated\": 1"), std::string::npos) << piped.substr(0, 300);
  EXPECT_NE(piped.find("wrote /dev/stdout"), std::string::npos);
  EXPECT_TRUE(fs::is_regular_file(root + "/out/seam.src"));
}

}  // namespace
}  // namespace accura::postproc

namespace accura::postproc {
namespace {

// A program whose name is 250 bytes long (a file name may have 255) could not be written: its
// temporary file ".NAME.PID.N.accura-tmp" was longer than a file name may be ("cannot write
// file: File name too long", the program failed). The temporary name is now cut to fit.
TEST(BatchFiles, AProgramWithALongButLegalNameIsWritten) {
  const std::string root = test::tempDir("batchfiles_longname");
  const std::string name(246, 'p');
  seam(root + "/in/" + name + ".src");
  const CliRun r = accura(root, "batch " + job() + "--in in --out out --jobs 1");
  EXPECT_EQ(r.code, 0) << r.out.substr(0, 600);
  EXPECT_TRUE(fs::is_regular_file(root + "/out/" + name + ".src"));
  EXPECT_TRUE(fs::is_regular_file(root + "/out/" + name + ".dat"));
  size_t entries = 0;
  for (const auto& e : fs::directory_iterator(root + "/out")) entries += e.path().filename().string().find("accura-tmp") == std::string::npos;
  EXPECT_EQ(entries, 2u);
  // the writer on its own, two files of one set whose cut temporary names would begin alike
  const std::string a = root + "/" + std::string(255, 'a'), b = root + "/" + std::string(254, 'a') + "b";
  calib::writeFilesAtomically({{a, "A"}, {b, "B"}});
  EXPECT_EQ(test::readText(a), "A");
  EXPECT_EQ(test::readText(b), "B");
}

}  // namespace
}  // namespace accura::postproc
