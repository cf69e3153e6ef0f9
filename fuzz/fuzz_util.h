// accura fuzz targets (fuzz/README.md): what every target shares.
//
// The contract each target asserts for every input: the reader returns a result, or throws
// accura::calib::InputError naming the file; never another exception, a crash, a hang (libFuzzer
// -timeout) or a leak (LeakSanitizer). FUZZ_STRICT=1 also requires every error to say what
// was expected and to carry a line and a column (issue 14: about 30% of rejections lack
// "expected", robot-file errors the column; fuzz/findings/README.md).
#pragma once

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "accura/calib/errors.h"

namespace accura::fuzz {

/// A private directory for the files a target writes, removed when the process exits (not
/// after a crash: the input is then in fuzz/findings/ anyway).
class Scratch {
 public:
  static Scratch& get() {
    static Scratch s;
    return s;
  }
  std::string path(const std::string& name) const { return dir_ + "/" + name; }
  /// Writes the bytes to dir/name (replacing it) and returns the path.
  std::string write(const std::string& name, std::string_view bytes) const {
    const std::string p = path(name);
    std::ofstream f(p, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!f) die("cannot write the scratch file " + p);
    return p;
  }
  ~Scratch() { cleanup(); }
  /// Removes the directory (also before an abort, which skips the destructor).
  void cleanup() {
    std::error_code ec;
    if (!dir_.empty()) std::filesystem::remove_all(dir_, ec);
  }

 private:
  Scratch() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "accura_fuzz_XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) die("cannot create a scratch directory");
    dir_ = tmpl;  // removed by the destructor when the process exits normally (libFuzzer ends with exit())
  }
  [[noreturn]] static void die(const std::string& what) {
    std::fprintf(stderr, "fuzz: %s\n", what.c_str());
    std::abort();
  }
  std::string dir_;
};

/// Aborts (a libFuzzer finding) with the message.
[[noreturn]] inline void violation(const std::string& what) {
  std::fprintf(stderr, "\nfuzz contract violation: %s\n", what.c_str());
  std::fflush(stderr);
  Scratch::get().cleanup();  // libFuzzer keeps the input itself (-artifact_prefix)
  std::abort();
}

/// The contract for an InputError: it names a file (FUZZ_STRICT=1: and says what was
/// expected, at a line and column; in a binary file, at a byte offset: "at byte N: ").
inline void checkInputError(const calib::InputError& e) {
  if (e.file().empty()) violation(std::string("InputError without a file: ") + e.what());
  static const bool strict = [] {
    const char* s = std::getenv("FUZZ_STRICT");
    return s && std::string(s) == "1";
  }();
  if (!strict) return;
  if (e.message().find("expected") == std::string::npos) violation(std::string("InputError without 'expected': ") + e.what());
  const bool byte_offset = e.line() == 0 && e.message().rfind("at byte ", 0) == 0;  // binary meshes
  if (!byte_offset && (e.line() < 1 || e.column() < 1)) violation(std::string("InputError without line:column: ") + e.what());
}

/// Runs `parse`; an InputError must keep the contract, any other exception is a finding.
template <class F>
void expectParsedOrInputError(F&& parse) {
  try {
    parse();
  } catch (const calib::InputError& e) {
    checkInputError(e);
  } catch (const std::exception& e) {
    violation(std::string("unexpected exception (not accura::calib::InputError): ") + e.what());
  } catch (...) {
    violation("unexpected non-standard exception");
  }
}

/// Splits an input into two parts at the first line "#####" (the second file of a pair:
/// .src/.dat, mapping/export, cell/mesh); no such line: the whole input and `fallback`.
inline std::pair<std::string_view, std::string_view> splitPair(std::string_view in, std::string_view fallback) {
  static constexpr std::string_view kSeparator = "\n#####\n";
  const size_t at = in.find(kSeparator);
  if (at == std::string_view::npos) return {in, fallback};
  return {in.substr(0, at + 1), in.substr(at + kSeparator.size())};
}

}  // namespace accura::fuzz
