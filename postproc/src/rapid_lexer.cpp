// RAPID tokens, pose conversions, predefined data and ABB confdata (rapid.h, rapid_internal.h).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>

#include "accura/calib/errors.h"
#include "accura/calib/ik.h"
#include "rapid_internal.h"

namespace accura::postproc {
namespace rapid_detail {
namespace {

bool isDigit(char c) { return std::isdigit(static_cast<unsigned char>(c)) != 0; }
bool isIdentStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) || c == '_'; }
bool isIdentChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

SourceLocation locate(const std::vector<size_t>& line_starts, const std::string& path, size_t off) {
  const auto it = std::upper_bound(line_starts.begin(), line_starts.end(), off);
  const size_t line = static_cast<size_t>(it - line_starts.begin());
  SourceLocation l;
  l.file = path;
  l.line = static_cast<int>(line);
  l.column = static_cast<int>(off - line_starts[line - 1]) + 1;
  return l;
}

std::vector<Tok> lexRapid(const std::string& s, const std::string& path) {
  std::vector<size_t> starts{0};
  for (size_t i = 0; i < s.size(); ++i)
    if (s[i] == '\n') starts.push_back(i + 1);
  auto fail = [&](size_t off, const std::string& msg) {
    const SourceLocation l = locate(starts, path, off);
    throw calib::InputError(l.file, l.line, l.column, msg);
  };
  std::vector<Tok> toks;
  size_t i = 0;
  bool line_start = true;
  while (i < s.size()) {
    const char c = s[i];
    if (c == '\0') fail(i, "expected a RAPID text file, found a NUL byte (binary file?)");
    if (line_start && s.compare(i, 3, "%%%") == 0) {  // .prg header block %%% ... %%%
      size_t j = s.find("%%%", i + 3);
      if (j == std::string::npos) fail(i, "expected the '%%%' that closes this header, found the end of the file");
      i = j + 3;
      continue;
    }
    if (c == '!') {
      while (i < s.size() && s[i] != '\n') ++i;
      continue;
    }
    if (c == '\n' || c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
      if (c == '\n') line_start = true;
      ++i;
      continue;
    }
    line_start = false;
    Tok t;
    t.b = i;
    if (isDigit(c) || (c == '.' && i + 1 < s.size() && isDigit(s[i + 1]))) {
      size_t j = i;
      while (j < s.size() && isDigit(s[j])) ++j;
      if (j < s.size() && s[j] == '.') ++j;
      while (j < s.size() && isDigit(s[j])) ++j;
      if (j < s.size() && (s[j] == 'e' || s[j] == 'E')) {
        size_t k = j + 1;
        if (k < s.size() && (s[k] == '+' || s[k] == '-')) ++k;
        if (k >= s.size() || !isDigit(s[k]))
          fail(j, "expected the digits of an exponent, found '" + s.substr(j, std::min<size_t>(k + 1, s.size()) - j) + "'");
        while (k < s.size() && isDigit(s[k])) ++k;
        j = k;
      }
      if (j < s.size() && isIdentStart(s[j])) fail(j, "expected an operator or a separator after the number " + s.substr(i, j - i) + ", found '" + s[j] + "'");
      t.kind = Tok::Kind::kNumber;
      t.e = j;
      t.s = s.substr(i, j - i);
      t.num = std::strtod(t.s.c_str(), nullptr);
      if (!std::isfinite(t.num)) fail(i, "expected a finite number, found '" + t.s + "'");
    } else if (isIdentStart(c)) {
      size_t j = i;
      while (j < s.size() && isIdentChar(s[j])) ++j;
      t.kind = Tok::Kind::kIdent;
      t.e = j;
      t.s = s.substr(i, j - i);
    } else if (c == '"') {
      size_t j = i + 1;
      while (j < s.size() && s[j] != '\n' && !(s[j] == '"' && !(j + 1 < s.size() && s[j + 1] == '"'))) j += s[j] == '"' ? 2 : 1;
      if (j >= s.size() || s[j] != '"') fail(i, "expected the closing '\"' of this string on its line, found the end of the line");
      t.kind = Tok::Kind::kString;
      t.e = j + 1;
      t.s = s.substr(i, t.e - i);
    } else {
      size_t n = 1;
      if (i + 1 < s.size() && ((c == ':' && s[i + 1] == '=') || (c == '<' && (s[i + 1] == '>' || s[i + 1] == '=')) || (c == '>' && s[i + 1] == '=')))
        n = 2;
      t.kind = Tok::Kind::kOp;
      t.e = i + n;
      t.s = s.substr(i, n);
    }
    t.u = upper(t.s);
    i = t.e;
    toks.push_back(std::move(t));
  }
  return toks;
}

Eigen::Isometry3d poseOf(const double xyz[3], const double wxyz[4]) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(xyz[0], xyz[1], xyz[2]);
  T.linear() = Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]).normalized().toRotationMatrix();
  return T;
}

std::array<double, 4> quaternionNear(const Eigen::Matrix3d& R, const double near[4]) {
  const Eigen::Quaterniond q(R);
  std::array<double, 4> v{q.w(), q.x(), q.y(), q.z()};
  double dot = 0;
  for (int k = 0; k < 4; ++k) dot += v[static_cast<size_t>(k)] * near[k];
  if (dot < 0)
    for (double& x : v) x = -x;
  return v;
}

std::optional<double> predefinedZoneMm(const std::string& u) {
  if (u == "Z0") return 0.3;
  static const int radii[] = {1, 5, 10, 15, 20, 30, 40, 50, 60, 80, 100, 150, 200};
  for (int r : radii)
    if (u == "Z" + std::to_string(r)) return static_cast<double>(r);
  return std::nullopt;
}

std::optional<double> predefinedSpeedMmS(const std::string& u) {
  static const int speeds[] = {5, 10, 20, 30, 40, 50, 60, 80, 100, 150, 200, 300, 400, 500, 600, 800, 1000, 1500, 2000, 2500, 3000, 4000, 5000, 6000, 7000};
  for (int v : speeds)
    if (u == "V" + std::to_string(v)) return static_cast<double>(v);
  return std::nullopt;
}

}  // namespace rapid_detail

std::array<int, 4> abbConfdata(const calib::RobotModel& model, const Eigen::VectorXd& q) {
  if (q.size() != model.dof() || q.size() < 6) throw calib::ArgumentError("abbConfdata: expected the 6 joints of the model");
  const calib::Configuration c = calib::kukaConfiguration(model, q);
  auto quadrant = [&](int k) { return static_cast<int>(std::floor(q[k] / 90.0)); };
  int cfx = 0;
  if (c.status >= 0) cfx = ((c.status & 1) ? 4 : 0) + ((c.status & 2) ? 0 : 2) + ((c.status & 4) ? 1 : 0);
  return {quadrant(0), quadrant(3), quadrant(5), cfx};
}

int kukaStatusOfCfx(int cfx) {
  if (cfx < 0 || cfx > 7) return -1;
  return ((cfx & 4) ? 1 : 0) + ((cfx & 2) ? 0 : 2) + ((cfx & 1) ? 4 : 0);
}

}  // namespace accura::postproc
