// accura: diagnosis of the sim-to-real gap (diagnose.h, docs/diagnosis.md): options, data
// preparation, the run and the entry point. The steps live in diagnose_{fit,selection,verdict,maps}.cpp.
#include "diagnose_internal.h"
#include "identify_internal.h"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <optional>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/identify.h"
#include "accura/calib/kinematics.h"

namespace accura::calib {

bool DiagnoseOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  const std::vector<std::string>& cat = effectCatalogue();
  for (const std::string& e : effects) {
    if (std::find(cat.begin(), cat.end(), e) == cat.end()) {
      std::string list;
      for (const auto& c : cat) list += (list.empty() ? "" : ", ") + c;
      return fail("unknown effect '" + e + "' (expected one of: " + list + ")");
    }
  }
  if (gear_harmonics < 1 || gear_harmonics > kMaxGearHarmonics)
    return fail("gear harmonics must be 1.." + std::to_string(kMaxGearHarmonics) + ", got " +
                std::to_string(gear_harmonics));
  if (folds < 2 || folds > 20) return fail("folds must be 2..20, got " + std::to_string(folds));
  if (!(std::isnan(noise_std_mm) || (noise_std_mm > 0 && std::isfinite(noise_std_mm))))
    return fail("noise std must be a number > 0 mm, got " + std::to_string(noise_std_mm));
  if (!(alpha > 0 && alpha < 0.5)) return fail("alpha must be in (0, 0.5)");
  if (!(min_gain >= 0 && min_gain < 1)) return fail("min_gain must be in [0, 1)");
  if (!(floor_alpha > 0 && floor_alpha < 0.5)) return fail("floor_alpha must be in (0, 0.5)");
  if (max_steps < 0 || max_steps > 100) return fail("max_steps must be 0..100");
  if (grid_cells < 2 || grid_cells > 50) return fail("grid_cells must be 2..50");
  if (joint_bins < 2 || joint_bins > 50) return fail("joint_bins must be 2..50");
  if (!(repeat_tol > 0 && repeat_tol <= 1)) return fail("repeat tolerance must be in (0, 1] deg (or mm), got " + std::to_string(repeat_tol));
  if (!(glitch_factor > 1 && std::isfinite(glitch_factor))) return fail("glitch_factor must be a number > 1");
  if (!(robust_k == 0 || (robust_k >= 1 && std::isfinite(robust_k))))
    return fail("robust_k must be 0 (off) or a number >= 1 (robust standard deviations), got " + std::to_string(robust_k));
  if (blocked_folds != 0 && (blocked_folds < 2 || blocked_folds > 20))
    return fail("blocked_folds must be 0 (off) or 2..20, got " + std::to_string(blocked_folds));
  if (!(joint_map_knot > 0 && std::isfinite(joint_map_knot)))
    return fail("joint_map_knot must be a number > 0 (deg or mm), got " + std::to_string(joint_map_knot));
  if (!(joint_map_smoothing >= 0 && std::isfinite(joint_map_smoothing)))
    return fail("joint_map_smoothing must be a number >= 0, got " + std::to_string(joint_map_smoothing));
  if (spectrum_max_cycles < 0 || spectrum_max_cycles > 360)
    return fail("spectrum_max_cycles must be 0..360, got " + std::to_string(spectrum_max_cycles));
  return true;
}

namespace diagnose_detail {

// One-sided upper tail of the standard normal distribution.
double upperTail(double z) { return 0.5 * std::erfc(z / std::sqrt(2.0)); }

Gain pairedGain(const Eigen::VectorXd& d_old, const Eigen::VectorXd& d_new) {
  Gain g;
  const Eigen::Index n = d_old.size();
  if (n < 2 || d_new.size() != n) return g;
  const Eigen::VectorXd delta = d_old - d_new;
  const double mean = delta.mean();
  const double var = (delta.array() - mean).square().sum() / double(n - 1);
  const double se = std::sqrt(var / double(n));
  const double base = d_old.mean();
  g.gain = base > 0 ? mean / base : 0.0;
  if (se > 0) {
    g.z = mean / se;
  } else {
    g.z = mean > 0 ? 1e9 : (mean < 0 ? -1e9 : 0.0);
  }
  g.p = upperTail(g.z);
  return g;
}

std::string jointList(const std::vector<int>& joints) {
  std::string s;
  for (int j : joints) s += (s.empty() ? "j" : ", j") + std::to_string(j);
  return s;
}

void statsOf(const std::vector<double>& e, HeldOutStats* s) {
  s->n = static_cast<int>(e.size());
  summarize(e, &s->rms_mm, &s->mean_mm, &s->max_mm, &s->p95_mm);
}

// What each effect needs to be told apart from the others.
std::string separator(const std::string& effect, const std::vector<int>& joints) {
  const std::string j = joints.empty() ? std::string("the joints") : "joint" + std::string(joints.size() > 1 ? "s " : " ") + jointList(joints);
  if (effect == "joint_compliance") return "poses with other payloads (the deflection scales with the load)";
  if (effect == "gear_periodic") return "poses spread over the whole range of " + j + " (several periods of the harmonics)";
  if (effect == "joint_scale") return "poses over the whole range of " + j + " (a scale error grows linearly with q)";
  if (effect == "backlash") return "each pose approached from both directions (dirN +1 and -1)";
  if (effect == "thermal") return "the same poses measured at another temperature (a cold and a warm robot)";
  return "other poses";
}

Diagnoser::Diagnoser(const RobotModel& start, const MeasurementSet& data, const MeasurementSet* validation,
                     const DiagnoseOptions& options)
    : o_(options), start_(start) {
  std::string why;
  if (!o_.IsValid(&why)) throw ArgumentError("diagnose: " + why);
  if (o_.effects.empty()) o_.effects = effectCatalogue();
  start_.validate();
  if (start_.deviations.gear_harmonics != o_.gear_harmonics) {
    // same deviations with another number of gear harmonics (the common ones kept)
    Deviations d = Deviations::zero(start_.dof(), o_.gear_harmonics);
    const Deviations& s = start_.deviations;
    d.base_mm = s.base_mm;
    d.base_rot_rad = s.base_rot_rad;
    d.tool_mm = s.tool_mm;
    d.tool_rot_rad = s.tool_rot_rad;
    d.links = s.links;
    d.compliance = s.compliance;
    d.joint_scale = s.joint_scale;
    d.backlash = s.backlash;
    d.thermal_alpha_per_k = s.thermal_alpha_per_k;
    const int H = std::min(s.gear_harmonics, o_.gear_harmonics);
    for (int i = 0; i < start_.dof(); ++i)
      for (int h = 0; h < H; ++h) {
        d.gear_sin[i * o_.gear_harmonics + h] = s.gear_sin[i * s.gear_harmonics + h];
        d.gear_cos[i * o_.gear_harmonics + h] = s.gear_cos[i * s.gear_harmonics + h];
      }
    start_.deviations = d;
  }
  prepareData(data, validation);
}

void Diagnoser::prepareData(const MeasurementSet& data, const MeasurementSet* validation) {
  const int n = start_.dof();
  auto prepare = [&](const MeasurementSet& in, MeasurementSet* outset) {
    *outset = in;
    if (outset->has_orientation) out_.orientation_ignored = true;
    outset->has_orientation = false;
    outset->has_std_orientation = false;
    for (Measurement& r : outset->rows) {
      if (r.q.size() != n)
        throw InputError(in.file, r.line, 0,
                         "expected " + std::to_string(n) + " joint values, found " + std::to_string(r.q.size()));
      r.has_orientation = false;
      // the model's context from the measured columns (whoever filled the row)
      if (in.has_temperature && std::isfinite(r.temp_c)) r.context.temp_c = r.temp_c;
      if (in.has_direction) r.context.dir = r.dir;
    }
  };
  prepare(data, &fit_);
  m_ = static_cast<int>(fit_.rows.size());
  fit_has_rot_ = data.has_orientation;
  use_rot_ = o_.use_orientation && data.has_orientation &&
             std::count_if(data.rows.begin(), data.rows.end(), [](const Measurement& r) { return r.has_orientation; }) >= 30;
  fit_has_std_rot_ = data.has_std_orientation;
  for (const Measurement& r : data.rows) {
    R_fit_.push_back(r.R_world_tcp);
    rot_ok_.push_back(data.has_orientation && r.has_orientation);
  }
  if (m_ < 30)
    throw InputError(data.file, 0, 0,
                     "the diagnosis needs at least 30 measured poses, found " + std::to_string(m_));
  if (validation) {
    prepare(*validation, &val_);
    has_val_ = true;
    out_.validation_file = validation->file;
    for (const Measurement& r : validation->rows) {
      R_val_.push_back(r.R_world_tcp);
      rot_ok_val_.push_back(validation->has_orientation && r.has_orientation);
    }
    nv_ = static_cast<int>(val_.rows.size());
    if (nv_ < 20)
      throw InputError(validation->file, 0, 0,
                       "the diagnosis needs at least 20 validation poses, found " + std::to_string(nv_));
  }
  if (use_rot_) out_.orientation_ignored = false;  // (the held-out errors are positions)
  out_.fits_orientation = use_rot_;
  out_.data_file = data.file;
  out_.fit_poses = m_;
  out_.validation_poses = has_val_ ? nv_ : m_;
  out_.robot = start_.nominal.name;
  for (const JointSpec& j : start_.nominal.joints) out_.joint_names.push_back(j.name);
}

Diagnosis Diagnoser::run() {
  const auto t0 = std::chrono::steady_clock::now();
  noiseFloor();
  baseline();
  columns();
  linearise();
  robust();
  schemes();
  selection();
  ranking();
  confounding();
  shrink();  // exact held-out residuals of the baseline and of the final model
  {
    const std::vector<std::vector<Correlation>> both = scan({&E0_, &E1_});
    const std::vector<Correlation>& before = both[0];
    std::vector<Correlation> after = both[1];
    for (size_t k = 0; k < after.size(); ++k) {
      after[k].r2_before = before[k].r2_after;
      after[k].p_before = before[k].p_after;
      after[k].pearson_before = before[k].pearson_before;
    }
    out_.correlations = after;
  }
  spectra();
  orientation();
  verdict();
  where();
  // (a std::string: the validation method names the data files, whose paths have no bound)
  out_.tests = "held-out error: " + out_.validation_method +
               "; selection: forward over (effect, joint) blocks, one-sided paired z-test of the per-pose held-out squared "
               "errors, p < " + fmtg("%.3g", o_.alpha) + " / (blocks tried in the round) (Bonferroni) and a drop of the held-out "
               "mean squared error of at least " + fmtg("%.3g", 100 * o_.min_gain) +
               "%; ranking and selection on the model linearised at the baseline, shrink table and verdict on exact non-linear "
               "refits; noise floor: z-test of the held-out squared errors against noise plus parameter variance, p < " +
               fmtg("%.3g", o_.floor_alpha) +
               "; confounding: an effect whose significant gain on the baseline drops below half once another is in the model; "
               "structure scan: the residual regressed on each variable times the joint Jacobian and a translation, made "
               "orthogonal to the geometric parameters' columns (added-variable), " + std::to_string(folds_) + "-fold cross-validated";
  for (const auto& kv : effect_note_)
    if (kv.first.find(':') != std::string::npos) out_.notes.push_back(kv.second);
  out_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out_;
}


void Diagnoser::setRowSets(const std::vector<int>& set_of_row, const std::vector<std::string>& files, bool own_stations) {
  if (static_cast<int>(set_of_row.size()) != m_) throw ArgumentError("diagnose: expected a data set per fit row");
  set_of_row_ = set_of_row;
  own_stations_ = own_stations;
  out_.row_files.clear();
  for (int s : set_of_row) {
    if (s < 0 || static_cast<size_t>(s) >= files.size()) throw ArgumentError("diagnose: a row's data set has no file");
    out_.row_files.push_back(files[static_cast<size_t>(s)]);
  }
}

}  // namespace diagnose_detail

StationSets combineStations(const RobotModel& start, const std::vector<MeasurementSet>& sets, bool same_station,
                            const std::vector<std::string>& groups) {
  if (sets.empty()) throw ArgumentError("combineStations: no data set given");
  StationSets out;
  for (const MeasurementSet& s : sets) {
    if (s.rows.empty()) throw InputError(s.file, 0, 0, "expected measured rows, found none");
    out.files.push_back(s.file);
  }
  out.T_first_station.assign(sets.size(), Eigen::Isometry3d::Identity());
  std::vector<MeasurementSet> moved = sets;
  if (sets.size() > 1 && !same_station) {
    IdentifyOptions io;
    io.groups = groups;
    IdentifySummary s;
    identify(start, sets, io, &s);
    if (s.T_world_base_per_set.size() != sets.size())
      throw NumericalError("combineStations: the identification returned no station per data set");
    for (size_t k = 1; k < sets.size(); ++k) {
      // a point measured from station k: p_k = T_k_base p_base, so p_1 = T_1_base T_k_base^-1 p_k
      const Eigen::Isometry3d T = s.T_world_base_per_set[0] * s.T_world_base_per_set[k].inverse();
      out.T_first_station[k] = T;
      for (Measurement& r : moved[k].rows) {
        r.p_world_mm = T * r.p_world_mm;
        if (r.has_orientation) r.R_world_tcp = Eigen::Quaterniond(T.linear() * r.R_world_tcp.toRotationMatrix());
      }
    }
  }
  out.combined = identify_detail::combine(moved, &out.set_of_row);
  if (sets.size() > 1) {
    // a context column counts only when every set has it (a row without it has no value)
    for (const MeasurementSet& s : sets) {
      out.combined.has_payload = out.combined.has_payload && s.has_payload;
      out.combined.has_temperature = out.combined.has_temperature && s.has_temperature;
      out.combined.has_direction = out.combined.has_direction && s.has_direction;
      out.combined.has_time = out.combined.has_time && s.has_time;
    }
    out.combined.file = sets[0].file;
    for (size_t k = 1; k < sets.size(); ++k) out.combined.file += " + " + sets[k].file;
  }
  return out;
}

namespace {

/// The gross rows of each set (and of the validation) left out, in `excluded`: a lost beam
/// would decide the noise floor and every held-out error (removeGrossRows; each set in its own
/// station frame, the tool point estimated).
std::vector<MeasurementSet> withoutGrossRows(const RobotModel& start, const std::vector<MeasurementSet>& sets,
                                            const MeasurementSet* validation, std::optional<MeasurementSet>& validation_out,
                                            std::vector<ExcludedRow>& excluded) {
  std::vector<MeasurementSet> out = sets;
  for (MeasurementSet& d : out) {
    const std::vector<ExcludedRow> e = removeGrossRows(start, d, true, true);
    excluded.insert(excluded.end(), e.begin(), e.end());
  }
  if (validation) {
    validation_out = *validation;
    const std::vector<ExcludedRow> e = removeGrossRows(start, *validation_out, true, true);
    excluded.insert(excluded.end(), e.begin(), e.end());
  }
  return out;
}

/// The rows of each set (and of the validation) written twice, left out before anything else:
/// the same measurement counts once in every statistic (removeDuplicatedRows; repeats are
/// looked for within each file). Returns them as Floors::duplicated_rows names them.
std::vector<RepeatPair> withoutDuplicatedRows(std::vector<MeasurementSet>& sets, std::optional<MeasurementSet>& validation,
                                              double tol) {
  std::vector<RepeatPair> out;
  auto take = [&](MeasurementSet& set, bool is_validation) {
    for (const DuplicatedRow& d : removeDuplicatedRows(set, tol)) {
      RepeatPair e;
      e.index_a = d.index;
      e.index_b = d.same_as_index;
      e.line_a = d.line;
      e.line_b = d.same_as_line;
      e.distance_mm = 0;
      e.validation = is_validation;
      e.file = set.file;
      out.push_back(e);
    }
  };
  for (MeasurementSet& s : sets) take(s, false);
  if (validation) take(*validation, true);
  return out;
}

/// The stale readings (staleReadings) of each set and of the validation, as warnings; found
/// after the rows written twice are out, before the gross rows are (a stale row is often one).
/// And a validation that is most likely the fit data exported again
/// (validationLooksLikeFitDataWarning).
std::vector<std::string> staleReadingWarnings(const std::vector<MeasurementSet>& sets, const MeasurementSet* validation, double tol) {
  std::vector<std::string> out;
  for (const MeasurementSet& s : sets)
    if (std::string w = staleReadingsWarning(s.file, staleReadings(s, tol)); !w.empty()) out.push_back(std::move(w));
  if (validation) {
    if (std::string w = staleReadingsWarning(validation->file, staleReadings(*validation, tol)); !w.empty()) out.push_back(std::move(w));
    if (std::string w = validationLooksLikeFitDataWarning(sets, *validation); !w.empty()) out.push_back(std::move(w));
  }
  return out;
}

}  // namespace

Diagnosis diagnose(const RobotModel& start, const std::vector<MeasurementSet>& sets_given, bool same_station,
                   const MeasurementSet* validation_given, const DiagnoseOptions& options, StationSets* stations) {
  refuseSharedMeasurements(sets_given);  // the same data twice would count twice
  std::vector<MeasurementSet> sets_in = sets_given;
  std::optional<MeasurementSet> validation_copy;
  if (validation_given) validation_copy = *validation_given;
  const std::vector<RepeatPair> duplicated = withoutDuplicatedRows(sets_in, validation_copy, options.repeat_tol);
  const MeasurementSet* validation_in = validation_copy ? &*validation_copy : nullptr;
  std::vector<ExcludedRow> excluded;
  std::optional<MeasurementSet> screened_validation;
  const std::vector<MeasurementSet> sets = withoutGrossRows(start, sets_in, validation_in, screened_validation, excluded);
  const MeasurementSet* validation = screened_validation ? &*screened_validation : nullptr;
  auto pass = [&](const StationSets& data) {
    diagnose_detail::Diagnoser d(start, data.combined, validation, options);
    if (data.files.size() > 1) d.setRowSets(data.set_of_row, data.files, !same_station);
    return d.run();
  };
  StationSets st = combineStations(start, sets, same_station);
  Diagnosis d = pass(st);
  if (sets.size() > 1 && !same_station && d.identify_params != "geometric") {
    std::vector<std::string> groups;
    std::string g;
    for (char c : d.identify_params + ",") {
      if (c != ',') {
        g += c;
      } else if (!g.empty()) {
        groups.push_back(g);
        g.clear();
      }
    }
    st = combineStations(start, sets, same_station, groups);
    d = pass(st);
    d.notes.push_back("stations registered by the geometric model plus " + d.identify_params.substr(std::string("geometric").size() + 1) +
                      " (what a first pass with the geometric model alone selected), then diagnosed again");
  }
  for (const HeldJoint& h : heldJoints(st.combined, start.nominal, options.repeat_tol))
    d.warnings.push_back(heldJointWarning(start.nominal, h, st.combined.rows.size(), options.repeat_tol));
  for (const std::string& w : staleReadingWarnings(sets_in, validation_in, options.repeat_tol)) d.warnings.push_back(w);
  if (stations) *stations = std::move(st);
  d.excluded = excluded;
  d.floors.duplicated_rows = duplicated;
  return d;
}

Diagnosis diagnose(const RobotModel& start, const MeasurementSet& data_given, const MeasurementSet* validation_given,
                   const DiagnoseOptions& options) {
  std::vector<MeasurementSet> given = {data_given};
  std::optional<MeasurementSet> validation_copy;
  if (validation_given) validation_copy = *validation_given;
  const std::vector<RepeatPair> duplicated = withoutDuplicatedRows(given, validation_copy, options.repeat_tol);
  std::vector<ExcludedRow> excluded;
  std::optional<MeasurementSet> screened_validation;
  const MeasurementSet data =
      withoutGrossRows(start, given, validation_copy ? &*validation_copy : nullptr, screened_validation, excluded).front();
  diagnose_detail::Diagnoser d(start, data, screened_validation ? &*screened_validation : nullptr, options);
  Diagnosis out = d.run();
  out.excluded = excluded;
  out.floors.duplicated_rows = duplicated;
  for (const HeldJoint& h : heldJoints(data, start.nominal, options.repeat_tol))
    out.warnings.push_back(heldJointWarning(start.nominal, h, data.rows.size(), options.repeat_tol));
  for (const std::string& w : staleReadingWarnings(given, validation_copy ? &*validation_copy : nullptr, options.repeat_tol))
    out.warnings.push_back(w);
  return out;
}

}  // namespace accura::calib
