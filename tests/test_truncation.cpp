// Files cut short (a copy interrupted, a disk full, a transfer that stopped): every reader
// (KRL .src and .dat, RAPID, URScript, the XML program) refuses a truncated file with an error at
// the end of the file that says what the end of the file cut off ("expected ENDIF to close the IF
// at line 65 ..., found the end of the file"), never a program with fewer motions or points,
// which `compensate` would write as the output: the worst outcome, data loss.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/postproc/krl.h"
#include "accura/postproc/rapid.h"
#include "accura/postproc/urscript.h"
#include "accura/postproc/xml_program.h"
#include "test_util.h"

namespace accura::postproc {
namespace {

enum class Reader { kKrlSrc, kKrlDat, kRapid, kUrScript, kXml };

/// A bundled program (with its .dat for KRL) cut at `cut` bytes of the file `Reader` reads (.src
/// or .dat; the other file is whole), read as the command reads it.
struct Read {
  bool ok = false;
  calib::InputError error{"none"};
  std::string file;  // the name of the truncated file
  int end_line = 0;  // the line the reader reports the end of the cut text on (endLine)
};

std::string readAll(const std::string& rel) { return test::readText(test::sourcePath(rel)); }

int lineAtEnd(const std::string& text) { return 1 + static_cast<int>(std::count(text.begin(), text.end(), '\n')); }

/// The line each reader reports the end of `text` on: RAPID and URScript the line after the last
/// line end; KRL the last line (the one the last line end ends); XML the line of the last
/// character that is not white space.
int endLine(Reader reader, const std::string& text) {
  if (reader == Reader::kRapid || reader == Reader::kUrScript) return lineAtEnd(text);
  if (reader == Reader::kXml) {
    const size_t last = text.find_last_not_of(" \t\r\n");
    return last == std::string::npos ? 1 : lineAtEnd(text.substr(0, last + 1));
  }
  return !text.empty() && text.back() == '\n' ? lineAtEnd(text) - 1 : lineAtEnd(text);
}

Read readCut(Reader reader, const std::string& rel, const std::string& dat_rel, size_t cut, const std::string& dir) {
  Read r;
  const std::string name = std::filesystem::path(reader == Reader::kKrlDat ? dat_rel : rel).filename().string();
  const std::string whole = readAll(reader == Reader::kKrlDat ? dat_rel : rel);
  const std::string text = whole.substr(0, cut);
  r.file = dir + "/" + name;
  r.end_line = endLine(reader, text);
  try {
    switch (reader) {
      case Reader::kKrlSrc:
      case Reader::kKrlDat: {
        const std::string src = dir + "/" + std::filesystem::path(rel).filename().string();
        test::writeText(src, reader == Reader::kKrlSrc ? text : readAll(rel));
        if (!dat_rel.empty())
          test::writeText(dir + "/" + std::filesystem::path(dat_rel).filename().string(), reader == Reader::kKrlDat ? text : readAll(dat_rel));
        readKrl(src);
        break;
      }
      case Reader::kRapid: parseRapid(text, r.file); break;
      case Reader::kUrScript: parseUrScript(text, r.file); break;
      case Reader::kXml: parseXmlProgram(text, r.file); break;
    }
    r.ok = true;
  } catch (const calib::InputError& e) {
    r.error = e;
  }
  return r;
}

struct Case {
  Reader reader;
  std::string file, dat;  // the program (and its .dat)
  std::string before;     // cut before the last occurrence of this text...
  int keep;               // ...keeping this many of its bytes
  int line;               // the error's line: 0 where the reader puts the end of the cut text (endLine)
  std::string expected;   // a part of the message
};

TEST(Truncation, EveryReaderSaysWhatTheEndOfTheFileCutOff) {
  const std::string seam = "examples/seam.src", seam_dat = "examples/seam.dat";
  const std::string glue = "tests/golden/krl/spline/glue_bead.src", glue_dat = "tests/golden/krl/spline/glue_bead.dat";
  const std::string palette = "tests/golden/krl/krc2/palette.src", palette_dat = "tests/golden/krl/krc2/PALETTE.DAT";
  const std::string robodk = "tests/golden/krl/robodk/Pick_Place.src";
  const std::string mod = "examples/irb120_seam.mod", script = "examples/ur10_seam.script", xml = "tests/golden/xml/weld_seam.xml";
  const std::vector<Case> cases = {
      // KRL .src: the innermost open block, then the DEF
      {Reader::kKrlSrc, seam, seam_dat, "\r\nEND", 2, 0, "expected END closing the DEF at line 7, found the end of the file"},
      {Reader::kKrlSrc, seam, seam_dat, ";ENDFOLD\r\n\r\nEND", 0, 0, "expected END closing the DEF at line 7, found the end of the file"},
      {Reader::kKrlSrc, seam, seam_dat, "ENDIF", 0, 0,
       "expected ENDIF to close the IF at line 65 (and END closing the DEF at line 7), found the end of the file"},
      {Reader::kKrlSrc, seam, seam_dat, "ENDIF", 4, 0, "expected ENDIF to close the IF at line 65"},  // mid-keyword: ENDI
      {Reader::kKrlSrc, palette, palette_dat, "ENDFOR", 0, 0, "expected ENDFOR to close the FOR at line 28 (and END closing the DEF at line 5)"},
      {Reader::kKrlSrc, glue, glue_dat, "ENDLOOP", 0, 0, "expected ENDLOOP to close the LOOP at line 23 (and END closing the DEF at line 3)"},
      {Reader::kKrlSrc, glue, glue_dat, "  ENDIF", 0, 0, "expected ENDIF to close the IF at line 43 (and END closing the DEF at line 3)"},
      {Reader::kKrlSrc, seam, seam_dat, "CIRC XP4, XP5", 7, 0,
       "expected ',' between the auxiliary point and the end point of CIRC, found the end of the file"},
      {Reader::kKrlSrc, robodk, "", "Y -250.000,Z 650.000,A 170", 5, 0, "expected ',' or '}' after the value of Y, found the end of the file"},
      {Reader::kKrlSrc, robodk, "", "{A1 0.000,A2", 12, 0, "expected a value for A2, found the end of the file"},
      {Reader::kKrlSrc, seam, seam_dat, "DEF seam", 0, 0, "expected a KRL program (DEF name( ) ... END), found the end of the file before any DEF line"},
      {Reader::kKrlSrc, seam, seam_dat, "DEF seam", 3, 0, "expected END closing the DEF at line 7, found the end of the file"},
      // KRL .dat
      {Reader::kKrlDat, seam, seam_dat, "ENDDAT", 0, 0, "expected ENDDAT closing the data list, found the end of the file"},
      {Reader::kKrlDat, seam, seam_dat, "Z 150.0,A 160.0", 5, 0, "expected ',' or '}' after the value of Z, found the end of the file"},
      {Reader::kKrlDat, seam, seam_dat, "\" \",TQ_STATE FALSE}\r\nDECL E6POS XP6", 2, 0, "expected a closing '\"' for this string, found the end of the file"},
      {Reader::kKrlDat, seam, seam_dat, "DECL E6POS XP1", 0, 0, "expected ENDDAT closing the data list, found the end of the file"},
      {Reader::kKrlDat, glue, glue_dat, "DEFDAT", 0, 0, "expected a data list (DEFDAT name ... ENDDAT), found the end of the file"},
      // RAPID: the routine, then the module; a robtarget cut short
      {Reader::kRapid, mod, "", "  ENDPROC", 0, 0, "expected ENDPROC of the routine main (PROC at line 15), then ENDMODULE, found the end of the file"},
      {Reader::kRapid, mod, "", "  ENDPROC", 9, 0, "expected ENDMODULE, found the end of the file"},
      {Reader::kRapid, mod, "", "ENDMODULE", 0, 0, "expected ENDMODULE, found the end of the file"},
      {Reader::kRapid, mod, "", "  ENDPROC", 6, 0,
       "expected ';' at the end of the statement 'ENDP', then ENDPROC of the routine main (PROC at line 15), then ENDMODULE, found the end of the file"},
      {Reader::kRapid, mod, "", "ENDMODULE", 6, 0, "expected ';' at the end of the statement 'ENDMOD', then ENDMODULE, found the end of the file"},
      {Reader::kRapid, mod, "", "MoveL p20", 8, 0,
       "expected ';' at the end of the statement 'MoveL p2', then ENDPROC of the routine main (PROC at line 15), then ENDMODULE, found the end of the file"},
      {Reader::kRapid, mod, "", "[[220,120", 6, 0, "to close this '[', found the end of the file"},
      {Reader::kRapid, mod, "", "[9E9", 3, 0, "expected the digits of an exponent, found 'E' and then the end of the file"},
      {Reader::kRapid, mod, "", "MODULE irb120_seam", 7, 0, "expected the module name after MODULE, found the end of the file"},
      // URScript: the block and what it is
      {Reader::kUrScript, script, "", "end", 0, 0, "ur10_seam.script:1:1, found the end of the file (the block is the def ur10_seam opened there)"},
      {Reader::kUrScript, script, "", "movej(home", 10, 0, "expected ')' to close this '(', found the end of the file"},
      {Reader::kUrScript, script, "", "approach = ", 11, 0, "expected a value after '=', found the end of the file"},
      {Reader::kUrScript, script, "", "def ur10_seam", 2, 0,
       "expected a statement (a call such as de(...), an assignment, end), found 'de' and then the end of the file (a file cut short?)"},
      // XML: what the end of the file is inside
      {Reader::kXml, xml, "", "</program>", 0, 0, "expected well-formed XML, found the end of the file before the element <program> opened at 2:1"},
      {Reader::kXml, xml, "", "</program>", 3, 0, "found the end of the file inside the end tag </p at 59:1 (the end tag </program> of <program> at 2:1 is cut short)"},
      {Reader::kXml, xml, "", "vel_m_s=\"0.0200\">", 12, 0, "found the end of the file inside the value of an attribute of <circ at"},
      {Reader::kXml, xml, "", "  ;Make your modifications here", 8, 0, "found the end of the file before the element <passthrough> opened at"},
      {Reader::kXml, xml, "", "<motions>", 0, 0, "found the end of the file before the element <program> opened at 2:1"},
      {Reader::kXml, xml, "", "<?xml", 7, 0, "found the end of the file inside a declaration opened at 1:1 (its '?>' is missing)"},
  };
  const std::string dir = test::tempDir("truncation_cases");
  for (const Case& c : cases) {
    const std::string whole = readAll(c.reader == Reader::kKrlDat ? c.dat : c.file);
    const size_t at = whole.rfind(c.before);
    ASSERT_NE(at, std::string::npos) << c.before;
    const Read r = readCut(c.reader, c.file, c.dat, at + static_cast<size_t>(c.keep), dir);
    const std::string what = c.file + " cut before '" + c.before + "' + " + std::to_string(c.keep);
    ASSERT_FALSE(r.ok) << what << ": read as a shorter program";
    EXPECT_EQ(r.error.file(), r.file) << what << ": " << r.error.what();
    EXPECT_EQ(r.error.line(), c.line ? c.line : r.end_line) << what << ": " << r.error.what();
    EXPECT_NE(r.error.message().find(c.expected), std::string::npos) << what << ": " << r.error.what();
  }
}

// Line ends, line starts and the middle of lines of the bundled programs (every line of the
// RAPID, URScript and XML ones, every few of the KRL ones): an error naming the file
// cut short, never a program; at the end of the file unless a bracket or a construct opened
// earlier is what is missing (the error is then where it opened).
TEST(Truncation, NoBundledProgramCutShortIsReadAsAShorterOne) {
  struct File {
    Reader reader;
    std::string file, dat;
    int stride;  // every stride-th line (a KRL read takes milliseconds: the test stays under a second)
  };
  const std::vector<File> files = {
      {Reader::kKrlSrc, "examples/seam.src", "examples/seam.dat", 9},
      {Reader::kKrlDat, "examples/seam.src", "examples/seam.dat", 4},
      {Reader::kKrlSrc, "tests/golden/krl/spline/glue_bead.src", "tests/golden/krl/spline/glue_bead.dat", 12},
      {Reader::kKrlSrc, "tests/golden/krl/robodk/Pick_Place.src", "", 7},
      {Reader::kRapid, "examples/irb120_seam.mod", "", 1},
      {Reader::kUrScript, "examples/ur10_seam.script", "", 1},
      {Reader::kXml, "tests/golden/xml/weld_seam.xml", "", 1},
  };
  const std::string dir = test::tempDir("truncation_sweep");
  for (const File& f : files) {
    const std::string whole = readAll(f.reader == Reader::kKrlDat ? f.dat : f.file);
    // the last line's end is where a whole file may end: not cut short
    size_t last = whole.size();
    while (last > 0 && (whole[last - 1] == '\n' || whole[last - 1] == '\r')) --last;
    std::vector<size_t> cuts;
    for (size_t line = 0, number = 0; line < last; ++number) {
      const size_t nl = std::min(whole.find('\n', line), last);
      if (number % static_cast<size_t>(f.stride) == 0) {
        cuts.push_back(line);
        cuts.push_back(line + (nl - line) / 2);
        cuts.push_back(nl);
      }
      line = nl + 1;
    }
    for (const size_t cut : cuts) {
      if (cut >= last) continue;
      const Read r = readCut(f.reader, f.file, f.dat, cut, dir);
      const std::string what = (f.reader == Reader::kKrlDat ? f.dat : f.file) + " cut at byte " + std::to_string(cut);
      ASSERT_FALSE(r.ok) << what << ": read as a shorter program";
      EXPECT_EQ(r.error.file(), r.file) << what << ": " << r.error.what();
      EXPECT_LE(r.error.line(), r.end_line) << what << ": " << r.error.what();
      EXPECT_EQ(r.error.message().rfind("expected ", 0), 0u) << what << ": " << r.error.what();
      if (f.reader == Reader::kKrlSrc) {
        EXPECT_EQ(r.error.message().find("DEFDAT"), std::string::npos) << what << ": " << r.error.what();
      }
    }
  }
}

// A .src cut short before its DEF, of a module whose DEF and DEFDAT are named apart from the
// file (prog1.src: DEF weld, DEFDAT weld): the error is the missing DEF, not "the data list of
// another module" (the .dat was checked against a DEF the cut took away).
TEST(Truncation, ASrcCutBeforeItsDefIsNotADataListOfAnotherModule) {
  const std::string dir = test::tempDir("truncation_defdat");
  test::writeText(dir + "/prog1.src", "&ACCESS RVP\n&REL 1\n");
  test::writeText(dir + "/prog1.dat", "DEFDAT weld\nDECL E6POS XP1={X 1000,Y 0,Z 800,A 0,B 90,C 0}\nENDDAT\n");
  try {
    readKrl(dir + "/prog1.src");
    FAIL() << "read";
  } catch (const calib::InputError& e) {
    EXPECT_EQ(e.file(), dir + "/prog1.src") << e.what();
    EXPECT_EQ(e.line(), 2) << e.what();
    EXPECT_EQ(e.message(), "expected a KRL program (DEF name( ) ... END), found the end of the file before any DEF line");
  }
  // whole, the module is read (DEFDAT names its DEF)
  test::writeText(dir + "/prog1.src", "&ACCESS RVP\n&REL 1\nDEF weld( )\nPTP XP1\nEND\n");
  EXPECT_EQ(readKrl(dir + "/prog1.src").motions.size(), 1u);
}

// A .src cut short within its leading comments (nothing but the & header, comments, folds and
// blank lines before the cut) was read as a program without a name or motions, and `compensate`
// wrote it as the output: the program lost without a word.
TEST(Truncation, ASrcOfCommentsOnlyIsNotWrittenAsAProgram) {
  const std::string dir = test::tempDir("truncation_comments");
  test::writeText(dir + "/p.src", "; generated by an OLP\r\n;FOLD header\r\n\r\n");
  test::writeText(dir + "/p.dat", "DEFDAT p\r\nENDDAT\r\n");
  const test::CliRun run = test::runAccuraIn(dir, "compensate --robot kuka_kr16 --in p.src --out out");
  EXPECT_EQ(run.code, 1) << run.out << run.err;
  EXPECT_NE(run.err.find("p.src:3:1: expected a KRL program (DEF name( ) ... END), found the end of the file before any DEF line"), std::string::npos)
      << run.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/p.src"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/p.dat"));
}

// A script of statements without a def, or a def cut in its first word ('de'), cut inside a
// name: the bare name was read as a statement and the script written as a shorter one. A bare
// name the script defines or uses elsewhere, and the keyword statements, are still read.
TEST(Truncation, AScriptCutInsideANameIsNotAShorterScript) {
  const std::string text =
      "movel(p[-0.35, 0.86, 0.2, 3.14, 0, 0], a=1.2, v=0.25)\nset_digital_out(0, True)\nmovel(p[-0.35, 0.86, 0.3, 3.14, 0, 0], a=1.2, v=0.25)\n";
  for (const std::string& cut : {std::string("m"), std::string("de"), text.substr(0, text.find("set_digital_out") + 6),
                                 text.substr(0, text.rfind("movel") + 3)}) {
    try {
      parseUrScript(cut, "cut.script");
      ADD_FAILURE() << cut << ": read";
    } catch (const calib::InputError& e) {
      EXPECT_EQ(e.line(), lineAtEnd(cut)) << e.what();
      EXPECT_NE(e.message().find("' and then the end of the file (a file cut short?)"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(parseUrScript("x = 1\nx", "x.script").motions.size(), 0u);  // a variable of the script
  EXPECT_EQ(parseUrScript("movel(p[-0.35, 0.86, 0.2, 3.14, 0, 0])\nhalt", "h.script").motions.size(), 1u);
  EXPECT_EQ(parseUrScript("movel(p[-0.35, 0.86, 0.2, 3.14, 0, 0])\nhalt # stop", "h.script").motions.size(), 1u);
}

// Control structures of each kind cut before their end (a program written for the test).
TEST(Truncation, TheInnermostOpenBlockIsNamed) {
  const std::string text =
      "DEF p( )\n"                                  // 1
      "FOR I=1 TO 3\n  $OUT[I]=TRUE\nENDFOR\n"       // 2-4
      "WHILE $IN[1]\n  WAIT SEC 1\nENDWHILE\n"       // 5-7
      "REPEAT\n  WAIT SEC 1\nUNTIL $IN[2]\n"         // 8-10
      "SWITCH N\nCASE 1\n  $OUT[3]=TRUE\nENDSWITCH\n"  // 11-14
      "LOOP\n  IF $IN[3] THEN\n    EXIT\n  ENDIF\nENDLOOP\n"  // 15-19
      "END\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"ENDFOR", "expected ENDFOR to close the FOR at line 2 (and END closing the DEF at line 1), found the end of the file"},
      {"ENDWHILE", "expected ENDWHILE to close the WHILE at line 5 (and END closing the DEF at line 1), found the end of the file"},
      {"UNTIL", "expected UNTIL to close the REPEAT at line 8 (and END closing the DEF at line 1), found the end of the file"},
      {"ENDSWITCH", "expected ENDSWITCH to close the SWITCH at line 11 (and END closing the DEF at line 1), found the end of the file"},
      {"  ENDIF", "expected ENDIF to close the IF at line 16 (and END closing the DEF at line 1), found the end of the file"},
      {"ENDLOOP", "expected ENDLOOP to close the LOOP at line 15 (and END closing the DEF at line 1), found the end of the file"},
  };
  const std::string dir = test::tempDir("truncation_blocks");
  for (const auto& [before, message] : cases) {
    const std::string cut = text.substr(0, text.find(before));
    test::writeText(dir + "/p.src", cut);
    try {
      readKrl(dir + "/p.src");
      ADD_FAILURE() << before << ": read";
    } catch (const calib::InputError& e) {
      EXPECT_EQ(e.line(), endLine(Reader::kKrlSrc, cut)) << e.what();
      EXPECT_EQ(e.message(), message) << e.what();
    }
  }
}

}  // namespace
}  // namespace accura::postproc
