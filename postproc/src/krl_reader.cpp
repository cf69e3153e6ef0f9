// KRL reader: the .src (motions, frames, speeds) on top of the data part (see krl.h).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "accura/calib/errors.h"
#include "krl_internal.h"
#include "start_tracker.h"

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

using namespace krl_detail;

// ---------------------------------------------------------------------------------------------
// The .src

bool isMotionKeyword(const std::string& up) {
  static const std::set<std::string> k = {"PTP", "LIN", "CIRC", "SPTP", "SLIN", "SCIRC", "SPL",
                                          "PTP_REL", "LIN_REL", "CIRC_REL", "SPTP_REL", "SLIN_REL", "SCIRC_REL", "SPL_REL"};
  return k.count(up) > 0;
}

bool isApproxTok(const Tok& t) {
  Approximation a;
  return t.kind == Tok::kIdent && parseApproximation(t.text, &a);
}

// DECL [GLOBAL] [CONST] TYPE ...: true for the types of the motion model (points, FDAT, LDAT,
// PDAT), whose values the model holds.
bool declaresModelType(const std::vector<Tok>& t) {
  for (const Tok& x : t) {
    if (x.kind != Tok::kIdent || x.up == "DECL" || x.up == "GLOBAL" || x.up == "CONST") continue;
    return isPointType(x.up) || x.up == "FDAT" || x.up == "LDAT" || x.up == "PDAT";
  }
  return false;
}

// The items of a declaration of points, DECL [GLOBAL] [CONST] E6POS XP1={..}, XP2, ..: the
// token ranges [first, last] between its depth-0 commas; none for a declaration of another type.
std::vector<std::pair<size_t, size_t>> declarationItems(const std::vector<Tok>& t) {
  size_t i = 0;
  while (i < t.size() && t[i].kind == Tok::kIdent && (t[i].up == "DECL" || t[i].up == "GLOBAL" || t[i].up == "CONST")) ++i;
  std::vector<std::pair<size_t, size_t>> items;
  if (i >= t.size() || !isPointType(t[i].up)) return items;
  int depth = 0;
  size_t first = i + 1;
  for (size_t k = i + 1; k <= t.size(); ++k) {
    if (k < t.size()) {
      const std::string& x = t[k].text;
      if (x == "[" || x == "(" || x == "{") ++depth;
      if (x == "]" || x == ")" || x == "}") --depth;
      if (!(depth == 0 && x == ",")) continue;
    }
    if (first < k) items.emplace_back(first, k - 1);
    first = k + 1;
  }
  return items;
}

// The names (upper case) a declaration of points gives a value: DECL [GLOBAL] [CONST] E6POS
// XP1={..}, XP2={..} -> XP1, XP2; none for other types and for names without a value.
std::vector<std::string> pointsDeclaredWithValue(const std::vector<Tok>& t) {
  std::vector<std::string> names;
  for (const auto& [first, last] : declarationItems(t))
    if (last > first && t[first].kind == Tok::kIdent && t[first + 1].kind == Tok::kPunct && t[first + 1].text == "=")
      names.push_back(t[first].up);
  return names;
}

// A declaration line of several points (DECL E6POS XP1={..},XP9={..}) without the points the
// motion model declares itself (`model`), which a KRL program written anew declares once: the
// line's text with the others only, its comment kept. `l` is the line of `f`, `t` its tokens.
std::string withoutModelPoints(const KrlFile& f, const Line& l, const std::vector<Tok>& t, const std::set<std::string>& model) {
  const std::vector<std::pair<size_t, size_t>> items = declarationItems(t);
  const std::string& text = f.text();
  std::string kept;
  for (const auto& [first, last] : items)
    if (!model.count(t[first].up)) kept += (kept.empty() ? "" : ",") + text.substr(t[first].begin, t[last].end - t[first].begin);
  if (kept.empty()) return std::string();
  return text.substr(l.begin, t[items.front().first].begin - l.begin) + kept + text.substr(t.back().end, l.content_end - t.back().end);
}

// How many of the points `names` (upper case) the model declares itself (`model`,
// pointsTheModelDeclares): none, some (the line carries the others: withoutModelPoints) or all.
size_t declaredByModel(const std::vector<std::string>& names, const std::set<std::string>& model) {
  return static_cast<size_t>(std::count_if(names.begin(), names.end(), [&](const std::string& n) { return model.count(n) > 0; }));
}

// The points (upper case) a KRL program written anew from the motion model declares itself
// (generateKrl): the named targets with a value that are not the $config.dat's. The
// declaration of any other point is carried as a pass-through statement (readKrl).
std::set<std::string> pointsTheModelDeclares(const Program& program) {
  std::set<std::string> out;
  for (const Motion& m : program.motions)
    for (const Target* x : {&m.target, m.aux ? &*m.aux : nullptr}) {
      if (!x || x->name.empty() || x->external) continue;
      bool any = false;
      for (const auto& c : x->pose) any = any || c.has_value();
      for (const auto& c : x->axes) any = any || c.has_value();
      if (any) out.insert(upper(x->name));
    }
  return out;
}

// INTERRUPT DECL n WHEN .. DO handler( ) (also GLOBAL): it declares the handler, it does not
// call it (the handler runs when the condition fires, wherever the program is).
bool declaresInterrupt(const std::vector<Tok>& t) {
  const size_t i = !t.empty() && t[0].up == "GLOBAL" ? 1 : 0;
  return t.size() > i + 1 && t[i].up == "INTERRUPT" && t[i + 1].up == "DECL";
}

// An assignment's depth-0 '=' (not '==', nor one inside an index or a call): its index in t,
// 0 when the statement is not an assignment.
size_t assignmentEnd(const std::vector<Tok>& t) {
  if (t.empty() || t[0].kind != Tok::kIdent) return 0;
  int depth = 0;
  for (size_t i = 1; i < t.size(); ++i) {
    const std::string& x = t[i].text;
    if (x == "[" || x == "(") ++depth;
    else if (x == "]" || x == ")") --depth;
    else if (depth == 0 && x == "=" && t[i].kind == Tok::kPunct) return i;
    else if (depth == 0 && x != "." && t[i].kind == Tok::kPunct) break;
  }
  return 0;
}

struct Reader {
  Declarations decl;
  std::map<std::string, SourceLocation> other_globals;  // KrlReadOptions::other_globals
  KrlSource* src = nullptr;
  Program* program = nullptr;
  const KrlFile* f = nullptr;

  FrameSetting tool, base;
  bool external_tcp = false;
  std::string fdat_name;  // as assigned to FDAT_ACT (upper case), "" none or an aggregate
  std::optional<Fdat> fdat;
  std::string fdat_problem;
  std::optional<MoveData> ldat, pdat;
  // why LDAT_ACT's values are not known where `ldat` is empty (BAS(#CP_PARAMS) makes its ORI_TYP
  // the $ORI_TYPE): not set by the program, or an LDAT the files do not declare
  std::string ldat_unknown_ = "the program does not set LDAT_ACT before it";
  std::optional<double> vel_cp, vel_ptp, apo_cdis, apo_cptp, apo_cvel, apo_cori;
  std::string ori_type_;  // $ORI_TYPE (Motion::ori_type): "" #VAR, the default; "?why" not known here
  std::string circ_type_;  // $CIRC_TYPE (Motion::circ_type): "" #BASE, the default; "?why" not known here
  // The program gives $ORI_TYPE / $CIRC_TYPE a value other than the default somewhere (an
  // assignment, an LDAT, a WITH): only then can a branch, a caller or a call leave it unknown
  bool ori_varies_ = false, circ_varies_ = false;
  std::set<std::string> ori_defs_, circ_defs_;  // the routines that set $ORI_TYPE / $CIRC_TYPE (themselves or through their calls)
  static std::string unknownOri(const std::string& why) { return "?" + why; }
  bool in_spline = false;
  /// The frames and speeds a SPLINE / PTP_SPLINE block's WITH clause sets for its motions
  /// (tool, base, external_tcp, vel_m_s, vel_percent); none outside a block or without WITH.
  std::optional<Motion> spline_block_;
  std::string first_function_;   // the file's first DEFFCT: "name (file:line:column)"
  std::vector<std::pair<std::string, int>> structure_;  // the open IF, SWITCH, loops, spline blocks: keyword, line
  int spline_blocks_ = 0;         // SPLINE / PTP_SPLINE blocks so far
  int spline_block_number_ = 0;   // the open block's number (Motion::spline_block), 0: none
  bool ptp_spline_block_ = false; // the open block is a PTP_SPLINE block
  int triggers = 0;
  bool missing_dat_ = false;  // resolveTarget met a named point and no .dat (Motion::target_file_missing)
  bool main_started = false, main_ended = false;  // the main program's DEF / END seen
  StartTracker flow_;  // where the robot comes from (Motion::start_unknown)
  bool def_open_ = false;  // a DEF (main or local) not closed by its END yet
  int def_line_ = 0;       // the line of that DEF
  bool def_fct_ = false;   // that DEF is a DEFFCT (closed by ENDFCT)
  std::string openEnd() const { return def_fct_ ? "ENDFCT closing the DEFFCT" : "END closing the DEF"; }

  // The KRL words that open a branch or a loop, and those that close one (not a spline block's:
  // its motions run one after the other).
  static bool opensBranch(const std::string& k) { return blockOpenedBy(k) && blockOpenedBy(k)->kind == BlockWords::kBranch; }
  static bool opensLoop(const std::string& k) { return blockOpenedBy(k) && blockOpenedBy(k)->kind == BlockWords::kLoop; }
  static bool closesBlock(const std::string& k) { return blockClosedBy(k) && blockClosedBy(k)->kind != BlockWords::kSpline; }

  // The nesting of the control structures, as the KRL compiler checks it: every IF, SWITCH, FOR,
  // WHILE, LOOP and REPEAT closed by its own end inside its routine, ELSE inside an IF, CASE and
  // DEFAULT inside a SWITCH. A file that breaks it is not a program the controller runs: an
  // error at the statement that breaks it (the structure decides where the robot may come from).
  void checkStructure(const std::vector<Tok>& t) {
    const std::string& k = t[0].up;
    if (t[0].kind != Tok::kIdent) return;
    const auto open = [&]() {
      const auto& [kw, line] = structure_.back();
      return "the " + kw + " at line " + std::to_string(line);
    };
    // the word that closes the innermost open block
    const auto end = [&]() { return std::string(blockOpenedBy(structure_.back().first)->close); };
    if (blockOpenedBy(k)) {
      structure_.emplace_back(k, f->loc(t[0].begin).line);
      return;
    }
    const bool routine_end = (k == "END" || k == "ENDFCT") && t.size() == 1;
    const bool routine_start = k == "DEF" || k == "DEFFCT" || (k == "GLOBAL" && t.size() > 1 && (t[1].up == "DEF" || t[1].up == "DEFFCT"));
    if ((routine_end || routine_start) && !structure_.empty())
      f->fail(t[0].begin, "expected " + end() + " to close " + open() + ", found " + t[0].text);
    if (k == "ELSE" && (structure_.empty() || structure_.back().first != "IF"))
      f->fail(t[0].begin, "expected ELSE inside an IF, found it " +
                              (structure_.empty() ? std::string("outside any block") : "inside " + open() + " (not closed)"));
    if ((k == "CASE" || k == "DEFAULT") && (structure_.empty() || structure_.back().first != "SWITCH"))
      f->fail(t[0].begin, "expected " + t[0].text + " inside a SWITCH, found it " +
                              (structure_.empty() ? std::string("outside any block") : "inside " + open() + " (not closed)"));
    if (k == "ENDSPLINE") {  // closes either kind of spline block
      if (structure_.empty()) f->fail(t[0].begin, "expected ENDSPLINE to close a SPLINE or PTP_SPLINE block, found no open block");
      if (end() != "ENDSPLINE") f->fail(t[0].begin, "expected " + end() + " to close " + open() + ", found ENDSPLINE");
      structure_.pop_back();
      return;
    }
    if (const BlockWords* b = blockClosedBy(k)) {
      const std::string kw = b->open;
      if (structure_.empty()) f->fail(t[0].begin, "expected " + k + " to close a " + kw + ", found no open " + kw);
      if (structure_.back().first != kw) f->fail(t[0].begin, "expected " + end() + " to close " + open() + ", found " + t[0].text);
      structure_.pop_back();
    }
  }

  // A statement that branches, loops or jumps (KRL control flow).
  void controlFlow(const std::vector<Tok>& t) {
    const std::string& k = t[0].up;
    const bool label = t.size() == 2 && t[0].kind == Tok::kIdent && t[1].text == ":";
    if (opensBranch(k)) {
      flow_.open(StartTracker::Block::kBranch);
      frame_blocks_.push_back({tool, base, false, false, t[0].text, f->loc(t[0].begin).line, 0, false, ori_type_, circ_type_});
    } else if (startsBranch(k)) {
      flow_.branch();
      if (!frame_blocks_.empty()) {  // each branch starts with the frames the block was entered with
        FrameBlock& fb = frame_blocks_.back();
        fb.tool_changed = fb.tool_changed || !sameFrame(tool, fb.tool);
        fb.base_changed = fb.base_changed || !sameFrame(base, fb.base);
        tool = fb.tool;
        base = fb.base;
        fb.ori_changed = fb.ori_changed || ori_type_ != fb.ori;
        fb.circ_changed = fb.circ_changed || circ_type_ != fb.circ;
        ori_type_ = fb.ori;
        circ_type_ = fb.circ;
      }
    } else if (opensLoop(k)) {
      flow_.open(StartTracker::Block::kLoop);
      frame_blocks_.push_back(
          {tool, base, false, false, t[0].text, f->loc(t[0].begin).line, program->motions.size(), true, ori_type_, circ_type_});
    } else if (closesBlock(k)) {
      flow_.close();
      if (!frame_blocks_.empty()) {
        // a frame a branch or a loop set differently is, after the block, whichever the run took
        const FrameBlock fb = frame_blocks_.back();
        frame_blocks_.pop_back();
        auto after = [&](FrameSetting& cur, const FrameSetting& entry, bool changed, const char* name) {
          if (!changed && sameFrame(cur, entry)) return;
          cur = runTimeFrame(name, f->loc(t[0].begin),
                             std::string(name) + " is set inside the " + fb.kind + " at line " + std::to_string(fb.line) +
                                 ": after it, its value depends on the way the program ran");
        };
        // a loop's next pass: its motions before the change run with the changed frame
        if (fb.loop)
          for (size_t i = fb.first_motion; i < program->motions.size(); ++i) {
            Motion& m = program->motions[i];
            for (auto [ms, cur, entry, name] : {std::make_tuple(&m.tool, &tool, &fb.tool, "$TOOL"), std::make_tuple(&m.base, &base, &fb.base, "$BASE")})
              if (!sameFrame(*cur, *entry) && sameFrame(*ms, *entry))
                *ms = runTimeFrame(name, f->loc(t[0].begin),
                                   std::string(name) + " is set later in the " + fb.kind + " at line " + std::to_string(fb.line) +
                                       ": the next pass runs this motion with the new value");
          }
        after(tool, fb.tool, fb.tool_changed, "$TOOL");
        after(base, fb.base, fb.base_changed, "$BASE");
        // $ORI_TYPE / $CIRC_TYPE the same way (a loop's motions before the change run with it
        // on the next pass; after a block that set it, whichever the run took)
        for (auto [cur, entry, changed, name, field] :
             {std::make_tuple(&ori_type_, &fb.ori, fb.ori_changed, "$ORI_TYPE", &Motion::ori_type),
              std::make_tuple(&circ_type_, &fb.circ, fb.circ_changed, "$CIRC_TYPE", &Motion::circ_type)}) {
          if (fb.loop && *cur != *entry)
            for (size_t i = fb.first_motion; i < program->motions.size(); ++i)
              if (program->motions[i].*field == *entry)
                program->motions[i].*field = unknownOri(std::string(name) + " is set later in the " + fb.kind + " at line " +
                                                        std::to_string(fb.line) + ": the next pass runs this motion with the new value");
          if (changed || *cur != *entry)
            *cur = unknownOri(std::string(name) + " is set inside the " + fb.kind + " at line " + std::to_string(fb.line) +
                              ": after it, its value depends on the way the program ran");
        }
      }
    } else if (k == "GOTO" || label) {
      flow_.unknown();
    }
  }
  /// At a subroutine's or function's start: $TOOL and $BASE are the caller's, run-time values
  /// until the routine sets them.
  void callerFrames(size_t at) {
    frame_blocks_.clear();
    ldat.reset();
    ldat_unknown_ = "a subroutine runs with the caller's LDAT_ACT until it sets its own";
    if (ori_varies_) ori_type_ = unknownOri("a subroutine runs with the caller's $ORI_TYPE until it sets its own");
    if (circ_varies_) circ_type_ = unknownOri("a subroutine runs with the caller's $CIRC_TYPE until it sets its own");
    for (const char* name : {"$TOOL", "$BASE"})
      (name[1] == 'T' ? tool : base) =
          runTimeFrame(name, f->loc(at), std::string("a subroutine runs with the caller's ") + name + " until it sets its own");
  }
  /// $TOOL / $BASE on entering an open IF, SWITCH or loop, and whether a branch changed them.
  struct FrameBlock {
    FrameSetting tool, base;
    bool tool_changed = false, base_changed = false;
    std::string kind;  // IF, SWITCH, FOR, ... as written
    int line = 0;
    size_t first_motion = 0;  // loops: the first motion of the body
    bool loop = false;
    std::string ori, circ;  // $ORI_TYPE / $CIRC_TYPE on entering the block
    bool ori_changed = false, circ_changed = false;
  };
  std::vector<FrameBlock> frame_blocks_;

  // A statement `name(...)` calling one of this file's subroutines that move the robot.
  // Calls of other modules' functions are taken not to move it: in KUKA programs they are the
  // technology packages' and the inline forms' (SET_CD_PARAMS, gripper and welding functions);
  // counting them would take the auxiliary points from every inline-form motion.
  bool isLocalCall(const std::vector<Tok>& t) const {
    // a subroutine's call is a statement; a function's (DEFFCT) is part of an expression
    for (size_t i = 0; i + 1 < t.size(); ++i)
      if (t[i].kind == Tok::kIdent && t[i + 1].text == "(" && local_defs_.count(t[i].up)) return true;
    return false;
  }
  std::set<std::string> local_defs_;  // the subroutines this .src defines that move the robot (upper case)
  // The names the routine being read holds itself (upper case -> why its value is not the data
  // list's): its parameters (NAME:IN / NAME:OUT, the value of the call) and, in a subroutine or a
  // function, the points it declares without a value. They hide the data list's points of
  // their names there (KRL: a routine's own data first), so a motion to one is not a motion to
  // the data list's point.
  std::map<std::string, std::string> routine_names_;

  // Starts a routine (DEF / DEFFCT line t, its name at `name_at`): its parameters.
  void startRoutine(const std::vector<Tok>& t, size_t name_at) {
    routine_names_.clear();
    routine_ = name_at < t.size() ? t[name_at].text : std::string();
    for (size_t i = name_at + 1; i + 1 < t.size(); ++i)
      if (t[i].kind == Tok::kIdent && t[i + 1].text == ":")
        routine_names_[t[i].up] = " is a parameter of " + routine_ + ": its value comes from the call";
  }
  std::string routine_;

  // A subroutine's or function's declaration line t of points without a value: its own.
  void noteRoutineDeclarations(const std::vector<Tok>& t) {
    size_t type = t[0].up == "DECL" ? 1 : 0;
    if (type < t.size() && t[type].up == "GLOBAL") ++type;
    if (type >= t.size() || !isPointType(t[type].up)) return;
    int depth = 0;
    for (size_t i = type + 1; i < t.size(); ++i) {
      const std::string& x = t[i].text;
      if (x == "[" || x == "(" || x == "{") ++depth;
      if (x == "]" || x == ")" || x == "}") --depth;
      if (depth == 0 && t[i].kind == Tok::kIdent && (i + 1 == t.size() || t[i + 1].text == "," || t[i + 1].text == "["))
        routine_names_.emplace(t[i].up, " is declared in " + routine_ + " without a value (" + f->loc(t[i].begin).str() +
                                            "): the routine's own, not the data list's point");
    }
  }
  std::set<std::string> tool_defs_, base_defs_;  // those that set $TOOL / $BASE (themselves or through their calls)
  std::set<std::string> defined_routines_;        // every DEF / DEFFCT of this .src (upper case)

  // A statement that only calls a routine this file does not define (`MoveSettings(1, 2)`; not
  // a control statement, nor one of KRL's own statements written with parentheses): its name.
  std::string externalCall(const std::vector<Tok>& t) const {
    static const std::set<std::string> kKrlStatements = {
        "IF", "WHILE", "UNTIL", "SWITCH", "CASE", "RETURN", "WAIT", "FOR", "REPEAT", "LOOP", "EXIT", "ELSE", "GOTO",
        "HALT", "INTERRUPT", "TRIGGER", "PULSE", "ANIN", "ANOUT", "CWRITE", "CREAD", "SWRITE", "SREAD", "BRAKE", "RESUME",
        "CAST_TO", "CAST_FROM", "COPEN", "CCLOSE", "CIOCTL", "SET_CD_PARAMS", "ON_ERROR_PROCEED", "STRCLEAR", "STRCOPY",
        "STRADD", "STRFIND", "STRCOMP", "STRLEN", "STRDECLLEN", "WAIT_FOR_ON", "EB_TEST"};
    if (t.size() < 3 || t[0].kind != Tok::kIdent || t[1].text != "(" || t.back().text != ")") return "";
    if (kKrlStatements.count(t[0].up) || defined_routines_.count(t[0].up)) return "";
    int depth = 0;
    for (size_t i = 1; i < t.size(); ++i) {
      depth += t[i].text == "(" ? 1 : t[i].text == ")" ? -1 : 0;
      if (depth == 0 && i + 1 < t.size()) return "";  // the call's ')' is not the statement's end
    }
    return t[0].text;
  }
  // Points whose value at a motion may not be the one the text before it gives, whatever the
  // motion's place: assigned inside a branch, a loop, a subroutine or a function (the order of
  // the text is not the order of the run). Upper-case name -> why. (A point changed from its own
  // value in the main program's straight line: pointChanged.)
  std::map<std::string, std::string> volatile_points_;
  std::map<std::string, std::string> assigned_points_;  // every point the .src assigns: where (first)
  std::string refuse;  // why the line just read cannot be converted ("" when it can)

  FrameSetting dataFrame(bool is_tool, int n, size_t at) const {
    FrameSetting s;
    s.where = f->loc(at);
    if (n == 0) {
      s.source = FrameSetting::Source::kNull;
      s.value = calib::XyzAbc{};
      s.text = is_tool ? "TOOL_DATA[0] ($NULLFRAME)" : "BASE_DATA[0] ($NULLFRAME)";
      return s;
    }
    s.source = FrameSetting::Source::kData;
    s.index = n;
    s.text = std::string(is_tool ? "TOOL_DATA[" : "BASE_DATA[") + std::to_string(n) + "]";
    s.value = tableValue(is_tool ? decl.tables.tool : decl.tables.base, n);
    return s;
  }

  FrameSetting unknownFrame(const std::string& text, size_t at, const std::string& note = "") const {
    FrameSetting s;
    s.source = FrameSetting::Source::kUnknown;
    s.text = text;
    s.note = note;
    s.where = f->loc(at);
    return s;
  }

  // Evaluates the right-hand side of $TOOL = ... / $BASE = ... (tokens [b, e)): an aggregate
  // (its missing components from `current`: KRL changes only the components it lists),
  // $NULLFRAME, TOOL_DATA[n] / BASE_DATA[n], a FRAME / POS / E6POS of the data lists, $TOOL,
  // $BASE, or the frame linkage of such operands with KRL's geometric operator
  // ($BASE = $BASE:{X 10,Y 0,Z 0,A 0,B 0,C 0}: A:B is T_A * T_B).
  FrameSetting evalFrame(const std::vector<Tok>& toks, size_t b, size_t e, bool is_tool, const FrameSetting& current) const {
    const std::string text = f->text().substr(toks[b].begin, toks[e - 1].end - toks[b].begin);
    // the operands of ':' at depth 0 (an aggregate's own "FRAME:" is inside its braces)
    std::vector<std::pair<size_t, size_t>> operands;
    int depth = 0;
    size_t from = b;
    for (size_t i = b; i < e; ++i) {
      const Tok& k = toks[i];
      if (k.kind != Tok::kPunct) continue;
      if (k.text == "(" || k.text == "[" || k.text == "{") ++depth;
      if (k.text == ")" || k.text == "]" || k.text == "}") --depth;
      if (depth == 0 && k.text == ":") {
        operands.emplace_back(from, i);
        from = i + 1;
      }
    }
    operands.emplace_back(from, e);
    if (operands.size() == 1 && toks[b].text == "{") {
      Agg a;
      if (const std::string why = frameAggregate(toks, b, e, &a); !why.empty()) {
        FrameSetting s = unknownFrame(text, toks[b].begin, why);
        s.run_time = true;
        return s;
      }
      bool partial = false;
      const auto v = toFrame(a, *f, current.value, &partial);
      FrameSetting s;
      s.where = f->loc(toks[b].begin);
      if (!v) {
        s.source = FrameSetting::Source::kUnknown;
        s.text = text;
        s.note = "a partial frame while the previous one is not known";
        return s;
      }
      s.source = FrameSetting::Source::kInline;
      s.value = v;
      s.text = text;
      return s;
    }
    if (e - b == 1 && toks[b].up == "$NULLFRAME") {
      FrameSetting s;
      s.source = FrameSetting::Source::kNull;
      s.value = calib::XyzAbc{};
      s.text = "$NULLFRAME";
      s.where = f->loc(toks[b].begin);
      return s;
    }
    if (const std::optional<int> n = tableIndex(toks, b, e, is_tool)) return dataFrame(is_tool, *n, toks[b].begin);
    // an expression: T_1 * T_2 * ... of its operands
    // (an operand the run computes makes the frame a run-time value, whatever the others lack)
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    std::optional<FrameSetting> problem;
    for (const auto& [ob, oe] : operands) {
      if (ob == oe) return unknownFrame(text, toks[b].begin, "expected an operand of ':', found none");
      FrameSetting operand;  // its value, or why there is none
      const std::string why = operandFrame(toks, ob, oe, &operand);
      if (!why.empty()) {
        if (!problem || (operand.run_time && !problem->run_time)) {
          problem = unknownFrame(text, toks[b].begin, why);
          problem->run_time = operand.run_time;
        }
        continue;
      }
      T = T * calib::toIsometry(*operand.value);
    }
    if (problem) return *problem;
    FrameSetting s;
    s.source = FrameSetting::Source::kInline;
    s.value = calib::toXyzAbc(T);
    s.text = text;
    s.where = f->loc(toks[b].begin);
    return s;
  }

  // The aggregate [b, e) of a frame into *a when each of its components is a number; else why
  // not ({X OFFS,..}, {X -DX,..}: values the program computes at run time).
  std::string frameAggregate(const std::vector<Tok>& toks, size_t b, size_t e, Agg* a) const {
    const std::string text = f->text().substr(toks[b].begin, toks[e - 1].end - toks[b].begin);
    try {
      Cursor c(*f, toks, toks[e - 1].end);
      c.seek(b);
      *a = parseAggregate(c);
      if (c.pos() != e) return "expected the end of the frame after the aggregate " + text + ", found " + describe(c.peek());
    } catch (const calib::InputError& x) {  // -DX, a function call: not a number accura can read
      return "the aggregate " + text + " holds values accura does not evaluate (" + x.what() + ")";
    }
    for (const AggItem& it : a->items)
      if (it.vk != AggItem::kNum) return "the aggregate " + text + " holds values computed at run time ('" + it.text + "')";
    return "";
  }

  // 'T' for the name of the tool table (TOOL_DATA, $TOOL_DATA), 'B' for the base table's, 0 else.
  static char frameTable(const std::string& up) {
    if (up == "TOOL_DATA" || up == "$TOOL_DATA") return 'T';
    if (up == "BASE_DATA" || up == "$BASE_DATA") return 'B';
    return 0;
  }

  // TOOL_DATA[n] / BASE_DATA[n] (also with '$'; the table of the frame assigned) in [b, e): n.
  static std::optional<int> tableIndex(const std::vector<Tok>& toks, size_t b, size_t e, bool is_tool) {
    if (e - b != 4 || toks[b + 1].text != "[" || toks[b + 2].kind != Tok::kNumber || toks[b + 3].text != "]") return std::nullopt;
    if (frameTable(toks[b].up) != (is_tool ? 'T' : 'B')) return std::nullopt;
    return std::atoi(toks[b + 2].text.c_str());
  }

  // One operand of a frame expression [b, e) into out->value; returns why it has no value
  // ("" when it has one; out->run_time when the value is the program's run-time state).
  std::string operandFrame(const std::vector<Tok>& toks, size_t b, size_t e, FrameSetting* out) const {
    const std::string text = f->text().substr(toks[b].begin, toks[e - 1].end - toks[b].begin);
    if (toks[b].text == "{") {
      Agg a;
      if (const std::string why = frameAggregate(toks, b, e, &a); !why.empty()) {
        out->run_time = true;
        return why;
      }
      bool partial = false;
      out->value = toFrame(a, *f, std::nullopt, &partial);
      if (!out->value)
        return "the aggregate " + text + " leaves out components of the frame (expected all of X, Y, Z, A, B, C: accura "
               "does not assume values for the missing ones in an expression)";
      return "";
    }
    if (e - b == 1 && toks[b].up == "$NULLFRAME") {
      out->value = calib::XyzAbc{};
      return "";
    }
    // TOOL_DATA[i] / BASE_DATA[i] with an index computed at run time (a variable, a routine's
    // parameter): the value the run takes
    if (e - b >= 4 && toks[b + 1].text == "[" && toks[e - 1].text == "]" && !(e - b == 4 && toks[b + 2].kind == Tok::kNumber) &&
        frameTable(toks[b].up)) {
      out->run_time = true;
      return "the index of " + text + " is computed at run time";
    }
    for (const bool table_of_tool : {true, false})
      if (const std::optional<int> n = tableIndex(toks, b, e, table_of_tool)) {
        const FrameSetting d = dataFrame(table_of_tool, *n, toks[b].begin);
        if (!d.value) return d.text + " has no value here (its value needs the $config.dat: --config)";
        out->value = d.value;
        return "";
      }
    if (e - b == 1 && (toks[b].up == "$TOOL" || toks[b].up == "$BASE")) {
      const bool of_tool = toks[b].up == "$TOOL";
      const FrameSetting& now = of_tool ? tool : base;
      for (const FrameBlock& fb : frame_blocks_)
        if (fb.loop) {
          out->run_time = true;
          return std::string("it is composed from ") + toks[b].text + " inside the " + fb.kind + " at line " + std::to_string(fb.line) +
                 ": each pass may compose another value";
        }
      if (!now.value) {
        out->run_time = now.run_time;
        return toks[b].text + " is not known here" +
               (now.source == FrameSetting::Source::kUnset ? std::string(" (not set before)") : " (" + now.text + (now.note.empty() ? "" : ": " + now.note) + ")");
      }
      out->value = now.value;
      return "";
    }
    if (e - b == 1 && toks[b].kind == Tok::kIdent && toks[b].up[0] != '$') {
      if (const auto own = routine_names_.find(toks[b].up); own != routine_names_.end()) {
        out->run_time = true;
        return toks[b].text + own->second;
      }
      const auto it = decl.points.find(toks[b].up);
      if (it == decl.points.end())
        return toks[b].text + " is not declared in the program's files (a global frame: give --config $config.dat)";
      if (it->second.type != "FRAME" && it->second.type != "POS" && it->second.type != "E6POS")
        return toks[b].text + " is a " + it->second.type + ", not a frame";
      Target v;
      const std::string problem = pointValue(it->second, toks[b].up, toks[b].text, &v);
      if (!problem.empty()) {
        out->run_time = true;
        return problem;
      }
      if (!v.completePose()) return toks[b].text + " does not give all of X, Y, Z, A, B, C (" + it->second.declared.str() + ")";
      out->value = v.xyzAbc();
      return "";
    }
    return "'" + text + "' is an expression accura does not evaluate";
  }

  void applyFdatFrames(size_t at) {
    if (!fdat) {
      const std::string name = fdat_name.empty() ? "FDAT_ACT" : fdat_name;
      const std::string why = fdat_problem.empty() ? "no FDAT_ACT before BAS" : fdat_problem;
      tool = unknownFrame("TOOL_DATA[" + name + ".TOOL_NO]", at, why);
      base = unknownFrame("BASE_DATA[" + name + ".BASE_NO]", at, why);
      return;
    }
    if (fdat->tool_no) tool = dataFrame(true, *fdat->tool_no, at);
    if (fdat->base_no) base = dataFrame(false, *fdat->base_no, at);
    external_tcp = fdat->external_tcp;
  }

  // Finds the end of an expression starting at b: a depth-0 ',' or approximation flag or WITH.
  // Two operands side by side at depth 0 (no operator between them) end the expression too.
  static size_t exprEnd(const std::vector<Tok>& t, size_t b, bool stop_at_comma = true) {
    int depth = 0;
    size_t i = b;
    bool after_operand = false;  // the previous depth-0 token ended an operand
    for (; i < t.size(); ++i) {
      const Tok& k = t[i];
      const bool opens = k.kind == Tok::kPunct && (k.text == "(" || k.text == "[" || k.text == "{");
      const bool starts_operand = k.kind == Tok::kIdent || k.kind == Tok::kNumber || k.kind == Tok::kString ||
                                  k.kind == Tok::kChar || k.kind == Tok::kEnum || (k.kind == Tok::kPunct && k.text == "{");
      if (depth == 0 && after_operand && starts_operand) break;
      if (opens) {
        ++depth;
      } else if (k.kind == Tok::kPunct && (k.text == ")" || k.text == "]" || k.text == "}")) {
        --depth;
      } else if (depth == 0 && ((stop_at_comma && k.kind == Tok::kPunct && k.text == ",") || isApproxTok(k) ||
                                (k.kind == Tok::kIdent && k.up == "WITH"))) {
        break;
      }
      if (depth == 0) {
        after_operand = k.kind == Tok::kIdent || k.kind == Tok::kNumber || k.kind == Tok::kString || k.kind == Tok::kChar ||
                        k.kind == Tok::kEnum || (k.kind == Tok::kPunct && (k.text == ")" || k.text == "]" || k.text == "}"));
      }
    }
    return i;
  }

  // Resolves a target expression [b, e) into `out`; returns the problem ("" when usable).
  std::string resolveTarget(const std::vector<Tok>& t, size_t b, size_t e, Target* out) {
    const std::string text = f->text().substr(t[b].begin, t[e - 1].end - t[b].begin);
    if (t[b].text == "{") {
      Cursor c(*f, t, t[e - 1].end);
      c.seek(b);
      const Agg a = parseAggregate(c);
      if (c.pos() != e) c.fail("expected the end of the target after the aggregate, found " + describe(c.peek()));
      *out = toTarget(a, "", *f, src);
      return "";
    }
    if (e - b == 1 && t[b].kind == Tok::kIdent) {
      const std::string& up = t[b].up;
      out->name = t[b].text;
      if (!up.empty() && up[0] == '$') return "the target is the system variable " + t[b].text;
      if (const auto own = routine_names_.find(up); own != routine_names_.end()) return t[b].text + own->second;
      auto it = decl.points.find(up);
      if (it == decl.points.end()) {
        if (decl.arrays.count(up)) return t[b].text + " is an array";
        // where a global point would be: the $config.dat given (it is not there either), else ask for it
        const std::string global = decl.tables.file.empty() ? "a global point: give --config $config.dat"
                                                            : "nor is it a global point of " + decl.tables.file;
        if (src->dat_path.empty()) {  // the missing .dat named, not only the undeclared point (issue 17)
          missing_dat_ = true;
          return t[b].text + " is not declared in " + src->src_path + ", and its data file " +
                 fs::path(src->src_path).replace_extension(".dat").string() + " does not exist (give --dat; " + global + ")";
        }
        // a GLOBAL point of another program's data list (another program of the batch): the
        // controller takes its value from there, which that program's compensation corrects
        // for its own tool, base and motions; --config would not find it
        if (const auto g = other_globals.find(up); g != other_globals.end())
          return t[b].text + " is not declared in " + src->src_path + " or " + src->dat_path + ": it is the GLOBAL point of " +
                 g->second.str() + ", another program's data list, whose compensation corrects it for that program's tool, base "
                 "and motions; this motion moves to that value (declare a point of this program's own to compensate it)";
        return t[b].text + " is not declared in " + src->src_path + " or " + src->dat_path + " (" + global + ")";
      }
      return pointValue(it->second, up, t[b].text, out);
    }
    // an element of a point array: XPA[1] is a point of its own when the data list gives it a
    // value (XPA[1]={X ..}); XPA[i] is one the program chooses at run time
    if (e - b >= 4 && t[b].kind == Tok::kIdent && t[b + 1].text == "[" && t[e - 1].text == "]") {
      const auto a = decl.arrays.find(t[b].up);
      if (a != decl.arrays.end()) {
        const std::optional<int> index = integerValue(t, b + 2, e - 1);
        if (!index) {
          // XPA[1,2]: constant indices of a two- or three-dimensional array, not a run-time one
          bool constant = true;
          for (size_t i = b + 2; i < e - 1; ++i)
            constant = constant && (t[i].kind == Tok::kNumber || t[i].text == "," || t[i].text == "+");
          if (constant)
            return "the target '" + text + "' is an element of the multi-dimensional array " + a->second.name +
                   ", which accura does not read (it corrects the elements of one-dimensional point arrays)";
          return "the target '" + text + "' is an element of the array " + a->second.name + " whose index is computed at run time";
        }
        const std::string name = arrayElementName(a->second, *index);
        const auto it = decl.points.find(upper(name));
        if (it == decl.points.end())
          return name + " is not given a value (the array " + a->second.name + " is declared at " + a->second.declared.str() + ")";
        // an assignment of the array in a block or a routine (the prescan's volatile and
        // assigned points hold the array, whatever the index) counts for each element
        return pointValue(it->second, upper(name), name, out, &a->second);
      }
    }
    return "the target '" + text + "' is computed at run time";
  }

  // The value of a declared point (upper-case name `up`, written `written`; an element of
  // `array`, whose assignments count for each element) into `out`; the problem ("" when usable).
  std::string pointValue(const PointEntry& p, const std::string& up, const std::string& written, Target* out,
                         const ArrayEntry* array = nullptr) const {
    if (!p.problem.empty()) return p.problem;
    for (const std::string& key : {up, array ? upper(array->name) : std::string()}) {
      if (key.empty()) continue;
      const std::string who = key == up ? written : written + ": " + array->name;
      if (const auto v = volatile_points_.find(key); v != volatile_points_.end()) return who + " " + v->second;
      if (const auto a = assigned_points_.find(key); a != assigned_points_.end() && main_ended)
        return who + " is assigned at " + a->second + ": in a subroutine its value depends on where it is called";
    }
    *out = *p.value;
    out->name = written;
    // declared GLOBAL in this program's data list (a $config.dat's point is the controller's,
    // which a program written anew must not declare again)
    out->global = p.global_keyword && !p.global;
    out->external = p.config;
    return "";
  }

  // True when the assignment is part of the motion model ($TOOL, $BASE, speeds, approximation,
  // the inline forms' data sets); a point changed by the program is a statement of its own.
  bool handleAssignment(const std::vector<Tok>& t, size_t eq) {
    assignModel(t, eq);
    static const std::set<std::string> model = {"$TOOL", "$BASE", "$VEL", "$VEL_AXIS", "$APO", "FDAT_ACT", "LDAT_ACT", "PDAT_ACT"};
    if (model.count(t[0].up) == 0) return false;
    // of $VEL and $APO the model holds $VEL.CP and $APO.CDIS / CPTP / CVEL / CORI: another
    // component ($VEL.ORI1, $VEL.ORI2, the orientation speeds) or the whole structure
    // ($VEL = {CP 0.2,ORI1 200,ORI2 200}) is a statement of its own, carried where it is
    if (t[0].up == "$VEL" || t[0].up == "$APO") {
      if (eq != 3 || t[1].text != ".") return false;
      static const std::set<std::string> fields = {"CP", "CDIS", "CPTP", "CVEL", "CORI"};
      return fields.count(t[2].up) > 0 && (t[0].up == "$APO") == (t[2].up != "CP");
    }
    return true;
  }

  // The value of $ORI_TYPE = t[b, e) (Motion::ori_type; $CIRC_TYPE with `circ`):
  // orientationControlValue of the constant, else the expression as written.
  std::string oriTypeValue(const std::vector<Tok>& t, size_t b, size_t e, bool circ = false) const {
    if (e == b + 1 && t[b].kind == Tok::kEnum) return orientationControlValue(t[b].text, circ);
    return f->text().substr(t[b].begin, t[e - 1].end - t[b].begin);
  }
  // $ORI_TYPE and $CIRC_TYPE from an LDAT's ORI_TYP and CIRC_TYP (SORI_TYP(LDAT),
  // SCIRC_TYP(LDAT)); each unchanged when the LDAT or its value is not known
  void oriTypeOf(const std::optional<MoveData>& l, std::string* ori_type, std::string* circ_type = nullptr) const {
    if (l && !l->ori_typ.empty() && ori_type) *ori_type = orientationControlValue(l->ori_typ, false);
    if (l && !l->circ_typ.empty() && circ_type) *circ_type = orientationControlValue(l->circ_typ, true);
  }

  void assignModel(const std::vector<Tok>& t, size_t eq) {
    // lhs = t[0, eq), rhs = t[eq+1, end)
    const size_t b = eq + 1, e = t.size();
    if (b >= e) return;
    const std::string lhs0 = t[0].up;
    const bool simple = eq == 1;
    if (simple && lhs0 == "$ORI_TYPE") {  // a statement of its own (carried), and the model's
      ori_type_ = oriTypeValue(t, b, e);
      return;
    }
    if (simple && lhs0 == "$CIRC_TYPE") {
      circ_type_ = oriTypeValue(t, b, e, true);
      return;
    }
    const bool field = eq == 3 && t[1].text == ".";
    const std::string fieldname = field ? t[2].up : "";
    if (simple && (lhs0 == "$TOOL" || lhs0 == "$BASE")) {
      const bool is_tool = lhs0 == "$TOOL";
      FrameSetting& s = is_tool ? tool : base;
      s = evalFrame(t, b, e, is_tool, s);
      return;
    }
    if ((lhs0 == "$TOOL" || lhs0 == "$BASE") && field) {
      FrameSetting& s = lhs0 == "$TOOL" ? tool : base;
      s = unknownFrame(f->text().substr(t[0].begin, t[e - 1].end - t[0].begin), t[0].begin);
      return;
    }
    if (lhs0 == "$VEL" && field && fieldname == "CP") { vel_cp = numberValue(t, b, e); return; }
    if (lhs0 == "$VEL_AXIS" && !simple) { vel_ptp = numberValue(t, b, e); return; }
    if (lhs0 == "$APO" && field) {
      const auto v = numberValue(t, b, e);
      if (fieldname == "CDIS") apo_cdis = v;
      if (fieldname == "CPTP") apo_cptp = v;
      if (fieldname == "CVEL") apo_cvel = v;
      if (fieldname == "CORI") apo_cori = v;
      return;
    }
    if (simple && (lhs0 == "FDAT_ACT" || lhs0 == "LDAT_ACT" || lhs0 == "PDAT_ACT")) {
      const bool name = e - b == 1 && t[b].kind == Tok::kIdent;
      const std::string key = name ? t[b].up : "";
      if (lhs0 == "FDAT_ACT") {
        fdat.reset();
        fdat_problem.clear();
        fdat_name = key;
        if (t[b].text == "{") {  // FDAT_ACT = {TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE}
          Cursor c(*f, t, t[e - 1].end);
          c.seek(b);
          fdat = toFdat(parseAggregate(c), *f);
          return;
        }
        auto it = decl.fdats.find(key);
        if (it != decl.fdats.end()) fdat = it->second;
        else fdat_problem = f->text().substr(t[b].begin, t[e - 1].end - t[b].begin) + " is not declared (a global FDAT: give --config $config.dat)";
      } else {
        auto& table = lhs0 == "LDAT_ACT" ? decl.ldats : decl.pdats;
        auto it = table.find(key);
        (lhs0 == "LDAT_ACT" ? ldat : pdat) = it != table.end() ? std::optional<MoveData>(it->second) : std::nullopt;
        if (lhs0 == "LDAT_ACT" && it == table.end())
          ldat_unknown_ = f->text().substr(t[0].begin, t[e - 1].end - t[0].begin) + " (" + f->loc(t[0].begin).str() +
                          ") names an LDAT the program's files do not declare (a global one: give --config $config.dat)";
      }
      return;
    }
    // a point changed by the program, or an element of a point array (XPA[2] = {..})
    std::string key = lhs0;
    bool whole = simple;  // the whole point is assigned (not a component)
    if (t.size() > 1 && t[1].text == "[") {
      const auto a = decl.arrays.find(lhs0);
      if (a == decl.arrays.end()) return;
      const std::optional<int> index = t.size() > 3 && t[3].text == "]" ? integerValue(t, 2, 3) : std::nullopt;
      if (!index) {  // XPA[i] = ..: any element may be the one changed
        for (auto& [up, p] : decl.points)
          if (up.compare(0, lhs0.size() + 1, lhs0 + "[") == 0) {
            pointChanged(up, true, t[0].begin);
            p.problem = p.name + " may be changed at run time (" + f->loc(t[0].begin).str() + ": an element of " + a->second.name +
                        " whose index is computed at run time)";
          }
        return;
      }
      key = upper(arrayElementName(a->second, *index));
      whole = eq == 4;
      if (!decl.points.count(key)) {  // an element the data list gives no value: from here on, this one's
        PointEntry element;
        element.name = arrayElementName(a->second, *index);
        element.type = a->second.type;
        element.declared = f->loc(t[0].begin);
        element.problem = element.name + " is not given a value before " + f->loc(t[0].begin).str();
        decl.points[key] = std::move(element);
      }
    }
    auto it = decl.points.find(key);
    if (it != decl.points.end()) {
      bool self = !whole;
      for (size_t i = b; i < e; ++i) self = self || (t[i].kind == Tok::kIdent && t[i].up == lhs0);
      pointChanged(key, self, t[0].begin);
      PointEntry& p = it->second;
      if (whole && t[b].text == "{" ) {
        Cursor c(*f, t, t[e - 1].end);
        c.seek(b);
        const Agg a = parseAggregate(c);
        if (c.pos() == e) {
          Target v = toTarget(a, p.type, *f, src);
          const bool complete = v.kind == Target::Kind::kCartesian ? v.completePose() : [&] {
            for (int k = 0; k < 6; ++k)
              if (!v.axes[k]) return false;
            return true;
          }();
          if (complete) {
            v.name = p.name;
            p.value = v;
            p.problem.clear();
            // a $config.dat's GLOBAL point the program assigns stays the controller's: not
            // declared GLOBAL again in a program written anew
            if (p.global) p.global_keyword = false;
            p.global = false;
            return;
          }
        }
      }
      p.problem = p.name + " is changed at run time (" + f->loc(t[0].begin).str() + ")";
    }
  }

  // BAS(#CP_PARAMS / #CP_DAT) = t: BAS.SRC's CP_DAT sets $ORI_TYPE = LDAT_ACT.ORI_TYP, #VAR where
  // that is not initialised (ON_ERROR_PROCEED); an LDAT whose ORI_TYP is not known leaves it not
  // known. $CIRC_TYPE from the LDAT's CIRC_TYP where it gives one (the later BAS.SRC's), else kept.
  void cpDatOriType(const std::vector<Tok>& t) {
    if (ldat) {
      ori_type_ = orientationControlValue(ldat->ori_typ, false);
      oriTypeOf(ldat, nullptr, &circ_type_);
      return;
    }
    const std::string why = " (" + f->text().substr(t[0].begin, t.back().end - t[0].begin) + " at " + f->loc(t[0].begin).str() + "), but " + ldat_unknown_;
    if (ori_varies_) ori_type_ = unknownOri("$ORI_TYPE is LDAT_ACT's ORI_TYP" + why);
    if (circ_varies_) circ_type_ = unknownOri("$CIRC_TYPE is LDAT_ACT's CIRC_TYP" + why);
  }

  // True when the BAS call is part of the motion model (frames, speeds, approximation).
  bool handleBas(const std::vector<Tok>& t) {
    // BAS ( #CMD [, value] )
    if (t.size() < 4 || t[1].text != "(" || t[2].kind != Tok::kEnum) return false;
    const std::string cmd = t[2].up;
    std::optional<double> value;
    if (t.size() >= 6 && t[3].text == ",") value = numberValue(t, 4, t.size() - 1);
    const size_t at = t[0].begin;
    if (cmd == "#INITMOV") {
      // BAS.SRC's INITMOV: `$ORI_TYPE=#VAR`, `$CIRC_TYPE=DEF_CIRC_TYP` (#BASE in the $config.dat);
      // the statement itself is carried (a program written anew initialises itself with it)
      ori_type_.clear();
      circ_type_.clear();
      return false;
    }
    if (cmd == "#TOOL" || cmd == "#BASE") {
      const auto n = t.size() >= 6 && t[3].text == "," ? integerValue(t, 4, t.size() - 1) : std::nullopt;
      FrameSetting& s = cmd == "#TOOL" ? tool : base;
      if (n) s = dataFrame(cmd == "#TOOL", *n, at);
      else if (t.size() >= 6 && t[3].text == ",")  // BAS(#TOOL, n) with n a variable: the run's value
        s = runTimeFrame(f->text().substr(t[0].begin, t.back().end - t[0].begin), f->loc(at), "the frame's number is computed at run time");
      else s = unknownFrame(f->text().substr(t[0].begin, t.back().end - t[0].begin), at);
    } else if (cmd == "#PTP_PARAMS") {
      applyFdatFrames(at);
      vel_ptp = value;
      if (pdat && pdat->apo_dist) apo_cptp = pdat->apo_dist;
    } else if (cmd == "#CP_PARAMS") {
      applyFdatFrames(at);
      vel_cp = value;
      if (ldat && ldat->apo_dist) apo_cdis = ldat->apo_dist;
      cpDatOriType(t);
    } else if (cmd == "#FRAMES") {
      applyFdatFrames(at);
    } else if (cmd == "#PTP_DAT") {  // KRC2 inline forms: PDAT_ACT, then BAS(#PTP_DAT)
      if (pdat && pdat->apo_dist) apo_cptp = pdat->apo_dist;
    } else if (cmd == "#CP_DAT") {
      if (ldat && ldat->apo_dist) apo_cdis = ldat->apo_dist;
      cpDatOriType(t);
    } else if (cmd == "#VEL_PTP") {
      vel_ptp = value;
    } else if (cmd == "#VEL_CP") {
      vel_cp = value;
    } else {
      return false;
    }
    return true;
  }

  // WITH assignments of a spline motion (valid for this motion only), or of a SPLINE block's
  // header (valid for the motions of the block: `m` is then the block's settings).
  void applyWith(const std::vector<Tok>& t, size_t b, size_t e, Motion& m) {
    size_t i = b;
    while (i < e) {
      size_t j = exprEnd(t, i);
      if (j > e) j = e;
      // one assignment [i, j)
      size_t eq = i;
      while (eq < j && !(t[eq].kind == Tok::kPunct && t[eq].text == "=")) ++eq;
      if (eq < j && eq > i && eq + 1 < j) {
        const std::string lhs = t[i].up;
        const size_t rb = eq + 1, re = j;
        const bool call = re - rb >= 3 && t[rb].kind == Tok::kIdent && t[rb + 1].text == "(";
        const std::string fn = call ? t[rb].up : "";
        auto arg = [&](size_t k) -> std::pair<size_t, size_t> {  // k-th argument of the call
          size_t s = rb + 2, n = 0;
          int depth = 0;
          for (size_t x = rb + 2; x < re; ++x) {
            const std::string& tx = t[x].text;
            if (tx == "(" || tx == "[" || tx == "{") ++depth;
            if ((tx == ")" && depth == 0) || (tx == "," && depth == 0)) {
              if (n == k) return {s, x};
              ++n;
              s = x + 1;
              if (tx == ")") break;
              continue;
            }
            if (tx == ")" || tx == "]" || tx == "}") --depth;
          }
          return {0, 0};
        };
        if ((lhs == "$TOOL" || lhs == "$BASE") && eq != i + 1) {  // $TOOL.X = ..: a frame accura does not follow
          FrameSetting& s = lhs == "$TOOL" ? m.tool : m.base;
          s = unknownFrame(f->text().substr(t[i].begin, t[re - 1].end - t[i].begin), t[i].begin);
        } else if (lhs == "$TOOL" || lhs == "$BASE") {
          const bool is_tool = lhs == "$TOOL";
          FrameSetting& s = is_tool ? m.tool : m.base;
          if (fn == "STOOL2" || fn == "SBASE") {
            const auto a = arg(0);
            // STOOL2(FP1) / SBASE(FP1.BASE_NO)
            std::string name = a.second > a.first ? t[a.first].up : "";
            auto it = decl.fdats.find(name);
            if (it != decl.fdats.end() && ((is_tool && it->second.tool_no) || (!is_tool && it->second.base_no))) {
              s = dataFrame(is_tool, is_tool ? *it->second.tool_no : *it->second.base_no, t[rb].begin);
              if (is_tool) m.external_tcp = it->second.external_tcp;
            } else {
              s = unknownFrame(f->text().substr(t[rb].begin, t[re - 1].end - t[rb].begin), t[rb].begin,
                               name.empty() ? "" : name + " is not declared (a global FDAT: give --config $config.dat)");
            }
          } else {
            s = evalFrame(t, rb, re, is_tool, s);
          }
        } else if (lhs == "$VEL" && eq == i + 3 && t[i + 1].text == "." && t[i + 2].up == "CP") {  // $VEL.CP = v (m/s)
          m.vel_m_s = numberValue(t, rb, re);
        } else if (lhs == "$VEL" && (fn == "SVEL_CP")) {
          const auto a = arg(0);
          m.vel_m_s = numberValue(t, a.first, a.second);
        } else if (lhs == "$VEL_AXIS" && fn == "SVEL_JOINT") {
          const auto a = arg(0);
          m.vel_percent = numberValue(t, a.first, a.second);
        } else if (lhs == "$APO" && (fn == "SAPO" || fn == "SAPO_PTP")) {
          const auto a = arg(0);
          if (a.second == a.first + 1) {
            const auto& table = fn == "SAPO" ? decl.ldats : decl.pdats;
            auto it = table.find(t[a.first].up);
            if (it != table.end() && it->second.apo_dist && !m.approximation.empty()) m.approximation_value = it->second.apo_dist;
          }
        } else if (lhs == "$ORI_TYPE" && eq == i + 1) {
          if (fn == "SORI_TYP") {  // the spline inline forms: SORI_TYP(LCPDAT1), the LDAT's ORI_TYP
            const auto a = arg(0);
            if (a.second == a.first + 1) {
              const auto it = decl.ldats.find(t[a.first].up);
              if (it != decl.ldats.end()) oriTypeOf(it->second, &m.ori_type);
            }
          } else {
            m.ori_type = oriTypeValue(t, rb, re);
          }
        } else if (lhs == "$CIRC_TYPE" && eq == i + 1) {
          if (fn == "SCIRC_TYP") {  // SCIRC_TYP(LCPDAT1), the LDAT's CIRC_TYP
            const auto a = arg(0);
            if (a.second == a.first + 1) {
              const auto it = decl.ldats.find(t[a.first].up);
              if (it != decl.ldats.end()) oriTypeOf(it->second, nullptr, &m.circ_type);
            }
          } else {
            m.circ_type = oriTypeValue(t, rb, re, true);
          }
        } else if (lhs == "$IPO_MODE" && fn == "SIPO_MODE") {
          const auto a = arg(0);
          if (a.second > a.first) {
            auto it = decl.fdats.find(t[a.first].up);
            if (it != decl.fdats.end()) m.external_tcp = it->second.external_tcp;
          }
        }
      }
      i = j;
      if (i < e && t[i].text == ",") ++i;
      else break;
    }
  }

  void handleMotion(const Line& l, const std::vector<Tok>& t) {
    Motion m;
    std::string kw = t[0].up;
    m.where = f->loc(t[0].begin);
    m.statement = f->text().substr(t[0].begin, l.code_end - t[0].begin);
    if (kw.size() > 4 && kw.compare(kw.size() - 4, 4, "_REL") == 0) {
      m.relative = true;
      kw = kw.substr(0, kw.size() - 4);
    }
    if (kw == "SPTP" || kw == "SLIN" || kw == "SCIRC" || kw == "SPL") {
      m.spline = true;
      kw = kw == "SPL" ? "SPL" : kw.substr(1);
    }
    if (kw == "PTP") m.type = MotionType::kPtp;
    else if (kw == "LIN") m.type = MotionType::kLin;
    else if (kw == "CIRC") m.type = MotionType::kCirc;
    else m.type = MotionType::kSpl;
    if (m.type == MotionType::kSpl && !in_spline)
      f->fail(t[0].begin, "expected SPL inside a SPLINE ... ENDSPLINE block, found it outside");
    if (in_spline && !m.spline)
      f->fail(t[0].begin, "expected a spline segment (SPL, SLIN, SCIRC, SPTP) inside the " + std::string(ptp_spline_block_ ? "PTP_SPLINE" : "SPLINE") +
                              " block, found " + t[0].text);
    if (in_spline && ptp_spline_block_ && m.type != MotionType::kPtp)
      f->fail(t[0].begin, "expected SPTP inside the PTP_SPLINE block, found " + t[0].text);
    m.spline_block = in_spline ? spline_block_number_ : 0;
    m.ptp_spline_block = in_spline && ptp_spline_block_;

    KrlSource::Statement st;
    st.file = f->index();
    st.line_begin = l.begin;
    st.code_begin = t[0].begin;
    st.code_end = l.code_end;
    st.eol = l.eol;

    Cursor c(*f, t, l.code_end);
    c.seek(1);
    auto takeTarget = [&](const char* what) -> std::pair<size_t, size_t> {
      const size_t b = c.pos();
      const size_t e = exprEnd(t, b);
      if (e == b) c.fail(std::string("expected ") + what + " after " + t[0].text + ", found " + describe(c.peek()));
      c.seek(e);
      return {b, e};
    };
    const auto first = takeTarget(m.type == MotionType::kCirc ? "the auxiliary point" : "a target");
    std::pair<size_t, size_t> end_range = first;
    if (m.type == MotionType::kCirc) {
      c.expectPunct(",", "between the auxiliary point and the end point of " + t[0].text);
      end_range = takeTarget("the end point");
      if (c.isPunct(",") && c.isIdent("CA", 1)) {
        c.next();
        c.next();
        const size_t b = c.pos();
        const size_t e = exprEnd(t, b);
        const auto v = numberValue(t, b, e);
        if (!v) c.fail("expected a number (deg) after CA, found " + describe(c.peek()));
        m.circ_angle_deg = *v;
        c.seek(e);
      }
    }
    // approximation flags, WITH, coordinate system of relative motions
    size_t with_b = 0, with_e = 0;
    while (!c.atEnd()) {
      const Tok& k = *c.peek();
      Approximation a;
      if (k.kind == Tok::kIdent && parseApproximation(k.text, &a)) {
        m.approximation.push_back(a);
        c.next();
      } else if (k.kind == Tok::kIdent && k.up == "WITH") {
        c.next();
        with_b = c.pos();
        size_t i = with_b;
        // the WITH list runs until a depth-0 approximation flag or the end
        while (i < t.size()) {
          const size_t j = exprEnd(t, i);
          i = j;
          if (i < t.size() && t[i].text == ",") {
            ++i;
            continue;
          }
          break;
        }
        with_e = i;
        c.seek(i);
      } else if (k.kind == Tok::kEnum && m.relative && (k.up == "#BASE" || k.up == "#TOOL")) {
        m.relative_in_tool = k.up == "#TOOL";
        c.next();
      } else {
        c.fail("expected an approximation flag (C_PTP, C_DIS, C_VEL, C_ORI, C_SPL) or WITH after the target, found " + describe(&k));
      }
    }

    // state at this motion
    m.tool = tool;
    m.base = base;
    m.external_tcp = external_tcp;
    m.ori_type = ori_type_;
    m.circ_type = circ_type_;
    if (m.type == MotionType::kPtp) m.vel_percent = vel_ptp;
    else m.vel_m_s = vel_cp;
    if (in_spline && spline_block_) {  // the block's WITH clause, then the motion's own
      m.tool = spline_block_->tool;
      m.base = spline_block_->base;
      m.external_tcp = spline_block_->external_tcp;
      m.ori_type = spline_block_->ori_type;
      m.circ_type = spline_block_->circ_type;
      if (m.type == MotionType::kPtp) m.vel_percent = spline_block_->vel_percent;
      else m.vel_m_s = spline_block_->vel_m_s;
    }
    if (!m.approximation.empty()) {
      switch (m.approximation.front()) {
        case Approximation::kCDis: m.approximation_value = apo_cdis; break;
        case Approximation::kCPtp: m.approximation_value = apo_cptp; break;
        case Approximation::kCVel: m.approximation_value = apo_cvel; break;
        case Approximation::kCOri: m.approximation_value = apo_cori; break;
        case Approximation::kCSpl: m.approximation_value = apo_cdis; break;
      }
    }
    if (with_e > with_b) applyWith(t, with_b, with_e, m);
    if (m.type != MotionType::kCirc) m.circ_type.clear();  // (only circles read $CIRC_TYPE)

    // targets
    std::string problem;
    missing_dat_ = false;
    if (m.type == MotionType::kCirc) {
      Target aux;
      problem = resolveTarget(t, first.first, first.second, &aux);
      m.aux = aux;
      st.targets.push_back({t[first.first].begin, t[first.second - 1].end});
    }
    {
      const std::string p2 = resolveTarget(t, end_range.first, end_range.second, &m.target);
      if (problem.empty()) problem = p2;
      st.targets.push_back({t[end_range.first].begin, t[end_range.second - 1].end});
    }
    if (m.relative && problem.empty()) problem = "a relative motion (" + t[0].text + ")";
    m.target_problem = problem;
    m.target_file_missing = missing_dat_ && !problem.empty();
    if (problem.empty() && m.type != MotionType::kPtp) {
      const auto check = [&](const Target& x, const char* what) {
        if (x.kind == Target::Kind::kAxis)
          f->fail(x.value_id >= 0 ? src->values[static_cast<size_t>(x.value_id)].begin : t[0].begin,
                  std::string("expected a Cartesian ") + what + " for " + t[0].text + " (E6POS, POS, FRAME), found an axis target" +
                      (x.name.empty() ? "" : " (" + x.name + ")"));
      };
      check(m.target, "target");
      if (m.aux) check(*m.aux, "auxiliary point");
    }
    m.trigger_count = triggers;
    triggers = 0;
    m.start_unknown = flow_.motion();
    m.statement_id = static_cast<int>(src->statements.size());
    src->statements.push_back(std::move(st));
    // the motions that read a point's current value (pointChangedFromItself)
    for (const Target* x : {&m.target, m.aux ? &*m.aux : nullptr})
      if (x && !x->name.empty() && m.target_problem.empty()) point_uses_[upper(x->name)].push_back(program->motions.size());
    program->motions.push_back(std::move(m));
  }

  // A point assigned from its own value (XP1.X = 8, XP1 = XP1 : {...}) at `at`: the motions that
  // read its current value would, corrected, carry their correction into the new value (half
  // corrected); they are kept and named. A complete new value (XP1 = {...}, XP1 = XP2) starts
  // afresh.
  void pointChanged(const std::string& up, bool from_itself, size_t at) {
    std::vector<size_t>& uses = point_uses_[up];
    if (from_itself)
      for (size_t i : uses) {
        Motion& m = program->motions[i];
        if (m.target_problem.empty())
          m.target_problem = (m.target.name.empty() ? up : m.target.name) + " is changed from its own value at " + f->loc(at).str() +
                             ": a correction of it here would carry into its new value";
      }
    uses.clear();
  }
  std::map<std::string, std::vector<size_t>> point_uses_;

  // A line of the .src: the motion model takes what it understands; every other statement
  // (and comment) is kept as a pass-through statement for `convert`.
  void handleLine(const Line& l) {
    const bool before_main_end = !main_ended;
    refuse.clear();
    declared_points_.clear();
    const bool model = interpretLine(l);
    if (model) return;
    const std::string text = f->text().substr(l.begin, l.content_end - l.begin);
    if (isFoldMarker(text)) return;
    PassThrough p;
    p.language = "KRL";
    p.text = text;
    p.section = before_main_end ? PassThrough::Section::kBody : PassThrough::Section::kTrailer;
    p.before_motion = program->motions.size();
    p.spline_block = in_spline ? spline_block_number_ : 0;
    p.where = f->loc(l.begin);
    p.refuse = refuse;
    if (!declared_points_.empty() && p.section == PassThrough::Section::kBody)
      point_declarations_.emplace_back(program->passthrough.size(), declared_points_);
    program->passthrough.push_back(std::move(p));
  }
  // The points the line just read declares with a value (pointsDeclaredWithValue).
  std::vector<std::string> declared_points_;
  // The main program's declarations of points with a value, carried for now (pass-through
  // index, names): readKrl drops those whose points the motion model declares itself.
  std::vector<std::pair<size_t, std::vector<std::string>>> point_declarations_;

  // True when the line is part of the motion model or carries nothing (blank, attribute
  // lines, the main program's DEF and END).
  bool interpretLine(const Line& l) {
    const std::vector<Tok> t = lex(*f, l.begin, l.code_end);
    if (t.empty()) {  // a comment line is a statement of its own; blank lines are not
      return f->text().find_first_not_of(" \t\r", l.begin) >= l.content_end;
    }
    if (t[0].text == "&") return true;
    checkStructure(t);
    const std::string& k = t[0].up;
    if (k == "DEFFCT" || (k == "GLOBAL" && t.size() > 1 && t[1].up == "DEFFCT")) {
      // a function of this file (after the main program's END): called from anywhere
      if (def_open_) f->fail(t[0].begin, "expected " + openEnd() + " at line " + std::to_string(def_line_) + ", found DEFFCT");
      const size_t name_at = k == "DEFFCT" ? 2 : 3;  // DEFFCT type name(..)
      if (first_function_.empty() && name_at < t.size() && t[name_at].kind == Tok::kIdent)
        first_function_ = t[name_at].text + " (" + f->loc(t[0].begin).str() + ")";
      def_open_ = true;
      def_fct_ = true;
      def_line_ = f->loc(t[0].begin).line;
      startRoutine(t, name_at);
      flow_ = StartTracker();
      flow_.unknown();
      callerFrames(t[0].begin);
      return false;
    }
    if (k == "ENDFCT" && t.size() == 1 && def_open_ && def_fct_) {
      def_open_ = false;
      return false;
    }
    if (k == "DEF" || (k == "GLOBAL" && t.size() > 1 && t[1].up == "DEF")) {
      if (def_open_) f->fail(t[0].begin, "expected " + openEnd() + " at line " + std::to_string(def_line_) + ", found another DEF");
      def_open_ = true;
      def_fct_ = false;
      def_line_ = f->loc(t[0].begin).line;
      startRoutine(t, k == "DEF" ? 1 : 2);
      if (program->name.empty()) {
        const size_t i = k == "DEF" ? 1 : 2;
        if (i < t.size() && t[i].kind == Tok::kIdent) program->name = t[i].text;
        // the parameter list as written, between the parentheses
        if (i + 1 < t.size() && t[i + 1].text == "(" && t.back().text == ")" && t.size() > i + 3)
          program->krl_parameters = f->text().substr(t[i + 2].begin, t[t.size() - 2].end - t[i + 2].begin);
      }
      if (main_started) {  // a local subroutine: called from anywhere, with the caller's frames
        flow_ = StartTracker();
        flow_.unknown();
        callerFrames(t[0].begin);
        return false;
      }
      main_started = true;
      return true;
    }
    if (k == "END" && t.size() == 1 && !def_fct_) def_open_ = false;
    if (k == "END" && t.size() == 1 && main_started && !main_ended) {
      main_ended = true;
      return true;
    }
    if (k == "SPLINE" || k == "PTP_SPLINE") {
      // SPLINE WITH $TOOL = .., $BASE = .., $VEL.CP = ..: the assignments hold for every motion
      // of the block (KSS: valid for the spline block, the program's own $TOOL/$BASE unchanged)
      in_spline = true;
      spline_block_number_ = ++spline_blocks_;
      ptp_spline_block_ = k == "PTP_SPLINE";
      spline_block_.reset();
      if (t.size() > 1 && t[1].kind == Tok::kIdent && t[1].up == "WITH") {
        Motion block;
        block.tool = tool;
        block.base = base;
        block.external_tcp = external_tcp;
        block.ori_type = ori_type_;
        block.circ_type = circ_type_;
        block.vel_m_s = vel_cp;
        block.vel_percent = vel_ptp;
        applyWith(t, 2, t.size(), block);
        spline_block_ = std::move(block);
      }
      return true;
    }
    if (k == "ENDSPLINE") {
      in_spline = false;
      spline_block_number_ = 0;
      spline_block_.reset();
      return true;
    }
    if (k == "TRIGGER") { ++triggers; return false; }
    if (k == "DECL" || ((isPointType(k) || k == "FDAT" || k == "LDAT" || k == "PDAT") && t.size() > 1 && t[1].kind == Tok::kIdent)) {
      Cursor c(*f, t, l.code_end);
      parseDeclaration(c, decl, src, false);
      if (main_ended || def_fct_) noteRoutineDeclarations(t);
      // a point declared without a value (the program assigns it) is not written anew from the
      // model: it travels as a pass-through statement, so that the program still declares it;
      // so does one with a value that no motion of the model names (readKrl: a point the
      // program only reads, a GLOBAL one other modules use, a run-time target)
      bool value = false;
      for (const Tok& x : t) value = value || (x.text == "=" && x.kind == Tok::kPunct);
      declared_points_ = pointsDeclaredWithValue(t);
      return declaresModelType(t) && value && declared_points_.empty();
    }
    if (isMotionKeyword(k) && t[0].kind == Tok::kIdent) {
      // "LIN = 3" would be an assignment to a variable named like a keyword: not KRL
      handleMotion(l, t);
      if (main_ended)
        refuse = "a motion in a local subroutine (after the main program's END): the motion model holds the main program's motions only";
      return !main_ended;
    }
    if (k == "BAS" && t.size() > 1 && t[1].text == "(") return handleBas(t);
    if (declaresInterrupt(t)) return false;  // (not a call of its handler)
    controlFlow(t);
    if (isLocalCall(t)) flow_.unknown();
    // a call of a subroutine or function of this file that sets $TOOL or $BASE: the frames after
    // it are its, which accura does not follow (until the program sets them again)
    for (size_t i = 0; i + 1 < t.size(); ++i) {
      if (t[i].kind != Tok::kIdent || t[i + 1].text != "(") continue;
      if (tool_defs_.count(t[i].up))
        tool = runTimeFrame("$TOOL", f->loc(t[i].begin), t[i].text + " (called here) sets $TOOL: the tool after the call is not followed");
      if (base_defs_.count(t[i].up))
        base = runTimeFrame("$BASE", f->loc(t[i].begin), t[i].text + " (called here) sets $BASE: the base after the call is not followed");
      if (ori_varies_ && ori_defs_.count(t[i].up))
        ori_type_ = unknownOri(t[i].text + " (called at " + f->loc(t[i].begin).str() + ") sets $ORI_TYPE: its value after the call is not followed");
      if (circ_varies_ && circ_defs_.count(t[i].up))
        circ_type_ = unknownOri(t[i].text + " (called at " + f->loc(t[i].begin).str() + ") sets $CIRC_TYPE: its value after the call is not followed");
    }
    // a routine of another module called while the program has not set $TOOL / $BASE (a cell's
    // MoveSettings(base, tool, ..)) may set them, which accura cannot see: the refusal of the
    // motions after it names the first such call and the option that gives the frame
    if (const std::string call = externalCall(t); !call.empty()) {
      const std::string at = f->loc(t[0].begin).str();
      for (auto [frame, var, option] : {std::make_tuple(&tool, "$TOOL", "--program-tool"), std::make_tuple(&base, "$BASE", "--program-base")})
        if (frame->source == FrameSetting::Source::kUnset && frame->note.empty())
          frame->note = std::string(var) + " is not set in this file before this motion; " + call + " (called at " + at +
                        "), a routine this file does not define, may set it: give the frame it sets with " + option +
                        " x,y,z,A,B,C, or set " + var + " in the program";
    }
    {
      Cursor c(*f, t, l.code_end);
      if (parseTableAssignment(c, decl)) return false;
    }
    // an assignment: at its depth-0 '='
    if (const size_t eq = assignmentEnd(t)) return handleAssignment(t, eq);
    return false;
  }
};

// The .dat's statements outside the motion model (declarations of other types, EXT, comments)
// as pass-through statements of the data part.
void datPassThrough(const KrlFile& f, Program& program) {
  const std::set<std::string> model_points = pointsTheModelDeclares(program);
  for (const Line& l : f.lines()) {
    const std::string text = f.text().substr(l.begin, l.content_end - l.begin);
    std::string carried = text;  // what travels of the line
    const std::vector<Tok> t = lex(f, l.begin, l.code_end);
    if (t.empty()) {
      if (text.find_first_not_of(" \t\r") == std::string::npos || isFoldMarker(text)) continue;
    } else {
      const std::string& k = t[0].up;
      if (t[0].text == "&" || k == "DEFDAT" || k == "ENDDAT" || (k == "PUBLIC" && t.size() > 1 && t[1].up == "DEFDAT")) continue;
      // a declaration the model holds the value of; one without a value (a point array: DECL
      // E6POS XPA[10], its elements' lines XPA[1]={..} carried too) travels as written, as in
      // the .src, so that the program still declares what it uses. So does a point with a value
      // that no motion of the model names (the model would not declare it): one the program only
      // reads (IF XP9.X>0, XP2=XP8), a GLOBAL one other modules use, a run-time target.
      bool value = false;
      for (const Tok& x : t) value = value || (x.kind == Tok::kPunct && x.text == "=");
      const std::vector<std::string> points = pointsDeclaredWithValue(t);
      const size_t by_model = declaredByModel(points, model_points);
      const bool model_declares = by_model == points.size();
      if ((k == "DECL" || isPointType(k) || k == "FDAT" || k == "LDAT" || k == "PDAT") && declaresModelType(t) && value && model_declares) continue;
      // some of its points the model declares: the others travel (a point declared twice would not compile)
      if (by_model > 0) carried = withoutModelPoints(f, l, t, model_points);
    }
    PassThrough p;
    p.language = "KRL";
    p.text = carried;
    p.section = PassThrough::Section::kData;
    p.where = f.loc(l.begin);
    program.passthrough.push_back(std::move(p));
  }
}



}  // namespace

std::string krlDatPath(const std::string& src_path) {
  const fs::path p(src_path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  const std::string stem = upper(p.stem().string());
  std::error_code ec;
  std::vector<std::string> found;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    if (!e.is_regular_file(ec)) continue;
    const fs::path q = e.path();
    if (upper(q.stem().string()) == stem && upper(q.extension().string()) == ".DAT")
      found.push_back(p.has_parent_path() ? (dir / q.filename()).string() : q.filename().string());
  }
  if (found.empty()) return "";
  std::sort(found.begin(), found.end());
  // prefer the exact-case sibling
  for (const auto& s : found)
    if (fs::path(s).stem() == p.stem()) return s;
  return found.front();
}

FrameTables readKrlFrameTables(const std::string& config_path) {
  const KrlFile f(config_path, readFileBytes(config_path, "the $config.dat"), 2);
  Declarations d;
  parseDataFile(f, d, nullptr, true);
  d.tables.file = config_path;
  return d.tables;
}

std::map<std::string, SourceLocation> krlGlobalPoints(const std::string& dat_path) {
  const KrlFile f(dat_path, readFileBytes(dat_path, "the KRL data file"), 1);
  Declarations d;
  KrlSource spans;  // (the values' text spans: not used)
  parseDataFile(f, d, &spans, false);
  std::map<std::string, SourceLocation> out;
  for (const auto& [up, p] : d.points)
    if (p.global_keyword) out[up] = p.declared;
  return out;
}

namespace {

// Every point of the program's files whose value a statement of the .src reads other than as a
// motion's target (`$BASE = XFB`, `XP2 = XFB`, `LIN XP1 WITH $TOOL = XT`, `IF XP1.X > 0`, a
// call's argument; an array's element XPA[1], and every element for XPA[I]):
// KrlSource::Value::read_elsewhere, the first such place. Declarations, the DEF line, a point's
// own assignment (XP1 = .., XP1.X = ..: the left-hand side) and, in a subroutine, the names of
// its parameters and its own declarations (which hide the data list's points) are not reads.
// `lines`: the tokens of the .src's lines, in order.
void notePointReads(const KrlFile& src, const std::vector<std::vector<Tok>>& lines, const Declarations& decl, KrlSource& source) {
  const auto noteRead = [&](const PointEntry& p, const std::vector<Tok>& t, size_t i) {
    if (!p.value || p.value->value_id < 0) return;
    const size_t id = static_cast<size_t>(p.value->value_id);
    if (id >= source.values.size() || !source.values[id].read_elsewhere.empty()) return;
    source.values[id].read_elsewhere = src.loc(t[i].begin).str() + " (" + src.text().substr(t[0].begin, t.back().end - t[0].begin) + ")";
  };
  bool main_seen = false, in_subroutine = false;
  std::set<std::string> local;  // a subroutine's parameters and declarations (upper case)
  for (const std::vector<Tok>& t : lines) {
    if (t.empty() || t[0].text == "&") continue;
    const std::string& k = t[0].up;
    const size_t def_at = k == "GLOBAL" && t.size() > 1 ? 1 : 0;
    if (t[def_at].up == "DEF" || t[def_at].up == "DEFFCT") {
      in_subroutine = main_seen || t[def_at].up == "DEFFCT";
      main_seen = main_seen || t[def_at].up == "DEF";
      local.clear();
      if (in_subroutine)  // its parameters: NAME:IN / NAME:OUT
        for (size_t i = 0; i + 1 < t.size(); ++i)
          if (t[i].kind == Tok::kIdent && t[i + 1].text == ":") local.insert(t[i].up);
      continue;
    }
    if (k == "DECL" || isPointType(k) || (k == "GLOBAL" && t.size() > 1 && t[1].up == "DECL")) {
      if (in_subroutine) {  // the names it declares (outside braces and brackets)
        int depth = 0;
        for (size_t i = 1; i < t.size(); ++i) {
          const std::string& x = t[i].text;
          if (x == "[" || x == "(" || x == "{") ++depth;
          if (x == "]" || x == ")" || x == "}") --depth;
          if (depth == 0 && t[i].kind == Tok::kIdent && (i + 1 == t.size() || t[i + 1].text == "," || t[i + 1].text == "=" || t[i + 1].text == "["))
            local.insert(t[i].up);
        }
      }
      continue;
    }
    const bool motion = isMotionKeyword(k) && t[0].kind == Tok::kIdent;
    // an assignment's left-hand side ends at its depth-0 '='; a motion's keyword is not a read
    size_t from = motion ? 1 : 0;
    if (const size_t eq = motion ? 0 : assignmentEnd(t)) from = eq + 1;
    int depth = 0;
    for (size_t i = from; i < t.size(); ++i) {
      const std::string& x = t[i].text;
      if (x == "[" || x == "(" || x == "{") ++depth;
      if (x == "]" || x == ")" || x == "}") --depth;
      if (t[i].kind != Tok::kIdent || local.count(t[i].up)) continue;
      // the tokens the operand takes: NAME, or NAME[ index ] of an array
      size_t last = i;
      const auto array = decl.arrays.find(t[i].up);
      std::optional<int> index;
      if (array != decl.arrays.end() && i + 1 < t.size() && t[i + 1].text == "[") {
        size_t close = i + 1;
        while (close < t.size() && t[close].text != "]") ++close;
        if (close == t.size()) continue;
        index = integerValue(t, i + 2, close);
        last = close;
      }
      // a motion's target written as the point's name alone: LIN XP1 C_DIS, CIRC XA, XB, LIN XPA[2]
      const bool target = motion && depth == 0 && (i == 1 || t[i - 1].text == ",") &&
                          (last + 1 == t.size() || t[last + 1].text == "," || t[last + 1].kind == Tok::kIdent);
      if (target && array != decl.arrays.end() && last > i && !index) {
        // LIN XPA[I]: the motion goes to whichever element the index names at run time
        const std::string prefix = upper(array->second.name) + "[";
        for (const auto& [up, p] : decl.points)
          if (up.compare(0, prefix.size(), prefix) == 0 && p.value && p.value->value_id >= 0 &&
              static_cast<size_t>(p.value->value_id) < source.values.size())
            source.values[static_cast<size_t>(p.value->value_id)].chosen_at_run_time.push_back(src.loc(t[0].begin));
        continue;
      }
      if (target) continue;
      if (array != decl.arrays.end() && last > i) {
        const std::string prefix = upper(array->second.name) + "[";
        for (const auto& [up, p] : decl.points)  // XPA[1], or every element for XPA[I]
          if (up.compare(0, prefix.size(), prefix) == 0 && (!index || up == upper(arrayElementName(array->second, *index)))) noteRead(p, t, i);
        continue;
      }
      if (const auto it = decl.points.find(t[i].up); it != decl.points.end()) noteRead(it->second, t, i);
    }
  }
}

}  // namespace

Program readKrl(const std::string& src_path, const KrlReadOptions& options) {
  auto source = std::make_shared<KrlSource>();
  source->src_path = src_path;
  source->src_text = readFileBytes(src_path, "the KRL program");
  source->dat_path = options.dat_path.empty() ? krlDatPath(src_path) : options.dat_path;
  if (!source->dat_path.empty()) source->dat_text = readFileBytes(source->dat_path, "the KRL data file");

  Program program;
  program.source_file = src_path;
  Reader r;
  r.src = source.get();
  r.program = &program;
  r.other_globals = options.other_globals;

  if (!options.config_path.empty()) {
    const KrlFile cfg(options.config_path, readFileBytes(options.config_path, "the $config.dat"), 2);
    parseDataFile(cfg, r.decl, nullptr, true);
    r.decl.tables.file = options.config_path;
  }
  if (!source->dat_path.empty()) {
    const KrlFile dat(source->dat_path, source->dat_text, 1);
    parseDataFile(dat, r.decl, source.get(), false);
  }
  const KrlFile src(src_path, source->src_text, 0);
  r.f = &src;
  // the .src's lines' tokens, lexed once for the prescan and notePointReads
  std::vector<std::vector<Tok>> lines;
  lines.reserve(src.lines().size());
  for (const Line& l : src.lines()) {
    lines.push_back(lex(src, l.begin, l.code_end));
    lines.back().shrink_to_fit();  // kept for the whole file: not its growth's spare room (a CAM path has 10^5 lines)
  }
  {
    // the subroutines defined here that move the robot, themselves or through the ones they
    // call (a call may come before the DEF)
    std::map<std::string, bool> moves, sets_tool, sets_base, sets_ori, sets_circ;
    std::map<std::string, std::set<std::string>> calls;
    // "" unless the line is a DEF or a DEFFCT (DEFFCT type name(...))
    auto defName = [](const std::vector<Tok>& t) -> std::string {
      const size_t i = !t.empty() && t[0].up == "GLOBAL" ? 1 : 0;
      if (t.size() > i + 1 && t[i].up == "DEF" && t[i + 1].kind == Tok::kIdent) return t[i + 1].up;
      if (t.size() > i + 2 && t[i].up == "DEFFCT" && t[i + 2].kind == Tok::kIdent) return t[i + 2].up;
      return "";
    };
    for (const std::vector<Tok>& t : lines)
      if (const std::string d = defName(t); !d.empty()) moves[d] = sets_tool[d] = sets_base[d] = sets_ori[d] = sets_circ[d] = false;
    std::string cur;
    for (const std::vector<Tok>& t : lines) {
      if (t.empty()) continue;
      if (const std::string d = defName(t); !d.empty()) {
        cur = d;
        continue;
      }
      if (isMotionKeyword(t[0].up) && t[0].kind == Tok::kIdent && !cur.empty()) moves[cur] = true;
      // $TOOL / $BASE set (an assignment, BAS(#TOOL/#BASE), an inline form's BAS with its FDAT)
      const bool assigns = t.size() > 1 && (t[1].text == "=" || t[1].text == ".");
      const bool bas = t[0].up == "BAS" && t.size() > 2 && t[1].text == "(";
      const bool inline_form = bas && (t[2].up == "#PTP_PARAMS" || t[2].up == "#CP_PARAMS");
      if (!cur.empty() && ((t[0].up == "$TOOL" && assigns) || (bas && t[2].up == "#TOOL") || inline_form)) sets_tool[cur] = true;
      if (!cur.empty() && ((t[0].up == "$BASE" && assigns) || (bas && t[2].up == "#BASE") || inline_form)) sets_base[cur] = true;
      // $ORI_TYPE / $CIRC_TYPE set (an assignment, an LDAT made active by BAS(#CP_PARAMS / #CP_DAT),
      // BAS(#INITMOV) setting them back to #VAR, #BASE)
      const bool cp_bas = bas && (t[2].up == "#CP_PARAMS" || t[2].up == "#CP_DAT" || t[2].up == "#INITMOV");
      if (!cur.empty() && ((t[0].up == "$ORI_TYPE" && assigns) || cp_bas)) sets_ori[cur] = true;
      if (!cur.empty() && ((t[0].up == "$CIRC_TYPE" && assigns) || cp_bas)) sets_circ[cur] = true;
      // a value other than the default anywhere (an assignment or a WITH of $ORI_TYPE / $CIRC_TYPE)
      for (size_t i = 0; i + 2 < t.size(); ++i) {
        if (t[i + 1].text != "=") continue;
        if (t[i].up == "$ORI_TYPE" && !orientationControlValue(t[i + 2].text, false).empty()) r.ori_varies_ = true;
        if (t[i].up == "$CIRC_TYPE" && !orientationControlValue(t[i + 2].text, true).empty()) r.circ_varies_ = true;
      }
      // calls: a subroutine's as a statement, a function's anywhere in an expression (an
      // interrupt's declaration names its handler without calling it)
      for (size_t i = 0; i + 1 < t.size() && !cur.empty() && !declaresInterrupt(t); ++i)
        if (t[i].kind == Tok::kIdent && t[i + 1].text == "(" && moves.count(t[i].up)) calls[cur].insert(t[i].up);
    }
    for (const auto& kv : moves) r.defined_routines_.insert(kv.first);
    r.local_defs_ = movingRoutines(moves, calls);
    r.tool_defs_ = movingRoutines(sets_tool, calls);  // (the same closure over the calls)
    r.base_defs_ = movingRoutines(sets_base, calls);
    r.ori_defs_ = movingRoutines(sets_ori, calls);
    r.circ_defs_ = movingRoutines(sets_circ, calls);
    for (const auto& [name, l] : r.decl.ldats) {  // (SORI_TYP(LDAT) and BAS read these)
      r.ori_varies_ = r.ori_varies_ || !orientationControlValue(l.ori_typ, false).empty();
      r.circ_varies_ = r.circ_varies_ || !orientationControlValue(l.circ_typ, true).empty();
    }
    // the points whose assignments make their value depend on more than the text before a motion
    int depth = 0;  // open IF, SWITCH and loops
    bool in_main = false, main_seen = false;
    for (size_t li = 0; li < lines.size(); ++li) {
      const std::vector<Tok>& t = lines[li];
      if (t.empty()) continue;
      if (!defName(t).empty()) {
        in_main = !main_seen;
        main_seen = true;
        depth = 0;
        continue;
      }
      const std::string& k = t[0].up;
      if (k == "END" || k == "ENDFCT") {
        in_main = false;
        continue;
      }
      if (Reader::opensBranch(k) || Reader::opensLoop(k)) ++depth;
      if (Reader::closesBlock(k) && depth > 0) --depth;
      if (t[0].kind != Tok::kIdent || k.empty() || k[0] == '$' || r.volatile_points_.count(k)) continue;
      size_t eq = 1;  // after the name, or after an array's index (XPA[2] = .., XPA[i].X = ..: the array)
      if (t.size() > 1 && t[1].text == "[") {
        int brackets = 0;
        for (eq = 1; eq < t.size(); ++eq) {
          if (t[eq].text == "[") ++brackets;
          if (t[eq].text == "]" && --brackets == 0) break;
        }
        ++eq;
      }
      const bool field = t.size() > eq + 2 && t[eq].text == "." && t[eq + 1].kind == Tok::kIdent;
      if (field) eq += 2;
      if (eq >= t.size() || t[eq].text != "=") continue;
      const std::string at = src.loc(t[0].begin).str();
      r.assigned_points_.emplace(k, at);
      if (!in_main || depth > 0)
        r.volatile_points_[k] = "is assigned at " + at + (in_main ? " inside a branch or a loop" : " inside a subroutine or a function") +
                                ": its value at a motion depends on the way the program runs";
    }
  }
  for (const Line& l : src.lines()) r.handleLine(l);
  // a file cut short: the innermost block still open is what the end of the file cut off
  // (an IF inside the DEF: its ENDIF is missing first)
  if (!r.structure_.empty()) {
    const auto& [kw, line] = r.structure_.back();
    src.fail(src.text().size(), "expected " + std::string(blockOpenedBy(kw)->close) + " to close the " + kw + " at line " + std::to_string(line) +
                                    (r.def_open_ ? " (and " + r.openEnd() + " at line " + std::to_string(r.def_line_) + ")" : std::string()) +
                                    ", found the end of the file");
  }
  if (r.def_open_)
    src.fail(src.text().size(), "expected " + r.openEnd() + " at line " + std::to_string(r.def_line_) + ", found the end of the file");
  // the main program's declarations of points the model declares itself are not carried
  {
    const std::set<std::string> model_points = pointsTheModelDeclares(program);
    for (auto it = r.point_declarations_.rbegin(); it != r.point_declarations_.rend(); ++it) {
      const size_t by_model = declaredByModel(it->second, model_points);
      if (by_model == it->second.size()) {
        program.passthrough.erase(program.passthrough.begin() + static_cast<std::ptrdiff_t>(it->first));
      } else if (by_model > 0) {
        // some of them: the others travel (withoutModelPoints)
        PassThrough& p = program.passthrough[it->first];
        const Line& l = src.lines().at(static_cast<size_t>(p.where.line - 1));
        p.text = withoutModelPoints(src, l, lex(src, l.begin, l.code_end), model_points);
      }
    }
  }
  notePointReads(src, lines, r.decl, *source);
  if (!source->dat_path.empty()) datPassThrough(KrlFile(source->dat_path, source->dat_text, 1), program);
  if (program.name.empty() && !r.first_function_.empty()) {
    // a module of functions only (KRC backups hold many): loaded by the controller, no motions
    program.name = fs::path(src_path).stem().string();
    program.krl_functions_only = r.first_function_;
  }
  // no DEF (nor DEFFCT): no program. Before the data list's name is checked against the DEF's:
  // a .src cut short before its DEF is that, not a data list of another module.
  if (program.name.empty()) {
    bool any = false;  // a statement (not the & header, a comment, a fold or a blank line)
    for (const Line& l : src.lines())
      if (l.code_end > l.begin && src.text()[src.text().find_first_not_of(" \t", l.begin)] != '&') any = true;
    if (any) throw calib::InputError(src_path, 1, 1, "expected a KRL program (DEF name( ) ... END), found no DEF line");
    // nothing but the header, comments and blank lines: the file ends before its DEF (cut short,
    // or empty); written back, it would be a module without its program
    src.fail(src.text().size(), "expected a KRL program (DEF name( ) ... END), found the end of the file before any DEF line");
  }
  // the data list is the module's: DEFDAT names the module (its file) or its DEF (KSS: a data
  // list of another name is not the module's, whose points it would silently replace)
  if (!r.decl.defdat_name.empty()) {
    const std::string dat = upper(r.decl.defdat_name), stem = upper(fs::path(src_path).stem().string());
    if (dat != stem && dat != upper(program.name)) {
      const SourceLocation& w = r.decl.defdat_where;
      throw calib::InputError(w.file, w.line, w.column,
                              "expected the data list of the module " + fs::path(src_path).stem().string() +
                                  (program.name.empty() || upper(program.name) == stem ? std::string() : " (DEF " + program.name + ")") +
                                  " (DEFDAT " + fs::path(src_path).stem().string() + "), found DEFDAT " + r.decl.defdat_name);
    }
  }
  program.krl = source;
  return program;
}


}  // namespace accura::postproc
