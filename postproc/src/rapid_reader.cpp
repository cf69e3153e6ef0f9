// RAPID reader (see rapid.h): statements, declarations, the motion model, pass-through lines.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "accura/calib/errors.h"
#include "accura/calib/file_io.h"
#include "accura/calib/text.h"
#include "excerpt.h"
#include "rapid_internal.h"
#include "start_tracker.h"

namespace fs = std::filesystem;

namespace accura::postproc {
namespace {

using namespace rapid_detail;
using detail::excerpt;

/// A target expression evaluated (wobj frame, mm) or why it cannot be.
struct TargetVal {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  std::array<int, 4> conf{};
  std::array<std::optional<double>, 6> ext;
  int value = -1;        ///< the robtarget value it is (-1: an expression)
  int reads = -1;        ///< an Offs/RelTool expression: the robtarget value it is built on
  std::string problem;
};

/// A robtarget array declared with a value (`CONST robtarget pts{3} := [v1, v2, v3];`,
/// `grid{2,3}`: RAPID's arrays have up to 3 dimensions, indexed from 1).
struct ArrayVal {
  std::string name;        ///< as written
  std::vector<int> dims;   ///< the size of each dimension
  /// The Decl (RapidSource::decls) of each element, row-major (the last index runs fastest,
  /// as RAPID writes the aggregate: [[g{1,1}, g{1,2}], [g{2,1}, g{2,2}]]); -1: an element not
  /// written as a robtarget value (a name, an expression)
  std::vector<int> decls;
  std::string problem;     ///< why its elements have no values ("" when they have)
  /// Why accura cannot read an element written as a robtarget value (a CONST num in its
  /// position, a non-unit quaternion: the controller loads the module), by element; "" when it
  /// reads it or the element is no such value
  std::vector<std::string> unread;
  SourceLocation where;    ///< its declaration
};

/// A frame declaration (tooldata / wobjdata) evaluated.
struct FrameVal {
  std::optional<Eigen::Isometry3d> T;
  std::string note;  ///< why it cannot be modelled
  SourceLocation where;
};

/// The data a scope declares: a routine's, a module's (its LOCAL data included) or the
/// program's global data (every module's data that is not LOCAL: RAPID's task-global data,
/// visible in every module of the task whatever the order).
struct Scope {
  /// Every name the scope declares, of any type (upper case -> where): the innermost scope that
  /// declares a name is the one it refers to, also when it is not a datum accura reads (a
  /// routine's `VAR num p10` hides the module's robtarget p10).
  std::map<std::string, SourceLocation> names;
  std::set<std::string> read_names;       ///< those of a datum of kReadTypes
  /// PERS declarations: upper-case name -> their type and value as written (a persistent the
  /// same in several modules is one object the modules share)
  std::map<std::string, std::string> persistents;
  std::map<std::string, int> robtargets;  ///< upper-case name -> value
  /// robtargets declared with a value accura cannot read: upper-case name -> why (unreadValue)
  std::map<std::string, std::string> unread_robtargets;
  std::map<std::string, int> robtarget_arrays;  ///< upper-case name -> index in Reader::arrays_
  std::map<std::string, FrameVal> tools, wobjs;
  std::map<std::string, std::array<double, 6>> joints;
  std::map<std::string, std::optional<double>> zones;   ///< zone radius (nullopt: fine)
  std::map<std::string, double> speeds;                 ///< v_tcp (mm/s)
  std::map<std::string, double> consts;  ///< CONST num declared with a number (its value)
  /// robtargets a module given with --config declares (upper-case name -> the index of that
  /// module in Reader::tasks_): read from there when a motion goes to them (Reader::taskRobtarget)
  std::map<std::string, size_t> task_robtargets;
  /// robtargets of a module given with --config that a motion keeps as written: upper-case name -> why
  std::map<std::string, std::string> task_kept;
};

/// The data types whose values accura reads (a second declaration of one of them in a scope is
/// an error: the controller refuses the ambiguous name).
const std::set<std::string> kReadTypes = {"ROBTARGET", "TOOLDATA", "WOBJDATA", "JOINTTARGET", "ZONEDATA", "SPEEDDATA"};

/// Block headers whose condition or expression may read data.
const std::set<std::string> kConditionHeads = {"IF", "ELSEIF", "WHILE", "FOR", "TEST", "CASE"};
const std::set<std::string> kBlockHeads = {"MODULE", "ENDMODULE", "PROC", "ENDPROC", "FUNC", "ENDFUNC", "TRAP", "ENDTRAP",
                                           "RECORD", "ENDRECORD", "IF", "ELSEIF", "ELSE", "ENDIF", "WHILE", "ENDWHILE", "FOR",
                                           "ENDFOR", "TEST", "CASE", "DEFAULT", "ENDTEST", "ERROR", "BACKWARD", "UNDO"};
/// Motion instructions accura does not model: their targets would be missed without a word.
const std::set<std::string> kOtherMoves = {
    "MOVELDO", "MOVEJDO", "MOVECDO", "MOVELSYNC", "MOVEJSYNC", "MOVECSYNC", "MOVELAO", "MOVEJAO", "MOVECAO", "MOVELGO",
    "MOVEJGO", "MOVECGO", "TRIGGL", "TRIGGJ", "TRIGGC", "TRIGGLIOS", "TRIGGJIOS", "ARCL", "ARCC", "ARCLSTART", "ARCLEND",
    "ARCCSTART", "ARCCEND", "ARCL1", "ARCL2", "ARCC1", "ARCC2", "ARCREPL", "ARCMOVEL", "ARCMOVEC", "SEARCHL", "SEARCHC",
    "SEARCHJ", "SEARCHEXTJ", "MOVEEXTJ", "SPOTL", "SPOTJ", "SPOTML", "SPOTMJ", "MOVEABSJDO", "CAPL", "CAPC", "PAINTL",
    "PAINTC", "PAINTLSIG", "PAINTLDO", "DISPL", "DISPC", "CONTACTL", "FCPRESSL", "FCPRESSC", "FCPRESSLSTART",
    "FCPRESSEND", "TRIGGRELJ", "TRIGGLDO", "TRIGGJDO", "TRIGGCDO", "CSSDEACTMOVEL", "MOVELTRACK",
    // Externally Guided Motion moves the robot where a sensor streams it (EGMRunPose,
    // EGMRunJoint) or corrects a programmed path on line (EGMMoveL, EGMMoveC: ToPoint after the
    // EGM id); the path recorder and the independent axes move the robot or an axis too
    // (PathRecMoveBwd, PathRecMoveFwd, StepBwdPath; IndAMove, IndCMove, IndDMove, IndRMove):
    // the position after them is not the target written before
    "EGMRUNPOSE", "EGMRUNJOINT", "EGMMOVEL", "EGMMOVEC", "PATHRECMOVEBWD", "PATHRECMOVEFWD", "STEPBWDPATH", "INDAMOVE",
    "INDCMOVE", "INDDMOVE", "INDRMOVE"};

/// The motion instructions with a robtarget that move as MoveL, MoveJ or MoveC and do
/// something else besides (ABB, Technical reference manual - RAPID Instructions, Functions and
/// Data types: MoveLDO ToPoint [\ID] Speed [\T] Zone Tool [\WObj] [\TLoad] Signal Value;
/// MoveLAO the same with an analog signal; MoveLSync ToPoint .. Tool [\WObj] [\TLoad] ProcName;
/// TriggL [\Conc] ToPoint [\ID] Speed [\T] Trigg_1 [\T2] .. [\T8] Zone [\Inpos] Tool [\WObj]
/// [\Corr] [\TLoad]; the J and C forms alike, C with CirPoint first; the arc welding option's
/// ArcL, ArcLStart, ArcLEnd ToPoint [\ID] Speed [\T] Seam Weld [\Weave] Zone [\Z] Tool [\WObj]
/// [\Corr] [\Track] [\SeamName], ArcC.. with CirPoint first): their targets are
/// compensated as those of MoveL/MoveJ/MoveC. The positional arguments: how many, and which are
/// the speed, the zone and the tool (the targets come first); `names`: the parameter names of the
/// positional arguments, one per argument (as the manual writes them; a required argument may be written with
/// its name, `ToPoint:=p20`). Another count (an instruction of another RobotWare, a typo the
/// controller would refuse) is kept as written and named, as the instructions of kOtherMoves are.
struct MoveLayout {
  MotionType type;
  size_t count, speed, zone, tool;
  std::vector<std::string> names;  ///< `count` of them
};
const std::map<std::string, MoveLayout> kLayouts = {
    {"MOVEL", {MotionType::kLin, 4, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool"}}},
    {"MOVEJ", {MotionType::kPtp, 4, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool"}}},
    {"MOVEC", {MotionType::kCirc, 5, 2, 3, 4, {"CirPoint", "ToPoint", "Speed", "Zone", "Tool"}}},
    {"MOVEABSJ", {MotionType::kPtp, 4, 1, 2, 3, {"ToJointPos", "Speed", "Zone", "Tool"}}},
    {"MOVELDO", {MotionType::kLin, 6, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool", "Signal", "Value"}}},
    {"MOVEJDO", {MotionType::kPtp, 6, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool", "Signal", "Value"}}},
    {"MOVECDO", {MotionType::kCirc, 7, 2, 3, 4, {"CirPoint", "ToPoint", "Speed", "Zone", "Tool", "Signal", "Value"}}},
    {"MOVELAO", {MotionType::kLin, 6, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool", "Signal", "Value"}}},
    {"MOVEJAO", {MotionType::kPtp, 6, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool", "Signal", "Value"}}},
    {"MOVECAO", {MotionType::kCirc, 7, 2, 3, 4, {"CirPoint", "ToPoint", "Speed", "Zone", "Tool", "Signal", "Value"}}},
    {"MOVELSYNC", {MotionType::kLin, 5, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool", "ProcName"}}},
    {"MOVEJSYNC", {MotionType::kPtp, 5, 1, 2, 3, {"ToPoint", "Speed", "Zone", "Tool", "ProcName"}}},
    {"MOVECSYNC", {MotionType::kCirc, 6, 2, 3, 4, {"CirPoint", "ToPoint", "Speed", "Zone", "Tool", "ProcName"}}},
    {"TRIGGL", {MotionType::kLin, 5, 1, 3, 4, {"ToPoint", "Speed", "Trigg_1", "Zone", "Tool"}}},
    {"TRIGGJ", {MotionType::kPtp, 5, 1, 3, 4, {"ToPoint", "Speed", "Trigg_1", "Zone", "Tool"}}},
    {"TRIGGC", {MotionType::kCirc, 6, 2, 4, 5, {"CirPoint", "ToPoint", "Speed", "Trigg_1", "Zone", "Tool"}}},
    {"ARCL", {MotionType::kLin, 6, 1, 4, 5, {"ToPoint", "Speed", "Seam", "Weld", "Zone", "Tool"}}},
    {"ARCLSTART", {MotionType::kLin, 6, 1, 4, 5, {"ToPoint", "Speed", "Seam", "Weld", "Zone", "Tool"}}},
    {"ARCLEND", {MotionType::kLin, 6, 1, 4, 5, {"ToPoint", "Speed", "Seam", "Weld", "Zone", "Tool"}}},
    {"ARCC", {MotionType::kCirc, 7, 2, 5, 6, {"CirPoint", "ToPoint", "Speed", "Seam", "Weld", "Zone", "Tool"}}},
    {"ARCCSTART", {MotionType::kCirc, 7, 2, 5, 6, {"CirPoint", "ToPoint", "Speed", "Seam", "Weld", "Zone", "Tool"}}},
    {"ARCCEND", {MotionType::kCirc, 7, 2, 5, 6, {"CirPoint", "ToPoint", "Speed", "Seam", "Weld", "Zone", "Tool"}}}};

/// A motion instruction (upper case): MoveL, MoveJ, MoveC, MoveAbsJ or one of kOtherMoves.
bool isMove(const std::string& u) { return isPlainMove(u) || kOtherMoves.count(u) > 0; }

class Reader {
 public:
  Reader(const std::string& text, const std::string& path) : src_(std::make_shared<RapidSource>()) {
    src_->path = path;
    src_->text = text;
    starts_.push_back(0);
    for (size_t i = 0; i < text.size(); ++i)
      if (text[i] == '\n') starts_.push_back(i + 1);
  }

  /// Another module of the task as a module of it sees it (the module given with --config).
  struct TaskModule {
    std::string path, text;
    Scope data;  ///< its task-global data (every module datum that is not LOCAL)
    /// The names it assigns (its routines run in the task too: `torch.tframe.trans.z := 250;`
    /// in a PROC of that module), with the first place.
    std::map<std::string, SourceLocation> assigned;
    std::map<std::string, SourceLocation> locals;  ///< its LOCAL data (upper case): invisible to other modules
    /// its text as read: the robtarget values and declarations data.robtargets refers to
    std::shared_ptr<const RapidSource> source;
    std::vector<std::array<std::optional<double>, 6>> ext;  ///< external axes of each of its values
    std::vector<size_t> line_starts;  ///< the offset of each of its lines (a place in its text as line:column)
  };

  /// The text as another module of the task (TaskModule), read as run() reads it. InputError for
  /// text that is no module.
  TaskModule taskData() {
    t_ = lexRapid(src_->text, src_->path);
    split();
    scanAssignments();
    moduleData();
    if (modules_.empty())
      fail(t_.empty() ? 0 : t_.front().b, "expected a RAPID module (MODULE name ... ENDMODULE) with the task's tooldata and wobjdata, found " +
                                              (t_.empty() ? std::string("an empty file") : "'" + excerpt(t_.front().s) + "'"));
    TaskModule m{src_->path, src_->text, global_, assigned_, {}, src_, ext_, starts_};
    for (const Scope& s : modules_)
      for (const auto& [u, where] : s.names)
        if (!global_.names.count(u)) m.locals.emplace(u, where);
    return m;
  }

  /// Another module of the task (CalibData.mod, user.sys) whose task-global data this module
  /// uses: RAPID's global data are visible in every module of the task. Its tooldata, wobjdata,
  /// speeddata, zonedata and CONST nums serve the names this program does not declare itself;
  /// what it assigns is a run-time value here too; its names are not a new point's
  /// (RapidSource::task_text).
  void useTaskData(TaskModule other) {
    std::vector<TaskModule> one;
    one.push_back(std::move(other));
    useTaskData(std::move(one));
  }
  /// Several modules of the task (--config given more than once): as above for each. A name
  /// two of them declare global (not LOCAL) is an error naming both: the controller refuses to
  /// load a task whose modules declare one global name twice (ABB, RAPID reference manual,
  /// "Basic characteristics", Data scope: global data are visible in every module of the task);
  /// a PERS declared alike in both is one persistent they share, as in one program's modules.
  void useTaskData(std::vector<TaskModule> others) {
    for (size_t j = 0; j < others.size(); ++j)
      for (size_t i = 0; i < j; ++i) sameGlobalName(others[i].data, others[j].data, others[j]);
    tasks_ = std::move(others);
    src_->task_text.clear();
    for (const TaskModule& m : tasks_) src_->task_text += m.text + "\n";
  }

  Program run() {
    t_ = lexRapid(src_->text, src_->path);
    findMovingRoutines();
    split();
    scanAssignments();
    findDisplacedRoutines();
    moduleData();
    addTaskData();
    Program p;
    p.source_file = src_->path;
    p.name = fs::path(src_->path).stem().string();
    for (const Range& st : stmts_) {
      statement(st, p);
      // after a motion that runs only when a compact IF's condition holds, the robot is at
      // its target or where it was before
      const std::string& u = t_[st.first].u;
      if (conditional_.count(st.first) && isMove(u))
        flow_.unknown();
    }
    if (!module_seen_) fail(t_.empty() ? 0 : t_.front().b, "expected a RAPID module (MODULE name ... ENDMODULE), found " +
                                                               (t_.empty() ? std::string("an empty file") : "'" + excerpt(t_.front().s) + "'"));
    // what the end of the file left open: the routine's end (a module cut short inside a
    // routine: missing first), then the module's
    const std::string routine_end = module_open_ && !routine_.empty()
                                        ? "END" + routine_kind_ + " of the routine " + excerpt(routine_) + " (" + routine_kind_ + " at line " +
                                              std::to_string(loc(t_[routine_line_.first].b).line) + ")"
                                        : std::string();
    if (cut_.second > cut_.first)
      fail(t_[cut_.second - 1].e, "expected ';' at the end of the statement '" + quoted(cut_) + "'" +
                                      (routine_end.empty() ? std::string() : ", then " + routine_end) +
                                      (module_open_ ? ", then ENDMODULE" : "") + ", found the end of the file");
    if (!routine_end.empty()) fail(src_->text.size(), "expected " + routine_end + ", then ENDMODULE, found the end of the file");
    if (module_open_) fail(src_->text.size(), "expected ENDMODULE, found the end of the file");
    if (!module_name_.empty()) p.name = module_name_;
    passThrough(p);
    p.rapid = src_;
    return p;
  }

 private:
  SourceLocation loc(size_t off) const { return locate(starts_, src_->path, off); }
  /// An InputError at off. A statement that ends where the file ends (nothing but white space
  /// after off: a file cut short) found the end of the file, not the end of a statement.
  [[noreturn]] void fail(size_t off, const std::string& msg) const {
    const SourceLocation l = loc(off);
    static const std::string kStatementEnd = "found the end of the statement";
    const bool cut = msg.size() >= kStatementEnd.size() && msg.compare(msg.size() - kStatementEnd.size(), kStatementEnd.size(), kStatementEnd) == 0 &&
                     src_->text.find_first_not_of(" \t\r\n", std::min(off, src_->text.size())) == std::string::npos;
    throw calib::InputError(l.file, l.line, l.column, cut ? msg.substr(0, msg.size() - kStatementEnd.size()) + "found the end of the file" : msg);
  }
  std::string text(Range r) const { return r.first < r.second ? src_->text.substr(t_[r.first].b, t_[r.second - 1].e - t_[r.first].b) : ""; }
  /// The text of r as a message quotes it (detail::excerpt: at most 80 bytes).
  std::string quoted(Range r) const { return excerpt(text(r)); }
  std::string found(size_t i, size_t end) const { return i < end ? "'" + excerpt(t_[i].s) + "'" : "the end of the statement"; }

  /// Statements: a block header runs to the end of its line (and its brackets; IF, ELSEIF,
  /// WHILE, FOR and CASE at least to their THEN, DO or ':'), and a statement that shares its
  /// line is one of its own; a label is one; any other statement runs to its ';'.
  void split() {
    size_t i = 0;
    while (i < t_.size()) {
      // a label (name:) is a statement of its own, whatever follows it on its line
      if (t_[i].kind == Tok::Kind::kIdent && !kBlockHeads.count(t_[i].u) && isOp(t_, i + 1, ":")) {
        stmts_.push_back({i, i + 2});
        i += 2;
        continue;
      }
      const size_t h = headAt(i);
      const bool head = h != kNoHead;
      // a header that needs its closing word runs over lines until it: IF ... THEN (a compact
      // IF ends with its statement's ';'), ELSEIF ... THEN, WHILE / FOR ... DO, CASE ...:
      const std::string& hu = head ? t_[h].u : std::string();
      const char* closing_word = hu == "IF" || hu == "ELSEIF" ? "THEN" : hu == "WHILE" || hu == "FOR" ? "DO" : nullptr;
      bool closed = !closing_word && hu != "CASE" && hu != "TEST";
      const int line = loc(t_[i].b).line;
      std::vector<size_t> open;
      size_t j = i;
      for (; j < t_.size(); ++j) {
        const Tok& t = t_[j];
        if (head && open.empty() && j > i && loc(t.b).line != line && closed) break;
        // (a TEST's expression runs to its first CASE, DEFAULT or ENDTEST, which start statements of their own)
        if (head && open.empty() && !closed && hu == "TEST" && j > i + 1 && t.kind == Tok::Kind::kIdent &&
            (t.u == "CASE" || t.u == "DEFAULT" || t.u == "ENDTEST"))
          break;
        if (head && open.empty() && !closed &&
            ((closing_word && t.kind == Tok::Kind::kIdent && t.u == closing_word) || (hu == "CASE" && isOp(t_, j, ":"))))
          closed = true;
        if (!head && open.empty() && j > i && t.kind == Tok::Kind::kIdent && kBlockHeads.count(t.u) && loc(t.b).line != loc(t_[j - 1].b).line)
          fail(t_[j - 1].e, "expected ';' at the end of the statement '" + quoted({i, j}) + "', found " + excerpt(t.s));
        if (opens(t)) open.push_back(j);
        if (closes(t)) {
          if (open.empty()) fail(t.b, "expected a statement, found an unmatched '" + t.s + "'");
          const std::string& o = t_[open.back()].s;
          const std::string want = o == "(" ? ")" : o == "[" ? "]" : "}";
          if (t.s != want) fail(t.b, "expected '" + want + "' to close the '" + o + "' at " + loc(t_[open.back()].b).str() + ", found '" + t.s + "'");
          open.pop_back();
        }
        if (open.empty() && isOp(t_, j, ";")) {
          ++j;
          break;
        }
      }
      if (!open.empty()) {
        const Tok& o = t_[open.back()];
        fail(o.b, "expected '" + std::string(o.s == "(" ? ")" : o.s == "[" ? "]" : "}") + "' to close this '" + o.s + "', found the end of the file");
      }
      if (!head && (j > t_.size() || !isOp(t_, j - 1, ";"))) {
        // the end of the file cut the last statement: an error after the statements before it
        // (read()), which says what else the end of the file cut off (the routine, the module)
        cut_ = {i, j};
        break;
      }
      // the statement a CASE, a DEFAULT or a compact IF (without THEN) holds on its line is one
      // of its own (a compact IF's runs only when the condition holds)
      const size_t inner = head ? innerStatement({i, j}) : j;
      stmts_.push_back({i, inner});
      if (inner < j && t_[i].u == "IF" && !(t_[inner - 1].kind == Tok::Kind::kIdent && t_[inner - 1].u == "THEN"))
        conditional_.insert(inner);
      i = inner;
    }
  }

  static constexpr size_t kNoHead = static_cast<size_t>(-1);
  /// The block keyword of a statement starting at token i (LOCAL PROC / FUNC / TRAP: the one
  /// after LOCAL); kNoHead when it is no block header.
  size_t headAt(size_t i) const {
    if (t_[i].kind != Tok::Kind::kIdent) return kNoHead;
    if (kBlockHeads.count(t_[i].u)) return i;
    if (t_[i].u == "LOCAL" && i + 1 < t_.size() && t_[i + 1].kind == Tok::Kind::kIdent &&
        (t_[i + 1].u == "PROC" || t_[i + 1].u == "FUNC" || t_[i + 1].u == "TRAP"))
      return i + 1;
    return kNoHead;
  }

  /// The ':=' of the assignment statement r (`name := ..`, `name.field.field := ..`); kNoHead
  /// when r is no assignment. (A name followed by ':=' elsewhere in a statement is a named or
  /// optional argument, `ToPoint:=p20`, `\WObj:=table`.)
  size_t assignmentAt(Range r) const {
    const size_t i = r.first;
    if (i >= r.second || t_[i].kind != Tok::Kind::kIdent || headAt(i) != kNoHead) return kNoHead;
    size_t j = i + 1;
    // (an array's element: `pts{2} := ..`, `pts{2}.trans.x := ..`)
    auto index = [&] {
      if (isOp(t_, j, "{")) j = closing(t_, j, r.second);
    };
    index();
    while (j + 1 < r.second && isOp(t_, j, ".") && t_[j + 1].kind == Tok::Kind::kIdent) {
      j += 2;
      index();
    }
    return j < r.second && isOp(t_, j, ":=") ? j : kNoHead;
  }

  /// The routine name of a PROC / FUNC / TRAP header r (its token); kNoHead for any other.
  size_t routineNameAt(Range r) const {
    const size_t h = headAt(r.first);
    if (h == kNoHead || (t_[h].u != "PROC" && t_[h].u != "FUNC" && t_[h].u != "TRAP")) return kNoHead;
    const size_t k = h + 1 + (t_[h].u == "FUNC" ? 1 : 0);  // (a FUNC's return type first)
    return k < r.second && t_[k].kind == Tok::Kind::kIdent ? k : kNoHead;
  }

  /// A routine's parameter: its name (upper case), whether a call may change the argument
  /// (INOUT, VAR), whether it is optional (\name).
  struct Param {
    std::string name;
    bool changed = false, optional = false;
  };
  /// The parameters of the routine whose name is token k of its header r:
  /// [\][VAR|PERS|INOUT] type name[{*}], separated by ',' or '|'; an optional one (\..) also
  /// without a comma before it (RAPID kernel, <next parameter declaration> ::= ',' <parameter
  /// declaration> | <optional parameter declaration> | ..: `PROC p(robtarget t \switch s)`).
  std::vector<Param> parameters(Range r, size_t k) const {
    std::vector<Param> out;
    if (!isOp(t_, k + 1, "(")) return out;
    Param cur;
    bool any = false;
    for (size_t q = k + 2; q < r.second && !isOp(t_, q, ")"); ++q) {
      if (isOp(t_, q, ",") || isOp(t_, q, "|") || (isOp(t_, q, "\\") && any)) {
        if (any) out.push_back(cur);
        cur = Param{};
        any = false;
        if (!isOp(t_, q, "\\")) continue;
      }
      any = true;
      if (isOp(t_, q, "\\")) cur.optional = true;
      if (t_[q].kind != Tok::Kind::kIdent) continue;
      if (t_[q].u == "INOUT" || t_[q].u == "VAR") cur.changed = true;
      if (cur.name.empty() && q + 1 < r.second &&
          (isOp(t_, q + 1, ",") || isOp(t_, q + 1, "|") || isOp(t_, q + 1, ")") || isOp(t_, q + 1, "{") || isOp(t_, q + 1, "\\")))
        cur.name = t_[q].u;
    }
    if (any) out.push_back(cur);
    return out;
  }

  /// Where a statement that shares the header's line begins in r (r.second when none): after
  /// THEN (IF, ELSEIF), DO (WHILE, FOR), the ':' of a CASE / DEFAULT, the word ELSE, ENDIF,
  /// ENDWHILE, ENDFOR, ENDTEST; before the CASE of a one-line TEST; after a compact IF's
  /// condition (the first name or '%' that follows a complete operand).
  size_t innerStatement(Range r) const {
    const std::string& u = t_[r.first].u;
    if (u == "ELSE" || u == "ENDIF" || u == "ENDWHILE" || u == "ENDFOR" || u == "ENDTEST") return r.first + 1;
    if (u != "CASE" && u != "DEFAULT" && u != "IF" && u != "ELSEIF" && u != "WHILE" && u != "FOR" && u != "TEST") return r.second;
    static const std::set<std::string> kOperatorWords = {"AND", "OR", "XOR", "NOT", "DIV", "MOD"};
    int depth = 0;
    for (size_t k = r.first + 1; k < r.second; ++k) {
      const Tok& t = t_[k];
      if (opens(t)) ++depth;
      if (closes(t)) --depth;
      if (depth != 0) continue;
      const bool word = t.kind == Tok::Kind::kIdent;
      if (u == "CASE" || u == "DEFAULT") {
        if (isOp(t_, k, ":")) return k + 1;
        continue;
      }
      if (u == "TEST") {
        if (word && k > r.first + 1 && (t.u == "CASE" || t.u == "DEFAULT")) return k;
        continue;
      }
      if (u == "WHILE" || u == "FOR") {
        if (word && t.u == "DO") return k + 1;
        continue;
      }
      if (word && t.u == "THEN") return k + 1;
      if (u == "ELSEIF") continue;
      const bool starts = (t.kind == Tok::Kind::kIdent && !kOperatorWords.count(t.u)) || isOp(t_, k, "%");
      const Tok& prev = t_[k - 1];
      const bool operand_before = k > r.first + 1 &&
                                  ((prev.kind == Tok::Kind::kIdent && !kOperatorWords.count(prev.u)) ||
                                   prev.kind == Tok::Kind::kNumber || prev.kind == Tok::Kind::kString ||
                                   isOp(t_, k - 1, ")") || isOp(t_, k - 1, "]") || isOp(t_, k - 1, "}"));
      if (starts && operand_before) return k;
    }
    return r.second;
  }

  /// Names assigned anywhere (name := ..., name.field := ...): their values change at run time.
  /// The routines called while a program displacement is active (PDispOn/PDispSet before the
  /// call in the caller's text, no PDispOff between), and those they call: their targets are
  /// displaced from their start.
  void findDisplacedRoutines() {
    std::set<std::string> names;
    for (const Range& r : stmts_)
      if (const size_t k = routineNameAt(r); k != kNoHead) names.insert(t_[k].u);
    std::map<std::string, std::set<std::string>> calls;  // caller -> callees
    std::string cur;
    bool active = false;
    for (const Range& r : stmts_) {
      if (headAt(r.first) != kNoHead) {
        if (const size_t k = routineNameAt(r); k != kNoHead) {
          cur = t_[k].u;
          active = false;
        }
        continue;
      }
      const std::string& u = t_[r.first].u;
      if (u == "PDISPON" || u == "PDISPSET") active = true;
      if (u == "PDISPOFF") active = false;
      if (t_[r.first].kind == Tok::Kind::kIdent && names.count(u)) {
        calls[cur].insert(u);
        if (active && !displaced_.count(u)) displaced_[u] = loc(t_[r.first].b);
      }
    }
    // the routines a displaced routine calls are displaced too
    std::vector<std::string> todo;
    for (const auto& [n, at] : displaced_) todo.push_back(n);
    while (!todo.empty()) {
      const std::string n = todo.back();
      todo.pop_back();
      for (const std::string& c : calls[n])
        if (!displaced_.count(c)) {
          displaced_[c] = displaced_.at(n);
          todo.push_back(c);
        }
    }
  }

  /// Also the data a call changes through its arguments: the INOUT and VAR parameters of the
  /// module's routines (not PERS: tooldata and wobjdata are passed so, to be read), the first
  /// argument of Add, and the SearchPoint of SearchL/SearchC/SearchJ.
  void scanAssignments() {
    // the module's routines: which of their parameters a call changes (INOUT, VAR)
    std::map<std::string, std::vector<bool>> changes;  // per positional (not optional) parameter
    for (const Range& r : stmts_) {
      const size_t k = routineNameAt(r);
      if (k == kNoHead || !isOp(t_, k + 1, "(")) continue;
      std::vector<bool>& ch = changes[t_[k].u];
      for (const Param& q : parameters(r, k))
        if (!q.optional) ch.push_back(q.changed);
    }
    for (const Range& r : stmts_)
      if (const size_t n = routineNameAt(r); n != kNoHead) routine_kinds_[t_[n].u] = t_[headAt(r.first)].u;
    std::string cur;  // the routine being scanned (upper case)
    for (const Range& r : stmts_) {
      size_t k = r.first;
      if (const size_t n = routineNameAt(r); n != kNoHead) cur = t_[n].u;
      if (k >= r.second || t_[k].kind != Tok::Kind::kIdent) continue;
      const size_t j = assignmentAt(r);
      if (j == kNoHead && routine_kinds_.count(t_[k].u) && headAt(k) == kNoHead) callees_[cur].insert(t_[k].u);
      for (size_t q = k; q + 1 < r.second; ++q)  // (a FUNC of the module called in an expression)
        if (t_[q].kind == Tok::Kind::kIdent && isOp(t_, q + 1, "(") && routine_kinds_.count(t_[q].u)) callees_[cur].insert(t_[q].u);
      if (headAt(k) != kNoHead) continue;
      // a function of the module with INOUT / VAR parameters, called in an expression
      for (size_t q = k; q + 1 < r.second; ++q) {
        if (t_[q].kind != Tok::Kind::kIdent || !isOp(t_, q + 1, "(")) continue;
        const auto fn = changes.find(t_[q].u);
        if (fn == changes.end()) continue;
        const size_t close = closing(t_, q + 1, r.second);
        size_t i = 0;
        for (Range a : items(t_, q + 2, close)) {
          if (a.first < a.second && isOp(t_, a.first, "\\")) continue;  // an optional argument
          if (a.second >= a.first + 3 && t_[a.first].kind == Tok::Kind::kIdent && isOp(t_, a.first + 1, ":=")) a.first += 2;  // (named)
          if (i < fn->second.size() && fn->second[i] && a.first < a.second && t_[a.first].kind == Tok::Kind::kIdent) {
            assigners_[t_[a.first].u].insert("");
            if (!assigned_.count(t_[a.first].u)) assigned_[t_[a.first].u] = loc(t_[a.first].b);
          }
          ++i;
        }
      }
      if (j != kNoHead) {
        // (a tool's load does not move its frame)
        const bool load_only = j > k + 1 && t_[k + 2].u == "TLOAD";
        if (!load_only && !assigned_.count(t_[k].u)) assigned_[t_[k].u] = loc(t_[k].b);
        if (!load_only) assigners_[t_[k].u].insert(cur);
        continue;
      }
      // a procedure call: its positional arguments
      const std::string& u = t_[k].u;
      const bool search = u == "SEARCHL" || u == "SEARCHC" || u == "SEARCHJ";
      const auto it = changes.find(u);
      if (u != "ADD" && !search && it == changes.end()) continue;
      if (headAt(k) != kNoHead || !isOp(t_, r.second - 1, ";")) continue;
      std::vector<Range> pos;
      for (const Arg& a : arguments({k, r.second}))
        if (a.main.first != a.main.second) pos.push_back(a.main);
      auto changed = [&](size_t i) {
        if (i >= pos.size() || t_[pos[i].first].kind != Tok::Kind::kIdent) return;
        assigners_[t_[pos[i].first].u].insert("");
        if (!assigned_.count(t_[pos[i].first].u)) assigned_[t_[pos[i].first].u] = loc(t_[pos[i].first].b);
      };
      if (u == "ADD") changed(0);
      if (search) changed(1);  // Search*: [\Stop|...,] Signal, SearchPoint, ...
      if (it != changes.end())
        for (size_t i = 0; i < it->second.size(); ++i)
          if (it->second[i]) changed(i);
    }
  }

  void markModel(Range r) { model_[r.first] = r.second; }

  /// The robtargets the tokens `r` of statement `st` read (a name that refers to a declared
  /// robtarget where it stands: not a field or an optional argument's name, not a routine's
  /// parameter): the first such place of each is its declaration's read_elsewhere.
  void noteReads(Range r, Range st) {
    for (size_t k = r.first; k < r.second; ++k) {
      if (t_[k].kind != Tok::Kind::kIdent || (k > 0 && (isOp(t_, k - 1, ".") || isOp(t_, k - 1, "\\")))) continue;
      if (isOp(t_, k + 1, ":=")) continue;  // (a named argument's parameter, `Point:=p20`)
      const std::string& u = t_[k].u;
      if (params_.count(u) && !local_.names.count(u)) continue;  // (the call's value)
      auto note = [&](int d) {
        if (d >= 0 && src_->decls[static_cast<size_t>(d)].read_elsewhere.empty())
          src_->decls[static_cast<size_t>(d)].read_elsewhere = loc(t_[k].b).str() + " ('" + quoted(st) + "')";
      };
      if (const int* a = lookup(&Scope::robtarget_arrays, u)) {
        // an array's element: the one a constant index names (none when it is outside the
        // array); every element when the index is a run-time value or the whole array is read
        const ArrayVal& arr = arrays_[static_cast<size_t>(*a)];
        if (isOp(t_, k + 1, "{")) {
          const size_t close = closing(t_, k + 1, r.second);
          std::string why;
          bool run_time = false;
          const int e = elementIndex(arr, {k + 2, close - 1}, why, run_time);
          if (e >= 0 && static_cast<size_t>(e) < arr.decls.size()) note(arr.decls[static_cast<size_t>(e)]);  // (none: no value)
          if (run_time)
            for (int d : arr.decls) note(d);
        } else {
          for (int d : arr.decls) note(d);
        }
        continue;
      }
      const int* id = lookup(&Scope::robtargets, u);
      if (!id || *id < 0) continue;
      note(src_->values[static_cast<size_t>(*id)].decl);
    }
  }
  void noteReads(Range r) { noteReads(r, r); }

  /// The declaration keyword (CONST, PERS, VAR) of a statement starting at i, after LOCAL or
  /// TASK; kNoHead when it is no declaration.
  size_t declarationAt(size_t i) const {
    size_t k = i;
    if (isKw(t_, k, "LOCAL") || isKw(t_, k, "TASK")) ++k;
    return isKw(t_, k, "CONST") || isKw(t_, k, "PERS") || isKw(t_, k, "VAR") ? k : kNoHead;
  }

  /// The offset of the first character of the line statement st starts on.
  size_t lineBegin(Range st) const { return starts_[static_cast<size_t>(loc(t_[st.first].b).line - 1)]; }
  /// The offset just after the line end that ends statement st (the text's end without one).
  size_t lineAfter(Range st) const {
    const size_t nl = src_->text.find('\n', t_[st.second - 1].e);
    return nl == std::string::npos ? src_->text.size() : nl + 1;
  }
  /// The blanks before statement st on its line.
  std::string indentOf(Range st) const { return src_->text.substr(lineBegin(st), t_[st.first].b - lineBegin(st)); }

  /// The module-level data of every module, read before any routine: a module's data are
  /// visible to all its routines, and its global (not LOCAL) data to every module of the
  /// program, whatever the order in which they are written (RAPID, "Scope of data"). A
  /// routine's own data are read where they are, at its start (they are its only). Statements
  /// outside a module are left to the reading in order, which names them.
  void moduleData() {
    bool open = false, in_routine = false, routine_seen = false;
    for (const Range& r : stmts_) {
      const size_t h = headAt(r.first);
      const std::string& u = h != kNoHead ? t_[h].u : std::string();
      // where a new point this module declares goes (taskRobtarget): after its data written
      // before its first routine, else after its MODULE line
      if (u == "MODULE") {
        ++module_index_;
        modules_.resize(static_cast<size_t>(module_index_) + 1);
        module_insert_.resize(modules_.size(), {lineAfter(r), indentOf(r) + "  "});
        routine_seen = false;
        open = true;
      } else if (u == "ENDMODULE") {
        open = false;
      } else if (routineNameAt(r) != kNoHead) {
        in_routine = true;
        routine_seen = true;
      } else if (u == "ENDPROC" || u == "ENDFUNC" || u == "ENDTRAP") {
        in_routine = false;
      } else if (h == kNoHead && open && !in_routine) {
        const size_t k = declarationAt(r.first);
        if (k == kNoHead) continue;
        declaration(r, k);
        module_data_.insert(r.first);
        if (!routine_seen && !module_insert_.empty()) module_insert_.back() = {lineAfter(r), indentOf(r)};
      }
    }
    module_index_ = -1;  // (the reading in order counts the modules again)
  }

  /// A name `second` (the global data of the module `where`, given with --config) declares that
  /// `first` (another such module's, or this program's) declares too: an error at the second,
  /// naming the first (RAPID: one global name per task). A persistent declared alike in both is
  /// one object they share (PERS, TASK PERS: its value is the task's, wherever it is declared);
  /// one of a type accura reads (a tooldata, a robtarget, ...) declared with another type or
  /// value is an error too, as in one program's modules (declare()): the value it starts with
  /// depends on the order in which the controller loads the modules.
  void sameGlobalName(const Scope& first, const Scope& second, const TaskModule& where) const {
    for (const auto& name_where : second.names) {
      const std::string& u = name_where.first;
      const auto it = first.names.find(u);
      if (it == first.names.end()) continue;
      const auto p1 = first.persistents.find(u), p2 = second.persistents.find(u);
      const bool both_pers = p1 != first.persistents.end() && p2 != second.persistents.end();
      if (both_pers && (p1->second == p2->second || !(first.read_names.count(u) || second.read_names.count(u)))) continue;
      const SourceLocation& l = name_where.second;
      const std::string name = excerpt(nameAt(where.text, l));
      if (both_pers)
        throw calib::InputError(l.file, l.line, l.column,
                                "expected the persistent '" + name + "' declared as at " + it->second.str() + " (one object the modules of the task " +
                                    "share), found another type or value: the value it starts with would depend on the order in which the " +
                                    "controller loads the modules");
      throw calib::InputError(l.file, l.line, l.column,
                              "expected one declaration of '" + name + "' in the task's global data (the modules of a " +
                                  "task share the data that is not LOCAL, and the controller refuses a task that declares one twice), found a " +
                                  "second (the first at " + it->second.str() + ")");
    }
  }

  /// The identifier at line:column of `text` (a declaration's name where a Scope records it).
  static std::string nameAt(const std::string& text, const SourceLocation& l) {
    size_t off = 0;
    for (int line = 1; line < l.line && off != std::string::npos; ++line) {
      off = text.find('\n', off);
      if (off != std::string::npos) ++off;
    }
    if (off == std::string::npos) return std::string();
    off += static_cast<size_t>(std::max(l.column, 1) - 1);
    size_t e = off;
    while (e < text.size() && (std::isalnum(static_cast<unsigned char>(text[e])) || text[e] == '_')) ++e;
    return off < text.size() ? text.substr(off, e - off) : std::string();
  }

  /// The task modules' (tasks_) frames, speeds, zones, constants and robtargets into the
  /// program's global data (its own global data and theirs are one name space: a name both
  /// declare is an error, sameGlobalName; its LOCAL data hide theirs).
  void addTaskData() {
    // (the program's own names against each module's first: the names added below are theirs)
    for (const TaskModule& task : tasks_) sameGlobalName(global_, task.data, task);
    for (size_t k = 0; k < tasks_.size(); ++k)
      for (const auto& name_where : tasks_[k].data.names) addTaskDatum(k, name_where.first, name_where.second);
  }

  void addTaskDatum(size_t k, const std::string& u, const SourceLocation& where) {
    const TaskModule& task = tasks_[k];
    for (const Scope& m : modules_)
      if (m.names.count(u)) return;  // (this module's LOCAL datum hides it)
    bool used = false;
    const auto take = [&](auto table) {
      const auto it = (task.data.*table).find(u);
      if (it == (task.data.*table).end()) return;
      (global_.*table)[u] = it->second;
      used = true;
    };
    take(&Scope::tools);
    take(&Scope::wobjs);
    take(&Scope::speeds);
    take(&Scope::zones);
    take(&Scope::consts);
    const auto assigned = task.assigned.find(u);
    if (const auto r = task.data.robtargets.find(u); r != task.data.robtargets.end()) {
      // a robtarget of that module: corrected into a new point of this module (taskRobtarget),
      // as that module is only read; kept as written where a copy would not be what the robot
      // uses (a persistent, a run-time value)
      const RapidSource::Decl& d = task.source->decls[static_cast<size_t>(task.source->values[static_cast<size_t>(r->second)].decl)];
      const std::string head = calib::upperAscii(d.head);
      if (task.data.persistents.count(u) || head.find("PERS") != std::string::npos)
        global_.task_kept[u] = "'" + excerpt(d.name) + "' is a PERS robtarget of " + task.path + " (" + where.str() + "), a module given with --config: " +
                               "a persistent's value is shared at run time (the modules and tasks that use it, ModPos, write it), so its " +
                               "correction can be neither written there (that module is only read) nor frozen into a copy in this module";
      else if (assigned != task.assigned.end())
        global_.task_kept[u] = "'" + excerpt(d.name) + "' is assigned at " + assigned->second.str() + ": its value at run time is not the declared one";
      else
        global_.task_robtargets[u] = k;
      used = true;
    } else if (const auto w = task.data.unread_robtargets.find(u); w != task.data.unread_robtargets.end()) {
      global_.task_kept[u] = "'" + excerpt(nameAt(task.text, where)) + "' is declared in " + task.path + ", a module given with --config, with a value accura cannot read (" +
                             w->second + ")";
      used = true;
    }
    if (!used) return;  // (a robtarget array of that module: its motions are kept, as not declared here)
    // assigned in that module: a run-time value here too, also after this module's own
    // assignment (a call may run that module's routine, which this module does not see: ""
    // as a change through a call); the place named is that module's (not in this text)
    if (assigned != task.assigned.end()) {
      assigned_[u] = assigned->second;
      assigners_[u].insert("");
    }
    global_.names[u] = where;
    if (task.data.read_names.count(u)) global_.read_names.insert(u);
  }

  /// The value of robtarget `u` that the module given with --config tasks_[k] declares, as a
  /// value of this module's source (one per module of this file): its declaration is that
  /// module's (RapidSource::Decl::task_module) with the place a new point goes in this module
  /// (after the module's data, LOCAL: the compensation never writes the value itself, Job).
  int taskRobtarget(const std::string& u, size_t k) {
    const auto key = std::make_pair(module_index_, u);
    if (const auto it = task_values_.find(key); it != task_values_.end()) return it->second;
    const TaskModule& task = tasks_[k];
    const int id = task.data.robtargets.at(u);
    RapidSource::Value v = task.source->values[static_cast<size_t>(id)];
    const RapidSource::Decl& from = task.source->decls[static_cast<size_t>(v.decl)];
    RapidSource::Decl d;
    d.name = from.name;
    const std::pair<size_t, std::string> at = module_insert_.at(static_cast<size_t>(module_index_));
    d.line_begin = d.line_end = at.first;
    d.indent = at.second;
    std::string storage = calib::upperAscii(from.head).find("VAR") != std::string::npos ? "VAR" : "CONST";
    d.head = "LOCAL " + storage + " robtarget ";
    const SourceLocation declared = locate(task.line_starts, task.path, v.begin);
    d.task_module = declared.str();
    v.begin = v.end = 0;
    for (auto& n : v.num) n = {0, 0};
    src_->decls.push_back(d);
    v.decl = static_cast<int>(src_->decls.size()) - 1;
    src_->values.push_back(v);
    ext_.push_back(task.ext[static_cast<size_t>(id)]);
    const int mine = static_cast<int>(src_->values.size()) - 1;
    src_->decls.back().value = mine;
    task_where_[mine] = declared;
    task_values_[key] = mine;
    return mine;
  }

  void statement(Range r, Program& p) {
    const std::vector<Tok>& t = t_;
    const size_t i = r.first;
    const std::string& u = t[i].u;
    if (const size_t h = headAt(i); h != kNoHead) {
      if (kConditionHeads.count(t[h].u)) noteReads(r);  // (IF p20.trans.z > 0 THEN)
      return block(r, p);
    }
    if (!module_open_) fail(t[i].b, "expected MODULE before the first statement, found '" + excerpt(t[i].s) + "'");
    if (const size_t k = declarationAt(i); k != kNoHead) {
      if (!module_data_.count(i)) declaration(r, k);  // (a routine's data; the modules' are read first)
      if (k + 2 < r.second) noteReads({k + 3, r.second}, r);  // its value (CONST robtarget p30 := p20;)
      return;
    }
    if ((u == "CONFL" || u == "CONFJ") && r.second - i == 4 && isOp(t, i + 1, "\\") && (isKw(t, i + 2, "ON") || isKw(t, i + 2, "OFF"))) {
      (u == "CONFL" ? confl_ : confj_) = t[i + 2].u == "ON";
      return markModel(r);
    }
    // a program displacement or an external axes offset moves every target after it
    if (u == "PDISPON" || u == "PDISPSET") pdisp_ = loc(t[i].b), pdisp_name_ = t[i].s;
    if (u == "PDISPOFF") pdisp_.reset();
    if (u == "EOFFSON" || u == "EOFFSSET") eoffs_ = loc(t[i].b), eoffs_name_ = t[i].s;
    if (u == "EOFFSOFF") eoffs_.reset();
    if (isPlainMove(u)) return move(r, p);
    if (t[i].kind == Tok::Kind::kIdent && kLayouts.count(u) && positionalCount(r) == kLayouts.at(u).count) return move(r, p);
    if (t[i].kind == Tok::Kind::kIdent && kOtherMoves.count(u)) {
      noteReads(r);  // (its target is kept as written)
      return otherMove(r, p);
    }
    frameAssignment(r);
    // a call: the data the routine (or one it calls) assigns are its values from here on
    if (isOp(t, i, "%") || u == "CALLBYVAR") assigned_here_ = Scope{};
    for (size_t k = i; k < r.second; ++k)
      if (t[k].kind == Tok::Kind::kIdent && routine_kinds_.count(t[k].u) && (k == i || isOp(t, k + 1, "(")) && !isOp(t, k + 1, ":="))
        for (const std::string& n : assignedThrough(t[k].u)) {
          assigned_here_.tools.erase(n);
          assigned_here_.wobjs.erase(n);
        }
    // an assignment reads its right-hand side (its left one is a run-time value: scanAssignments);
    // a call reads every argument, also those after a named one (`weld p30, Speed:=2;`)
    const size_t assign = assignmentAt(r);
    noteReads({assign == kNoHead ? i : assign + 1, r.second}, r);
    // a call of one of the module's routines that move the robot, a late-bound call
    // (%"name"%, CallByVar), a jump or a label (reached from a GOTO)
    if ((t[i].kind == Tok::Kind::kIdent && (routines_.count(u) || u == "GOTO" || u == "CALLBYVAR")) || isOp(t, i, "%") ||
        (r.second - i == 2 && t[i].kind == Tok::Kind::kIdent && isOp(t, i + 1, ":")))
      flow_.unknown();
    // a label: reached from a GOTO, maybe before the assignments above it ran
    if (r.second - i == 2 && t[i].kind == Tok::Kind::kIdent && isOp(t, i + 1, ":")) assigned_here_ = Scope{};
  }

  /// A tooldata or wobjdata given a value in the routine being read (RoboDK's ABB output sets
  /// `rdkTool := [TRUE,[[..],[..]],..];` and `rdkWObj := [..];` at the start of the routine
  /// before every motion): the motions after it, in the routine's straight-line code, use that
  /// value, as they do on the controller (statements run in order). Only a whole value written
  /// out (an aggregate of numbers), at the routine's top level (not in a branch, a loop, a
  /// compact IF or an error handler), of a datum that only PROCs assign (not a FUNC or a TRAP,
  /// which may run inside an expression or at any time) and no call changes through an
  /// argument; any other assignment of it (a field, a branch's) makes it a run-time value again
  /// from there, as do a call of a routine that assigns it (itself or through the ones it
  /// calls), a late-bound call and a label (a GOTO may come from before the assignment).
  /// Motions before it, and in other routines, use a value the program sets at run time (kept,
  /// named).
  void frameAssignment(Range r) {
    const size_t i = r.first;
    const size_t j = assignmentAt(r);
    if (routine_.empty() || j == kNoHead || declarationAt(i) != kNoHead) return;
    const std::string& u = t_[i].u;
    if (j > i + 1 && t_[i + 2].u == "TLOAD") return;  // (a tool's load does not move its frame)
    assigned_here_.tools.erase(u);
    assigned_here_.wobjs.erase(u);
    const Scope* s = declaring(u);
    const bool tool = s && s->tools.count(u), wobj = s && s->wobjs.count(u);
    const auto by = assigners_.find(u);
    bool procs_only = by != assigners_.end();
    if (procs_only)
      for (const std::string& a : by->second) procs_only = procs_only && routine_kinds_.count(a) && routine_kinds_.at(a) == "PROC";
    for (const auto& [name, kind] : routine_kinds_)  // (also through a PROC a FUNC or a TRAP calls)
      if (procs_only && kind != "PROC") procs_only = !assignedThrough(name).count(u);
    if (!(tool || wobj) || j != i + 1 || depth_ != 0 || in_handler_ || conditional_.count(i) || (params_.count(u) && !local_.names.count(u)) ||
        !procs_only || handler_assigns_.count(u) || !isOp(t_, j + 1, "[") || !isOp(t_, r.second - 1, ";"))
      return;
    const Range val{j + 1, r.second - 1};
    try {
      const FrameVal f = tool ? toolValue(val, excerpt(t_[i].s)) : wobjValue(val, excerpt(t_[i].s));
      (tool ? assigned_here_.tools : assigned_here_.wobjs)[u] = f;
    } catch (const calib::InputError&) {
      // (a value the controller computes: names or expressions in the aggregate)
    }
  }

  /// A loop whose header is r: what its body assigns (also through a call) runs before its
  /// first statements from the second pass on, so those values are not known in the loop.
  void forgetAssignedInLoop(Range r) {
    for (const std::string& n : assignedFrom(r.second, true)) {
      assigned_here_.tools.erase(n);
      assigned_here_.wobjs.erase(n);
    }
  }

  /// The names the statements from token `from` assign (assignmentAt: name := .., name.field
  /// := .., a tool's load too; or a call of a routine that assigns them), up to the end of the
  /// loop they are in (`loop`) or of the routine.
  std::set<std::string> assignedFrom(size_t from, bool loop) const {
    std::set<std::string> out;
    int open = 0;
    for (const Range& r : stmts_) {
      if (r.first < from) continue;
      const std::string& u = t_[r.first].kind == Tok::Kind::kIdent ? t_[r.first].u : std::string();
      if (u == "WHILE" || u == "FOR") ++open;
      if (loop && (u == "ENDWHILE" || u == "ENDFOR") && open-- == 0) break;
      if (u == "ENDPROC" || u == "ENDFUNC" || u == "ENDTRAP") break;
      if (assignmentAt(r) != kNoHead) out.insert(u);
      for (size_t k = r.first; k < r.second; ++k)
        if (t_[k].kind == Tok::Kind::kIdent && routine_kinds_.count(t_[k].u))
          for (const std::string& n : assignedThrough(t_[k].u)) out.insert(n);
    }
    return out;
  }

  /// The names that the routine `callee` (upper case) assigns, itself or through the routines
  /// it calls.
  std::set<std::string> assignedThrough(const std::string& callee) const {
    std::set<std::string> seen{callee};
    std::vector<std::string> todo{callee};
    while (!todo.empty()) {
      const std::string c = todo.back();
      todo.pop_back();
      if (const auto it = callees_.find(c); it != callees_.end())
        for (const std::string& n : it->second)
          if (seen.insert(n).second) todo.push_back(n);
    }
    std::set<std::string> out;
    for (const auto& [name, by] : assigners_)
      for (const std::string& a : by)
        if (seen.count(a)) out.insert(name);
    return out;
  }

  /// The module's PROCs that move the robot, themselves or through the ones they call (a call
  /// may come before the routine): a call of any other does not change where the robot is.
  void findMovingRoutines() {
    std::map<std::string, bool> moves;
    std::map<std::string, std::set<std::string>> calls;
    for (size_t k = 0; k + 1 < t_.size(); ++k)
      if (t_[k].kind == Tok::Kind::kIdent && t_[k].u == "PROC" && t_[k + 1].kind == Tok::Kind::kIdent) moves[t_[k + 1].u] = false;
    std::string cur;
    for (size_t k = 0; k < t_.size(); ++k) {
      if (t_[k].kind != Tok::Kind::kIdent) continue;
      const std::string& u = t_[k].u;
      if ((u == "PROC" || u == "FUNC" || u == "TRAP") && k + 1 < t_.size()) {
        cur = u == "PROC" ? t_[k + 1].u : "";
        ++k;
      } else if (u == "ENDPROC" || u == "ENDFUNC" || u == "ENDTRAP") {
        cur.clear();
      } else if (!cur.empty() && isMove(u)) {
        moves[cur] = true;
      } else if (!cur.empty() && moves.count(u)) {
        calls[cur].insert(u);
      }
    }
    routines_ = movingRoutines(moves, calls);
  }

  void block(Range r, Program& p) {
    const size_t h = headAt(r.first);
    const std::string& u = t_[h].u;
    if (u == "MODULE") {
      // a .prg of the S4C era holds every module of the program, one after the other (their
      // global data are shared, as in the controller); a MODULE inside a module is an error
      if (module_open_) fail(t_[r.first].b, "expected ENDMODULE of the module " + excerpt(module_name_) + " before the next MODULE, found MODULE");
      if (r.second - r.first < 2 || t_[r.first + 1].kind != Tok::Kind::kIdent) fail(t_[r.first].e, "expected the module name after MODULE, found " + found(r.first + 1, r.second));
      module_seen_ = module_open_ = true;
      ++module_index_;
      if (module_name_.empty()) module_name_ = t_[r.first + 1].s;  // the program's name: its first module's
      return markModel(r);
    }
    if (u == "ENDMODULE") {
      if (!module_open_) fail(t_[r.first].b, "expected MODULE before ENDMODULE, found ENDMODULE");
      if (!routine_.empty()) fail(t_[r.first].b, "expected END" + routine_kind_ + " of the routine " + excerpt(routine_) + ", found ENDMODULE");
      module_open_ = false;
      return markModel(r);
    }
    if (!module_open_) fail(t_[r.first].b, "expected MODULE before the first statement, found '" + excerpt(t_[r.first].s) + "'");
    if (u == "PROC" || u == "FUNC" || u == "TRAP") {
      if (!routine_.empty()) fail(t_[r.first].b, "expected END" + routine_kind_ + " of the routine " + excerpt(routine_) + ", found " + u);
      size_t k = h + 1;
      if (u == "FUNC" && k < r.second) ++k;  // the return type
      if (k >= r.second || t_[k].kind != Tok::Kind::kIdent) fail(t_[r.first].e, "expected the routine name after " + u + ", found " + found(k, r.second));
      routine_ = t_[k].s;
      routine_kind_ = u;
      routine_line_ = r;
      local_ = Scope{};
      pdisp_.reset();  // (a routine's text is not run after the one before it)
      eoffs_.reset();
      if (const auto d = displaced_.find(t_[k].u); d != displaced_.end()) {
        pdisp_ = d->second;  // called with a program displacement active
        pdisp_name_ = "a call of " + routine_ + " with PDispOn/PDispSet active";
      }
      // the parameters (name: its value comes from the call; it hides a module datum of the
      // same name): [\][VAR|PERS|INOUT] type name[{*}], separated by ',' or '|'
      params_.clear();
      assigned_here_ = Scope{};
      depth_ = 0;
      in_handler_ = false;
      // what its error handler assigns: a RETRY / TRYNEXT goes back into the routine's body
      handler_assigns_.clear();
      for (size_t q = r.second; q < t_.size() && !(t_[q].kind == Tok::Kind::kIdent && (t_[q].u == "ENDPROC" || t_[q].u == "ENDFUNC" || t_[q].u == "ENDTRAP")); ++q)
        if (t_[q].kind == Tok::Kind::kIdent && (t_[q].u == "ERROR" || t_[q].u == "BACKWARD" || t_[q].u == "UNDO")) {
          handler_assigns_ = assignedFrom(q + 1, false);
          break;
        }
      for (const Param& q : parameters(r, k))
        if (!q.name.empty()) params_.insert(q.name);
      flow_ = StartTracker();  // a routine's first motion: called from anywhere
      flow_.unknown();
      return;
    }
    // branches and loops (a compact IF, without THEN, holds one statement and no block)
    if (u == "IF") {
      bool then = false;
      for (size_t k = r.first; k < r.second; ++k) then = then || (t_[k].kind == Tok::Kind::kIdent && t_[k].u == "THEN");
      if (then) {
        ++depth_;
        return flow_.open(StartTracker::Block::kBranch);
      }
      for (size_t k = r.first; k < r.second; ++k)
        if (t_[k].kind == Tok::Kind::kIdent && (routines_.count(t_[k].u) || t_[k].u == "GOTO")) flow_.unknown();
      return;
    }
    if (u == "TEST" || u == "WHILE" || u == "FOR") ++depth_;
    if (u == "WHILE" || u == "FOR") forgetAssignedInLoop(r);
    if (u == "ENDIF" || u == "ENDTEST" || u == "ENDWHILE" || u == "ENDFOR") depth_ = std::max(0, depth_ - 1);
    if (u == "TEST") return flow_.open(StartTracker::Block::kBranch);
    if (u == "ELSEIF" || u == "ELSE" || u == "CASE" || u == "DEFAULT") return flow_.branch();
    if (u == "WHILE" || u == "FOR") return flow_.open(StartTracker::Block::kLoop);
    if (u == "ENDIF" || u == "ENDTEST" || u == "ENDWHILE" || u == "ENDFOR") return flow_.close();
    if (u == "ERROR" || u == "BACKWARD" || u == "UNDO") {  // a handler: entered from wherever the routine was
      assigned_here_ = Scope{};
      in_handler_ = true;
      flow_ = StartTracker();
      flow_.unknown();
      return;
    }
    if (u == "ENDPROC" || u == "ENDFUNC" || u == "ENDTRAP") {
      if (routine_.empty() || "END" + routine_kind_ != u)
        fail(t_[r.first].b, "expected " + (routine_.empty() ? std::string("a routine before it") : "END" + routine_kind_ + " of " + excerpt(routine_)) + ", found " + u);
      if (main_routine_ == routine_) {
        markModel(routine_line_);
        markModel(r);
      }
      routine_.clear();
      return;
    }
    (void)p;
  }

  // --- data

  [[noreturn]] void shape(size_t at, const std::string& what, const std::string& got) const {
    fail(t_[at].b, "expected " + what + ", found '" + excerpt(got) + "'");
  }

  /// [[x,y,z],[q1,q2,q3,q4]] (pose) at r: the spans and values of its 7 numbers.
  void poseParts(Range r, const std::string& what, std::pair<size_t, size_t>* spans, double* v) {
    const auto parts = bracketItems(r, 2, what + " [[x,y,z],[q1,q2,q3,q4]]");
    numbers(parts[0], 3, "a position [x,y,z] (mm)", spans, v);
    numbers(parts[1], 4, "a quaternion [q1,q2,q3,q4]", spans + 3, v + 3);
    checkPose(spans, v);
  }

  /// A position within kMaxPositionMm and a quaternion of norm 1 within kQuaternionNormTol.
  void checkPose(const std::pair<size_t, size_t>* spans, const double* v) const {
    for (int k = 0; k < 3; ++k)
      if (std::abs(v[k]) > kMaxPositionMm)
        fail(spans[k].first, "expected a position in mm within +-" + calib::formatFixed(kMaxPositionMm, 0) + ", found " +
                                 excerpt(src_->text.substr(spans[k].first, spans[k].second - spans[k].first)));
    const double n = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
    if (!(std::abs(n - 1.0) <= kQuaternionNormTol))
      fail(spans[3].first, "expected a unit quaternion (norm 1 within " + calib::formatFixed(kQuaternionNormTol, 3) + "), found norm " +
                               calib::formatFixed(n, 6));
  }

  /// The items of the bracket [..] at r, which must have n of them.
  std::vector<Range> bracketItems(Range r, size_t n, const std::string& what) {
    if (!(isOp(t_, r.first, "[") && closing(t_, r.first, r.second) == r.second)) shape(r.first < r.second ? r.first : r.first - 1, what, text(r));
    auto parts = items(t_, r.first + 1, r.second - 1);
    if (parts.size() != n || parts.front().first == parts.front().second)
      fail(t_[r.first].b, "expected " + what + " with " + std::to_string(n) + " items, found " + std::to_string(r.first + 2 == r.second ? 0 : parts.size()) + " in '" + quoted(r) + "'");
    return parts;
  }

  void numbers(Range r, size_t n, const std::string& what, std::pair<size_t, size_t>* spans, double* v) {
    const auto parts = bracketItems(r, n, what);
    for (size_t k = 0; k < n; ++k) {
      const std::optional<double> x = number(t_, parts[k]);
      if (!x) shape(parts[k].first < parts[k].second ? parts[k].first : r.first, "a number in " + what, text(parts[k]));
      v[k] = *x;
      spans[k] = {t_[parts[k].first].b, t_[parts[k].second - 1].e};
    }
  }

  /// A robtarget value [[x,y,z],[q1..q4],[cf1,cf4,cf6,cfx],[eax_a..eax_f]] at r.
  int robtargetValue(Range r, int decl) {
    const auto parts = bracketItems(r, 4, "a robtarget [[x,y,z],[q1,q2,q3,q4],[cf1,cf4,cf6,cfx],[eax_a,..,eax_f]]");
    RapidSource::Value v;
    v.begin = t_[r.first].b;
    v.end = t_[r.second - 1].e;
    v.decl = decl;
    numbers(parts[0], 3, "a position [x,y,z] (mm)", v.num, v.v);
    numbers(parts[1], 4, "a quaternion [q1,q2,q3,q4]", v.num + 3, v.v + 3);
    checkPose(v.num, v.v);
    numbers(parts[2], 4, "confdata [cf1,cf4,cf6,cfx]", v.num + 7, v.v + 7);
    for (int k = 7; k < 11; ++k)
      if (v.v[k] != std::floor(v.v[k]) || std::abs(v.v[k]) > 1000)
        fail(v.num[k].first, "expected an integer in confdata, found " + excerpt(src_->text.substr(v.num[k].first, v.num[k].second - v.num[k].first)));
    std::pair<size_t, size_t> es[6];
    double ev[6];
    numbers(parts[3], 6, "external axes [eax_a,..,eax_f]", es, ev);
    src_->values.push_back(v);
    ext_.push_back({});
    for (int k = 0; k < 6; ++k)
      if (std::abs(ev[k]) < kUnusedAxis) ext_.back()[static_cast<size_t>(k)] = ev[k];
    return static_cast<int>(src_->values.size()) - 1;
  }

  /// Whether the robtarget aggregate r has the shape the controller loads: 4 items, each
  /// written as [..] of 3, 4, 4 and 6 items or as another expression (a name, a call). A value of
  /// that shape that accura cannot read (a CONST num or an expression in its position, a
  /// non-unit quaternion, a position beyond kMaxPositionMm) is a module the controller loads:
  /// not an error of the module, only of the motions that go to it (kept and named).
  bool readableShape(Range r) const {
    if (!(isOp(t_, r.first, "[") && closing(t_, r.first, r.second) == r.second)) return false;
    const std::vector<Range> parts = items(t_, r.first + 1, r.second - 1);
    static const size_t kCounts[4] = {3, 4, 4, 6};
    if (parts.size() != 4) return false;
    for (size_t k = 0; k < 4; ++k) {
      const Range q = parts[k];
      if (q.first >= q.second) return false;
      if (!isOp(t_, q.first, "[")) continue;
      if (closing(t_, q.first, q.second) != q.second) return false;
      const std::vector<Range> n = items(t_, q.first + 1, q.second - 1);
      if (n.size() != kCounts[k] || n.front().first == n.front().second) return false;
    }
    return true;
  }
  /// Why a declared robtarget value is not read: the error, where it is.
  static std::string unreadValue(const calib::InputError& e) {
    return SourceLocation{e.file(), e.line(), e.column()}.str() + ": " + e.message();
  }

  /// Declaration `d` (a scalar robtarget, or one element of an array) with its value `v`: added
  /// to src_->decls with the value read, and its value's id returned. A value of the right shape
  /// that accura cannot read (a CONST in a number: the controller loads it) gives -1, the reason
  /// in `*unread` (file:line:column: what), and no declaration (its text is passed through); a
  /// value of the wrong shape throws.
  int declaredRobtarget(const RapidSource::Decl& d, Range v, std::string* unread) {
    src_->decls.push_back(d);
    try {
      const int id = robtargetValue(v, static_cast<int>(src_->decls.size()) - 1);
      src_->decls.back().value = id;
      return id;
    } catch (const calib::InputError& e) {
      if (!readableShape(v)) throw;
      src_->decls.pop_back();
      *unread = unreadValue(e);
      return -1;
    }
  }

  TargetVal valueTarget(int id) const {
    const RapidSource::Value& v = src_->values[static_cast<size_t>(id)];
    TargetVal tv;
    tv.T = poseOf(v.v, v.v + 3);
    for (int k = 0; k < 4; ++k) tv.conf[static_cast<size_t>(k)] = static_cast<int>(v.v[7 + k]);
    tv.ext = ext_[static_cast<size_t>(id)];
    tv.value = id;
    return tv;
  }

  bool boolean(Range r, const std::string& what) const {
    if (r.second == r.first + 1 && (isKw(t_, r.first, "TRUE") || isKw(t_, r.first, "FALSE"))) return t_[r.first].u == "TRUE";
    shape(r.first, "TRUE or FALSE for " + what, text(r));
  }

  Eigen::Isometry3d framePose(Range r, const std::string& what) {
    std::pair<size_t, size_t> s[7];
    double v[7];
    poseParts(r, what, s, v);
    return poseOf(v, v + 3);
  }

  FrameVal toolValue(Range r, const std::string& name) {
    const auto parts = bracketItems(r, 3, "a tooldata [robhold, [[x,y,z],[q1,q2,q3,q4]], loaddata]");
    FrameVal f;
    f.where = loc(t_[r.first].b);
    const bool robhold = boolean(parts[0], "robhold of tooldata " + name);
    const Eigen::Isometry3d T = framePose(parts[1], "the tframe of tooldata " + name);
    if (robhold) f.T = T;
    else f.note = "tooldata " + name + " has robhold FALSE (a stationary tool with a robot-held work object), which accura does not model";
    return f;
  }

  FrameVal wobjValue(Range r, const std::string& name) {
    const auto parts = bracketItems(r, 5, "a wobjdata [robhold, ufprog, ufmec, uframe, oframe]");
    FrameVal f;
    f.where = loc(t_[r.first].b);
    const bool robhold = boolean(parts[0], "robhold of wobjdata " + name);
    const bool ufprog = boolean(parts[1], "ufprog of wobjdata " + name);
    const Eigen::Isometry3d uf = framePose(parts[3], "the uframe of wobjdata " + name);
    const Eigen::Isometry3d of = framePose(parts[4], "the oframe of wobjdata " + name);
    if (robhold) f.note = "wobjdata " + name + " has robhold TRUE (the robot holds the work object: a stationary tool), which accura does not model";
    else if (!ufprog) f.note = "wobjdata " + name + " has ufprog FALSE (a user frame moved by the mechanical unit " + quoted(parts[2]) + "), which accura does not model";
    else f.T = uf * of;
    return f;
  }

  /// The scopes a declaration at r (its type at k + 1, its name at k + 2) goes into: the
  /// routine's, or the module's and, unless LOCAL, the program's global data. A second
  /// declaration of a name whose value accura reads in one scope is an error naming the first
  /// (the controller refuses the ambiguous name; which one accura took would be a guess).
  std::vector<Scope*> declare(Range r, size_t k, size_t name) {
    std::vector<Scope*> into;
    into.push_back(routine_.empty() ? &modules_.at(static_cast<size_t>(module_index_)) : &local_);
    if (routine_.empty() && !isKw(t_, r.first, "LOCAL")) into.push_back(&global_);
    const std::string& u = t_[name].u;
    const bool read_type = kReadTypes.count(t_[k + 1].u) > 0;
    // a PERS: its type and value as written, without blanks
    std::string pers;
    if (isKw(t_, k, "PERS"))
      for (size_t i = k + 1; i < r.second; ++i) pers += t_[i].u + " ";
    for (Scope* s : into) {
      const auto it = s->names.find(u);
      if (it == s->names.end()) {
        s->names[u] = loc(t_[name].b);
        if (read_type) s->read_names.insert(u);
        if (!pers.empty()) s->persistents[u] = pers;
        continue;
      }
      // the same persistent declared alike in two modules: one object they share
      if (s == &global_ && !pers.empty() && s->persistents.count(u) && s->persistents.at(u) == pers) continue;
      if (read_type && s->read_names.count(u))
        fail(t_[name].b, "expected one declaration of '" + excerpt(t_[name].s) + "' in " +
                             (s == &global_ ? "the program's global data (its modules share the data that is not LOCAL)"
                              : s == &local_ ? "the routine " + excerpt(routine_)
                                             : std::string("the module")) +
                             ", found a second (the first at " + it->second.str() + ")");
    }
    return into;
  }

  void declaration(Range r, size_t k) {
    const std::vector<Tok>& t = t_;
    const size_t type = k + 1, name = k + 2;
    if (name >= r.second || t[type].kind != Tok::Kind::kIdent || t[name].kind != Tok::Kind::kIdent) return;  // pass-through
    // the name is the scope's (an array, a datum without a value or of another type too: it
    // hides a datum of its name declared further out)
    const std::vector<Scope*> into = declare(r, k, name);
    const std::string& ty = t[type].u;
    const std::string& nm = t[name].s;
    const std::string& u = t[name].u;
    if (ty == "ROBTARGET" && isOp(t, name + 1, "{")) return robtargetArray(r, k, into);
    if (!isOp(t, name + 1, ":=")) return;  // no initial value (VAR robtarget p;): an unknown value
    const Range val{name + 2, r.second - 1};
    if (val.first >= val.second) fail(t[name + 1].e, "expected a value after ':=', found ';'");
    if (ty == "ROBTARGET") {
      if (!isOp(t, val.first, "[")) return;
      RapidSource::Decl d;
      d.name = nm;
      d.line_begin = lineBegin(r);
      d.line_end = lineAfter(r);
      d.indent = indentOf(r);
      d.head = src_->text.substr(t[r.first].b, t[name].b - t[r.first].b);
      std::string unread;
      const int id = declaredRobtarget(d, val, &unread);
      if (id < 0) {
        for (Scope* s : into) s->unread_robtargets[u] = unread;
        return;
      }
      for (Scope* s : into) s->robtargets[u] = id;
      return markModel(r);
    }
    if (ty == "TOOLDATA" && isOp(t, val.first, "[")) {
      const FrameVal f = toolValue(val, excerpt(nm));
      for (Scope* s : into) s->tools[u] = f;
      return markModel(r);
    }
    if (ty == "WOBJDATA" && isOp(t, val.first, "[")) {
      const FrameVal f = wobjValue(val, excerpt(nm));
      for (Scope* s : into) s->wobjs[u] = f;
      return markModel(r);
    }
    if (ty == "JOINTTARGET" && isOp(t, val.first, "[")) {
      const auto parts = bracketItems(val, 2, "a jointtarget [[rax_1,..,rax_6],[eax_a,..,eax_f]]");
      std::pair<size_t, size_t> s[6];
      double v[6], e[6];
      numbers(parts[0], 6, "robot axes [rax_1,..,rax_6] (deg)", s, v);
      numbers(parts[1], 6, "external axes [eax_a,..,eax_f]", s, e);
      for (Scope* sc : into) sc->joints[u] = {v[0], v[1], v[2], v[3], v[4], v[5]};
      return;  // a MoveAbsJ target: pass-through data (never changed)
    }
    if (ty == "ZONEDATA" && isOp(t, val.first, "[")) {
      const auto parts = bracketItems(val, 7, "a zonedata [finep, pzone_tcp, pzone_ori, pzone_eax, zone_ori, zone_leax, zone_reax]");
      const std::optional<double> z = number(t, parts[1]);
      if (!z || *z < 0) shape(parts[1].first, "pzone_tcp >= 0 (mm) in zonedata " + excerpt(nm), text(parts[1]));
      const std::optional<double> radius = boolean(parts[0], "finep of zonedata " + excerpt(nm)) ? std::nullopt : std::optional<double>(*z);
      for (Scope* s : into) s->zones[u] = radius;
      return;
    }
    if (ty == "NUM" && isKw(t, k, "CONST")) {
      // (a constant: its value is the one written; a VAR or PERS num may change while it runs)
      if (const std::optional<double> x = number(t, val)) for (Scope* s : into) s->consts[u] = *x;
      return;
    }
    if (ty == "SPEEDDATA" && isOp(t, val.first, "[")) {
      const auto parts = bracketItems(val, 4, "a speeddata [v_tcp, v_ori, v_leax, v_reax]");
      const std::optional<double> v = number(t, parts[0]);
      if (!v || *v <= 0) shape(parts[0].first, "v_tcp > 0 (mm/s) in speeddata " + excerpt(nm), text(parts[0]));
      for (Scope* s : into) s->speeds[u] = *v;
    }
  }

  /// A robtarget array `CONST|PERS|VAR robtarget name{d1[,d2[,d3]]} [:= value];` (the type at
  /// k + 1, the name at k + 2): each element written as a robtarget value gets its Decl, as a
  /// scalar robtarget does, so that a motion to `name{2}` is corrected in the array's value (the
  /// other elements keep their text) or goes to a new point declared after the array. An array
  /// whose sizes are not constants, that has no value or whose value does not have the declared
  /// shape keeps its elements' motions as written, named with the reason.
  void robtargetArray(Range r, size_t k, const std::vector<Scope*>& into) {
    const size_t name = k + 2, open = name + 1;
    const size_t close = closing(t_, open, r.second);
    ArrayVal a;
    a.name = t_[name].s;
    a.where = loc(t_[name].b);
    for (const Range& d : items(t_, open + 1, close - 1)) {
      const std::optional<double> n = numValue(d);
      if (!n || *n != std::floor(*n) || *n < 1 || *n > 1e6) {
        a.problem = "the size of the robtarget array " + excerpt(a.name) + " ('" + quoted(d) + "') is not a number accura reads";
        break;
      }
      a.dims.push_back(static_cast<int>(*n));
    }
    if (a.problem.empty() && (a.dims.empty() || a.dims.size() > 3))
      a.problem = "the robtarget array " + excerpt(a.name) + " has " + std::to_string(a.dims.size()) + " dimensions (RAPID: 1 to 3)";
    if (a.problem.empty() && !isOp(t_, close, ":=")) a.problem = "the robtarget array " + excerpt(a.name) + " is declared without a value";
    std::vector<Range> elements;
    if (a.problem.empty()) {
      // the value: one aggregate per dimension, the elements in the innermost
      std::vector<Range> level{{close + 1, r.second - 1}};
      for (size_t dim = 0; dim < a.dims.size() && a.problem.empty(); ++dim) {
        std::vector<Range> next;
        for (const Range& v : level) {
          const std::vector<Range> parts = v.first < v.second && isOp(t_, v.first, "[") && closing(t_, v.first, v.second) == v.second
                                               ? items(t_, v.first + 1, v.second - 1)
                                               : std::vector<Range>{};
          if (parts.size() != static_cast<size_t>(a.dims[dim])) {
            a.problem = "the value of the robtarget array " + excerpt(a.name) + " is not written as an aggregate of " + std::to_string(a.dims[dim]) +
                        " element(s) ('" + quoted(v) + "')";
            break;
          }
          next.insert(next.end(), parts.begin(), parts.end());
        }
        level = next;
      }
      if (a.problem.empty()) elements = level;
    }
    a.decls.assign(elements.size(), -1);
    a.unread.assign(elements.size(), std::string());
    // (the array's declaration, which a new point follows)
    RapidSource::Decl decl;
    decl.line_begin = lineBegin(r);
    decl.line_end = lineAfter(r);
    decl.indent = indentOf(r);
    decl.head = src_->text.substr(t_[r.first].b, t_[name].b - t_[r.first].b);
    for (size_t e = 0; e < elements.size(); ++e) {
      const Range v = elements[e];
      if (!(v.first < v.second && isOp(t_, v.first, "["))) continue;  // (a name or an expression: its value at load)
      std::string index;
      size_t rest = e;
      for (size_t dim = a.dims.size(); dim-- > 0;) {
        index = std::to_string(rest % static_cast<size_t>(a.dims[dim]) + 1) + (index.empty() ? "" : "," + index);
        rest /= static_cast<size_t>(a.dims[dim]);
      }
      RapidSource::Decl d = decl;
      d.name = a.name + "{" + index + "}";
      // (the other elements are read; one accura cannot read is named by the motions that go to it)
      std::string unread;
      if (declaredRobtarget(d, v, &unread) < 0) {
        a.unread[e] = unread;
        continue;
      }
      a.decls[e] = static_cast<int>(src_->decls.size()) - 1;
    }
    arrays_.push_back(a);
    for (Scope* s : into) s->robtarget_arrays[t_[name].u] = static_cast<int>(arrays_.size()) - 1;
    if (a.problem.empty()) markModel(r);
  }

  /// The element (row-major) of array `a` that the indices `r` (inside its braces) name; -1 with
  /// `why` when there is none: `run_time` when an index is a value the controller computes
  /// (a variable, an expression); else a constant index outside the array, or another number of
  /// indices than the array's dimensions.
  int elementIndex(const ArrayVal& a, Range r, std::string& why, bool& run_time) const {
    const std::vector<Range> idx = items(t_, r.first, r.second);
    const std::string written = excerpt(a.name) + "{" + quoted(r) + "}";
    size_t flat = 0;
    for (size_t i = 0; i < idx.size(); ++i) {
      const std::optional<double> n = idx[i].first < idx[i].second ? numValue(idx[i]) : std::nullopt;
      if (!n) {
        run_time = true;
        why = "the index of '" + written + "' is computed at run time";
        return -1;
      }
      if (i >= a.dims.size()) break;
      if (*n != std::floor(*n) || *n < 1 || *n > a.dims[i]) {
        std::string size;
        for (size_t j = 0; j < a.dims.size(); ++j) size += (j ? "," : "") + std::to_string(a.dims[j]);
        why = "'" + written + "' is outside the array " + excerpt(a.name) + "{" + size + "} (declared at " + a.where.str() +
              "; indices from 1): the controller stops with an error when it runs this motion";
        return -1;
      }
      flat = flat * static_cast<size_t>(a.dims[i]) + static_cast<size_t>(*n) - 1;
    }
    if (idx.size() != a.dims.size()) {
      why = "'" + written + "' gives " + std::to_string(idx.size()) + " index(es) of the array " + excerpt(a.name) + ", which has " +
            std::to_string(a.dims.size()) + " dimension(s)";
      return -1;
    }
    return static_cast<int>(flat);
  }

  /// A target `name{i[,j[,k]]}`: the value of an element of a robtarget array.
  TargetVal element(Range r) const {
    TargetVal tv;
    const std::string& u = t_[r.first].u;
    if (params_.count(u) && !local_.names.count(u)) {
      tv.problem = "'" + quoted(r) + "' is an element of " + excerpt(t_[r.first].s) + ", a parameter of " + excerpt(routine_) + ": its value comes from the call";
      return tv;
    }
    const int* id = lookup(&Scope::robtarget_arrays, u);
    if (!id) {
      tv.problem = "'" + quoted(r) + "' is not an element of a robtarget array declared in this module";
      return tv;
    }
    const ArrayVal& a = arrays_[static_cast<size_t>(*id)];
    if (!a.problem.empty()) {
      tv.problem = "'" + quoted(r) + "' is an element of an array accura cannot read: " + a.problem;
      return tv;
    }
    if (const auto as = assigned_.find(u); as != assigned_.end()) {
      tv.problem = "'" + quoted(r) + "' is an element of " + excerpt(a.name) + ", which is assigned at " + as->second.str() +
                   ": its value at run time is not the declared one";
      return tv;
    }
    bool run_time = false;
    const int e = elementIndex(a, {r.first + 2, r.second - 1}, tv.problem, run_time);
    if (e < 0) return tv;
    const int d = a.decls[static_cast<size_t>(e)];
    if (!a.unread[static_cast<size_t>(e)].empty()) {
      tv.problem = "'" + quoted(r) + "' is declared in the array " + excerpt(a.name) + " with a value accura cannot read (" + a.unread[static_cast<size_t>(e)] + ")";
      return tv;
    }
    if (d < 0) {
      tv.problem = "'" + quoted(r) + "' is not written as a robtarget value in the declaration of " + excerpt(a.name) + " at " + a.where.str();
      return tv;
    }
    return valueTarget(src_->decls[static_cast<size_t>(d)].value);
  }

  /// The innermost scope that declares `u` (upper case) where the text being read is: the
  /// routine's data, its module's (LOCAL included), the program's global data; nullptr: none.
  const Scope* declaring(const std::string& u) const {
    if (!routine_.empty() && local_.names.count(u)) return &local_;
    if (module_index_ >= 0 && static_cast<size_t>(module_index_) < modules_.size() && modules_[static_cast<size_t>(module_index_)].names.count(u))
      return &modules_[static_cast<size_t>(module_index_)];
    return global_.names.count(u) ? &global_ : nullptr;
  }

  /// The value of the datum `u` (upper case) of a type (`m`) that the text being read refers
  /// to; nullptr when the name it refers to is no such datum with a value.
  template <class T>
  const T* lookup(const std::map<std::string, T> Scope::*m, const std::string& u) const {
    const Scope* s = declaring(u);
    if (!s) return nullptr;
    const auto it = (s->*m).find(u);
    return it == (s->*m).end() ? nullptr : &it->second;
  }

  // --- target expressions

  /// The number r is: a literal (with its sign), or the name of a CONST num declared with a
  /// number where the text refers to it, with an optional sign (`Offs(p, 0, 0, dz)`,
  /// `\Rz:=-ang`); nullopt for anything else (a VAR or PERS num, an expression, a parameter).
  std::optional<double> numValue(Range r) const {
    if (const std::optional<double> x = number(t_, r)) return x;
    size_t k = r.first;
    const bool minus = r.second == r.first + 2 && isOp(t_, k, "-");
    if (r.second == r.first + 2 && (minus || isOp(t_, k, "+"))) ++k;
    if (k + 1 != r.second || t_[k].kind != Tok::Kind::kIdent) return std::nullopt;
    const std::string& u = t_[k].u;
    if (params_.count(u) && !local_.names.count(u)) return std::nullopt;  // (the call's value)
    const double* c = lookup(&Scope::consts, u);
    if (!c) return std::nullopt;
    return minus ? -*c : *c;
  }

  TargetVal target(Range r) {
    TargetVal tv;
    if (r.first >= r.second) {
      tv.problem = "an empty target";
      return tv;
    }
    if (isOp(t_, r.first, "[")) return valueTarget(robtargetValue(r, -1));
    if (r.second == r.first + 1 && t_[r.first].kind == Tok::Kind::kIdent) {
      const std::string& u = t_[r.first].u;
      if (params_.count(u) && !local_.names.count(u)) {
        tv.problem = "'" + excerpt(t_[r.first].s) + "' is a parameter of " + excerpt(routine_) + ": its value comes from the call";
        return tv;
      }
      const int* id = lookup(&Scope::robtargets, u);
      if (const std::string* why = id ? nullptr : lookup(&Scope::unread_robtargets, u)) {
        tv.problem = "'" + excerpt(t_[r.first].s) + "' is declared with a value accura cannot read (" + *why + ")";
        return tv;
      }
      if (const std::string* why = id ? nullptr : lookup(&Scope::task_kept, u)) {
        tv.problem = *why;
        return tv;
      }
      int task_id = -1;
      if (const size_t* k = id ? nullptr : lookup(&Scope::task_robtargets, u)) {
        task_id = taskRobtarget(u, *k);
        id = &task_id;
      }
      if (!id) {
        tv.problem = "'" + excerpt(t_[r.first].s) + "' is not a robtarget declared with a value in this module";
        return tv;
      }
      const auto a = assigned_.find(u);
      if (a != assigned_.end()) {
        tv.problem = "'" + excerpt(t_[r.first].s) + "' is assigned at " + a->second.str() + ": its value at run time is not the declared one";
        return tv;
      }
      return valueTarget(*id);
    }
    if (t_[r.first].kind == Tok::Kind::kIdent && isOp(t_, r.first + 1, "{") && closing(t_, r.first + 1, r.second) == r.second) return element(r);
    const bool offs = isKw(t_, r.first, "OFFS"), reltool = isKw(t_, r.first, "RELTOOL");
    if ((offs || reltool) && isOp(t_, r.first + 1, "(") && closing(t_, r.first + 1, r.second) == r.second) return offset(r, reltool);
    tv.problem = "'" + quoted(r) + "' is not a target accura can evaluate (a robtarget, a declared robtarget, Offs or RelTool of one)";
    return tv;
  }

  /// Offs(p, dx, dy, dz) (wobj axes) or RelTool(p, dx, dy, dz [\Rx:=a] [\Ry:=b] [\Rz:=c])
  /// (tool axes; rotations about x, then y, then z of the tool, deg).
  TargetVal offset(Range r, bool reltool) {
    const std::string f = reltool ? "RelTool" : "Offs";
    auto args = items(t_, r.first + 2, r.second - 1);
    std::map<std::string, double> rot;
    // an optional argument follows the one before it with or without a comma (RAPID kernel,
    // function calls: <function argument> ::= .. | <optional function argument> | ','
    // <optional function argument>): `RelTool(p,0,0,0,\Rz:=45)` as `RelTool(p,0,0,0\Rz:=45)`
    if (reltool)
      for (size_t i = args.size(); i-- > 1;)
        if (args[i].first < args[i].second && isOp(t_, args[i].first, "\\")) {
          args[i - 1].second = args[i].second;
          args.erase(args.begin() + static_cast<std::ptrdiff_t>(i));
        }
    // (a comma before an optional argument is not part of the value it follows)
    auto valueEnd = [&](size_t b, size_t e) { return e > b && isOp(t_, e - 1, ",") ? e - 1 : e; };
    if (reltool && args.size() >= 4) {  // the optional \Rx:=.. follow dz
      Range& last = args.back();
      size_t k = last.first;
      while (k < last.second && !isOp(t_, k, "\\")) ++k;
      size_t o = k;
      last.second = valueEnd(last.first, k);
      while (o < r.second - 1) {
        if (!(isOp(t_, o, "\\") && o + 2 < r.second && t_[o + 1].kind == Tok::Kind::kIdent && isOp(t_, o + 2, ":=")) ||
            !(t_[o + 1].u == "RX" || t_[o + 1].u == "RY" || t_[o + 1].u == "RZ"))
          fail(t_[o].b, "expected \\Rx:=, \\Ry:= or \\Rz:= in RelTool, found '" + excerpt(t_[o].s + (o + 1 < r.second ? t_[o + 1].s : "")) + "'");
        size_t e = o + 3;
        while (e < r.second - 1 && !isOp(t_, e, "\\")) ++e;
        const size_t ve = valueEnd(o + 3, e);
        const std::optional<double> x = numValue({o + 3, ve});
        if (!x) {
          TargetVal tv;
          tv.problem = "RelTool(...) at " + loc(t_[r.first].b).str() + " has a rotation that is not a number or a CONST num ('" + quoted({o + 3, ve}) + "')";
          return tv;
        }
        if (std::abs(*x) > kMaxAngleDeg) shape(o + 3, "a rotation in deg within +-" + calib::formatFixed(kMaxAngleDeg, 0) + " in RelTool", text({o + 3, ve}));
        rot[t_[o + 1].u] = *x;
        o = e;
      }
    }
    if (args.size() != 4) fail(t_[r.first].b, "expected " + f + "(point, dx, dy, dz) with 4 arguments, found " + std::to_string(args.size()));
    // (each level is a call: a pathological depth would overflow the stack)
    if (++offset_depth_ > kMaxOffsetNesting)
      fail(t_[r.first].b, "expected Offs/RelTool nested at most " + std::to_string(kMaxOffsetNesting) + " deep, found deeper nesting");
    TargetVal base = target(args[0]);
    --offset_depth_;
    TargetVal tv;
    if (!base.problem.empty()) {
      tv.problem = f + "(...) at " + loc(t_[r.first].b).str() + " cannot be evaluated: " + base.problem;
      return tv;
    }
    double d[3];
    for (int k = 0; k < 3; ++k) {
      const std::optional<double> x = numValue(args[static_cast<size_t>(k + 1)]);
      if (!x) {
        tv.problem = f + "(...) at " + loc(t_[r.first].b).str() + " has an offset that is not a number or a CONST num ('" + quoted(args[static_cast<size_t>(k + 1)]) + "')";
        return tv;
      }
      if (std::abs(*x) > kMaxPositionMm)
        shape(args[static_cast<size_t>(k + 1)].first, "an offset in mm within +-" + calib::formatFixed(kMaxPositionMm, 0) + " in " + f,
              text(args[static_cast<size_t>(k + 1)]));
      d[k] = *x;
    }
    tv = base;
    tv.value = -1;
    tv.reads = base.value >= 0 ? base.value : base.reads;
    if (reltool) {
      Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
      D.translation() = Eigen::Vector3d(d[0], d[1], d[2]);
      D.linear() = (Eigen::AngleAxisd(rot["RX"] * calib::kDegToRad, Eigen::Vector3d::UnitX()) *
                    Eigen::AngleAxisd(rot["RY"] * calib::kDegToRad, Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(rot["RZ"] * calib::kDegToRad, Eigen::Vector3d::UnitZ())).toRotationMatrix();
      tv.T = base.T * D;
    } else {
      tv.T.translation() += Eigen::Vector3d(d[0], d[1], d[2]);
    }
    for (int k = 0; k < 3; ++k)
      if (std::abs(tv.T.translation()[k]) > kMaxPositionMm)
        fail(t_[r.first].b, "expected " + f + "(...) to give a position within +-" + calib::formatFixed(kMaxPositionMm, 0) + " mm, found " +
                                calib::formatFixed(tv.T.translation()[k], 4) + " in '" + quoted(r) + "'");
    return tv;
  }

  // --- motions

  struct Arg {
    Range main;  ///< a required argument's value (after its name, when it is named)
    /// The parameter name of a required argument written with it (`ToPoint:=p20`; upper case;
    /// RAPID kernel, procedure call: <required procedure argument> ::= [<identifier> ':='] <expression>)
    std::string name;
    std::vector<std::pair<std::string, Range>> opts;  ///< \Name[:=value] (upper-case name)
  };

  std::vector<Arg> arguments(Range r) {
    std::vector<Arg> out;
    for (const Range& it : items(t_, r.first + 1, r.second - 1)) {
      Arg a;
      size_t k = it.first;
      int depth = 0;
      while (k < it.second && !(depth == 0 && isOp(t_, k, "\\"))) {
        if (opens(t_[k])) ++depth;
        if (closes(t_[k])) --depth;
        ++k;
      }
      a.main = {it.first, k};
      if (k >= it.first + 2 && t_[it.first].kind == Tok::Kind::kIdent && isOp(t_, it.first + 1, ":=")) {
        a.name = t_[it.first].u;
        a.main.first += 2;
        if (a.main.first == a.main.second) fail(t_[it.first + 1].e, "expected a value after '" + excerpt(t_[it.first].s) + ":=', found " + found(k, it.second));
      }
      while (k < it.second) {
        if (k + 1 >= it.second || t_[k + 1].kind != Tok::Kind::kIdent) fail(t_[k].b, "expected an optional argument name after '\\', found " + found(k + 1, it.second));
        const std::string n = t_[k + 1].u;
        size_t e = k + 2, v = e;
        if (isOp(t_, e, ":=")) v = ++e;
        depth = 0;
        while (e < it.second && !(depth == 0 && isOp(t_, e, "\\"))) {
          if (opens(t_[e])) ++depth;
          if (closes(t_[e])) --depth;
          ++e;
        }
        a.opts.push_back({n, {v, e}});
        k = e;
      }
      if (a.main.first == a.main.second && a.opts.empty()) fail(t_[it.first < r.second ? it.first : r.first].b, "expected an argument, found an empty one");
      out.push_back(a);
    }
    return out;
  }

  /// The number of positional (not optional) arguments of the instruction statement r.
  size_t positionalCount(Range r) {
    size_t n = 0;
    for (const Arg& a : arguments(r)) n += a.main.first != a.main.second ? 1 : 0;
    return n;
  }

  void move(Range r, Program& p) {
    const std::string& f = t_[r.first].s;
    const std::string u = t_[r.first].u;
    const MoveLayout& lay = kLayouts.at(u);
    const bool circ = lay.type == MotionType::kCirc;
    std::vector<Arg> all = arguments({r.first, r.second});
    std::vector<Arg> pos;
    std::map<std::string, Range> opt;
    for (const Arg& a : all) {
      if (a.main.first != a.main.second) pos.push_back(a);
      for (const auto& o : a.opts) opt[o.first] = o.second;
    }
    const size_t want = lay.count;
    if (pos.size() != want) {
      static const char* sig[] = {"ToPoint, Speed, Zone, Tool", "CirPoint, ToPoint, Speed, Zone, Tool", "ToJointPos, Speed, Zone, Tool"};
      fail(t_[r.first].b, "expected " + f + " " + sig[u == "MOVEC" ? 1 : u == "MOVEABSJ" ? 2 : 0] + " (" + std::to_string(want) +
                              " arguments), found " + std::to_string(pos.size()) + " in '" + quoted(r) + "'");
    }
    // a required argument written with its name is the positional one when the name is that
    // argument's; another name (arguments in another order, a misspelt name) is kept as written
    for (size_t i = 0; i < pos.size() && i < lay.names.size(); ++i)
      if (!pos[i].name.empty() && pos[i].name != calib::upperAscii(lay.names[i])) {
        noteReads(r);
        return otherMove(r, p, "its argument " + std::to_string(i + 1) + " is named " + t_[pos[i].main.first - 2].s + ", where " + f +
                                   "'s argument " + std::to_string(i + 1) + " is " + lay.names[i] + ": accura reads a named argument in its place only");
      }
    Motion m;
    m.where = loc(t_[r.first].b);
    m.statement = text(r);
    m.type = lay.type;
    m.conf_monitored = m.type == MotionType::kPtp ? confj_ : confl_;
    m.start_unknown = flow_.motion();
    RapidSource::Statement st = statementSpan(r, m.where);
    speed(pos[lay.speed].main, opt, m);
    if (const auto it = opt.find("T"); it != opt.end()) {
      // \T:= the motion's duration (s): a motion split by the compensation gets each piece its share
      const std::optional<double> time_s = number(t_, it->second);
      if (time_s && !(*time_s > 0 && *time_s <= 1e6)) shape(it->second.first, "\\T:= a time in (0, 1e6] s", text(it->second));
      if (time_s) {
        st.duration_text = {t_[it->second.first].b, t_[it->second.second - 1].e};
        st.duration_s = *time_s;
        m.duration_s = *time_s;
      } else {
        m.duration_expr = it->second.first < it->second.second ? text(it->second) : std::string("\\T");
      }
    }
    zone(pos[lay.zone].main, opt, m);
    tool(pos[lay.tool].main, m);
    wobj(opt, m);
    singleReason(r, opt, st, m);
    // (its pieces would each set the signal, fire the triggers or call the procedure)
    if (m.single_reason.empty() && !isPlainMove(u))
      m.single_reason = "it is a " + f + ", whose pieces would each repeat what it does besides moving (a signal, a trigger, a procedure, a weld)";
    if (pdisp_ && m.target_problem.empty() && u != "MOVEABSJ")
      m.target_problem = "a program displacement is active (" + pdisp_name_ + " at " + pdisp_->str() +
                         "): the robot goes to the displaced target, which accura does not model";
    if (eoffs_ && m.target_problem.empty())
      m.target_problem = "an external axes offset is active (" + eoffs_name_ + " at " + eoffs_->str() + "), which accura does not model";
    // what the move reads besides its plain targets (Offs of a run-time value, a \WObj, ...)
    std::vector<Range> targets;
    if (u != "MOVEABSJ") targets.push_back(pos[0].main);
    if (circ) targets.push_back(pos[1].main);
    size_t from = r.first + 1;
    for (const Range& a : targets) {
      noteReads({from, a.first}, r);
      from = a.second;
    }
    noteReads({from, r.second}, r);
    if (u == "MOVEABSJ") {
      jointTarget(pos[0].main, m);
      st.targets.push_back({t_[pos[0].main.first].b, t_[pos[0].main.second - 1].e});
      st.target_value.push_back(-1);
      st.target_reads.push_back(-1);
    } else {
      auto cart = [&](Range a) {
        const TargetVal v = target(a);
        Target tg;
        tg.kind = Target::Kind::kCartesian;
        tg.where = loc(t_[a.first].b);
        if (!isOp(t_, a.first, "[")) tg.name = text(a);
        if (v.problem.empty()) {
          tg.setPose(calib::toXyzAbc(v.T));
          tg.abb_conf = v.conf;
          tg.ext = v.ext;
          tg.value_id = v.value;
          if (const auto w = task_where_.find(v.value); w != task_where_.end()) tg.where = w->second;  // (a --config module's)
          else if (v.value >= 0 && src_->values[static_cast<size_t>(v.value)].decl >= 0) tg.where = loc(src_->values[static_cast<size_t>(v.value)].begin);
        } else if (m.target_problem.empty()) {
          m.target_problem = v.problem;
        }
        st.targets.push_back({t_[a.first].b, t_[a.second - 1].e});
        st.target_value.push_back(v.problem.empty() ? v.value : -1);
        st.target_reads.push_back(v.problem.empty() ? v.reads : -1);
        // a target the motion keeps as written (an Offs of a run-time value) reads its points
        if (!v.problem.empty() && !(a.second == a.first + 1)) noteReads(a, r);
        return tg;
      };
      if (circ) m.aux = cart(pos[0].main);
      m.target = cart(pos[circ ? 1 : 0].main);
    }
    addMotion(r, m, st, p);
  }

  /// Why the pieces of this move, were it split by auxiliary points, would not do what it does
  /// (Motion::single_reason): another statement on its line (a label, a CASE, a compact IF, an
  /// assignment before it, a motion after it) would be repeated or run at another time; \ID
  /// synchronises one move per ID with another task (MultiMove); a time \T that is not a
  /// number cannot be shared among the pieces.
  void singleReason(Range r, const std::map<std::string, Range>& opt, const RapidSource::Statement& st, Motion& m) const {
    const std::string& s = src_->text;
    const size_t line_end = s.find('\n', st.code_end);
    const size_t first_code = s.find_first_not_of(" \t", st.line_begin);
    bool other = first_code < st.code_begin;
    for (size_t k = r.second; k < t_.size() && t_[k].b < line_end; ++k) other = true;  // code after it on its line
    if (other) m.single_reason = "it shares its line with another statement";
    else if (opt.count("ID")) m.single_reason = "it carries \\ID (a MultiMove synchronisation: one move per ID)";
    else if (opt.count("T") && st.duration_s == 0) m.single_reason = "its time \\T:= is not a number that the pieces could share";
  }

  RapidSource::Statement statementSpan(Range r, const SourceLocation& where) const {
    RapidSource::Statement st;
    st.code_begin = t_[r.first].b;
    st.code_end = t_[r.second - 1].e;
    st.line_begin = starts_[static_cast<size_t>(where.line - 1)];
    const size_t nl = src_->text.find('\n', st.code_end);
    st.eol = nl == std::string::npos ? "" : (nl > 0 && src_->text[nl - 1] == '\r' ? "\r\n" : "\n");
    return st;
  }

  void addMotion(Range r, Motion& m, RapidSource::Statement& st, Program& p) {
    if (routine_.empty()) fail(t_[r.first].b, "expected " + excerpt(t_[r.first].s) + " inside a routine (PROC), found it at module level");
    if (main_routine_.empty()) main_routine_ = routine_;
    if (routine_ != main_routine_) other_routine_motion_ = true;
    m.statement_id = static_cast<int>(src_->statements.size());
    src_->statements.push_back(st);
    p.motions.push_back(m);
    motion_lines_.push_back(loc(t_[r.first].b).line);
    markModel(r);
  }

  void jointTarget(Range a, Motion& m) {
    m.target.kind = Target::Kind::kAxis;
    m.target.where = loc(t_[a.first].b);
    if (isOp(t_, a.first, "[")) {
      const auto parts = bracketItems(a, 2, "a jointtarget [[rax_1,..,rax_6],[eax_a,..,eax_f]]");
      std::pair<size_t, size_t> s[6];
      double v[6], e[6];
      numbers(parts[0], 6, "robot axes [rax_1,..,rax_6] (deg)", s, v);
      numbers(parts[1], 6, "external axes [eax_a,..,eax_f]", s, e);
      for (int k = 0; k < 6; ++k) m.target.axes[static_cast<size_t>(k)] = v[k];
      return;
    }
    m.target.name = text(a);
    const auto* q = a.second == a.first + 1 ? lookup(&Scope::joints, t_[a.first].u) : nullptr;
    if (q && !assigned_.count(t_[a.first].u)) {
      for (int k = 0; k < 6; ++k) m.target.axes[static_cast<size_t>(k)] = (*q)[static_cast<size_t>(k)];
    } else {
      m.target_problem = "'" + quoted(a) + "' is not a jointtarget declared with a constant value in this module";
    }
  }

  void speed(Range a, const std::map<std::string, Range>& opt, Motion& m) {
    std::optional<double> v;
    if (a.second == a.first + 1 && t_[a.first].kind == Tok::Kind::kIdent) {
      v = predefinedSpeedMmS(t_[a.first].u);
      if (!v) {
        const double* d = lookup(&Scope::speeds, t_[a.first].u);
        if (d) v = *d;
      }
    } else if (isOp(t_, a.first, "[")) {
      const auto parts = bracketItems(a, 4, "a speeddata [v_tcp, v_ori, v_leax, v_reax]");
      v = number(t_, parts[0]);
      if (!v || *v <= 0) shape(parts[0].first, "v_tcp > 0 (mm/s)", text(parts[0]));
    }
    const auto it = opt.find("V");
    if (it != opt.end()) {
      const std::optional<double> x = number(t_, it->second);
      if (x && !(*x > 0 && *x <= 1e5)) shape(it->second.first, "\\V:= a TCP speed in (0, 100000] mm/s", text(it->second));
      v = x;
    }
    if (v && m.type != MotionType::kPtp) m.vel_m_s = *v / 1000.0;
  }

  void zone(Range a, const std::map<std::string, Range>& opt, Motion& m) {
    std::optional<double> radius;
    bool known = true, fine = false;
    if (a.second == a.first + 1 && t_[a.first].kind == Tok::Kind::kIdent) {
      const std::string& u = t_[a.first].u;
      if (u == "FINE") fine = true;
      else if ((radius = predefinedZoneMm(u))) {
      } else if (const auto* z = lookup(&Scope::zones, u)) {
        fine = !z->has_value();
        radius = *z;
      } else {
        known = false;
      }
    } else if (isOp(t_, a.first, "[")) {
      const auto parts = bracketItems(a, 7, "a zonedata [finep, pzone_tcp, pzone_ori, pzone_eax, zone_ori, zone_leax, zone_reax]");
      radius = number(t_, parts[1]);
      if (!radius || *radius < 0) shape(parts[1].first, "pzone_tcp >= 0 (mm)", text(parts[1]));
      fine = boolean(parts[0], "finep");
    } else {
      known = false;
    }
    const auto it = opt.find("Z");
    if (it != opt.end() && !fine) {
      radius = number(t_, it->second);
      if (radius && !(*radius >= 0 && *radius <= 1e4)) shape(it->second.first, "\\Z:= a zone radius in [0, 10000] mm", text(it->second));
    }
    // \Inpos: stop point data, which replaces the zone (the move ends in a stop point)
    if (fine || opt.count("INPOS")) return;
    m.approximation = {Approximation::kCDis};
    if (known && radius) m.approximation_value = *radius;
  }

  /// The frame named at `a` (tooldata or wobjdata): `builtin` (tool0 / wobj0) is the
  /// identity, a declaration its value (or why it cannot be modelled), anything else unset
  /// with the option that supplies it.
  FrameSetting frameArg(Range a, const std::map<std::string, FrameVal> Scope::*table, const char* builtin, const std::string& type,
                        const std::string& option) {
    FrameSetting f;
    f.where = loc(t_[a.first].b);
    f.text = text(a);
    const bool single = a.second == a.first + 1;
    const std::string u = single ? t_[a.first].u : std::string();
    const auto assigned = single ? assigned_.find(u) : assigned_.end();
    if (single && u == builtin) {
      f.source = FrameSetting::Source::kNull;
      f.value = calib::XyzAbc{};
    } else if (isOp(t_, a.first, "?")) {
      // a conditional argument (\WObj?wo: RAPID kernel, <conditional procedure argument>):
      // given only when the routine's caller gives its optional parameter, else left out
      f.source = FrameSetting::Source::kUnknown;
      f.note = "the " + type + " is the conditional argument '" + excerpt(f.text) + "' of " + excerpt(routine_) +
               ": given or left out by the call";
      f.run_time = true;
    } else if (single && params_.count(u) && !local_.names.count(u)) {
      f.source = FrameSetting::Source::kUnknown;
      f.note = "the " + type + " '" + excerpt(f.text) + "' is a parameter of " + excerpt(routine_) + ": its value comes from the call";
      f.run_time = true;
    } else if (const auto h = single ? (assigned_here_.*table).find(u) : (assigned_here_.*table).end(); h != (assigned_here_.*table).end()) {
      f.where = h->second.where;  // (the value the routine assigned before this motion)
      f.source = h->second.T ? FrameSetting::Source::kInline : FrameSetting::Source::kUnknown;
      if (h->second.T) f.value = calib::toXyzAbc(*h->second.T);
      f.note = h->second.note;
    } else if (assigned != assigned_.end()) {
      f.source = FrameSetting::Source::kUnknown;
      f.note = "the " + type + " '" + excerpt(f.text) + "' is assigned at " + assigned->second.str() + ": its value at run time is not the declared one";
      f.run_time = true;
    } else if (const FrameVal* v = single ? lookup(table, u) : nullptr) {
      f.where = v->where;
      f.source = v->T ? FrameSetting::Source::kInline : FrameSetting::Source::kUnknown;
      if (v->T) f.value = calib::toXyzAbc(*v->T);
      f.note = v->note;
    } else {
      f.source = FrameSetting::Source::kUnset;
      // with --config given: LOCAL there (RAPID: a LOCAL datum is its module's only) or not
      // declared there with a value; else that option is the other way to give it
      const SourceLocation* local = nullptr;
      std::string paths;
      for (const TaskModule& task : tasks_) {
        paths += (paths.empty() ? "" : ", ") + task.path;
        const auto it = task.locals.find(u);
        if (single && !local && it != task.locals.end()) local = &it->second;
      }
      const std::string given = tasks_.size() > 1 ? "the modules given with --config" : "the module given with --config";
      if (tasks_.empty())
        f.note = "the " + type + " '" + excerpt(f.text) + "' is not declared with a value in this module (" + option + ", or the module that declares it with --config)";
      else if (local)
        f.note = "the " + type + " '" + excerpt(f.text) + "' is not declared with a value in this module, and is LOCAL in " +
                 (tasks_.size() > 1 ? std::string("a module") : std::string("the module")) + " given with --config (" + local->str() + "): invisible to other modules (" + option + ")";
      else
        f.note = "the " + type + " '" + excerpt(f.text) + "' is not declared with a value in this module nor in " + given + ", " + paths + " (" + option + ")";
    }
    return f;
  }

  void tool(Range a, Motion& m) {
    m.tool = frameArg(a, &Scope::tools, "TOOL0", "tooldata",
                      "give its TCP with --program-tool x,y,z,A,B,C");
  }

  void wobj(const std::map<std::string, Range>& opt, Motion& m) {
    const auto it = opt.find("WOBJ");
    if (it == opt.end()) {
      m.base.source = FrameSetting::Source::kNull;
      m.base.value = calib::XyzAbc{};
      m.base.text = "wobj0";
      m.base.where = m.where;
      return;
    }
    const Range a = it->second;
    if (a.first >= a.second) fail(t_[a.first - 1].e, "expected a wobjdata after \\WObj:=, found nothing");
    m.base = frameArg(a, &Scope::wobjs, "WOBJ0", "wobjdata",
                      "give its frame with --program-base x,y,z,A,B,C");
  }

  /// A motion instruction accura does not model (or, `why`, does not read as written): kept, and
  /// reported by compensate.
  void otherMove(Range r, Program& p, const std::string& why = std::string()) {
    Motion m;
    m.where = loc(t_[r.first].b);
    m.statement = text(r);
    const std::string& u = t_[r.first].u;
    m.type = u.find('J') != std::string::npos && u.find("MOVEJ") == 0 ? MotionType::kPtp : MotionType::kLin;
    m.start_unknown = flow_.motion();
    m.target_problem = why.empty() ? t_[r.first].s + " is a motion instruction accura does not model (MoveL, MoveJ, MoveC, MoveAbsJ)" : why;
    // MoveExtJ moves one or several mechanical units without a TCP (ABB, Technical reference
    // manual - RAPID Instructions, Functions and Data types, MoveExtJ): the arm's axes stay
    if (u == "MOVEEXTJ") {
      m.arm_stays = true;
      m.target_problem = t_[r.first].s + " moves external axes only (mechanical units without a TCP), which accura does not model";
    }
    RapidSource::Statement st = statementSpan(r, m.where);
    addMotion(r, m, st, p);
  }

  void passThrough(Program& p) const {
    // a line is the motion model's only when every statement on it is: a motion followed by
    // SetDO on the same line is carried (and refused or dropped by other formats) as a statement
    std::vector<bool> model_only(starts_.size() + 1, false);
    const auto mark = [&](Range r, bool model) {
      const int a = loc(t_[r.first].b).line, b = loc(t_[r.second - 1].b).line;
      for (int l = a; l <= b; ++l) model_only[static_cast<size_t>(l)] = model;
    };
    for (const auto& r : model_) mark(r, true);
    for (const Range& r : stmts_)
      if (!model_.count(r.first)) mark(r, false);
    rapidPassThrough(*src_, t_, stmts_, starts_, model_only, motion_lines_, main_routine_, other_routine_motion_, p);
  }

  std::shared_ptr<RapidSource> src_;
  std::vector<size_t> starts_;
  std::vector<Tok> t_;
  std::vector<Range> stmts_;
  std::set<size_t> conditional_;  ///< first tokens of the statements a compact IF holds
  std::set<std::string> params_;  ///< the current routine's parameters (upper case)
  std::optional<SourceLocation> pdisp_, eoffs_;  ///< where PDispOn/PDispSet, EOffsOn/EOffsSet was (until Off)
  std::string pdisp_name_, eoffs_name_;
  std::map<std::string, SourceLocation> assigned_;
  /// The routines (upper case) whose statements assign each name with ':=' (whole or a field,
  /// not a tool's load); "" for a change through a call's argument (INOUT, VAR, Add, Search*).
  std::map<std::string, std::set<std::string>> assigners_;
  std::map<std::string, std::string> routine_kinds_;           ///< the module's routines (upper case) -> PROC, FUNC or TRAP
  std::map<std::string, std::set<std::string>> callees_;       ///< routine -> the module's routines its statements call
  /// The tooldata / wobjdata values the routine being read has assigned so far (frameAssignment).
  Scope assigned_here_;
  int depth_ = 0;            ///< blocks (IF, WHILE, FOR, TEST) open in the routine being read
  bool in_handler_ = false;  ///< in the routine's ERROR / BACKWARD / UNDO handler
  std::set<std::string> handler_assigns_;  ///< what the routine's handler assigns (assignedFrom)
  std::vector<std::array<std::optional<double>, 6>> ext_;  ///< external axes of each value (9E9: none)
  std::vector<ArrayVal> arrays_;  ///< the robtarget arrays (Scope::robtarget_arrays)
  std::map<size_t, size_t> model_;  ///< the statements of the motion model (markModel): first token -> end
  std::vector<int> motion_lines_;
  std::vector<Scope> modules_;  ///< each module's data (moduleData), by module_index_
  Scope global_, local_;        ///< the program's global data; the current routine's
  std::vector<TaskModule> tasks_;  ///< the other modules of the task (useTaskData; none: empty)
  /// (module of this file, robtarget) -> its value read from a module of tasks_ (taskRobtarget)
  std::map<std::pair<int, std::string>, int> task_values_;
  std::map<int, SourceLocation> task_where_;  ///< those values -> their place in that module
  /// each module of this file: where a new point goes (taskRobtarget), the indent it takes
  std::vector<std::pair<size_t, std::string>> module_insert_;
  int module_index_ = -1;       ///< the module being read (its MODULE's count - 1)
  std::set<size_t> module_data_;  ///< first tokens of the module-level declarations (read first)
  std::string module_name_, routine_, routine_kind_, main_routine_;
  Range routine_line_{0, 0};
  Range cut_{0, 0};  // a last statement the end of the file cut off (no ';'), when there is one
  bool module_seen_ = false, module_open_ = false, other_routine_motion_ = false;
  StartTracker flow_;               ///< where the robot comes from (Motion::start_unknown)
  std::set<std::string> routines_;  ///< the module's PROCs that move the robot (upper case)
  std::map<std::string, SourceLocation> displaced_;  ///< routines called with a displacement active: the call
  bool confl_ = true, confj_ = true;
  /// Offs/RelTool nested in the target being read: at most kMaxOffsetNesting.
  int offset_depth_ = 0;
  static constexpr int kMaxOffsetNesting = 100;
};

}  // namespace

Program parseRapid(const std::string& text, const std::string& path) { return Reader(text, path).run(); }

namespace {

std::string moduleText(const std::string& path) {
  if (const std::string problem = calib::notAFileProblem(path); !problem.empty())
    throw calib::InputError(path, 0, 0, "cannot read the RAPID module: " + problem);
  std::ifstream f(path, std::ios::binary);
  if (!f) throw calib::InputError(path, 0, 0, "cannot read the RAPID module");
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) throw calib::InputError(path, 0, 0, "cannot read the RAPID module");
  return text;
}

}  // namespace

Program readRapid(const std::string& path) { return parseRapid(moduleText(path), path); }

Program readRapid(const std::string& path, const std::string& task_module) {
  if (task_module.empty()) return readRapid(path);
  return readRapid(path, std::vector<std::string>{task_module});
}

Program readRapid(const std::string& path, const std::vector<std::string>& task_modules) {
  if (task_modules.empty()) return readRapid(path);
  // a module is loaded into the task once: the program itself given with --config (a batch
  // over a task's folder whose --config points into it), or one module given twice, is that
  // one module (the same file, through whatever path)
  std::vector<std::string> paths{path};
  const auto sameFile = [&paths](const std::string& m) {
    for (const std::string& q : paths) {
      std::error_code ec;
      if (q == m || fs::equivalent(q, m, ec)) return true;
    }
    return false;
  };
  std::vector<Reader::TaskModule> tasks;
  for (const std::string& m : task_modules) {
    if (sameFile(m)) continue;
    paths.push_back(m);
    Reader data(moduleText(m), m);
    tasks.push_back(data.taskData());
  }
  Reader r(moduleText(path), path);
  if (!tasks.empty()) r.useTaskData(std::move(tasks));
  return r.run();
}

}  // namespace accura::postproc
