// accura batch: a tree with a bad file (the others converted, the bad one reported, exit code
// non-zero), the input tree unchanged (content hash before and after), --jobs 1 and --jobs 2
// byte-identical, the mirrored layout, no temporary files left, an interrupted run leaving no
// half-written file; and the atomic writer on its own.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
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

// A tree of programs: the golden seam (KRL, CRLF) in three places, an XML program, a program
// with a malformed target, an unreachable one, and a robot file (not a program).
std::string makeTree(const std::string& root, int extra_copies = 0) {
  const std::string in = root + "/in";
  test::copyText(test::golden("compensate/seam.src"), in + "/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), in + "/seam.dat");
  test::copyText(test::golden("compensate/seam.src"), in + "/cell2/Seam_B.SRC");
  test::copyText(test::golden("compensate/seam.dat"), in + "/cell2/Seam_B.dat");
  test::copyText(test::golden("compensate/seam.src"), in + "/cell2/deep/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), in + "/cell2/deep/seam.dat");
  test::copyText(test::golden("xml/weld_seam.xml"), in + "/cell2/weld_seam.xml");
  test::copyText(test::golden("compensate/kr16_real.xml"), in + "/robot_model.xml");
  test::writeText(in + "/cell2/broken.src", "DEF broken( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nLIN {X 1000,Y 0,Z 800,A 0,B 90,Q 0}\nEND\n");
  test::writeText(in + "/far.src", "DEF far( )\n$TOOL={X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE=$NULLFRAME\nPTP {X 5000,Y 0,Z 800,A 0,B 90,C 0}\nEND\n");
  for (int k = 0; k < extra_copies; ++k) {
    test::copyText(test::golden("compensate/seam.src"), in + "/many/p" + std::to_string(k) + ".src");
    test::copyText(test::golden("compensate/seam.dat"), in + "/many/p" + std::to_string(k) + ".dat");
  }
  test::copyText(test::golden("compensate/kr16_real.xml"), root + "/model.xml");
  test::copyText(test::golden("compensate/$config.dat"), root + "/$config.dat");
  return in;
}

TEST(Batch, FindsProgramsSorted) {
  const std::string root = test::tempDir("batch_find");
  const std::string in = makeTree(root);
  test::writeText(in + "/.hidden/x.src", "");
  const std::vector<std::string> expected = {"cell2/Seam_B.SRC", "cell2/broken.src", "cell2/deep/seam.src", "cell2/weld_seam.xml",
                                             "far.src", "robot_model.xml", "seam.src"};
  EXPECT_EQ(findPrograms(in), expected);
}

TEST(Batch, ABadFileIsReportedTheRestConvertedInputUnchanged) {
  const std::string root = test::tempDir("batch_tree");
  const std::string in = makeTree(root);
  const auto before = test::snapshot(in);
  const std::string common = "batch --robot model.xml --config '$config.dat' --in in --tol 0.02";
  const CliRun r1 = accura(root, common + " --out out1 --jobs 1 --json report1.json");
  const CliRun r2 = accura(root, common + " --out out2 --jobs 2 --json report2.json");
  EXPECT_EQ(r1.code, 2) << r1.err;
  EXPECT_EQ(r2.code, 2) << r2.err;
  EXPECT_EQ(test::snapshot(in), before);  // the input tree is never modified

  // --jobs 1 and --jobs 2: byte-identical outputs, summary and report (but its out path)
  const auto out1 = test::snapshot(root + "/out1"), out2 = test::snapshot(root + "/out2");
  EXPECT_EQ(out1, out2);
  EXPECT_EQ(r1.out.substr(0, r1.out.find("wrote report")), r2.out.substr(0, r2.out.find("wrote report")));
  std::string j1 = test::readText(root + "/report1.json"), j2 = test::readText(root + "/report2.json");
  j1.replace(j1.find("\"out1\""), 6, "\"out\"");
  j2.replace(j2.find("\"out2\""), 6, "\"out\"");
  EXPECT_EQ(j1, j2);

  // the mirrored tree: every good program, nothing for the bad ones, no temporary file
  std::vector<std::string> files;
  for (const auto& [path, text] : out1) files.push_back(path);
  const std::vector<std::string> expected = {"cell2/Seam_B.SRC", "cell2/Seam_B.dat", "cell2/deep/seam.dat", "cell2/deep/seam.src",
                                             "cell2/weld_seam.xml", "seam.dat", "seam.src"};
  EXPECT_EQ(files, expected);
  // each KRL program equals the single-program compensation (the golden)
  EXPECT_EQ(out1.at("seam.src"), test::readText(test::golden("compensate/expected/seam.src")));
  EXPECT_EQ(out1.at("seam.dat"), test::readText(test::golden("compensate/expected/seam.dat")));
  EXPECT_EQ(out1.at("cell2/deep/seam.dat"), test::readText(test::golden("compensate/expected/seam.dat")));
  EXPECT_EQ(out1.at("cell2/Seam_B.SRC"), test::readText(test::golden("compensate/expected/seam.src")));

  // the report: the bad files with their errors (file:line:column), in sorted order
  EXPECT_NE(r1.out.find("FAILED cell2/broken.src: in/cell2/broken.src:4:32: expected a component of a Cartesian target"),
            std::string::npos)
      << r1.out;
  EXPECT_NE(r1.out.find("FAILED far.src: in/far.src:4:1: "), std::string::npos) << r1.out;
  EXPECT_NE(r1.out.find("skipped robot_model.xml: not an XML program"), std::string::npos) << r1.out;
  EXPECT_NE(r1.out.find("accura batch: 4 compensated, 2 failed, 1 skipped, 7 programs in in"), std::string::npos) << r1.out;
  EXPECT_LT(r1.out.find("cell2/Seam_B.SRC"), r1.out.find("cell2/broken.src"));
  EXPECT_LT(r1.out.find("cell2/broken.src"), r1.out.find("far.src"));
  const nlohmann::json report = nlohmann::json::parse(j1);
  EXPECT_EQ(report["compensated"], 4);
  EXPECT_EQ(report["failed"], 2);
  ASSERT_EQ(report["files"].size(), 7u);
  EXPECT_EQ(report["files"][1]["input"], "cell2/broken.src");
  EXPECT_EQ(report["files"][1]["status"], "failed");
  EXPECT_EQ(report["files"][0]["status"], "compensated");
  EXPECT_EQ(report["files"][0]["outputs"], nlohmann::json({"cell2/Seam_B.SRC", "cell2/Seam_B.dat"}));
  EXPECT_EQ(report["files"][0]["segments"].size(), 5u);
  EXPECT_EQ(report["files"][0]["segments"][0]["file"], "cell2/Seam_B.SRC");
  // progress lines on stderr (not a terminal here): one per program
  int lines = 0;
  for (size_t p = r1.err.find("accura batch: ["); p != std::string::npos; p = r1.err.find("accura batch: [", p + 1)) ++lines;
  EXPECT_EQ(lines, 7) << r1.err;
}

TEST(Batch, AllConvertedExitsZeroAndTheOutputMayNotBeInsideTheInput) {
  const std::string root = test::tempDir("batch_ok");
  test::copyText(test::golden("compensate/seam.src"), root + "/in/a/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), root + "/in/a/seam.dat");
  test::copyText(test::golden("compensate/kr16_real.xml"), root + "/model.xml");
  test::copyText(test::golden("compensate/$config.dat"), root + "/$config.dat");
  CliRun r = accura(root, "batch --robot model.xml --config '$config.dat' --in in --out out --jobs 3");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(fs::exists(root + "/out/a/seam.src"));
  const auto before = test::snapshot(root + "/in");
  r = accura(root, "batch --robot model.xml --config '$config.dat' --in in --out in/compensated");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("the output directory is inside the input tree"), std::string::npos) << r.err;
  EXPECT_EQ(test::snapshot(root + "/in"), before);
  r = accura(root, "batch --robot model.xml --in in --out out --jobs 0");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("--jobs: expected an integer in [1, 1024], found '0' (see accura batch --help)"), std::string::npos) << r.err;
}

// A tree with a $config.dat for its KRL/XML programs may hold URScript programs too: the
// $config.dat frames are KUKA's, so batch gives them to the KRL and XML programs only (before,
// every .script failed with "--config: only for KRL and XML programs"). With the nominal UR10
// there is nothing to correct: the script comes back byte for byte.
TEST(Batch, ConfigServesTheKrlProgramsOfAMixedTreeNotTheUrScriptOnes) {
  const std::string root = test::tempDir("batch_mixed");
  test::copyText(test::golden("urscript/ur10_seam.script"), root + "/in/ur/seam.script");
  test::copyText(test::golden("compensate/$config.dat"), root + "/$config.dat");
  const CliRun r = accura(root, "batch --robot ur10 --config '$config.dat' --in in --out out --jobs 1");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(test::readText(root + "/out/ur/seam.script"), test::readText(test::golden("urscript/ur10_seam.script")));
  // a single URScript program given --config is still told that it has no use for it
  const CliRun c = accura(root, "compensate --robot ur10 --config '$config.dat' --in in/ur/seam.script --out single");
  EXPECT_EQ(c.code, 1);
  EXPECT_NE(c.err.find("--config: only for KRL and XML programs ($config.dat frames), found the URScript program"), std::string::npos) << c.err;
}

// A program that uses a GLOBAL point of another program's data list (other.src: LIN XG1, XG1
// declared GLOBAL in p3.dat): the controller takes the value p3.dat holds, which p3's
// compensation corrects for p3's tool and base. other's motion is kept, and the warning says
// where the point is declared and what moves it -- not "give --config $config.dat", which
// would not find it. p3 names the corrected GLOBAL point at its declaration.
TEST(Batch, AProgramThatUsesAnotherProgramsGlobalPointIsToldWhereItIsDeclared) {
  const std::string root = test::tempDir("batch_global");
  const std::string in = root + "/in";
  fs::create_directories(in);
  test::writeText(in + "/other.src", "DEF other( )\n$TOOL = {X 0,Y 0,Z 100,A 0,B 0,C 0}\n$BASE = {X 900,Y -300,Z 200,A 30,B 0,C 0}\n"
                                     "PTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\nLIN XG1\nEND\n");
  test::writeText(in + "/other.dat", "DEFDAT other\nENDDAT\n");
  test::writeText(in + "/p3.src", "DEF p3( )\n$TOOL = {X 0,Y 0,Z 200,A 0,B 90,C 0}\n$BASE = {X 900,Y -300,Z 200,A 30,B 0,C 0}\n"
                                  "PTP {A1 10,A2 -80,A3 100,A4 20,A5 30,A6 40}\nLIN XG1\nEND\n");
  test::writeText(in + "/p3.dat", "DEFDAT p3 PUBLIC\nDECL GLOBAL E6POS XG1={X 135.598,Y -264.075,Z 477.826,A 115.342,B -63.826,C -129.097,S 2,T 2}\nENDDAT\n");
  BatchOptions o;
  o.job.calibrated = test::loadBundled("kuka_kr16");
  o.job.calibrated.deviations.base_mm = Eigen::Vector3d(0.2, -0.1, 0.3);
  const BatchResult r = runBatch(in, root + "/out", o, nullptr);
  ASSERT_EQ(r.files.size(), 2u);
  ASSERT_EQ(r.converted, 2) << r.files[0].message << r.files[1].message;
  const BatchFileResult& other = r.files[0];
  ASSERT_EQ(other.input, "other.src");
  ASSERT_EQ(other.report.warnings.size(), 1u);
  EXPECT_EQ(other.report.warnings[0].where.line, 5);
  EXPECT_EQ(other.report.warnings[0].message,
            "LIN left unchanged (not compensated): XG1 is not declared in " + in + "/other.src or " + in + "/other.dat: it is the GLOBAL point of " +
                in + "/p3.dat:2:19, another program's data list, whose compensation corrects it for that program's tool, base and motions; "
                "this motion moves to that value (declare a point of this program's own to compensate it); the position after it is not known");
  const BatchFileResult& p3 = r.files[1];
  bool named = false;
  for (const ProgramIssue& w : p3.report.warnings)
    if (w.message.rfind("GLOBAL point XG1 corrected", 0) == 0) {
      named = true;
      EXPECT_EQ(w.where.str(), in + "/p3.dat:2:23");
    }
  EXPECT_TRUE(named);
  EXPECT_NE(test::readText(root + "/out/p3.dat"), test::readText(in + "/p3.dat"));  // corrected
}

// SIGINT in the middle of a run: exit 130 (or 0 when it finished first); no temporary file;
// every output file there is complete (equal to the uninterrupted run's).
TEST(Batch, AnInterruptedRunLeavesNoHalfWrittenFile) {
  const std::string root = test::tempDir("batch_sigint");
  const std::string in = makeTree(root, 40);
  const CliRun ref = accura(root, "batch --robot model.xml --config '$config.dat' --in in --out ref --jobs 2");
  ASSERT_EQ(ref.code, 2) << ref.err;
  const auto reference = test::snapshot(root + "/ref");
  const auto before = test::snapshot(in);
  for (int delay_ms : {30, 120}) {
    const std::string out = root + "/out" + std::to_string(delay_ms);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      if (chdir(root.c_str()) != 0) _exit(99);
      const std::string outarg = "out" + std::to_string(delay_ms);
      const std::string jsonarg = outarg + ".json";
      execl(ACCURA_CLI, ACCURA_CLI, "batch", "--robot", "model.xml", "--config", "$config.dat", "--in", "in", "--out",
            outarg.c_str(), "--jobs", "2", "--json", jsonarg.c_str(), static_cast<char*>(nullptr));
      _exit(98);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
    kill(pid, SIGINT);
    int status = 0;
    waitpid(pid, &status, 0);
    if (WIFSIGNALED(status)) {
      // the signal came before accura installed its handler (a loaded machine: it was still
      // starting up, before any output is written): the default action ended it
      EXPECT_EQ(WTERMSIG(status), SIGINT);
    } else {
      ASSERT_TRUE(WIFEXITED(status));
      const int code = WEXITSTATUS(status);
      EXPECT_TRUE(code == 130 || code == 2) << code;
      // the report of what the run did, written whole (before: none when interrupted): each
      // program compensated, failed, or not started, and the files on disk agree with it
      const nlohmann::json report = nlohmann::json::parse(test::readText(out + ".json"));
      EXPECT_EQ(report["interrupted"], code == 130);
      int not_started = 0;
      for (const auto& f : report["files"]) {
        const std::string input = f["input"], st = f["status"];
        if (st == "not_started") {
          ++not_started;
          EXPECT_FALSE(fs::exists(out + "/" + input)) << input;
        } else if (st == "compensated") {
          EXPECT_TRUE(fs::exists(out + "/" + input)) << input;
        }
      }
      EXPECT_EQ(report["not_started"], not_started);
      EXPECT_EQ(report["compensated"].get<int>() + report["failed"].get<int>() + not_started, report["programs"].get<int>());
    }
    if (!fs::exists(out)) continue;  // interrupted before the first file
    for (const auto& [path, text] : test::snapshot(out)) {
      EXPECT_EQ(path.find("accura-tmp"), std::string::npos) << path;
      ASSERT_TRUE(reference.count(path)) << path;
      EXPECT_EQ(text, reference.at(path)) << path;
    }
  }
  EXPECT_EQ(test::snapshot(in), before);
}

// The batch under installInterruptStop (accura batch's handler), a SIGINT raised as the first
// program is done (--jobs 1, three programs): the run stops taking programs, says it was
// interrupted, the first program is compensated and written, the other two are "not started"
// and nothing of them is written. In a child process: the handler and the signal are the
// process's. (Before: the handler ended the process at once and the report was never written.)
TEST(Batch, AnInterruptStopsTakingProgramsAndTheResultSaysWhichWereNotStarted) {
  const std::string root = test::tempDir("batch_stop");
  for (const char* name : {"a", "b", "c"}) {
    test::copyText(test::golden("compensate/seam.src"), root + "/in/" + name + ".src");
    test::copyText(test::golden("compensate/seam.dat"), root + "/in/" + name + ".dat");
  }
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    calib::installInterruptStop("");
    BatchOptions o;
    o.job.calibrated = test::loadBundled("kuka_kr16");
    o.config_path = test::golden("compensate/$config.dat");
    o.jobs = 1;
    const BatchResult r = runBatch(root + "/in", root + "/out", o, [](const BatchFileResult&, int done, int) {
      if (done == 1) raise(SIGINT);
    });
    std::string text = r.interrupted ? "interrupted" : "finished";
    for (const BatchFileResult& f : r.files) text += " " + f.input + ":" + std::to_string(static_cast<int>(f.status));
    text += " " + std::to_string(r.converted) + "/" + std::to_string(r.not_started);
    std::FILE* f = std::fopen((root + "/result.txt").c_str(), "w");
    std::fputs(text.c_str(), f);
    std::fclose(f);
    _exit(0);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  // statuses: 0 converted, 3 not started
  EXPECT_EQ(test::readText(root + "/result.txt"), "interrupted a.src:0 b.src:3 c.src:3 1/2");
  EXPECT_TRUE(fs::exists(root + "/out/a.src") && fs::exists(root + "/out/a.dat"));
  EXPECT_FALSE(fs::exists(root + "/out/b.src") || fs::exists(root + "/out/c.src"));
}

// accura batch --cell: a tree with the golden seam twice and a copy of it whose retreat (its
// last LIN) goes to 40 mm under the seam's end XP3 instead of up and away: the torch (capsule of
// tests/data/cell/seam_cell.xml, radius 15 mm ending at the TCP) drives into the plate, whose
// top is 30 mm under XP3. That program fails with its first violation (file:line, clearance,
// by how much: the same as accura compensate --cell reports for it alone) and is not written;
// the others are converted, checked (passed) and equal to the single-program outputs of
// accura compensate --cell; --jobs 1 and --jobs 2 give the same bytes; --warn-only writes it.
TEST(Batch, CellCheckFailsTheProgramWhosePathTouchesAFixture) {
  const std::string root = test::tempDir("batch_cell");
  const std::string in = root + "/in";
  test::copyText(test::golden("compensate/seam.src"), in + "/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), in + "/seam.dat");
  test::copyText(test::golden("compensate/seam.src"), in + "/sub/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), in + "/sub/seam.dat");
  std::string touch = test::readText(test::golden("compensate/seam.src"));
  const std::string retreat = "lin {X 400.0,Y 150.0,Z 600.0,A 150.0,B 20.0,C -170.0}";
  const size_t at = touch.find(retreat);
  ASSERT_NE(at, std::string::npos);
  touch.replace(at, retreat.size(), "lin {X 400.0,Y -250.0,Z 380.0,A 150.0,B 25.0,C -175.0}");  // XP3 - 40 mm in z
  const int touch_line = 1 + static_cast<int>(std::count(touch.begin(), touch.begin() + static_cast<long>(at), '\n'));
  test::writeText(in + "/touch.src", touch);
  test::copyText(test::golden("compensate/seam.dat"), in + "/touch.dat");
  test::copyText(test::golden("compensate/kr16_real.xml"), root + "/model.xml");
  test::copyText(test::golden("compensate/$config.dat"), root + "/$config.dat");
  for (const char* f : {"seam_cell.xml", "plate_m.obj"}) test::copyText(test::sourcePath(std::string("tests/data/cell/") + f), root + "/cell/" + f);
  const auto before = test::snapshot(in);
  const std::string common = "--robot model.xml --config '$config.dat' --tol 0.02 --cell cell/seam_cell.xml";

  // the single-program runs: the seam passes, the touching copy fails (nothing written)
  const CliRun one = accura(root, "compensate " + common + " --in in/seam.src --out single");
  ASSERT_EQ(one.code, 0) << one.out << one.err;
  const CliRun one_touch = accura(root, "compensate " + common + " --in in/touch.src --out single_touch --json single_touch.json");
  ASSERT_EQ(one_touch.code, 2) << one_touch.out << one_touch.err;
  const nlohmann::json single = nlohmann::json::parse(test::readText(root + "/single_touch.json"));
  ASSERT_FALSE(single["check"]["violations"].empty());
  const nlohmann::json& first = single["check"]["violations"][0];
  EXPECT_EQ(first["check"], "clearance");
  EXPECT_EQ(first["line"], touch_line);
  EXPECT_EQ(first["obstacle"], "plate");
  EXPECT_EQ(first["robot_part"], "tool");
  EXPECT_GT(first["excess"].get<double>(), 0.0);

  const CliRun r1 = accura(root, "batch " + common + " --in in --out out1 --jobs 1 --json report1.json");
  const CliRun r2 = accura(root, "batch " + common + " --in in --out out2 --jobs 2 --json report2.json");
  EXPECT_EQ(r1.code, 2) << r1.out << r1.err;  // not every program converted
  EXPECT_EQ(r2.code, 2) << r2.out << r2.err;
  EXPECT_EQ(test::snapshot(in), before);
  const auto out1 = test::snapshot(root + "/out1"), out2 = test::snapshot(root + "/out2");
  EXPECT_EQ(out1, out2);
  std::string j1 = test::readText(root + "/report1.json"), j2 = test::readText(root + "/report2.json");
  j1.replace(j1.find("\"out1\""), 6, "\"out\"");
  j2.replace(j2.find("\"out2\""), 6, "\"out\"");
  EXPECT_EQ(j1, j2);

  // the failing program is not written; the others equal the single-program output
  std::vector<std::string> files;
  for (const auto& [path, text] : out1) files.push_back(path);
  EXPECT_EQ(files, (std::vector<std::string>{"seam.dat", "seam.src", "sub/seam.dat", "sub/seam.src"}));
  EXPECT_EQ(out1.at("seam.src"), test::readText(root + "/single/seam.src"));
  EXPECT_EQ(out1.at("seam.dat"), test::readText(root + "/single/seam.dat"));
  EXPECT_EQ(out1.at("sub/seam.src"), test::readText(root + "/single/seam.src"));
  EXPECT_EQ(out1.at("seam.src"), test::readText(test::golden("compensate/expected/seam.src")));  // the check changes no byte

  // the report names the violation: file:line, the check, by how much
  const std::string where = "in/touch.src:" + std::to_string(touch_line) + ":";
  const size_t failed = r1.out.find("FAILED touch.src: failed the checks of cell/seam_cell.xml: " + where);
  ASSERT_NE(failed, std::string::npos) << r1.out;
  const std::string line = r1.out.substr(failed, r1.out.find('\n', failed) - failed);
  char excess[64];
  std::snprintf(excess, sizeof excess, "%.3f", first["excess"].get<double>());
  if (std::string(excess) == "0.000") {  // the first violation is where the clearance crosses the minimum
    EXPECT_NE(line.find("clearance: tool comes closer to plate than the required 5.000 mm from here on, on the path at s "), std::string::npos) << line;
  } else {
    EXPECT_NE(line.find("clearance: tool is "), std::string::npos) << line;
    EXPECT_NE(line.find("from plate"), std::string::npos) << line;
    EXPECT_NE(line.find("(short by " + std::string(excess) + " mm)"), std::string::npos) << line << " / " << excess;
  }
  EXPECT_NE(line.find("smallest clearance on this motion 0.000 mm"), std::string::npos) << line;  // touches: 0
  EXPECT_NE(r1.out.find("accura batch: 2 compensated, 1 failed, 0 skipped, 3 programs in in"), std::string::npos) << r1.out;
  const nlohmann::json report = nlohmann::json::parse(j1);
  EXPECT_EQ(report["cell"], "cell/seam_cell.xml");
  ASSERT_EQ(report["files"].size(), 3u);
  for (int k : {0, 1}) {
    EXPECT_EQ(report["files"][k]["status"], "compensated");
    EXPECT_TRUE(report["files"][k]["check"]["passed"].get<bool>());
    EXPECT_TRUE(report["files"][k]["check"]["violations"].empty());
  }
  const nlohmann::json& t = report["files"][2];
  EXPECT_EQ(t["input"], "touch.src");
  EXPECT_EQ(t["status"], "failed");
  EXPECT_TRUE(t["outputs"].empty());
  EXPECT_FALSE(t["check"]["passed"].get<bool>());
  // the same check as the single-program run, the file named relative to the tree
  nlohmann::json expected = single["check"]["violations"];
  for (auto& v : expected) v["file"] = "touch.src";
  EXPECT_EQ(t["check"]["violations"], expected);

  // --warn-only: every program written (the touching one as compensate --warn-only writes it), exit 0
  const CliRun w = accura(root, "batch " + common + " --warn-only --in in --out outw --jobs 2 --json reportw.json");
  EXPECT_EQ(w.code, 0) << w.out << w.err;
  const CliRun one_w = accura(root, "compensate " + common + " --warn-only --in in/touch.src --out single_w");
  ASSERT_EQ(one_w.code, 0) << one_w.err;
  EXPECT_EQ(test::readText(root + "/outw/touch.src"), test::readText(root + "/single_w/touch.src"));
  EXPECT_EQ(test::readText(root + "/outw/seam.src"), out1.at("seam.src"));
  const nlohmann::json rw = nlohmann::json::parse(test::readText(root + "/reportw.json"));
  EXPECT_EQ(rw["compensated"], 3);
  EXPECT_EQ(rw["files"][2]["status"], "compensated");
  EXPECT_FALSE(rw["files"][2]["check"]["passed"].get<bool>());
  EXPECT_NE(w.err.find("touch.src: failed the checks"), std::string::npos) << w.err;
}

TEST(Batch, AtomicWriterWritesAllOrNothing) {
  const std::string dir = test::tempDir("batch_atomic");
  test::writeText(dir + "/a.txt", "old");
  calib::writeFilesAtomically({{dir + "/a.txt", "new a"}, {dir + "/b.txt", "new b"}});
  EXPECT_EQ(test::readText(dir + "/a.txt"), "new a");
  EXPECT_EQ(test::readText(dir + "/b.txt"), "new b");
  // the second file cannot be written: the first stays as it was, no temporary file is left
  std::string message;
  try {
    calib::writeFilesAtomically({{dir + "/a.txt", "newer"}, {dir + "/missing/c.txt", "c"}});
  } catch (const calib::InputError& e) {
    message = e.what();
  }
  // the missing directory is named (before: "cannot write file: No such file or directory", as if
  // the output file itself had to exist)
  EXPECT_EQ(message, dir + "/missing/c.txt: cannot write file: the directory " + dir + "/missing does not exist");
  EXPECT_EQ(test::readText(dir + "/a.txt"), "new a");
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"a.txt", "b.txt"}));
}

// A directory where an output file goes (simulate --out DIR) is said to be one, as identify's
// pre-check says it (before: "cannot rename the temporary file into place: Is a directory"), and
// nothing is left behind; a program file given to batch as --in is said to be a file, with the
// command for one program (before: "found none", as if it did not exist).
TEST(Batch, ADirectoryForAFileAndAFileForADirectoryAreNamed) {
  const std::string dir = test::tempDir("batch_dir_file");
  fs::create_directories(dir + "/out.csv");
  std::string message;
  try {
    calib::writeFileAtomically(dir + "/out.csv", "x");
  } catch (const calib::InputError& e) {
    message = e.what();
  }
  EXPECT_EQ(message, dir + "/out.csv: cannot write file: it is a directory");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);  // no temporary file left
  EXPECT_TRUE(fs::is_empty(dir + "/out.csv"));
  test::copyText(test::golden("compensate/seam.src"), dir + "/seam.src");
  BatchOptions o;
  o.job.calibrated = test::loadBundled("kuka_kr16");
  message.clear();
  try {
    runBatch(dir + "/seam.src", dir + "/o", o);
  } catch (const calib::InputError& e) {
    message = e.what();
  }
  EXPECT_EQ(message, dir + "/seam.src: expected a directory of programs (--in), found a file; one program: accura compensate --in " + dir +
                         "/seam.src --out DIR");
}

// One set naming a file twice writes nothing (the second would replace the first); two threads
// writing one path at once both succeed, each through its own temporary file, and the file holds
// one of the two contents whole (before: one shared temporary name, so that a writer could be
// told "written" while the other's bytes ended up in the file, and 1 call in 5 failed to rename).
TEST(Batch, AtomicWriterRefusesOneFileTwiceAndIsSafeForConcurrentWriters) {
  const std::string dir = test::tempDir("batch_atomic_twice");
  EXPECT_THROW(calib::writeFilesAtomically({{dir + "/a.txt", "one"}, {dir + "/./a.txt", "two"}}), calib::InputError);
  EXPECT_FALSE(fs::exists(dir + "/a.txt"));
  const std::string big(1 << 20, 'A'), small = "BBBB";
  int failures = 0;
  std::mutex m;
  auto writer = [&](const std::string& text) {
    for (int k = 0; k < 40; ++k) {
      try {
        calib::writeFileAtomically(dir + "/same.txt", text);
      } catch (const calib::InputError&) {
        std::lock_guard<std::mutex> lock(m);
        ++failures;
      }
    }
  };
  std::thread other(writer, big);
  writer(small);
  other.join();
  EXPECT_EQ(failures, 0);
  const std::string now = test::readText(dir + "/same.txt");
  EXPECT_TRUE(now == big || now == small) << now.size();
  for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename().string().find("accura-tmp"), std::string::npos);
}

// A symbolic link in the input tree is mirrored under --out by its own name: the file it points to
// (outside both trees here) is never written (before: its output went to the link's target).
TEST(Batch, ASymbolicLinkInTheInputTreeIsNeverFollowedOutOfTheOutputTree) {
  const std::string root = test::tempDir("batch_symlink");
  test::copyText(test::golden("compensate/seam.src"), root + "/elsewhere/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), root + "/elsewhere/seam.dat");
  test::copyText(test::golden("compensate/seam.dat"), root + "/in/link.dat");
  fs::create_directories(root + "/in");
  fs::create_symlink(root + "/elsewhere/seam.src", root + "/in/link.src");
  const auto before = test::snapshot(root + "/elsewhere");
  EXPECT_EQ(findPrograms(root + "/in"), std::vector<std::string>{"link.src"});
  const CliRun r = accura(root, "batch --robot " + test::golden("compensate/kr16_real.xml") + " --in in --out out --config '" +
                                     test::golden("compensate/$config.dat") + "' --jobs 1");
  EXPECT_EQ(r.code, 0) << r.out << r.err;
  EXPECT_TRUE(fs::is_regular_file(root + "/out/link.src"));
  EXPECT_TRUE(fs::is_regular_file(root + "/out/link.dat"));
  EXPECT_EQ(test::snapshot(root + "/elsewhere"), before);
}

// Two programs whose outputs would be one file (SEAM.SRC and seam.src share seam.dat: the .dat is
// found case-insensitively) both fail, named, and neither is written, for any --jobs (before:
// exit 0 and one program's .src paired with the other's .dat).
TEST(Batch, TwoProgramsWithOneOutputFileBothFailAndNeitherIsWritten) {
  const std::string root = test::tempDir("batch_collide");
  test::copyText(test::golden("compensate/seam.src"), root + "/in/dup/SEAM.SRC");
  test::copyText(test::golden("compensate/seam.src"), root + "/in/dup/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), root + "/in/dup/seam.dat");
  test::copyText(test::golden("compensate/seam.src"), root + "/in/other.src");
  test::copyText(test::golden("compensate/seam.dat"), root + "/in/other.dat");
  for (const char* jobs : {"1", "2"}) {
    SCOPED_TRACE(jobs);
    fs::remove_all(root + "/out");
    const CliRun r = accura(root, "batch --robot " + test::golden("compensate/kr16_real.xml") + " --in in --out out --config '" +
                                       test::golden("compensate/$config.dat") + "' --jobs " + jobs);
    EXPECT_EQ(r.code, 2) << r.out << r.err;
    EXPECT_NE(r.out.find("FAILED dup/SEAM.SRC: its output"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("FAILED dup/seam.src: its output"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("1 compensated, 2 failed"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(root + "/out/dup"));
    EXPECT_TRUE(fs::is_regular_file(root + "/out/other.src"));
  }
}

// --config given once per module of an ABB task (the tool and work object in calib.sys, the
// approach points in points.mod) and once for the $config.dat of the KRL programs of the same
// tree: each program takes its own (before: --config was taken once). The RAPID module's
// points from points.mod go to new points of its own, with the golden module's corrections.
TEST(Batch, ConfigGivenPerModuleOfTheTaskAndForTheKrlPrograms) {
  const std::string root = test::tempDir("batch_rapid_task");
  test::copyText(test::golden("compensate/seam.src"), root + "/in/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), root + "/in/seam.dat");
  std::string module = test::readText(test::golden("rapid/irb120_seam.mod"));
  std::string calib = "MODULE CalibData(SYSMODULE)\n", points = "MODULE Points\n";
  for (const char* head : {"  PERS tooldata torch", "  PERS wobjdata table", "  CONST robtarget p10 ", "  CONST robtarget p20 "}) {
    const size_t b = module.find(head), e = module.find('\n', b) + 1;
    ASSERT_NE(b, std::string::npos) << head;
    (std::string(head).find("robtarget") != std::string::npos ? points : calib) += module.substr(b, e - b);
    module.erase(b, e - b);
  }
  fs::create_directories(root + "/in/abb");
  fs::create_directories(root + "/task");
  test::writeText(root + "/in/abb/seam.mod", module);
  test::writeText(root + "/task/calib.sys", calib + "ENDMODULE\n");
  test::writeText(root + "/task/points.mod", points + "ENDMODULE\n");
  const auto before = test::snapshot(root);
  const CliRun r = accura(root, "batch --robot " + test::golden("rapid/irb120_real.xml") + " --in in/abb --out out/abb --config task/calib.sys --config task/points.mod");
  ASSERT_EQ(r.code, 0) << r.out << r.err;
  const std::string want = test::readText(test::golden("rapid/expected/irb120_seam.mod"));
  const size_t v = want.find("  CONST robtarget p10 := ") + 25;
  const std::string written = test::readText(root + "/out/abb/seam.mod");
  EXPECT_NE(written.find("  VAR num seams := 0;\n  LOCAL CONST robtarget p10_1 := " + want.substr(v, want.find(';', v) - v) + ";\n  LOCAL CONST robtarget p20_1 := "),
            std::string::npos)
      << written;
  EXPECT_NE(written.find("    MoveJ p10_1, v1000, z20, torch\\WObj:=table;\n    MoveL p20_1, v200, fine, torch\\WObj:=table;\n"), std::string::npos) << written;
  // a mixed tree: the RAPID modules take the modules, the KRL program the $config.dat
  const CliRun m = accura(root, "batch --robot " + test::golden("compensate/kr16_real.xml") + " --in in --out out/mixed --config task/calib.sys --config '" +
                                    test::golden("compensate/$config.dat") + "' --config task/points.mod --jobs 2");
  EXPECT_NE(m.out.find("compensated seam.src"), std::string::npos) << m.out << m.err;
  EXPECT_TRUE(fs::is_regular_file(root + "/out/mixed/seam.src"));
  EXPECT_EQ(m.out.find("FAILED seam.src"), std::string::npos) << m.out;
  // two $config.dat: refused before anything is written
  const CliRun k = accura(root, "batch --robot " + test::golden("compensate/kr16_real.xml") + " --in in --out out/two --config '" + test::golden("compensate/$config.dat") +
                                    "' --config in/seam.dat");
  EXPECT_EQ(k.code, 1) << k.out << k.err;
  EXPECT_NE(k.err.find("--config: one $config.dat for the KRL and XML programs of the tree (the controller has one, KRC:\\R1\\System\\$config.dat), found "),
            std::string::npos)
      << k.err;
  EXPECT_FALSE(fs::exists(root + "/out/two"));
  for (const auto& [path, text] : before) EXPECT_EQ(test::readText(root + "/" + path), text) << path;
}

// A report path that names an input (the robot file, the $config.dat) or a program the run
// writes is refused; the file keeps its bytes (before: replaced by the JSON report, exit 0).
TEST(Batch, TheReportNeverReplacesAnInputOrAnOutput) {
  const std::string root = test::tempDir("batch_json_inputs");
  test::copyText(test::golden("compensate/seam.src"), root + "/in/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), root + "/in/seam.dat");
  test::copyText(test::golden("compensate/kr16_real.xml"), root + "/model.xml");
  test::copyText(test::golden("compensate/$config.dat"), root + "/config.dat");
  const std::string model = test::readText(root + "/model.xml"), config = test::readText(root + "/config.dat");
  const std::string job = "--robot model.xml --config config.dat ";
  for (const std::string& target : {std::string("model.xml"), std::string("config.dat")}) {
    SCOPED_TRACE(target);
    EXPECT_EQ(accura(root, "batch " + job + "--in in --out out1 --json " + target).code, 1);
    EXPECT_EQ(accura(root, "compensate " + job + "--in in/seam.src --out out2 --json " + target).code, 1);
    EXPECT_EQ(accura(root, "check " + job + "--cell " + test::sourcePath("examples/cell/seam_cell.xml") + " --in in/seam.src --json " +
                               target).code,
              1);
  }
  // an --out that is a file: refused before any work (it used to fail program by program, exit 2)
  test::writeText(root + "/afile", "x");
  const CliRun f = accura(root, "batch " + job + "--in in --out afile");
  EXPECT_EQ(f.code, 1);
  EXPECT_NE(f.err.find("afile: expected an output directory (--out), found a file"), std::string::npos) << f.err;
  EXPECT_EQ(test::readText(root + "/model.xml"), model);
  EXPECT_EQ(test::readText(root + "/config.dat"), config);
  // the report on a program the run writes: batch writes the programs, not the report; compensate nothing
  const CliRun b = accura(root, "batch " + job + "--in in --out out3 --json out3/seam.src");
  EXPECT_EQ(b.code, 1);
  EXPECT_NE(b.err.find("is the output of seam.src"), std::string::npos) << b.err;
  EXPECT_EQ(test::readText(root + "/out3/seam.src").rfind("&ACCESS", 0), 0u);
  EXPECT_EQ(accura(root, "compensate " + job + "--in in/seam.src --out out4 --json out4/seam.src").code, 1);
  EXPECT_FALSE(fs::exists(root + "/out4/seam.src"));
}

// An --out that cannot be created (here: under a file) is refused before any work, as an --out
// that is a file is; before, every program was compensated and then failed on its own
// ("out/d0: cannot create the directory: Not a directory", exit 2 and one line per program).
TEST(Batch, AnOutputDirectoryThatCannotBeCreatedIsRefusedBeforeAnyWork) {
  const std::string root = test::tempDir("batch_out_under_file");
  test::copyText(test::golden("compensate/seam.src"), root + "/in/sub/seam.src");
  test::copyText(test::golden("compensate/seam.dat"), root + "/in/sub/seam.dat");
  test::writeText(root + "/afile", "x");
  BatchOptions o;
  o.job.calibrated = test::loadBundled("kuka_kr16");
  int calls = 0;
  std::string message;
  try {
    runBatch(root + "/in", root + "/afile/out", o, [&](const BatchFileResult&, int, int) { ++calls; });
  } catch (const calib::InputError& e) {
    message = e.what();
  }
  EXPECT_EQ(message, root + "/afile/out: cannot create the output directory (--out): " + root + "/afile is not a directory");
  EXPECT_EQ(calls, 0);  // no program was read
  EXPECT_EQ(test::readText(root + "/afile"), "x");
  // an --out that is a symbolic link to nothing: its directories cannot be created (before: the
  // check walked up to the link's directory and passed; every program then failed after its work)
  std::filesystem::create_symlink(root + "/nowhere", root + "/dangling");
  message.clear();
  try {
    runBatch(root + "/in", root + "/dangling", o, [&](const BatchFileResult&, int, int) { ++calls; });
  } catch (const calib::InputError& e) {
    message = e.what();
  }
  EXPECT_EQ(message, root + "/dangling: cannot create the output directory (--out): it is a symbolic link to " + root +
                         "/nowhere, which does not exist");
  EXPECT_EQ(calls, 0);
  EXPECT_FALSE(std::filesystem::exists(root + "/nowhere"));
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace accura::postproc
