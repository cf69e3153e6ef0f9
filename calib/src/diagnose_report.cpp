// accura: the diagnosis as JSON, as a self-contained HTML page (inline SVG) and as text.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "accura/calib/json_text.h"
#include "accura/calib/diagnose.h"
#include "accura/calib/text.h"

namespace accura::calib {
namespace {

using nlohmann::ordered_json;

ordered_json num(double v) { return std::isfinite(v) ? ordered_json(v) : ordered_json(nullptr); }

ordered_json arrayOf(const std::vector<double>& v) {
  ordered_json a = ordered_json::array();
  for (double x : v) a.push_back(num(x));
  return a;
}

std::string f(const char* format, double v) {
  if (!std::isfinite(v)) return "-";
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string jointsText(const std::vector<int>& joints) {
  if (joints.empty()) return "";
  std::string s;
  for (int j : joints) s += (s.empty() ? "j" : ",j") + std::to_string(j);
  return s;
}

ordered_json jointNames(const Diagnosis& d, const std::vector<int>& joints) {
  ordered_json a = ordered_json::array();
  for (int j : joints)
    a.push_back(j >= 1 && j <= static_cast<int>(d.joint_names.size()) ? d.joint_names[static_cast<size_t>(j - 1)] : "?");
  return a;
}

ordered_json evidenceJson(const Diagnosis& d, const EffectEvidence& e) {
  ordered_json j;
  j["effect"] = e.effect;
  j["joints"] = e.joints;
  j["joint_names"] = jointNames(d, e.joints);
  j["testable"] = e.testable;
  j["significant"] = e.significant;
  j["validation_rms_before_mm"] = num(e.rms_before_mm);
  j["validation_rms_after_mm"] = num(e.rms_after_mm);
  j["validation_max_after_mm"] = num(e.max_after_mm);
  j["gain_percent"] = num(100 * e.gain);
  j["z"] = num(e.z);
  j["p_value"] = num(e.p_value);
  j["delta_bic"] = num(e.delta_bic);
  ordered_json ps = ordered_json::array();
  for (const EffectParameter& p : e.parameters)
    ps.push_back({{"name", p.name},
                  {"value", num(p.value)},
                  {"sigma", num(p.sigma)},
                  {"unit", p.unit},
                  {"value_over_sigma", num(p.sigma > 0 ? p.value / p.sigma : NAN)}});
  j["parameters"] = ps;
  ordered_json pj = ordered_json::array();
  for (const JointEvidence& je : e.per_joint)
    pj.push_back({{"joint", je.joint},
                  {"validation_rms_after_mm", num(je.rms_after_mm)},
                  {"gain_percent", num(100 * je.gain)},
                  {"z", num(je.z)},
                  {"p_value", num(je.p_value)}});
  j["per_joint"] = pj;
  j["note"] = e.note;
  j["implausible"] = e.implausible;
  j["blocked_gain_percent"] = num(100 * e.blocked_gain);
  j["blocked_scheme"] = e.blocked_scheme;
  ordered_json cov = ordered_json::array();
  for (const Coverage& c : e.coverage)
    cov.push_back({{"variable", c.variable}, {"unit", c.unit}, {"min", num(c.lo)}, {"max", num(c.hi)}});
  j["coverage"] = cov;
  j["params"] = e.params;
  return j;
}

std::string rowRef(const std::string& file, int line, int index) {
  return file + ":" + (line > 0 ? std::to_string(line) : "row " + std::to_string(index + 1));
}

// A fit row of the diagnosis by its own file (several data sets) or the data file.
std::string rowRef(const Diagnosis& d, int line, int index) {
  const std::string& file =
      index >= 0 && static_cast<size_t>(index) < d.row_files.size() ? d.row_files[static_cast<size_t>(index)] : d.data_file;
  return rowRef(file, line, index);
}

// A row of a glitch (RepeatPair): row a, or row b of a pair.
std::string glitchRowRef(const Diagnosis& d, const RepeatPair& p, bool a) {
  if (!p.file.empty()) return a ? rowRef(p.file, p.line_a, p.index_a) : rowRef(p.file, p.line_b, p.index_b);
  if (p.validation) return a ? rowRef(d.validation_file, p.line_a, p.index_a) : rowRef(d.validation_file, p.line_b, p.index_b);
  return a ? rowRef(d, p.line_a, p.index_a) : rowRef(d, p.line_b, p.index_b);
}

// A glitch in words: the pair, or the odd row against its configuration's centre.
std::string glitchText(const Diagnosis& d, const RepeatPair& p) {
  if (p.index_b >= 0) return glitchRowRef(d, p, true) + " / " + glitchRowRef(d, p, false);
  return glitchRowRef(d, p, true) + " (against the centre of its configuration's " + std::to_string(p.measurements) +
         " measurements)";
}

ordered_json floorsJson(const Diagnosis& d) {
  const Floors& fl = d.floors;
  ordered_json j;
  j["instrument_rms_3d_mm"] = num(fl.instrument_known ? fl.instrument_rms_mm : NAN);
  j["repeatability"] = {{"tolerance", num(fl.repeat_tol)},
                        {"tolerance_unit", "deg (mm for prismatic joints), every joint"},
                        {"configurations", fl.repeat_groups},
                        {"pairs", fl.repeat_pairs},
                        {"validation_configurations", fl.repeat_groups_validation},
                        {"validation_pairs", fl.repeat_pairs_validation},
                        {"rows_apart_min", fl.repeat_min_gap},
                        {"rows_apart_max", fl.repeat_max_gap},
                        {"median_pair_distance_mm", num(fl.median_pair_mm)},
                        {"std_per_axis_mm", num(fl.repeat_std_axis_mm)},
                        {"rms_3d_mm", num(fl.repeat_rms_mm)},
                        {"degrees_of_freedom", num(fl.repeat_dof)}};
  j["judged_against"] = d.noise_floor_source;
  ordered_json dups = ordered_json::array();
  for (const RepeatPair& p : fl.duplicated_rows)
    dups.push_back({{"row", glitchRowRef(d, p, true)}, {"same_as", glitchRowRef(d, p, false)}});
  j["duplicated_rows"] = dups;
  j["glitch_threshold_mm"] = num(fl.glitch_threshold_mm);
  ordered_json g = ordered_json::array();
  for (const RepeatPair& p : fl.glitches) {
    ordered_json rows = ordered_json::array({glitchRowRef(d, p, true)});
    if (p.index_b >= 0) rows.push_back(glitchRowRef(d, p, false));
    g.push_back({{"rows", rows},
                 {"distance_mm", num(p.distance_mm)},
                 {"against", p.index_b >= 0 ? "pair" : "configuration centre"},
                 {"measurements", p.measurements},
                 {"orientation_jump_deg", num(p.rotation_deg)}});
  }
  j["glitches"] = g;
  return j;
}

ordered_json spectraJson(const Diagnosis& d) {
  ordered_json a = ordered_json::array();
  for (const JointSpectrum& sp : d.spectra)
    a.push_back({{"joint", sp.joint},
                 {"range_deg", num(sp.range_deg)},
                 {"cycles_per_rev", sp.cycles},
                 {"amplitude_urad_before", arrayOf(sp.amplitude_urad_before)},
                 {"amplitude_urad_after", arrayOf(sp.amplitude_urad_after)},
                 {"peak_before", {{"cycles_per_rev", sp.peak_cycles_before},
                                  {"amplitude_urad", num(sp.peak_amplitude_urad_before)},
                                  {"p_value", num(sp.peak_p_before)}}},
                 {"peak_after", {{"cycles_per_rev", sp.peak_cycles},
                                 {"amplitude_urad", num(sp.peak_amplitude_urad)},
                                 {"share", num(sp.peak_share)},
                                 {"p_value", num(sp.peak_p)}}}});
  return a;
}

ordered_json statsJson(const HeldOutStats& s, double floor_mm) {
  ordered_json j;
  j["n"] = s.n;
  j["validation_rms_mm"] = num(s.rms_mm);
  j["validation_max_mm"] = num(s.max_mm);
  j["validation_mean_mm"] = num(s.mean_mm);
  j["validation_p95_mm"] = num(s.p95_mm);
  j["expected_rms_at_noise_floor_mm"] = num(s.expected_rms_mm);
  j["rms_over_noise_floor"] = num(floor_mm > 0 ? s.rms_mm / floor_mm : NAN);
  j["floor_z"] = num(s.floor_z);
  j["floor_p"] = num(s.floor_p);
  return j;
}


// ---------------------------------------------------------------------------------------
// HTML helpers

std::string esc(const std::string& s) { return xmlEscape(s); }

// Colour of t in [0, 1]: a perceptual ramp from dark blue through green to yellow.
std::string ramp(double t) {
  static const double stops[5][3] = {{68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  if (!std::isfinite(t)) return "#e6e6e6";
  t = std::clamp(t, 0.0, 1.0) * 4;
  const int k = std::min(3, static_cast<int>(t));
  const double u = t - k;
  char buf[16];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", static_cast<int>(stops[k][0] + u * (stops[k + 1][0] - stops[k][0])),
                static_cast<int>(stops[k][1] + u * (stops[k + 1][1] - stops[k][1])),
                static_cast<int>(stops[k][2] + u * (stops[k + 1][2] - stops[k][2])));
  return buf;
}

std::string heatmap(const FieldMap& fm, const std::vector<double>& values, double vmax, const std::string& title) {
  const int g = static_cast<int>(fm.x_edges_mm.size()) - 1;
  const int W = 300, H = 300, L = 56, T = 28, B = 40, R = 10;
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W + L + R << "\" height=\"" << H + T + B << "\">";
  s << "<text x=\"" << L << "\" y=\"18\" font-size=\"13\" font-weight=\"bold\">" << esc(title) << "</text>";
  const double cw = double(W) / g, ch = double(H) / g;
  for (int y = 0; y < g; ++y)
    for (int x = 0; x < g; ++x) {
      const double v = values[static_cast<size_t>(y * g + x)];
      s << "<rect x=\"" << L + x * cw << "\" y=\"" << T + (g - 1 - y) * ch << "\" width=\"" << cw + 0.5 << "\" height=\""
        << ch + 0.5 << "\" fill=\"" << ramp(vmax > 0 ? v / vmax : 0) << "\"><title>" << f("%.4f", v) << " mm, "
        << fm.count[static_cast<size_t>(y * g + x)] << " poses</title></rect>";
    }
  s << "<rect x=\"" << L << "\" y=\"" << T << "\" width=\"" << W << "\" height=\"" << H
    << "\" fill=\"none\" stroke=\"#333\"/>";
  s << "<text x=\"" << L << "\" y=\"" << T + H + 14 << "\" font-size=\"10\">" << f("%.0f", fm.x_edges_mm.front()) << "</text>";
  s << "<text x=\"" << L + W << "\" y=\"" << T + H + 14 << "\" font-size=\"10\" text-anchor=\"end\">"
    << f("%.0f", fm.x_edges_mm.back()) << "</text>";
  s << "<text x=\"" << L + W / 2 << "\" y=\"" << T + H + 30 << "\" font-size=\"11\" text-anchor=\"middle\">" << esc(fm.x_label)
    << "</text>";
  s << "<text x=\"" << L - 4 << "\" y=\"" << T + H << "\" font-size=\"10\" text-anchor=\"end\">" << f("%.0f", fm.y_edges_mm.front())
    << "</text>";
  s << "<text x=\"" << L - 4 << "\" y=\"" << T + 10 << "\" font-size=\"10\" text-anchor=\"end\">" << f("%.0f", fm.y_edges_mm.back())
    << "</text>";
  s << "<text transform=\"translate(" << 14 << "," << T + H / 2 << ") rotate(-90)\" font-size=\"11\" text-anchor=\"middle\">"
    << esc(fm.y_label) << "</text>";
  s << "</svg>";
  return s.str();
}

std::string colourBar(double vmax) {
  std::ostringstream s;
  const int W = 300;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W + 120 << "\" height=\"40\">";
  for (int k = 0; k < 60; ++k)
    s << "<rect x=\"" << 56 + k * W / 60.0 << "\" y=\"4\" width=\"" << W / 60.0 + 0.5 << "\" height=\"14\" fill=\""
      << ramp(k / 59.0) << "\"/>";
  s << "<text x=\"56\" y=\"32\" font-size=\"10\">0</text><text x=\"" << 56 + W << "\" y=\"32\" font-size=\"10\" text-anchor=\"end\">"
    << f("%.3f", vmax) << " mm RMS per cell</text></svg>";
  return s.str();
}

// Bars of held-out RMS with the noise floor as a dashed line.
std::string barChart(const std::vector<std::pair<std::string, double>>& bars, double floor_mm, const std::string& title) {
  const int L = 230, W = 420, rowh = 24, T = 26;
  const int H = T + rowh * static_cast<int>(bars.size()) + 24;
  double vmax = floor_mm;
  for (const auto& b : bars) vmax = std::max(vmax, std::isfinite(b.second) ? b.second : 0.0);
  if (!(vmax > 0)) vmax = 1;
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << L + W + 90 << "\" height=\"" << H << "\">";
  s << "<text x=\"4\" y=\"16\" font-size=\"13\" font-weight=\"bold\">" << esc(title) << "</text>";
  for (size_t k = 0; k < bars.size(); ++k) {
    const double y = T + rowh * double(k);
    const double w = std::isfinite(bars[k].second) ? W * bars[k].second / vmax : 0;
    s << "<text x=\"" << L - 6 << "\" y=\"" << y + 16 << "\" font-size=\"12\" text-anchor=\"end\">" << esc(bars[k].first) << "</text>";
    s << "<rect x=\"" << L << "\" y=\"" << y + 4 << "\" width=\"" << w << "\" height=\"" << rowh - 8 << "\" fill=\""
      << (k == 0 ? "#c0392b" : "#2e86c1") << "\"/>";
    s << "<text x=\"" << L + w + 4 << "\" y=\"" << y + 16 << "\" font-size=\"11\">" << f("%.4f", bars[k].second) << " mm</text>";
  }
  if (floor_mm > 0) {
    const double x = L + W * floor_mm / vmax;
    s << "<line x1=\"" << x << "\" y1=\"" << T << "\" x2=\"" << x << "\" y2=\"" << H - 18
      << "\" stroke=\"#27ae60\" stroke-width=\"2\" stroke-dasharray=\"5,3\"/>";
    s << "<text x=\"" << x << "\" y=\"" << H - 4 << "\" font-size=\"11\" fill=\"#27ae60\" text-anchor=\"middle\">noise floor "
      << f("%.4f", floor_mm) << " mm</text>";
  }
  s << "</svg>";
  return s.str();
}

std::string jointChart(const JointProfile& jp, double vmax) {
  const int W = 220, H = 120, L = 40, T = 20, B = 30;
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << W + L + 10 << "\" height=\"" << H + T + B << "\">";
  s << "<text x=\"" << L << "\" y=\"14\" font-size=\"12\" font-weight=\"bold\">joint " << jp.joint << " (" << esc(jp.name)
    << ")</text>";
  s << "<rect x=\"" << L << "\" y=\"" << T << "\" width=\"" << W << "\" height=\"" << H << "\" fill=\"#fafafa\" stroke=\"#999\"/>";
  const int nb = static_cast<int>(jp.rms_before_mm.size());
  auto path = [&](const std::vector<double>& v, const char* colour) {
    std::string d;
    bool pen = false;
    for (int k = 0; k < nb; ++k) {
      if (!std::isfinite(v[static_cast<size_t>(k)])) {
        pen = false;
        continue;
      }
      const double x = L + W * (k + 0.5) / nb;
      const double y = T + H - H * std::min(1.0, v[static_cast<size_t>(k)] / vmax);
      d += (pen ? " L" : " M") + f("%.1f", x) + " " + f("%.1f", y);
      pen = true;
    }
    s << "<path d=\"" << d << "\" fill=\"none\" stroke=\"" << colour << "\" stroke-width=\"2\"/>";
  };
  path(jp.rms_before_mm, "#c0392b");
  path(jp.rms_after_mm, "#2e86c1");
  s << "<text x=\"" << L - 3 << "\" y=\"" << T + 8 << "\" font-size=\"9\" text-anchor=\"end\">" << f("%.3f", vmax) << "</text>";
  s << "<text x=\"" << L - 3 << "\" y=\"" << T + H << "\" font-size=\"9\" text-anchor=\"end\">0</text>";
  s << "<text x=\"" << L << "\" y=\"" << T + H + 14 << "\" font-size=\"9\">" << f("%.0f", jp.edges.front()) << "</text>";
  s << "<text x=\"" << L + W << "\" y=\"" << T + H + 14 << "\" font-size=\"9\" text-anchor=\"end\">" << f("%.0f", jp.edges.back())
    << "</text>";
  s << "<text x=\"" << L + W / 2 << "\" y=\"" << T + H + 26 << "\" font-size=\"10\" text-anchor=\"middle\">q" << jp.joint << " ("
    << jp.unit << ")</text>";
  s << "<text class=\"y-label\" transform=\"translate(10," << T + H / 2 << ") rotate(-90)\" font-size=\"9\" "
       "text-anchor=\"middle\">held-out RMS (mm)</text>";
  s << "</svg>";
  return s.str();
}

// Where the diagnosis comes from: date, version, instrument, files.
std::string reportHeader(const DiagnosisReportContext& c) {
  if (c.date_utc.empty() && c.version.empty() && c.instrument.empty() && c.data_files.empty()) return "";
  std::ostringstream s;
  s << "<table id=\"report-meta\"><tr><th class=\"l\">date</th><td class=\"l\">" << esc(c.date_utc) << "</td></tr>"
    << "<tr><th class=\"l\">accura</th><td class=\"l\">" << esc(c.version) << "</td></tr>"
    << "<tr><th class=\"l\">instrument</th><td class=\"l\">" << esc(c.instrument) << "</td></tr>"
    << "<tr><th class=\"l\">data files</th><td class=\"l\">";
  for (size_t k = 0; k < c.data_files.size(); ++k) s << (k ? "<br>" : "") << esc(c.data_files[k]);
  s << "</td></tr></table>\n";
  return s.str();
}

// The identified parameters with sigmas, an error histogram and the per-axis split.
std::string modelSection(const DiagnosisReportContext& c) {
  std::ostringstream s;
  if (!c.parameters.empty()) {
    s << "<h2>The identified complete geometric model</h2>\n<table id=\"parameters\"><tr><th class=\"l\">parameter</th>"
         "<th>value</th><th>1 sigma</th><th class=\"l\">unit</th><th class=\"l\">meaning</th></tr>";
    for (const auto& p : c.parameters)
      s << "<tr><td class=\"l\">" << esc(p.name) << "</td><td>" << f("%.6f", p.value) << "</td><td>" << f("%.6f", p.sigma)
        << "</td><td class=\"l\">" << esc(p.unit) << "</td><td class=\"l\">"
        << (p.station ? "tracker station (absolute)" : "deviation from the nominal model") << "</td></tr>";
    s << "</table>\n";
  }
  if (c.residuals_mm.empty()) return s.str();
  std::vector<double> e;
  Eigen::Vector3d sq = Eigen::Vector3d::Zero(), mean = Eigen::Vector3d::Zero();
  for (const auto& r : c.residuals_mm) {
    e.push_back(r.norm());
    sq += r.cwiseAbs2();
    mean += r;
  }
  const double n = static_cast<double>(e.size());
  const double emax = *std::max_element(e.begin(), e.end());
  const int bins = 20;
  const double width = emax > 0 ? emax / bins : 1.0;
  std::vector<int> count(bins, 0);
  for (double x : e) ++count[static_cast<size_t>(std::min(bins - 1, static_cast<int>(x / width)))];
  const int cmax = *std::max_element(count.begin(), count.end());
  const int W = 400, H = 150, L = 50, T = 10, B = 36;
  s << "<h2>Error of that model on the fit data</h2>\n<svg id=\"histogram\" xmlns=\"http://www.w3.org/2000/svg\" width=\""
    << W + L + 10 << "\" height=\"" << H + T + B << "\"><rect x=\"" << L << "\" y=\"" << T << "\" width=\"" << W
    << "\" height=\"" << H << "\" fill=\"#fafafa\" stroke=\"#999\"/>";
  for (int k = 0; k < bins; ++k) {
    const double bh = cmax > 0 ? H * count[static_cast<size_t>(k)] / static_cast<double>(cmax) : 0;
    s << "<rect x=\"" << f("%.1f", L + W * k / static_cast<double>(bins) + 1) << "\" y=\"" << f("%.1f", T + H - bh)
      << "\" width=\"" << f("%.1f", W / static_cast<double>(bins) - 2) << "\" height=\"" << f("%.1f", bh)
      << "\" fill=\"#2e86c1\"><title>" << f("%.4f", k * width) << " .. " << f("%.4f", (k + 1) * width) << " mm: "
      << count[static_cast<size_t>(k)] << " poses</title></rect>";
  }
  s << "<text x=\"" << L << "\" y=\"" << T + H + 14 << "\" font-size=\"9\">0</text><text x=\"" << L + W << "\" y=\""
    << T + H + 14 << "\" font-size=\"9\" text-anchor=\"end\">" << f("%.4f", emax) << "</text>"
    << "<text x=\"" << L + W / 2 << "\" y=\"" << T + H + 30 << "\" font-size=\"10\" text-anchor=\"middle\">"
       "position error (mm)</text>"
    << "<text x=\"" << L - 6 << "\" y=\"" << T + 8 << "\" font-size=\"9\" text-anchor=\"end\">" << cmax << "</text>"
    << "<text transform=\"translate(12," << T + H / 2 << ") rotate(-90)\" font-size=\"10\" text-anchor=\"middle\">"
       "poses</text></svg>\n";
  s << "<table id=\"per-axis\"><tr><th class=\"l\">axis (measurement frame)</th><th>RMS (mm)</th><th>mean (mm)</th></tr>";
  const char* axis[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a)
    s << "<tr><td class=\"l\">" << axis[a] << "</td><td>" << f("%.4f", std::sqrt(sq[a] / n)) << "</td><td>"
      << f("%.4f", mean[a] / n) << "</td></tr>";
  s << "<tr><td class=\"l\">3D</td><td>" << f("%.4f", std::sqrt(sq.sum() / n)) << "</td><td></td></tr></table>\n";
  return s.str();
}

// Plain-language notes for the report's technical terms.
std::string glossary() {
  return "<h2>Terms used in this report</h2>\n<dl id=\"glossary\">"
         "<dt>tau2 (tau1 .. tau6)</dt><dd>the gravity torque on joint 2 (N&middot;m) from the link masses and the payload "
         "in that pose: an error that follows it is joint compliance (the joint gives under load).</dd>"
         "<dt>dir4 (dir1 .. dir6)</dt><dd>the direction in which joint 4 last moved before the pose was measured (+1 or "
         "-1): an error that follows it is backlash (play in the gear).</dd>"
         "<dt>base_xy, base_rz</dt><dd>maps of the error over the workspace in the robot base frame: seen from above (x, "
         "y), and as radius from the first axis against height (r, z).</dd>"
         "<dt>negative R&sup2;</dt><dd>R&sup2; is the share of the residual a variable explains on poses it was not "
         "fitted to; below 0 it predicts them worse than a constant: the variable explains nothing.</dd>"
         "<dt>floor z</dt><dd>how far the held-out RMS lies above what the noise floor and the parameter uncertainty "
         "alone would give, in standard errors: about 0 means the model is down to the noise; above 2, error is "
         "left.</dd></dl>\n";
}

std::string confoundingText(const Confounding& c) {
  const std::string a = c.effect_a + (c.joints_a.empty() ? "" : " " + jointsText(c.joints_a));
  const std::string b = c.effect_b + (c.joints_b.empty() ? "" : " " + jointsText(c.joints_b));
  std::string s;
  if (c.indistinguishable && c.rms_b_alone_mm < c.rms_a_alone_mm) {
    // b alone does better on the held-out poses; it is not selected for a reason of its own
    // (a coverage rule, a blocked fold: see the effects not selected)
    s = "confounded: " + a + " and " + b + " explain the same residual; " + c.effect_b + " alone does better on the held-out " +
        "poses (RMS alone " + f("%.4f", c.rms_b_alone_mm) + " vs " + f("%.4f", c.rms_a_alone_mm) + " mm) but is not selected " +
        "(see 'not selected'; p = " + f("%.2g", c.p_a_better) + " that " + c.effect_a + " is better; canonical correlation " +
        f("%.2f", c.canonical_correlation) + ")";
  } else if (c.indistinguishable) {
    s = "confounded: " + a + " and " + b + " explain the same residual and this data cannot tell them apart (held-out RMS " +
        "alone " + f("%.4f", c.rms_a_alone_mm) + " vs " + f("%.4f", c.rms_b_alone_mm) + " mm, p = " + f("%.2g", c.p_a_better) +
        "; canonical correlation " + f("%.2f", c.canonical_correlation) + ")";
  } else {
    s = "overlap: " + b + " also explains part of the residual of " + a + " (gain alone " + f("%.1f%%", 100 * c.gain_b_alone) +
        ", " + f("%.1f%%", 100 * c.gain_b_given_a) + " once " + c.effect_a + " is in; canonical correlation " +
        f("%.2f", c.canonical_correlation) + "); the data prefers " + c.effect_a + " (held-out RMS alone " +
        f("%.4f", c.rms_a_alone_mm) + " vs " + f("%.4f", c.rms_b_alone_mm) + " mm, p = " + f("%.2g", c.p_a_better) + ")";
  }
  return s + "; to separate them: " + c.separate_by;
}

}  // namespace

std::string diagnosisJson(const Diagnosis& d) {
  ordered_json j;
  j["robot"] = d.robot;
  j["joint_names"] = d.joint_names;
  j["data"] = d.data_file;
  j["validation"] = {{"method", d.validation_method}, {"poses", d.validation_poses}};
  j["fit_poses"] = d.fit_poses;
  j["orientation_ignored"] = d.orientation_ignored;
  j["fits_orientation"] = d.fits_orientation;
  j["effects_tested"] = d.effects_tested;
  j["noise_floor_mm"] = num(d.noise_floor_mm);
  j["noise_floor"] = {{"rms_3d_mm", num(d.noise_floor_mm)},
                      {"std_per_axis_mm", num(d.noise_std_axis_mm)},
                      {"source", d.noise_floor_source},
                      {"known", d.noise_floor_known},
                      {"degrees_of_freedom", num(d.noise_floor_dof)}};
  j["floors"] = floorsJson(d);
  ordered_json dw = ordered_json::array();
  for (const DownWeighted& w : d.downweighted)
    dw.push_back({{"row", rowRef(w.file, w.line, w.index)}, {"residual_mm", num(w.residual_mm)}, {"weight", num(w.weight)}});
  j["downweighted"] = dw;
  ordered_json excl = ordered_json::array();
  for (const ExcludedRow& e : d.excluded)
    excl.push_back({{"file", e.file}, {"line", e.line}, {"error_mm", num(e.error_mm)}, {"median_mm", num(e.median_mm)}});
  j["excluded_rows"] = excl;  // gross rows left out before the diagnosis
  j["tests"] = d.tests;
  j["baseline"] = statsJson(d.baseline, d.noise_floor_mm);
  ordered_json ranking = ordered_json::array();
  for (const auto& e : d.ranking) ranking.push_back(evidenceJson(d, e));
  j["ranking"] = ranking;
  ordered_json selected = ordered_json::array();
  for (const auto& e : d.selected) selected.push_back(evidenceJson(d, e));
  j["selected"] = selected;
  j["identify_params"] = d.identify_params;
  ordered_json rej = ordered_json::array();
  for (const Rejected& r : d.rejected) rej.push_back({{"effect", r.effect}, {"joints", r.joints}, {"reason", r.reason}});
  j["rejected"] = rej;
  ordered_json conf = ordered_json::array();
  for (const Confounding& c : d.confounded)
    conf.push_back({{"effect_a", c.effect_a},
                    {"joints_a", c.joints_a},
                    {"effect_b", c.effect_b},
                    {"joints_b", c.joints_b},
                    {"gain_b_alone_percent", num(100 * c.gain_b_alone)},
                    {"gain_b_given_a_percent", num(100 * c.gain_b_given_a)},
                    {"canonical_correlation", num(c.canonical_correlation)},
                    {"validation_rms_a_alone_mm", num(c.rms_a_alone_mm)},
                    {"validation_rms_b_alone_mm", num(c.rms_b_alone_mm)},
                    {"p_a_better", num(c.p_a_better)},
                    {"indistinguishable", c.indistinguishable},
                    {"separate_by", c.separate_by}});
  j["confounded"] = conf;
  ordered_json shrink = ordered_json::array();
  for (const ShrinkStep& s : d.shrink) {
    ordered_json row = {{"effect", s.effect}, {"joints", s.joints}};
    const ordered_json stats = statsJson(s.heldout, d.noise_floor_mm);
    for (auto it = stats.begin(); it != stats.end(); ++it) row[it.key()] = it.value();
    shrink.push_back(row);
  }
  j["shrink"] = shrink;
  j["verdict"] = {{"effect", d.verdict.effect},
                  {"joints", d.verdict.joints},
                  {"joint_names", jointNames(d, d.verdict.joints)},
                  {"validation_rms_after_mm", num(d.verdict.validation_rms_after_mm)},
                  {"explanation", d.verdict.explanation},
                  {"correlates", d.verdict.correlates},
                  {"confounded_with", d.verdict.confounded_with},
                  {"effects", d.verdict.effects},
                  {"explained_share", num(d.verdict.explained_share)}};
  j["spectra"] = spectraJson(d);
  j["orientation_residual_deg"] = {{"rms_before", num(d.orientation_rms_before_deg)},
                                   {"rms_after", num(d.orientation_rms_after_deg)}};
  ordered_json where;
  ordered_json fields = ordered_json::array();
  for (const FieldMap& fm : d.fields)
    fields.push_back({{"plane", fm.plane},
                      {"x_label", fm.x_label},
                      {"y_label", fm.y_label},
                      {"x_edges_mm", fm.x_edges_mm},
                      {"y_edges_mm", fm.y_edges_mm},
                      {"rms_before_mm", arrayOf(fm.rms_before_mm)},
                      {"rms_after_mm", arrayOf(fm.rms_after_mm)},
                      {"count", fm.count}});
  where["fields"] = fields;
  ordered_json joints = ordered_json::array();
  for (const JointProfile& jp : d.joints)
    joints.push_back({{"joint", jp.joint},
                      {"name", jp.name},
                      {"unit", jp.unit},
                      {"edges", jp.edges},
                      {"rms_before_mm", arrayOf(jp.rms_before_mm)},
                      {"rms_after_mm", arrayOf(jp.rms_after_mm)},
                      {"count", jp.count}});
  where["joints"] = joints;
  ordered_json corr = ordered_json::array();
  for (const Correlation& c : d.correlations)
    corr.push_back({{"variable", c.variable},
                    {"r2_cv_before", num(c.r2_before)},
                    {"p_before", num(c.p_before)},
                    {"r2_cv_after", num(c.r2_after)},
                    {"p_after", num(c.p_after)},
                    {"pearson_magnitude_before", num(c.pearson_before)},
                    {"via_joint_after", c.via_joint_after}});
  where["correlation"] = corr;
  ordered_json regions = ordered_json::array();
  for (const Region& r : d.worst_regions)
    regions.push_back({{"plane", r.plane},
                       {"x_mm", {num(r.x0_mm), num(r.x1_mm)}},
                       {"y_mm", {num(r.y0_mm), num(r.y1_mm)}},
                       {"poses", r.count},
                       {"rms_before_mm", num(r.rms_before_mm)},
                       {"rms_after_mm", num(r.rms_after_mm)}});
  where["worst_regions"] = regions;
  ordered_json poses = ordered_json::array();
  for (const WorstPose& p : d.worst_poses)
    poses.push_back({{"line", p.line}, {"row", p.index}, {"error_before_mm", num(p.error_before_mm)}, {"error_after_mm", num(p.error_after_mm)}});
  where["worst_poses"] = poses;
  j["where"] = where;
  j["notes"] = d.notes;
  j["warnings"] = d.warnings;
  j["seconds"] = num(d.seconds);
  return calib::jsonText(j);
}

std::string diagnosisText(const Diagnosis& d) {
  std::ostringstream s;
  s << "accura diagnose: " << d.robot << ", " << d.fit_poses << " poses from " << d.data_file << "\n";
  s << "held-out error by " << d.validation_method << "\n";
  for (const std::string& w : d.warnings) s << "WARNING: " << w << "\n";
  if (d.orientation_ignored) s << "orientation columns are not used by the diagnosis' fits (positions only)\n";
  if (d.fits_orientation)
    s << "fits: positions and orientations, each row weighted as identify weights it (std and the geometric baseline's "
         "unmodelled-error term); held-out errors: positions\n";
  s << "noise floor: " << f("%.4f", d.noise_floor_mm) << " mm (3D RMS; " << f("%.4f", d.noise_std_axis_mm)
    << " mm per axis); source: " << d.noise_floor_source << "\n";
  {
    const Floors& fl = d.floors;
    s << "floors: instrument (std columns) " << (fl.instrument_known ? f("%.4f", fl.instrument_rms_mm) + " mm" : std::string("unknown"))
      << "; repeatability ";
    if (fl.repeat_pairs == 0) {
      s << "unknown: no configuration measured again (joints within " << f("%g", fl.repeat_tol) << " deg)\n";
    } else {
      s << (fl.repeat_dof > 0 ? f("%.4f", fl.repeat_rms_mm) + " mm 3D RMS" : std::string("unknown")) << " from "
        << fl.repeat_groups << " configurations measured again (" << fl.repeat_pairs << " pairs, " << fl.repeat_min_gap << "-"
        << fl.repeat_max_gap << " rows apart, joints within " << f("%g", fl.repeat_tol) << " deg";
      if (fl.repeat_pairs_validation > 0)
        s << "; the validation set's: " << fl.repeat_groups_validation << " configurations, " << fl.repeat_pairs_validation
          << " pairs";
      s << "), median pair distance " << (std::isfinite(fl.median_pair_mm) ? f("%.4f", fl.median_pair_mm) + " mm" : std::string("- (every pair a glitch)"))
        << "\n";
    }
    if (!fl.duplicated_rows.empty()) {
      s << "WARNING: " << fl.duplicated_rows.size()
        << " row(s) repeat an earlier row of their configuration exactly (every measured value equal): the same "
           "measurement written twice, counted once (left out of the diagnosis):";
      for (size_t k = 0; k < fl.duplicated_rows.size() && k < 12; ++k)
        s << " " << glitchRowRef(d, fl.duplicated_rows[k], true) << " = " << glitchRowRef(d, fl.duplicated_rows[k], false);
      if (fl.duplicated_rows.size() > 12) s << " ... (all in the JSON)";
      s << "\n";
    }
    if (!fl.glitches.empty()) {
      s << "glitches (repeat pairs, or rows of a configuration measured three times or more against its centre, "
           "further apart than "
        << f("%.3f", fl.glitch_threshold_mm) << " mm):";
      for (const RepeatPair& p : fl.glitches)
        s << "\n  " << glitchText(d, p) << "  " << f("%.3f", p.distance_mm) << " mm" << (std::isfinite(p.rotation_deg) ? ", orientation jump " + f("%.3f", p.rotation_deg) + " deg" : "");
      s << "\n";
      if (d.validation_glitch_rows_left_out > 0)
        s << d.validation_glitch_rows_left_out << " validation row(s) of these glitches left out of the held-out statistics ("
          << d.validation_poses << " validation poses remain)\n";
    }
    for (const std::string& w : excludedRowWarnings(d.excluded, "the diagnosis")) s << "WARNING: " << w << "\n";
    if (!d.downweighted.empty()) {
      s << "robust estimation down-weighted " << d.downweighted.size() << " row(s):";
      for (size_t k = 0; k < d.downweighted.size() && k < 12; ++k)
        s << " " << rowRef(d.downweighted[k].file, d.downweighted[k].line, d.downweighted[k].index) << " ("
          << f("%.2f", d.downweighted[k].residual_mm) << " mm, w " << f("%.2f", d.downweighted[k].weight) << ")";
      if (d.downweighted.size() > 12) s << " ... (all in the JSON)";
      s << "\n";
    }
  }
  s << "baseline (complete geometric model): held-out RMS " << f("%.4f", d.baseline.rms_mm) << " mm, max "
    << f("%.4f", d.baseline.max_mm) << " mm\n";
  s << "ranking (each effect alone on the baseline; held-out RMS before -> after, gain, p):\n";
  for (const EffectEvidence& e : d.ranking) {
    char buf[512];
    if (!e.testable) {
      std::snprintf(buf, sizeof buf, "  %-17s %s\n", e.effect.c_str(), e.note.c_str());
    } else {
      std::snprintf(buf, sizeof buf, "  %-17s %-14s %.4f -> %.4f mm  gain %5.1f%%  p %.2g  dBIC %.1f%s\n", e.effect.c_str(),
                    jointsText(e.joints).c_str(), e.rms_before_mm, e.rms_after_mm, 100 * e.gain, e.p_value, e.delta_bic,
                    e.significant ? "" : "  (fails the selection tests)");
    }
    s << buf;
  }
  s << "shrink (exact refits; held-out RMS, max, against the noise floor):\n";
  for (const ShrinkStep& st : d.shrink) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "  %-28s RMS %.4f  max %.4f mm  expected at the floor %s mm\n",
                  (st.effect == "baseline" ? std::string("baseline") : "+ " + st.effect + " " + jointsText(st.joints)).c_str(),
                  st.heldout.rms_mm, st.heldout.max_mm, f("%.4f", st.heldout.expected_rms_mm).c_str());
    s << buf;
  }
  for (const EffectEvidence& e : d.selected) {
    s << "selected: " << e.params << "  blocked cross-validation gain " << f("%.1f", 100 * e.blocked_gain) << "% (worst: "
      << e.blocked_scheme << ")";
    // a map is zero outside the range its data cover: held-out blocks beyond it can only show
    // harm, so a selected map's worst blocked gain may be about zero (admissible)
    if (e.effect == "joint_map") s << ", held to no harm: a map is zero outside the range it is fitted on";
    s << "; fitted on";
    for (const Coverage& c : e.coverage) s << " " << c.variable << " " << f("%.1f", c.lo) << ".." << f("%.1f", c.hi) << " " << c.unit;
    s << "\n";
  }
  for (const Rejected& r : d.rejected)
    s << "not selected: " << r.effect << (r.joints.empty() ? "" : " " + jointsText(r.joints)) << ": " << r.reason << "\n";
  s << "identify --params " << d.identify_params << "\n";
  for (const Confounding& c : d.confounded) s << confoundingText(c) << "\n";
  if (!d.spectra.empty()) {
    s << "per-joint spectrum of the residual (largest peak, before -> after; p Bonferroni over every joint and k):\n";
    for (const JointSpectrum& sp : d.spectra) {
      char buf[256];
      std::snprintf(buf, sizeof buf, "  j%d (range %.0f deg): %2d cycles/rev %6.0f urad p %.2g -> %2d cycles/rev %6.0f urad p %.2g\n",
                    sp.joint, sp.range_deg, sp.peak_cycles_before, sp.peak_amplitude_urad_before, sp.peak_p_before,
                    sp.peak_cycles, sp.peak_amplitude_urad, sp.peak_p);
      s << buf;
    }
  }
  if (std::isfinite(d.orientation_rms_before_deg))
    s << "orientation residual (the same parameter groups identified on positions and orientations, as identify does): " << f("%.4f", d.orientation_rms_before_deg) << " -> "
      << f("%.4f", d.orientation_rms_after_deg) << " deg RMS\n";
  s << "verdict: " << d.verdict.effect;
  // unexplained: the joint is not a cause's but the one whose motion the residual acts like most
  if (!d.verdict.joints.empty())
    s << (d.verdict.effect == "unexplained" ? " (the rest acts most like a motion of " : " (")
      << jointsText(d.verdict.joints) << ")";
  s << ", held-out RMS after " << f("%.4f", d.verdict.validation_rms_after_mm) << " mm\n  " << d.verdict.explanation << "\n";
  return s.str();
}

std::string diagnosisHtml(const Diagnosis& d) { return diagnosisHtml(d, DiagnosisReportContext{}); }

std::string diagnosisHtml(const Diagnosis& d, const DiagnosisReportContext& ctx) {
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>Remaining error of " << esc(d.robot)
    << "</title>\n<style>body{font-family:sans-serif;margin:24px;color:#222;max-width:1200px}"
       "h1{font-size:22px}h2{font-size:17px;margin-top:28px;border-bottom:1px solid #ccc}"
       "table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}"
       "th{background:#f0f0f0}td.l,th.l{text-align:left}.verdict{font-size:18px;padding:12px;border-radius:6px;"
       "background:#eaf2f8;border:2px solid #2e86c1}.verdict.unexplained{background:#fdedec;border-color:#c0392b}"
       ".verdict.none{background:#eafaf1;border-color:#27ae60}.small{font-size:12px;color:#555}"
       ".maps{display:flex;flex-wrap:wrap;gap:10px}</style></head><body>\n";
  h << "<h1>Remaining error of " << esc(d.robot) << "</h1>\n";
  h << reportHeader(ctx);
  h << "<p class=\"small\">" << d.fit_poses << " poses from " << esc(d.data_file) << "; held-out error by "
    << esc(d.validation_method) << "; noise floor " << f("%.4f", d.noise_floor_mm) << " mm (3D RMS); source: "
    << esc(d.noise_floor_source) << "</p>\n";
  for (const std::string& w : d.warnings) h << "<p><b>Warning:</b> " << esc(w) << "</p>\n";
  h << "<div class=\"verdict " << esc(d.verdict.effect) << "\"><b>Verdict: " << esc(d.verdict.effect);
  if (!d.verdict.joints.empty()) h << " (" << esc(jointsText(d.verdict.joints)) << ")";
  h << "</b> &mdash; held-out RMS " << f("%.4f", d.baseline.rms_mm) << " &rarr; " << f("%.4f", d.verdict.validation_rms_after_mm)
    << " mm<br><span style=\"font-size:14px\">" << esc(d.verdict.explanation) << "</span></div>\n";
  {
    // floors, glitches, robust rows, what to identify
    const Floors& fl = d.floors;
    h << "<h2>Floors and outliers</h2>\n<p>instrument (std columns): "
      << (fl.instrument_known ? f("%.4f", fl.instrument_rms_mm) + " mm" : std::string("unknown")) << "; repeatability: "
      << (fl.repeat_dof > 0 ? f("%.4f", fl.repeat_rms_mm) + " mm 3D RMS" : std::string("unknown")) << " from " << fl.repeat_groups
      << " configurations measured again, median pair distance " << f("%.4f", fl.median_pair_mm) << " mm; "
      << fl.glitches.size() << " glitch(es); " << d.downweighted.size() << " row(s) down-weighted by the robust fit.</p>\n";
    if (!fl.glitches.empty()) {
      h << "<table><tr><th class=\"l\">glitch (pair, or row against its configuration's centre)</th><th>distance (mm)</th><th>orientation jump (deg)</th></tr>\n";
      for (const RepeatPair& p : fl.glitches)
        h << "<tr><td class=\"l\">" << esc(glitchText(d, p)) << "</td><td>" << f("%.3f", p.distance_mm) << "</td><td>"
          << f("%.3f", p.rotation_deg) << "</td></tr>\n";
      h << "</table>\n";
    }
    h << "<p>identify --params " << esc(d.identify_params) << "</p>\n";
  }

  // shrink
  h << "<h2>How far it shrinks</h2>\n";
  std::vector<std::pair<std::string, double>> bars;
  for (const ShrinkStep& s : d.shrink)
    bars.push_back({s.effect == "baseline" ? "geometric model" : "+ " + s.effect + " " + jointsText(s.joints), s.heldout.rms_mm});
  h << barChart(bars, d.noise_floor_mm, "held-out RMS after each selected effect") << "\n";
  h << "<table><tr><th class=\"l\">model</th><th>held-out RMS (mm)</th><th>max (mm)</th><th>p95 (mm)</th>"
       "<th>expected at the noise floor (mm)</th><th>RMS / floor</th><th>floor z</th></tr>\n";
  for (const ShrinkStep& s : d.shrink)
    h << "<tr><td class=\"l\">" << esc(s.effect == "baseline" ? "complete geometric model" : "+ " + s.effect + " " + jointsText(s.joints))
      << "</td><td>" << f("%.4f", s.heldout.rms_mm) << "</td><td>" << f("%.4f", s.heldout.max_mm) << "</td><td>"
      << f("%.4f", s.heldout.p95_mm) << "</td><td>" << f("%.4f", s.heldout.expected_rms_mm) << "</td><td>"
      << f("%.2f", d.noise_floor_mm > 0 ? s.heldout.rms_mm / d.noise_floor_mm : NAN) << "</td><td>" << f("%.1f", s.heldout.floor_z)
      << "</td></tr>\n";
  h << "</table>\n";

  // ranking
  h << "<h2>Which effect: ranking (each effect alone on the geometric model)</h2>\n";
  std::vector<std::pair<std::string, double>> rbars = {{"geometric model", d.baseline.rms_mm}};
  for (const EffectEvidence& e : d.ranking)
    if (e.testable) rbars.push_back({e.effect + " " + jointsText(e.joints) + (e.significant ? "" : " (n.s.)"), e.rms_after_mm});
  h << barChart(rbars, d.noise_floor_mm, "held-out RMS with each effect") << "\n";
  h << "<table><tr><th class=\"l\">effect</th><th class=\"l\">joints</th><th>RMS before</th><th>RMS after</th>"
       "<th>gain</th><th>z</th><th>p</th><th>&Delta;BIC</th><th class=\"l\">parameters (value &plusmn; 1&sigma;)</th></tr>\n";
  for (const EffectEvidence& e : d.ranking) {
    h << "<tr><td class=\"l\">" << esc(e.effect) << "</td>";
    if (!e.testable) {
      h << "<td class=\"l\" colspan=\"8\">" << esc(e.note) << "</td></tr>\n";
      continue;
    }
    h << "<td class=\"l\">" << esc(jointsText(e.joints)) << "</td><td>" << f("%.4f", e.rms_before_mm) << "</td><td>"
      << f("%.4f", e.rms_after_mm) << "</td><td>" << f("%.1f%%", 100 * e.gain) << "</td><td>" << f("%.1f", e.z) << "</td><td>"
      << f("%.2g", e.p_value) << "</td><td>" << f("%.1f", e.delta_bic) << "</td><td class=\"l\">";
    for (size_t k = 0; k < e.parameters.size() && k < 8; ++k)
      h << esc(e.parameters[k].name) << " " << f("%.4g", e.parameters[k].value) << " &plusmn; " << f("%.2g", e.parameters[k].sigma)
        << " " << esc(e.parameters[k].unit) << "<br>";
    if (e.parameters.size() > 8) h << "&hellip;";
    h << (e.significant ? "" : "<i>fails the selection tests</i>") << "</td></tr>\n";
  }
  h << "</table>\n";
  if (!d.confounded.empty()) {
    h << "<h3>Effects that explain the same residual</h3><ul>";
    for (const Confounding& c : d.confounded) h << "<li>" << esc(confoundingText(c)) << "</li>";
    h << "</ul>\n";
  }

  // where
  h << "<h2>Where: the error over the workspace, before and after</h2>\n";
  double vmax = 0;
  for (const FieldMap& fm : d.fields)
    for (double v : fm.rms_before_mm)
      if (std::isfinite(v)) vmax = std::max(vmax, v);
  for (const FieldMap& fm : d.fields) {
    h << "<div class=\"maps\">" << heatmap(fm, fm.rms_before_mm, vmax, fm.plane + ": geometric model")
      << heatmap(fm, fm.rms_after_mm, vmax, fm.plane + ": after " + (d.shrink.size() > 1 ? d.shrink.back().effect : "(nothing added)"))
      << "</div>\n";
  }
  h << colourBar(vmax) << "\n";
  h << "<h3>Over each joint's range (red: geometric model, blue: after)</h3><div class=\"maps\">";
  double jmax = 0;
  for (const JointProfile& jp : d.joints)
    for (double v : jp.rms_before_mm)
      if (std::isfinite(v)) jmax = std::max(jmax, v);
  if (!(jmax > 0)) jmax = 1;
  for (const JointProfile& jp : d.joints) h << jointChart(jp, jmax);
  h << "</div>\n";
  h << "<h3>Worst regions</h3><table><tr><th class=\"l\">plane</th><th>x / r range (mm)</th><th>y / z range (mm)</th>"
       "<th>poses</th><th>RMS before</th><th>RMS after</th></tr>";
  for (const Region& r : d.worst_regions)
    h << "<tr><td class=\"l\">" << esc(r.plane) << "</td><td>" << f("%.0f", r.x0_mm) << " .. " << f("%.0f", r.x1_mm) << "</td><td>"
      << f("%.0f", r.y0_mm) << " .. " << f("%.0f", r.y1_mm) << "</td><td>" << r.count << "</td><td>" << f("%.4f", r.rms_before_mm)
      << "</td><td>" << f("%.4f", r.rms_after_mm) << "</td></tr>";
  h << "</table>\n";
  h << "<h3>What the residual follows (cross-validated share of its variance)</h3><table><tr><th class=\"l\">variable</th>"
       "<th>R&sup2; before</th><th>p before</th><th>R&sup2; after</th><th>p after</th><th>joint axis</th></tr>";
  std::vector<Correlation> corr = d.correlations;
  std::sort(corr.begin(), corr.end(), [](const Correlation& a, const Correlation& b) { return a.r2_before > b.r2_before; });
  for (const Correlation& c : corr)
    h << "<tr><td class=\"l\">" << esc(c.variable) << "</td><td>" << f("%.3f", c.r2_before) << "</td><td>" << f("%.2g", c.p_before)
      << "</td><td>" << f("%.3f", c.r2_after) << "</td><td>" << f("%.2g", c.p_after) << "</td><td>"
      << (c.via_joint_after > 0 ? "j" + std::to_string(c.via_joint_after) : std::string("translation")) << "</td></tr>";
  h << "</table>\n";
  h << modelSection(ctx);
  h << glossary();
  h << "<h2>Method</h2><p class=\"small\">" << esc(d.tests) << "</p>\n";
  if (!d.notes.empty()) {
    h << "<p class=\"small\">Left out: ";
    for (size_t k = 0; k < d.notes.size(); ++k) h << (k ? "; " : "") << esc(d.notes[k]);
    h << "</p>\n";
  }
  h << "</body></html>\n";
  return h.str();
}

}  // namespace accura::calib
