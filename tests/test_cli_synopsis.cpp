// The README's synopses against the parser (issue 17): every command has exactly one synopsis;
// a synopsis lists every option of the command's --help (but --chain, described once for every
// command with --robot) and nothing else; every accura command the README or
// scripts/example.sh runs uses only options of that command's --help and of its synopsis.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "test_util.h"

namespace accura::calib {
namespace {

const std::vector<std::string> kCommands = {"fk",       "simulate", "identify", "export",   "compensate",
                                            "batch",    "check",    "convert",  "diagnose", "selfcheck"};

std::set<std::string> optionsIn(const std::string& text) {
  std::set<std::string> out;
  static const std::regex opt("(^|[^a-z0-9-])(--[a-z][a-z0-9-]*)");
  for (std::sregex_iterator it(text.begin(), text.end(), opt), end; it != end; ++it) out.insert((*it)[2]);
  return out;
}

std::set<std::string> helpOptions(const std::string& command) {
  const std::string dir = test::tempDir("synopsis_help");
  const std::string cmd = std::string(ACCURA_CLI) + " " + command + " --help >" + dir + "/out 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << command;
  std::set<std::string> o = optionsIn(test::readText(dir + "/out"));
  o.erase("--help");
  return o;
}

struct Use {
  std::string command, text, where;
};

// `accura CMD ...` lines of the fenced blocks (a synopsis starts at column 0 with "accura ",
// continues on indented lines; a command run starts with "build/cli/accura " or "accura " and
// continues after a trailing backslash), and inline `accura CMD ...` spans of the prose.
void readmeUses(const std::string& text, std::vector<Use>* synopses, std::vector<Use>* runs) {
  std::istringstream in(text);
  bool fenced = false;
  int n = 0;
  Use* open = nullptr;
  bool continues = false;
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  static const std::regex start("^(build/cli/)?accura ([a-z]+)(\\s|$)");
  for (const std::string& l : lines) {
    ++n;
    if (l.rfind("```", 0) == 0) {
      fenced = !fenced;
      open = nullptr;
      continue;
    }
    if (!fenced) continue;
    std::smatch m;
    if (std::regex_search(l, m, start)) {
      const bool synopsis = !m[1].matched && l.find('[') != std::string::npos;
      auto* list = synopsis ? synopses : runs;
      list->push_back({m[2], l, "README.md:" + std::to_string(n)});
      open = &list->back();
      continues = !l.empty() && l.back() == '\\';
    } else if (open && (continues || (!l.empty() && l[0] == ' '))) {
      open->text += "\n" + l;
      continues = !l.empty() && l.back() == '\\';
    } else {
      open = nullptr;
    }
  }
  static const std::regex inline_span("`(build/cli/)?accura ([a-z]+)( [^`]*)?`");
  for (std::sregex_iterator it(text.begin(), text.end(), inline_span), end; it != end; ++it)
    runs->push_back({(*it)[2], it->str(), "README.md (inline)"});
}

TEST(ReadmeSynopsis, OneCompleteSynopsisPerCommandAndEveryUsedOptionExists) {
  std::vector<Use> synopses, runs;
  readmeUses(test::readText(test::sourcePath("README.md")), &synopses, &runs);
  // scripts/example.sh runs the commands as "$accura" CMD ... with backslash continuations
  {
    std::istringstream in(test::readText(test::sourcePath("scripts/example.sh")));
    int n = 0;
    Use* open = nullptr;
    for (std::string l; std::getline(in, l);) {
      ++n;
      static const std::regex start("^\"\\$accura\" ([a-z]+) ");
      std::smatch m;
      if (std::regex_search(l, m, start)) {
        runs.push_back({m[1], l, "scripts/example.sh:" + std::to_string(n)});
        open = &runs.back();
      } else if (open && !open->text.empty() && open->text.back() == '\\') {
        open->text += "\n" + l;
      } else {
        open = nullptr;
      }
    }
  }
  std::map<std::string, std::set<std::string>> help;
  for (const auto& c : kCommands) help[c] = helpOptions(c);

  std::map<std::string, std::vector<const Use*>> by_command;
  for (const Use& s : synopses) by_command[s.command].push_back(&s);
  for (const auto& c : kCommands) {
    ASSERT_EQ(by_command[c].size(), 1u) << "accura " << c << ": expected one synopsis in README.md, found "
                                        << by_command[c].size();
    const Use& s = *by_command[c][0];
    std::set<std::string> expected = help[c];
    expected.erase("--chain");  // README: "--chain ... works everywhere a robot does"
    EXPECT_EQ(optionsIn(s.text), expected) << s.where << ": the synopsis of accura " << c
                                           << " differs from accura " << c << " --help:\n" << s.text;
  }
  ASSERT_GT(runs.size(), 10u);
  for (const Use& r : runs) {
    if (!help.count(r.command)) {
      ADD_FAILURE() << r.where << ": accura " << r.command << " is not a command";
      continue;
    }
    const std::set<std::string> synopsis = optionsIn(by_command[r.command][0]->text);
    for (const std::string& o : optionsIn(r.text)) {
      EXPECT_TRUE(help[r.command].count(o)) << r.where << ": " << o << " is not an option of accura " << r.command;
      EXPECT_TRUE(synopsis.count(o) || o == "--chain")
          << r.where << ": " << o << " is used but not in the synopsis of accura " << r.command;
    }
  }
}

}  // namespace
}  // namespace accura::calib
