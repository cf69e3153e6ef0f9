// The diagnosis report of `accura diagnose --report` as a deliverable (issue 17), rendered by
// headless Chromium (--dump-dom: the DOM the browser built from the page): its title, the
// header (date, accura's version, instrument, data files), the per-joint plots' y-axis label
// and unit, the identified parameters with sigmas, the error histogram, the per-axis split
// (checked against the data: the 3D RMS equals the root sum of the axes' squares) and the
// plain-language notes. Skipped (GTEST_SKIP) only when /usr/bin/chromium is absent.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <regex>

#include "test_util.h"

namespace accura::calib {
namespace {

std::string between(const std::string& s, const std::string& a, const std::string& b) {
  const size_t i = s.find(a);
  if (i == std::string::npos) return "";
  const size_t j = s.find(b, i + a.size());
  return s.substr(i + a.size(), j == std::string::npos ? std::string::npos : j - i - a.size());
}

TEST(CliReport, ChromiumRendersTheDeliverableElements) {
  const std::string chromium = "/usr/bin/chromium";
  if (access(chromium.c_str(), X_OK) != 0)
    GTEST_SKIP() << "/usr/bin/chromium is absent: install Debian's chromium (scripts/install-deps.sh) to render the report";
  const std::string dir = test::tempDir("cli_report");
  const std::string cli = std::string(ACCURA_CLI);
  ASSERT_EQ(std::system(("cd " + dir + " && " + cli + " simulate --robot kuka_kr16 --tool 80,40,150 --poses 80 --seed 4 "
                         "--effects geometric,joint_compliance --payloads 0,10 --out d.csv >/dev/null").c_str()), 0);
  ASSERT_EQ(std::system(("cd " + dir + " && " + cli + " diagnose --robot kuka_kr16 --tool 80,40,150 --data d.csv "
                         "--effects joint_compliance --noise-mm 0.02 --report r.html >/dev/null").c_str()), 0);
  const std::string cmd = "timeout 120 " + chromium + " --headless --no-sandbox --disable-gpu --user-data-dir=" + dir +
                          "/profile --dump-dom file://" + dir + "/r.html >" + dir + "/dom.html 2>/dev/null";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  const std::string dom = test::readText(dir + "/dom.html");
  ASSERT_GT(dom.size(), 1000u);
  EXPECT_NE(dom.find("<title>Remaining error of KUKA KR 16</title>"), std::string::npos);
  EXPECT_NE(dom.find("<h1>Remaining error of KUKA KR 16</h1>"), std::string::npos);
  // header
  const std::string meta = between(dom, "id=\"report-meta\"", "</table>");
  EXPECT_TRUE(std::regex_search(meta, std::regex("<th class=\"l\">date</th><td class=\"l\">20[0-9]{2}-[0-9]{2}-[0-9]{2} [0-9]{2}:[0-9]{2} UTC</td>")))
      << meta;
  EXPECT_NE(meta.find("<th class=\"l\">accura</th><td class=\"l\">accura 0.1.0</td>"), std::string::npos) << meta;
  EXPECT_NE(meta.find("<th class=\"l\">instrument</th><td class=\"l\">noise floor 0.0346 mm (3D RMS), from given: 0.02 mm per axis</td>"),
            std::string::npos) << meta;
  EXPECT_NE(meta.find("fit: d.csv"), std::string::npos) << meta;
  // every per-joint plot has its y-axis label with the unit (six joints)
  size_t labels = 0;
  for (size_t p = dom.find("held-out RMS (mm)</text>"); p != std::string::npos; p = dom.find("held-out RMS (mm)</text>", p + 1)) ++labels;
  EXPECT_EQ(labels, 6u);
  // parameters with sigmas: the station apart from the deviations
  const std::string params = between(dom, "id=\"parameters\"", "</table>");
  EXPECT_NE(params.find("<td class=\"l\">base_x</td>"), std::string::npos) << params;
  EXPECT_NE(params.find("tracker station (absolute)"), std::string::npos);
  EXPECT_NE(params.find("<td class=\"l\">j2_a</td>"), std::string::npos);
  EXPECT_NE(params.find("deviation from the nominal model"), std::string::npos);
  // the histogram: 20 bins whose counts add up to the 80 poses
  const std::string hist = between(dom, "id=\"histogram\"", "</svg>");
  int total = 0, bins = 0;
  const std::regex bin(" mm: ([0-9]+) poses</title>");
  for (std::sregex_iterator it(hist.begin(), hist.end(), bin), end; it != end; ++it, ++bins) total += std::stoi((*it)[1]);
  EXPECT_EQ(bins, 20);
  EXPECT_EQ(total, 80);
  // per-axis split: x, y, z and 3D; the 3D RMS is the root of the sum of the axes' squares
  const std::string axes = between(dom, "id=\"per-axis\"", "</table>");
  double rms[4];
  const char* rows[4] = {"x", "y", "z", "3D"};
  for (int a = 0; a < 4; ++a) {
    std::smatch m;
    ASSERT_TRUE(std::regex_search(axes, m, std::regex(std::string("<td class=\"l\">") + rows[a] + "</td><td>([0-9.]+)</td>"))) << axes;
    rms[a] = std::stod(m[1]);
  }
  EXPECT_NEAR(rms[3], std::sqrt(rms[0] * rms[0] + rms[1] * rms[1] + rms[2] * rms[2]), 2e-4);  // 4 decimals printed
  // the 3D RMS is the fit RMS of the same model identified independently by accura identify
  ASSERT_EQ(std::system(("cd " + dir + " && " + cli + " identify --robot kuka_kr16 --tool 80,40,150 --data d.csv "
                         "--holdout 0 --out cal.xml --json id.json >/dev/null").c_str()), 0);
  const auto id = nlohmann::json::parse(test::readText(dir + "/id.json"));
  EXPECT_NEAR(rms[3], id["fit"]["rms_mm"].get<double>(), 1e-4);
  // plain-language notes
  const std::string notes = between(dom, "id=\"glossary\"", "</dl>");
  for (const char* term : {"<dt>tau2 (tau1 .. tau6)</dt>", "<dt>dir4 (dir1 .. dir6)</dt>", "<dt>base_xy, base_rz</dt>",
                           "<dt>negative R²</dt>", "<dt>floor z</dt>"})
    EXPECT_NE(notes.find(term), std::string::npos) << term << "\n" << notes;
}

}  // namespace
}  // namespace accura::calib
