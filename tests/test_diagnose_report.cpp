// The diagnosis report renders in headless Chromium (Debian's chromium) and its screenshot is
// not blank: the baseline's bar and the hottest cell of the error map are drawn in their
// colours. Skipped (GTEST_SKIP) only when no chromium executable can be found.
#include <dlfcn.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>

#include "accura/calib/diagnose.h"
#include "accura/calib/simulate.h"
#include "test_util.h"

namespace accura {
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

std::uint32_t be32(const std::uint8_t* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) | p[3];
}

// Minimal PNG reader: 8-bit RGB or RGBA, not interlaced (what Chromium writes). The zlib
// stream is inflated by the system's zlib (Debian's zlib1g, which every system has), loaded
// at run time. Returns false with *why on anything else.
bool decodePng(const std::string& bytes, Image* img, std::string* why) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(bytes.data());
  if (bytes.size() < 8 || std::memcmp(p, "\x89PNG\r\n\x1a\n", 8) != 0) return (*why = "not a PNG file", false);
  size_t pos = 8;
  int depth = 0, colour = -1, interlace = 0;
  std::string idat;
  while (pos + 12 <= bytes.size()) {
    const std::uint32_t len = be32(p + pos);
    const std::string type(bytes.data() + pos + 4, 4);
    if (pos + 12 + len > bytes.size()) return (*why = "truncated chunk " + type, false);
    const std::uint8_t* data = p + pos + 8;
    if (type == "IHDR") {
      img->width = static_cast<int>(be32(data));
      img->height = static_cast<int>(be32(data + 4));
      depth = data[8];
      colour = data[9];
      interlace = data[12];
    } else if (type == "IDAT") {
      idat.append(reinterpret_cast<const char*>(data), len);
    } else if (type == "IEND") {
      break;
    }
    pos += 12 + len;
  }
  if (depth != 8 || (colour != 2 && colour != 6) || interlace != 0)
    return (*why = "unsupported PNG (depth " + std::to_string(depth) + ", colour type " + std::to_string(colour) + ")", false);
  const int bpp = colour == 6 ? 4 : 3;
  const size_t stride = static_cast<size_t>(img->width) * bpp;
  std::vector<std::uint8_t> raw((stride + 1) * static_cast<size_t>(img->height));
  void* z = dlopen("libz.so.1", RTLD_NOW);
  if (!z) return (*why = "cannot load libz.so.1", false);
  using Uncompress = int (*)(unsigned char*, unsigned long*, const unsigned char*, unsigned long);
  auto uncompress = reinterpret_cast<Uncompress>(dlsym(z, "uncompress"));
  if (!uncompress) return (*why = "libz.so.1 has no uncompress", false);
  unsigned long out_len = raw.size();
  const int rc = uncompress(raw.data(), &out_len, reinterpret_cast<const unsigned char*>(idat.data()), idat.size());
  if (rc != 0 || out_len != raw.size()) return (*why = "zlib error " + std::to_string(rc), false);
  // undo the per-row filters (PNG spec, section 9)
  std::vector<std::uint8_t> cur(stride), prev(stride, 0);
  img->rgb.resize(static_cast<size_t>(img->width) * img->height * 3);
  for (int y = 0; y < img->height; ++y) {
    const std::uint8_t* row = raw.data() + static_cast<size_t>(y) * (stride + 1);
    const int filter = row[0];
    for (size_t x = 0; x < stride; ++x) {
      const int a = x >= static_cast<size_t>(bpp) ? cur[x - bpp] : 0;
      const int b = prev[x];
      const int c = x >= static_cast<size_t>(bpp) ? prev[x - bpp] : 0;
      int pred = 0;
      switch (filter) {
        case 0: pred = 0; break;
        case 1: pred = a; break;
        case 2: pred = b; break;
        case 3: pred = (a + b) / 2; break;
        case 4: {
          const int pp = a + b - c, pa = std::abs(pp - a), pb = std::abs(pp - b), pc = std::abs(pp - c);
          pred = (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
          break;
        }
        default: return (*why = "bad filter " + std::to_string(filter), false);
      }
      cur[x] = static_cast<std::uint8_t>(row[1 + x] + pred);
    }
    for (int x = 0; x < img->width; ++x)
      for (int k = 0; k < 3; ++k) img->rgb[(static_cast<size_t>(y) * img->width + x) * 3 + k] = cur[static_cast<size_t>(x) * bpp + k];
    std::swap(cur, prev);
  }
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
}  // namespace accura
