// accura: where the robot comes from, while a program is read in text order
// (Motion::start_unknown), for the KRL, RAPID and URScript readers.
#pragma once

#include <map>
#include <set>
#include <string>
#include <vector>

namespace accura::postproc {

/// The position before a motion is the previous motion's target in the text only when nothing
/// between them can move the robot elsewhere. The readers report the program's blocks, calls
/// and motions in text order; motion() answers whether that motion's start is unknown:
/// - after a branch block or a branch of it that moved the robot (ELSE starts from before the IF,
///   after ENDIF from any branch's end or from before the block);
/// - at a loop's first motion (from before the loop or from the end of the last pass), and after
///   a loop that moved the robot (it may run no pass);
/// - at a routine's first motion (called from anywhere), after a routine's text (the text goes
///   on in its caller), after a call of a routine that moves the robot, a label or a jump.
/// A block without motions changes nothing; nested blocks pass their motions outwards.
class StartTracker {
 public:
  enum class Block { kBranch, kLoop, kRoutine };

  void open(Block kind) {
    stack_.push_back({kind, moved_, false, kind == Block::kLoop});
    moved_ = false;
    if (kind == Block::kRoutine) unknown_ = true;
  }
  /// Another branch of the innermost branch block (ELSE, ELSEIF, CASE, DEFAULT, elif).
  void branch() {
    if (moved_) unknown_ = true;
    if (!stack_.empty()) stack_.back().moved_inside = stack_.back().moved_inside || moved_;
    moved_ = false;
  }
  /// The end of the innermost block (ignored when none is open).
  void close() {
    if (stack_.empty()) return;
    const Frame f = stack_.back();
    stack_.pop_back();
    const bool inside = f.moved_inside || moved_;
    if (inside || f.kind == Block::kRoutine) unknown_ = true;
    moved_ = f.moved_before || (inside && f.kind != Block::kRoutine);
  }
  /// A call of a routine that moves the robot, a label, a jump.
  void unknown() { unknown_ = true; }
  /// A motion: whether its start is unknown.
  bool motion() {
    bool u = unknown_;
    for (Frame& f : stack_)
      if (f.loop_first) {
        u = true;
        f.loop_first = false;
      }
    unknown_ = false;
    moved_ = true;
    return u;
  }

 private:
  struct Frame {
    Block kind;
    bool moved_before;  ///< a motion in the enclosing branch before this block
    bool moved_inside;  ///< a motion in an earlier branch of this block
    bool loop_first;    ///< a loop whose first motion is still to come
  };
  std::vector<Frame> stack_;
  bool moved_ = false;    ///< a motion in the current branch
  bool unknown_ = false;  ///< the next motion's start is unknown
};

/// The routines that move the robot: those with a motion of their own (`moves`: every routine
/// of the file, true when it has one) and those that call one of them, directly or through
/// others (`calls`: each routine's calls of the file's routines).
inline std::set<std::string> movingRoutines(std::map<std::string, bool> moves,
                                            const std::map<std::string, std::set<std::string>>& calls) {
  for (bool changed = true; changed;) {
    changed = false;
    for (auto& [name, m] : moves) {
      const auto c = calls.find(name);
      if (m || c == calls.end()) continue;
      for (const std::string& callee : c->second)
        if (moves[callee]) m = changed = true;
    }
  }
  std::set<std::string> out;
  for (const auto& [name, m] : moves)
    if (m) out.insert(name);
  return out;
}

}  // namespace accura::postproc
