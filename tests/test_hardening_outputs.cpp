// Issue 14, outputs and silently wrong values: the reproducers of tests/data/hardening/ that
// lost a report to a non-UTF-8 byte (MIN8-MIN10), left a partial output set behind (D8), wrote
// over an input (D9), wrapped a 32-bit index (D10), read a blank attribute as zero (D11), copied
// a point name into a program as a statement (D13) or took 1e309 as infinity (D16). Each runs
// the command on a copy and asserts the outcome: the exit status, the located message, and the
// files written or left untouched.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <string>
#include <unistd.h>

#include "test_util.h"

namespace accura {
namespace {

namespace fs = std::filesystem;

/// A recursive copy of a folder of tests/data/hardening/ in a fresh temporary directory
/// (removed when the test ends).
class Copy {
 public:
  explicit Copy(const std::string& folder) {
    dir_ = fs::temp_directory_path() / ("accura_hardening_out_" + std::to_string(::getpid()) + "_" + folder);
    fs::remove_all(dir_);
    fs::copy(test::sourcePath("tests/data/hardening/" + folder), dir_, fs::copy_options::recursive);
    for (const auto& e : fs::recursive_directory_iterator(dir_))
      fs::permissions(e.path(), fs::perms::owner_read | fs::perms::owner_write | fs::perms::owner_exec,
                      fs::perm_options::add);
  }
  ~Copy() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string dir() const { return dir_.string(); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  bool exists(const std::string& name) const { return fs::exists(dir_ / name); }
  /// Every file (relative path -> bytes), the CLI's .stdout/.stderr aside.
  std::map<std::string, std::string> files() const {
    std::map<std::string, std::string> m;
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (name == ".stdout" || name == ".stderr") continue;
      m[fs::relative(e.path(), dir_).string()] = e.is_regular_file() ? test::readText(e.path().string()) : "<dir>";
    }
    return m;
  }

 private:
  fs::path dir_;
};

const std::string kReplacement = "\xEF\xBF\xBD";  // U+FFFD in UTF-8

TEST(HardeningOutputs, BatchReportQuotesANonUtf8ByteAsTheReplacementCharacter) {
  Copy c("MIN8_batch_json_non_utf8_exit4");
  const test::CliRun r = test::runAccuraIn(c.dir(), "batch --robot kuka_kr16 --in in --out out --json report.json");
  EXPECT_EQ(r.code, 2) << r.err;  // one program failed: batch's status for "some failed"
  ASSERT_TRUE(c.exists("report.json")) << r.err;
  const std::string json = test::readText(c.path("report.json"));
  EXPECT_NE(json.find("found '" + kReplacement + "'"), std::string::npos) << json;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
}

TEST(HardeningOutputs, IdentifySummaryKeepsACp1252ColumnName) {
  Copy c("MIN9_identify_json_cp1252_header_exit4_partial_output");
  fs::create_directories(c.path("out"));
  const test::CliRun r = test::runAccuraIn(
      c.dir(), "identify --robot kuka_kr16 --data data.csv --out out/model.xml --json out/summary.json --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string json = test::readText(c.path("out/summary.json"));
  EXPECT_NE(json.find("\"Temp " + kReplacement + "C\""), std::string::npos) << json;
  EXPECT_TRUE(c.exists("out/model.xml"));
}

TEST(HardeningOutputs, CompensateReportKeepsALatin1PointName) {
  Copy c("MIN10_compensate_json_cp1252_name_exit4_partial_output");
  const test::CliRun r = test::runAccuraIn(
      c.dir(), "compensate --robot kr16_real.xml --in seam.src --config '$config.dat' --out out --json out/report.json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(c.exists("out/seam.src"));
  const std::string json = test::readText(c.path("out/report.json"));
  EXPECT_NE(json.find(kReplacement), std::string::npos) << json;
}

TEST(HardeningOutputs, ASecondOutputThatCannotBeWrittenLeavesNoFirstOutput) {
  Copy c("D8_partial_output_second_output_fails");
  const auto before = c.files();
  const test::CliRun comp = test::runAccuraIn(
      c.dir(), "compensate --robot kr16_real.xml --in seam.src --config '$config.dat' --out out --json nodir/r.json");
  EXPECT_EQ(comp.code, 1) << comp.err;
  EXPECT_NE(comp.err.find("nodir/r.json: cannot write file"), std::string::npos) << comp.err;
  EXPECT_EQ(c.files(), before);  // no out/ directory, no program

  fs::create_directories(c.path("o2"));
  const test::CliRun id =
      test::runAccuraIn(c.dir(), "identify --robot kr16_real.xml --data fit.csv --out o2/m.xml --json nodir/s.json");
  EXPECT_EQ(id.code, 1) << id.err;
  EXPECT_NE(id.err.find("nodir/s.json: cannot write file"), std::string::npos) << id.err;
  EXPECT_FALSE(c.exists("o2/m.xml"));

  const test::CliRun sim = test::runAccuraIn(
      c.dir(), "simulate --robot kuka_kr16 --poses 10 --out o2/s.csv --truth nodir/t.xml");
  EXPECT_EQ(sim.code, 1) << sim.err;
  EXPECT_FALSE(c.exists("o2/s.csv"));
}

TEST(HardeningOutputs, AnOutputThatCannotBeWrittenIsRefusedBeforeTheFit) {
  Copy c("D8_partial_output_second_output_fails");
  const auto before = c.files();
  const test::CliRun id = test::runAccuraIn(c.dir(), "identify --robot kr16_real.xml --data fit.csv --out nodir/m.xml");
  EXPECT_EQ(id.code, 1) << id.err;
  EXPECT_NE(id.err.find("nodir/m.xml: cannot write file: the directory nodir does not exist"), std::string::npos) << id.err;
  EXPECT_EQ(id.out.find("solver:"), std::string::npos) << id.out;  // refused before the fit, not after it
  const test::CliRun onto = test::runAccuraIn(c.dir(), "identify --robot kr16_real.xml --data fit.csv --out m.xml --json fit.csv");
  EXPECT_EQ(onto.code, 1) << onto.err;
  EXPECT_NE(onto.err.find("fit.csv: the output would overwrite the input fit.csv"), std::string::npos) << onto.err;
  EXPECT_EQ(onto.out.find("solver:"), std::string::npos) << onto.out;
  const test::CliRun dg = test::runAccuraIn(c.dir(), "diagnose --robot kr16_real.xml --data fit.csv --json . --report r.html");
  EXPECT_EQ(dg.code, 1) << dg.err;
  EXPECT_NE(dg.err.find(".: cannot write file: it is a directory"), std::string::npos) << dg.err;
  EXPECT_EQ(dg.out.find("verdict"), std::string::npos) << dg.out;
  EXPECT_EQ(c.files(), before);
  // a stream is no file in a directory (/dev is not writable to a user): written into as before
  const test::CliRun to_stdout =
      test::runAccuraIn(c.dir(), "identify --robot kr16_real.xml --data fit.csv --quiet --out /dev/null --json /dev/stdout");
  EXPECT_EQ(to_stdout.code, 0) << to_stdout.err;
  EXPECT_NE(to_stdout.out.find("\"parameters\""), std::string::npos) << to_stdout.out;
}

TEST(HardeningOutputs, AnOutputOntoAnInputIsRefused) {
  Copy c("D9_output_overwrites_input");
  const auto before = c.files();
  const test::CliRun id = test::runAccuraIn(c.dir(), "identify --robot kuka_kr16 --data fit.csv --out fit.csv");
  EXPECT_EQ(id.code, 1) << id.err;
  EXPECT_NE(id.err.find("fit.csv: the output would overwrite the input fit.csv"), std::string::npos) << id.err;
  const test::CliRun sim =
      test::runAccuraIn(c.dir(), "simulate --robot r.xml --poses 20 --out s2.csv --truth r.xml");
  EXPECT_EQ(sim.code, 1) << sim.err;
  EXPECT_NE(sim.err.find("r.xml: the output would overwrite the input r.xml"), std::string::npos) << sim.err;
  const test::CliRun dia = test::runAccuraIn(c.dir(), "diagnose --robot kuka_kr16 --data fit.csv --json fit.csv");
  EXPECT_EQ(dia.code, 1) << dia.err;
  EXPECT_NE(dia.err.find("fit.csv: the output would overwrite the input fit.csv"), std::string::npos) << dia.err;
  EXPECT_EQ(c.files(), before);
}

TEST(HardeningOutputs, JointNumbersDoNotWrapAndMustExist) {
  Copy c("D10_krl_index_32bit_wrap");
  const test::CliRun wrap = test::runAccuraIn(
      c.dir(), "identify --robot kuka_kr16 --data fit.csv --out m.xml --params geometric,gear_periodic:j4294967297");
  EXPECT_EQ(wrap.code, 1) << wrap.err;
  EXPECT_NE(wrap.err.find("expected joints as j1+j2+..., found 'j4294967297'"), std::string::npos) << wrap.err;
  const test::CliRun seven = test::runAccuraIn(
      c.dir(), "identify --robot kuka_kr16 --data fit.csv --out m.xml --params geometric,gear_periodic:j7");
  EXPECT_EQ(seven.code, 1) << seven.err;
  EXPECT_NE(seven.err.find("parameter group 'gear_periodic': expected joints j1..j6 of KUKA KR 16, found j7"),
            std::string::npos)
      << seven.err;
  EXPECT_FALSE(c.exists("m.xml"));
}

TEST(HardeningOutputs, ABlankNumberAttributeIsNotZero) {
  Copy c("D11_whitespace_attribute_is_zero");
  const test::CliRun r = test::runAccuraIn(c.dir(), "fk --robot r.xml --q 0,-90,90,0,45,0");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.err.find("r.xml:14:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("attribute 'a_mm': expected a finite number, found ' '"), std::string::npos) << r.err;
}

TEST(HardeningOutputs, APointNameCannotCarryAStatement) {
  Copy c("D13_convert_xml_to_krl_injection");
  fs::create_directories(c.path("out"));
  const test::CliRun r =
      test::runAccuraIn(c.dir(), "convert --in cell_program.xml --config '$config.dat' --out out/p.src");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.err.find("attribute 'name': expected a point name (a letter, '_' or '$', then letters, digits, '_' or "
                       "'$'; at most 64 characters), found 'XPARK\\x0A$OUT[1]=TRUE'"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(c.exists("out/p.src"));
}

TEST(HardeningOutputs, ANumberBeyondADoubleIsLocated) {
  Copy c("D15_D16_krl_missing_dat_and_inf_speed");
  fs::create_directories(c.path("out"));
  const test::CliRun r = test::runAccuraIn(c.dir(), "convert --in inf.src --config '$config.dat' --out out/inf.xml");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.err.find("inf.src:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("expected a number within +-1.7e308, found '1e309'"), std::string::npos) << r.err;
  EXPECT_FALSE(c.exists("out/inf.xml"));
}

}  // namespace
}  // namespace accura
