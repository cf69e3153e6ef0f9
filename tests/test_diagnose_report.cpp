// The diagnosis report renders in headless Chromium (Debian's chromium) and its screenshot is
// not blank: the baseline's bar and the hottest cell of the error map are drawn in their
// colours. Skipped (GTEST_SKIP) only when no chromium executable can be found.
#include <gtest/gtest.h>
#include <png.h>
#include <sys/wait.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>

#include "accura/calib/diagnose.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura::calib {
namespace {

std::string findChromium() {
  const char* env = std::getenv("ACCURA_CHROMIUM");
  if (env && *env) return env;
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "/usr/bin:/bin";
  dirs += ":/usr/bin:/usr/lib/chromium";
  for (const char* name : {"chromium", "chromium-browser", "chromium-headless-shell", "google-chrome"}) {
    size_t start = 0;
    while (start <= dirs.size()) {
      const size_t end = dirs.find(':', start);
      const std::string dir = dirs.substr(start, end == std::string::npos ? std::string::npos : end - start);
      const std::string candidate = (dir.empty() ? "." : dir) + "/" + name;
      if (access(candidate.c_str(), X_OK) == 0) return candidate;
      if (end == std::string::npos) break;
      start = end + 1;
    }
  }
  return "";
}

// A decoded 8-bit RGB(A) PNG.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // 3 bytes per pixel
};

// Decodes a PNG file (any format libpng reads) into 8-bit RGB. Returns false with *why.
bool decodePng(const std::string& bytes, Image* img, std::string* why) {
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size()))
    return (*why = std::string("not a readable PNG: ") + image.message, false);
  image.format = PNG_FORMAT_RGB;
  img->width = static_cast<int>(image.width);
  img->height = static_cast<int>(image.height);
  img->rgb.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, img->rgb.data(), 0, nullptr))
    return (*why = std::string("PNG decoding failed: ") + image.message, false);
  return true;
}

int countNear(const Image& img, int r, int g, int b, int tol) {
  int n = 0;
  for (size_t i = 0; i + 2 < img.rgb.size(); i += 3)
    if (std::abs(img.rgb[i] - r) <= tol && std::abs(img.rgb[i + 1] - g) <= tol && std::abs(img.rgb[i + 2] - b) <= tol) ++n;
  return n;
}

TEST(DiagnoseReport, RendersInHeadlessChromiumAndIsNotBlank) {
  const std::string chromium = findChromium();
  if (chromium.empty()) GTEST_SKIP() << "no chromium executable found (install Debian's chromium: scripts/install-deps.sh)";
  RobotModel nominal = test::loadBundled("kuka_kr16");
  nominal.nominal.T_flange_tcp = toIsometry(XyzAbc{80, 40, 150, 0, 0, 0});
  SimulateOptions o;
  o.poses = 200;
  o.seed = 3;
  o.effects = {"geometric", "joint_compliance"};
  o.payloads_kg = {0, 8, 16};
  o.tool = {80, 40, 150, 0, 0, 0};
  o.set_tool = true;
  o.write_std = true;
  const MeasurementSet fit = simulateMeasurements(perturbModel(nominal, o), o);
  const Diagnosis d = diagnose(nominal, fit, nullptr, DiagnoseOptions{});
  const std::string dir = test::tempDir("diag_report");
  test::writeText(dir + "/diag.html", diagnosisHtml(d));
  const std::string cmd = "timeout 120 " + chromium + " --headless --no-sandbox --disable-gpu --hide-scrollbars " +
                          "--user-data-dir=" + dir + "/profile --window-size=1200,2600 --screenshot=" + dir +
                          "/shot.png file://" + dir + "/diag.html >" + dir + "/log 2>&1";
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << cmd << "\n" << test::readText(dir + "/log");
  Image img;
  std::string why;
  ASSERT_TRUE(decodePng(test::readText(dir + "/shot.png"), &img, &why)) << why;
  EXPECT_EQ(img.width, 1200);
  EXPECT_EQ(img.height, 2600);
  const int total = img.width * img.height;
  const int white = countNear(img, 255, 255, 255, 3);
  EXPECT_GT(total - white, total / 10) << "more than 90% of the page is white";
  std::set<std::uint32_t> colours;
  for (size_t i = 0; i + 2 < img.rgb.size(); i += 3)
    colours.insert((std::uint32_t(img.rgb[i]) << 16) | (std::uint32_t(img.rgb[i + 1]) << 8) | img.rgb[i + 2]);
  EXPECT_GT(colours.size(), 50u);
  // the geometric model's bars (#c0392b, two bars of about 420 x 16 px at full scale) and the
  // hottest cell of the error map (#fde725, the top of the colour ramp, about 37 x 37 px)
  EXPECT_GT(countNear(img, 0xc0, 0x39, 0x2b, 8), 4000);
  EXPECT_GT(countNear(img, 0xfd, 0xe7, 0x25, 8), 900);
}

}  // namespace
}  // namespace accura::calib
