// The --cell options and the printed check report of accura check, shared with accura compensate
// (defined in cmd_check.cpp).
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "accura/postproc/cell.h"
#include "accura/postproc/check.h"

namespace accura::cli {

/// A cell and the options of its checks, from the command line.
struct CellCheck {
  std::string cell_path;
  postproc::Cell cell;
  postproc::CheckOptions options;
  /// The cell file and every mesh file it names: inputs, which a --json or --out never overwrites.
  std::vector<std::string> files() const;
};

/// Exit status of accura check / compensate --cell when a check fails.
constexpr int kCheckFailed = 2;

/// Adds --cell (required or not), --joint-margin-deg, --singular-threshold,
/// --min-clearance-mm and, with `as_written_flag`, --as-written; the function reads the cell
/// (empty without --cell).
std::function<std::optional<CellCheck>()> addCellOptions(CLI::App* c, bool required, bool as_written_flag);
/// Prints the report (violations on stdout, warnings on stderr).
void printCheckReport(const postproc::CheckReport& r, const std::string& program);

}  // namespace accura::cli
