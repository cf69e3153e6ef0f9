// accura post-processor: KUKA KRL programs (.src with its .dat), read into the shared Program
// representation and written back byte for byte with only the corrected values changed and the
// auxiliary points inserted (docs/program-formats.md).
//
// What the reader understands (keywords case-insensitive):
//   motions   PTP LIN CIRC SPTP SLIN SCIRC SPL (inside SPLINE..ENDSPLINE), *_REL (not
//             compensated), targets inline ({X ..}, {E6POS: ..}, {AXIS: A1 ..}) or named
//             (DECL E6POS/POS/FRAME/E6AXIS/AXIS in the .dat, the .src or the $config.dat;
//             an element of a point array given a value there, XPA[1]={X ..}: "XPA[1]"),
//             CIRC's CA, approximation C_PTP C_DIS C_VEL C_ORI C_SPL, WITH clauses of spline
//             motions ($TOOL = STOOL2(F), $BASE = SBASE(F.BASE_NO), $VEL = SVEL_CP(v,..),
//             $VEL_AXIS[1] = SVEL_JOINT(v), $APO = SAPO(L) / SAPO_PTP(P)); a SPLINE block's
//             WITH clause ($TOOL, $BASE, $VEL.CP) holds for every motion of the block.
//   frames    $TOOL / $BASE = inline frame, TOOL_DATA[n] / BASE_DATA[n], $NULLFRAME;
//             BAS(#TOOL,n), BAS(#BASE,n); inline forms: FDAT_ACT = F.. then BAS(#PTP_PARAMS,v),
//             BAS(#CP_PARAMS,v) or BAS(#FRAMES); TOOL_DATA / BASE_DATA resolved from the
//             $config.dat when one is given.
//   speeds    $VEL.CP, $VEL_AXIS[n], BAS(#VEL_PTP / #VEL_CP / #PTP_PARAMS / #CP_PARAMS, v),
//             LDAT / PDAT of the inline forms; $APO.CDIS / CPTP / CVEL / CORI, APO_DIST.
//   the rest  comments, FOLDs (;FOLD .. ;ENDFOLD, inline forms with ;%{PE}), logic, I/O,
//             declarations of other types: kept as text, passed through.
// Errors (accura::calib::InputError, file:line:column, what was expected and what was found): a
// malformed aggregate of a target or frame, an unknown component, a component given twice, a
// motion statement without a target, an unterminated string.
#pragma once

#include <map>
#include <string>

#include "accura/postproc/program.h"

namespace accura::postproc {

struct KrlReadOptions {
  /// The .dat file; empty: the .src's name with the extension .dat (any case) when that file
  /// exists, else none.
  std::string dat_path;
  /// $config.dat (TOOL_DATA, BASE_DATA, global points such as XHOME); empty: none.
  std::string config_path;
  /// The GLOBAL points of other programs' data lists (upper-case name -> where declared;
  /// krlGlobalPoints), e.g. of the other programs of a batch. Not read as values: a motion of
  /// this program to one of them is kept as written, and its warning says where the point is
  /// declared (its value there is that program's, corrected for that program's motions).
  std::map<std::string, SourceLocation> other_globals;
};

/// Reads a KRL program. Throws InputError (file:line:column) on a malformed target, frame or
/// motion statement, on an unreadable or binary file.
Program readKrl(const std::string& src_path, const KrlReadOptions& options = {});

/// The .dat readKrl pairs with `src_path` when no dat_path is given: the file of the same stem
/// and extension .dat in its directory, the exact-case one first, else the first of the
/// case-insensitive matches in byte order; "" when there is none.
std::string krlDatPath(const std::string& src_path);

/// Reads TOOL_DATA[n] / BASE_DATA[n] from a $config.dat. Throws InputError.
FrameTables readKrlFrameTables(const std::string& config_path);

/// The points a data list (.dat) declares GLOBAL (DECL GLOBAL E6POS XG1={..}; the elements of a
/// GLOBAL point array, "XPA[1]"): upper-case name -> where declared. Throws InputError on an
/// unreadable or malformed file.
std::map<std::string, SourceLocation> krlGlobalPoints(const std::string& dat_path);

/// The text of a program as .src and .dat files.
struct KrlText {
  std::string src;
  std::string dat;  ///< empty when the program has no .dat
};

/// Writes a program as KRL. A program read from KRL (program.krl set) is written back byte for
/// byte, except the values of targets marked `modified` (rewritten in place with the number
/// formats of program.h) and the motions marked `inserted` (a copy of their anchor statement
/// with inline targets, inserted on the line before it); a modified target declared outside
/// the program's files (a $config.dat point, never rewritten) is written into its motion's
/// statement as an inline aggregate. Any other program is written as a new .src and .dat
/// (named targets declared in the .dat). Throws ArgumentError when two motions need different
/// values in one declaration.
KrlText writeKrl(const Program& program);

/// The aggregate text of a target, e.g. "{X 1.0000,Y ..,A 0.00000,..,S 2,T 35}" (pose with the
/// program.h number formats; S, T, external axes as given).
std::string krlAggregate(const Target& target);

}  // namespace accura::postproc
