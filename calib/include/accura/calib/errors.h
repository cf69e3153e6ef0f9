// accura: error types shared by every module.
//
// accura never aborts on bad input or misuse: it throws one of the exceptions below, and
// the command-line tool and the C ABI turn them into a message and a non-zero status.
//
// The rule: exceptions vs. returned errors.
// - Throw (InputError, ArgumentError, NumericalError) when the call cannot give what it
//   promises: a file that cannot be read or written, a malformed or impossible input, an
//   argument of the wrong size or meaning, a numerical procedure without a trustworthy answer.
//   The caller gets no partial result.
// - Return the outcome as data when a finding about the input is the answer itself, and the
//   caller decides what it means: an IK status (IkStatus: unreachable, joint limits, ...), the
//   violations of a check (CheckReport), the problems of a program's compensation
//   (JobReport::errors of compensateProgramReport), a file of a batch that failed
//   (BatchFileResult). Such results are complete (every total computed), never half-filled.
// - The boundaries translate, and only they: main() prints an exception and sets the exit
//   status, the C ABI turns it into an accura_status and a message (plugin/src), and a
//   function that throws for its callers' convenience (compensateProgram) is a thin wrapper of
//   the one that returns (compensateProgramReport).
#pragma once

#include <stdexcept>
#include <string>

namespace accura::calib {

/// Bad input read from a file or given on the command line.
///
/// what() is "FILE:LINE:COLUMN: MESSAGE" (line and column omitted when unknown, 1-based),
/// where MESSAGE says what was expected and what was found.
class InputError : public std::runtime_error {
 public:
  InputError(std::string file, int line, int column, const std::string& message);
  /// An input error that is not tied to a place in a file (a command-line value, ...).
  explicit InputError(const std::string& message);

  const std::string& file() const { return file_; }
  int line() const { return line_; }      ///< 1-based; 0 when unknown
  int column() const { return column_; }  ///< 1-based; 0 when unknown
  const std::string& message() const { return message_; }

 private:
  std::string file_;
  int line_ = 0;
  int column_ = 0;
  std::string message_;
};

/// A call with arguments of the wrong size or meaning ("expected 6 joint values, got 5").
class ArgumentError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A numerical procedure that could not produce a trustworthy answer (rank-deficient data,
/// non-convergence, singular pose). The message says which quantity and by how much.
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Formats "FILE:LINE:COLUMN: " as used by InputError (parts that are unknown are left out).
std::string formatLocation(const std::string& file, int line, int column);

}  // namespace accura::calib
