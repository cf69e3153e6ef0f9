// RAPID reader and writer internals (rapid.h): tokens, pose conversions, the predefined data.
#pragma once

#include <Eigen/Geometry>
#include <optional>
#include <string>
#include <vector>

#include "accura/postproc/rapid.h"

namespace accura::postproc::rapid_detail {

struct Tok {
  enum class Kind { kIdent, kNumber, kString, kOp };
  Kind kind = Kind::kOp;
  size_t b = 0, e = 0;
  std::string s;   ///< as written
  std::string u;   ///< upper case (identifiers: RAPID is case-insensitive)
  double num = 0;
};

/// Tokens of `text` (comments '!' and %%% headers skipped). Throws calib::InputError
/// (`path`:line:column) on a NUL byte, an unterminated string or a malformed number.
std::vector<Tok> lexRapid(const std::string& text, const std::string& path);

/// The largest position component accepted (mm): beyond any robot cell, a typo.
constexpr double kMaxPositionMm = 1e5;
/// The largest RelTool rotation accepted (deg).
constexpr double kMaxAngleDeg = 1e4;
/// A quaternion whose norm is off 1 by more than this is an error; within it, normalised.
constexpr double kQuaternionNormTol = 1e-3;
/// An external axis value at or beyond this is ABB's "not used" (9E9).
constexpr double kUnusedAxis = 8.99e9;

/// T (mm) of a position (mm) and a unit quaternion (w, x, y, z).
Eigen::Isometry3d poseOf(const double xyz[3], const double wxyz[4]);
/// The quaternion (w, x, y, z) of R with the sign of `near` (w, x, y, z; the one nearer).
std::array<double, 4> quaternionNear(const Eigen::Matrix3d& R, const double near[4]);

/// The TCP zone radius (mm) of a predefined zonedata (z0 -> 0.3, z1, z5, ..., z200);
/// nullopt when `upper` is not one.
std::optional<double> predefinedZoneMm(const std::string& upper);
/// The TCP speed (mm/s) of a predefined speeddata (v5 .. v7000); nullopt when not one.
std::optional<double> predefinedSpeedMmS(const std::string& upper);

/// MoveL, MoveJ, MoveC or MoveAbsJ (`upper`: upper case): the motion instructions that only move
/// (the MoveLDO, TriggL, ArcL, ... family does something else besides).
inline bool isPlainMove(const std::string& upper) { return upper == "MOVEL" || upper == "MOVEJ" || upper == "MOVEC" || upper == "MOVEABSJ"; }

using Range = std::pair<size_t, size_t>;  ///< token indices [first, second)

bool isOp(const std::vector<Tok>& t, size_t i, const char* s);
/// Identifier `u` (upper case) at i.
bool isKw(const std::vector<Tok>& t, size_t i, const char* u);
bool opens(const Tok& t);
bool closes(const Tok& t);
/// Index one past the bracket closing the one at i (end when none).
size_t closing(const std::vector<Tok>& t, size_t i, size_t end);
/// Comma-separated items of [i, j) at bracket depth 0.
std::vector<Range> items(const std::vector<Tok>& t, size_t i, size_t j);
/// A signed number written as [+|-] number, else nullopt.
std::optional<double> number(const std::vector<Tok>& t, Range r);

/// Every code line of `src` outside the motion model (`model_line`, by line number) as a
/// PassThrough of language RAPID (comment-only and blank lines are not statements): module
/// level -> kData, the routine `main_routine` -> kBody (before the motions that follow it,
/// `motion_lines`), other routines -> kTrailer (refused by other formats when
/// `other_routine_motion`: their motions are not the main routine's).
void rapidPassThrough(const RapidSource& src, const std::vector<Tok>& tokens, const std::vector<Range>& statements,
                      const std::vector<size_t>& line_starts, const std::vector<bool>& model_line, const std::vector<int>& motion_lines,
                      const std::string& main_routine, bool other_routine_motion, Program& p);

/// Line-number helper: the location of byte `off`.
SourceLocation locate(const std::vector<size_t>& line_starts, const std::string& path, size_t off);

}  // namespace accura::postproc::rapid_detail
