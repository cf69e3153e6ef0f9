// accura: simulated measurement campaigns: a perturbed ("real") robot measured by a tracker.
// For the demo, the tests, and for planning a campaign before going to the robot.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "accura/calib/measurements.h"
#include "accura/calib/robot.h"

namespace accura::calib {

/// An effect outside the effect catalogue, for `accura selfcheck` only: joint `to` turns
/// (moves, if prismatic) by `ratio` times the value of joint `from` (q_from in rad, or mm),
/// a cross-coupling of the wrist gears that no catalogued effect describes. It is not part of
/// any RobotModel (a model cannot carry it, which is the point): simulateMeasurements applies
/// it to the joint values the real robot reaches, and the file records the commanded ones.
struct JointCoupling {
  int from = -1, to = -1;  ///< 0-based joints; -1: none
  double ratio = 0;        ///< rad per rad (revolute `to`), mm per rad or mm per mm otherwise
};

/// The coupling used for the effect "unmodelled_coupling" when none is given: the
/// second-to-last joint moves with the one before it (6R: A5 with A4), 200e-6 rad/rad
/// (0.05 mm/rad when that joint is prismatic). Throws ArgumentError for fewer than 2 joints.
JointCoupling defaultCoupling(const RobotModel& model);

struct SimulateOptions {
  int poses = 300;
  std::uint64_t seed = 1;
  /// Errors to put into the real robot: "geometric" (base = the tracker station below,
  /// tool, offsets, lengths, angles) and the effect catalogue (magnitudes drawn from the
  /// seed, per joint): "joint_compliance" (0.5-1.5 urad/Nm on joints 1-3, 2-6 urad/Nm on the
  /// others; 0.5-1.5 um/N prismatic), "gear_periodic" (each harmonic 1..H of every revolute
  /// joint: amplitude 0.004-0.012 deg, random phase), "joint_scale" (+-50..150 ppm),
  /// "backlash" (full width 0.006-0.016 deg; 0.005-0.015 mm prismatic), "thermal"
  /// (alpha 15-25 ppm/K); and "unmodelled_coupling" (see JointCoupling; for the selfcheck).
  /// "none": measure the model as given.
  std::vector<std::string> effects = {"geometric"};
  /// The coupling applied with "unmodelled_coupling"; ratio 0: defaultCoupling().
  JointCoupling coupling;
  /// Every repeat_every-th row measures the previous pose again (same q, directions and
  /// payload, the next time stamp): repeated poses give the diagnosis a noise floor.
  /// 0: no repeats.
  int repeat_every = 0;
  /// Measurement noise: one standard deviation per axis (mm) and per rotation axis (deg).
  double noise_mm = 0.02;
  double noise_deg = 0.002;
  bool orientation = false;      ///< also write the measured orientation (qw..qz)
  bool write_std = false;        ///< write std columns (the noise levels above)
  /// Payload masses (kg) cycled over the poses.
  std::vector<double> payloads_kg = {0.0};
  /// Where the robot base stands in the tracker frame (T_world_base of the real robot), used
  /// when set_station: 3 m from the tracker, turned 30 deg about z and slightly tilted
  /// (tracker not level).
  XyzAbc station = {2400.0, -1700.0, -600.0, 30.0, 0.4, -0.3};
  bool set_station = true;
  /// The measured target on the flange (nominal T_flange_tcp of the real robot), used when
  /// set_tool; the "geometric" effect adds its error on top.
  XyzAbc tool = {};
  bool set_tool = false;
  /// Fraction of each joint range kept free at both ends when drawing random poses.
  double limit_margin = 0.05;
  /// Scale of the random geometric errors: lengths 0.3 mm, angles 0.03 deg (1 sigma) times
  /// this factor.
  double error_scale = 1.0;

  bool IsValid(std::string* error) const;
};

/// The "real" robot: `nominal` with the errors of options.effects drawn from options.seed.
RobotModel perturbModel(const RobotModel& nominal, const SimulateOptions& options);

/// Measurements of `truth` at random poses within its joint limits: positions (and with
/// options.orientation, orientations) with Gaussian noise, and every context column
/// (payload_kg, temp_c, dir1..dirN, time_s) whatever the effects are. The temperature warms
/// up from 19 to 25 C over the campaign with a +-0.8 C ripple (hall ventilation); time_s is
/// 30 s per row; each joint's approach direction is random. Deterministic for a given seed.
MeasurementSet simulateMeasurements(const RobotModel& truth, const SimulateOptions& options);

}  // namespace accura::calib
