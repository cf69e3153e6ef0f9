// accura: the one writer of output files (see file_io.h): temporary files renamed into place,
// the interrupt clean-up, sameFile.
#include "accura/calib/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <mutex>
#include <thread>

#include "accura/calib/errors.h"

namespace fs = std::filesystem;

namespace accura::calib {
namespace {

// ---------------------------------------------------------------------------------------------
// Temporary files in flight, visible to the signal handler.

constexpr int kSlots = 256;
constexpr size_t kNameMax = 255;  // NAME_MAX of Linux file systems (ext4, xfs, btrfs, tmpfs)
constexpr size_t kPathMax = 4096;
enum SlotState : int { kFree = 0, kWriting = 1, kCommitting = 2, kReserved = 3 };

struct Slot {
  std::atomic<int> state{kFree};
  char path[kPathMax];
};

Slot g_slots[kSlots];
std::atomic<int> g_interrupted{0};  // signals received
// installInterruptStop: the first signal only asks the work to stop (the note is said); the
// second acts at once
std::atomic<const char*> g_stop_note{nullptr};
std::once_flag g_install_once;

// The process is to end now: a signal without installInterruptStop, or the second one with it.
bool exitRequested() {
  const int n = g_interrupted.load();
  return n >= (g_stop_note.load() ? 2 : 1);
}

void writeStderr(const char* msg) {
  const size_t n = std::strlen(msg);
  ssize_t r = ::write(2, msg, n);
  (void)r;
}

// Removes every temporary file that is being written (not those being renamed into place).
// A slot stays kReserved from its reservation until its file is open; once g_interrupted is
// set no new slot is handed out (acquireSlot), so waiting (bounded: the handler may run on
// the very thread that holds the slot) for the kReserved ones lets their files be unlinked too.
void unlinkWriting() {
  for (int spin = 0; spin < 2000; ++spin) {  // at most ~200 ms
    bool reserved = false;
    for (Slot& s : g_slots) reserved = reserved || s.state.load() == kReserved;
    if (!reserved) break;
    struct timespec ts{0, 100000};  // 0.1 ms; nanosleep is async-signal-safe
    ::nanosleep(&ts, nullptr);
  }
  for (Slot& s : g_slots)
    if (s.state.load() == kWriting) ::unlink(s.path);
}

[[noreturn]] void exitInterrupted() {
  unlinkWriting();
  writeStderr("\naccura: interrupted: no file was left half-written\n");
  ::_exit(130);
}

extern "C" void onInterrupt(int) {
  const int n = g_interrupted.fetch_add(1) + 1;
  if (const char* note = g_stop_note.load(); note && n == 1) {  // the work stops, the command reports it
    writeStderr(note);
    return;
  }
  bool committing = false;
  for (Slot& s : g_slots) {
    const int st = s.state.load();
    if (st == kWriting || st == kReserved) ::unlink(s.path);
    if (st == kCommitting) committing = true;
  }
  // A program's files being renamed into place: that thread finishes and exits.
  if (!committing) exitInterrupted();
}

int acquireSlot(const std::string& path) {
  if (path.size() + 1 > kPathMax) throw InputError(path, 0, 0, "path too long for a temporary file");
  for (;;) {
    for (int i = 0; i < kSlots; ++i) {
      int expected = kFree;
      if (g_slots[i].state.compare_exchange_strong(expected, kReserved)) {
        std::memcpy(g_slots[i].path, path.c_str(), path.size() + 1);
        if (exitRequested()) {  // interrupted: no new temporary file; the handler exits
          g_slots[i].state.store(kFree);
          for (;;) std::this_thread::sleep_for(std::chrono::seconds(1));
        }
        return i;  // stays kReserved until its file is open (writeFilesAtomically)
      }
    }
    std::this_thread::yield();  // more files in flight than slots: wait for one
  }
}

void releaseSlot(int i) { g_slots[i].state.store(kFree); }

void writeAll(int fd, const std::string& text, const std::string& path) {
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t w = ::write(fd, text.data() + done, text.size() - done);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw InputError(path, 0, 0, std::string("cannot write: ") + std::strerror(errno));
    }
    done += static_cast<size_t>(w);
  }
}

// f's text into the descriptor `fd` just opened for it (-1: the open failed, errno says why),
// synced to the disk first when `sync`, then closed; every failure an InputError naming f.
void writeOpened(int fd, const OutputFile& f, bool sync) {
  if (fd < 0) {
    // a missing or unwritable directory ("No such file or directory" would read as the output
    // file's own absence): named as refuseUnwritableOutputs names it; else the open's reason
    const int err = errno;
    const std::string problem = directoryWriteProblem(fs::path(f.path).parent_path().string());
    throw InputError(f.path, 0, 0, "cannot write file: " + (problem.empty() ? std::string(std::strerror(err)) : problem));
  }
  try {
    writeAll(fd, f.text, f.path);
  } catch (...) {
    ::close(fd);
    throw;
  }
  if ((sync && ::fsync(fd) != 0) || ::close(fd) != 0)
    throw InputError(f.path, 0, 0, std::string("cannot write file: ") + std::strerror(errno));
}

// An output that is not a file to replace but a stream to write into: the process's own
// standard output or error named as a file (/dev/stdout, /dev/stderr, /dev/fd/N,
// /proc/self/fd/N: written to the descriptor N), or an existing character device, FIFO or
// socket (/dev/null, a named pipe: opened and written). A temporary file renamed onto such a
// path would replace the device or the link with a regular file (as root, /dev/null itself)
// and nobody would read the output. Returns -1 for an ordinary file (written through a
// temporary file), the descriptor number N, or kOpenByPath.
constexpr int kOpenByPath = -2;

int streamTarget(const std::string& path) {
  for (const char* prefix : {"/dev/fd/", "/proc/self/fd/"}) {
    const std::string pre(prefix);
    if (path.size() > pre.size() && path.size() - pre.size() < 6 && path.compare(0, pre.size(), pre) == 0 &&
        path.find_first_not_of("0123456789", pre.size()) == std::string::npos)
      return std::stoi(path.substr(pre.size()));
  }
  if (path == "/dev/stdout") return 1;
  if (path == "/dev/stderr") return 2;
  struct stat st;  // (stat only: opening a FIFO to look would end its reader's input)
  if (::stat(path.c_str(), &st) != 0 || S_ISREG(st.st_mode) || S_ISDIR(st.st_mode)) return -1;
  return kOpenByPath;
}

void writeStream(const OutputFile& f) {
  const int target = streamTarget(f.path);
  if (target != kOpenByPath) {  // the descriptor the C and C++ streams write to: what they hold goes first
    std::fflush(nullptr);
    writeAll(target, f.text, f.path);
    return;
  }
  writeOpened(::open(f.path.c_str(), O_WRONLY | O_CLOEXEC), f, false);
}

}  // namespace

void installInterruptStop(const char* note) {
  g_stop_note.store(note);
  installInterruptCleanup();
}

void installInterruptCleanup() {
  std::call_once(g_install_once, [] {
    struct sigaction sa;
    std::memset(&sa, 0, sizeof sa);
    sa.sa_handler = onInterrupt;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
  });
}

bool interruptRequested() { return g_interrupted.load() != 0; }

void writeFilesAtomically(const std::vector<OutputFile>& files) {
  // one file named twice in one set: the second would silently replace the first
  for (size_t i = 0; i < files.size(); ++i)
    for (size_t j = 0; j < i; ++j)
      if (sameFile(files[i].path, files[j].path))
        throw InputError(files[i].path + ": cannot write file: it is also another output of the same call (" + files[j].path +
                         "); choose different output paths");
  // a temporary name of its own for every file written by this process (threads of a batch, a
  // plug-in host's threads): two writers of one path never share a temporary file
  static std::atomic<unsigned long> counter{0};
  // streams (/dev/stdout, /dev/null, a FIFO) are written into once the files are in place
  std::vector<OutputFile> regular, streams;
  for (const OutputFile& f : files) (streamTarget(f.path) != -1 ? streams : regular).push_back(f);
  if (!streams.empty()) {
    if (!regular.empty()) writeFilesAtomically(regular);
    for (const OutputFile& f : streams) writeStream(f);
    return;
  }
  std::vector<int> slots;
  std::vector<std::string> temps;
  auto cleanup = [&]() {
    for (size_t i = 0; i < slots.size(); ++i) {
      ::unlink(temps[i].c_str());
      releaseSlot(slots[i]);
    }
  };
  try {
    for (const OutputFile& f : files) {
      const fs::path target(f.path);
      const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
      // the name is cut where the temporary name would be longer than a file name may be (255
      // bytes): a program whose own name is legal is written (the pid and counter keep it unique)
      const std::string suffix = "." + std::to_string(::getpid()) + "." + std::to_string(counter.fetch_add(1)) + ".accura-tmp";
      std::string name = target.filename().string();
      if (1 + name.size() + suffix.size() > kNameMax) name.resize(kNameMax - 1 - suffix.size());
      const std::string tmp = (dir / ("." + name + suffix)).string();
      const int slot = acquireSlot(tmp);
      slots.push_back(slot);
      temps.push_back(tmp);
      const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
      g_slots[slot].state.store(kWriting);
      writeOpened(fd, f, true);
    }
  } catch (...) {
    cleanup();
    throw;
  }
  // commit: all written; rename them together
  for (int s : slots) g_slots[s].state.store(kCommitting);
  if (exitRequested()) {
    cleanup();
    exitInterrupted();
  }
  for (size_t i = 0; i < files.size(); ++i) {
    if (::rename(temps[i].c_str(), files[i].path.c_str()) != 0) {
      // a directory where the file goes (simulate --out DIR): said as refuseUnwritableOutputs says it
      const std::string why = errno == EISDIR ? std::string("it is a directory")
                                              : std::string("cannot rename the temporary file into place: ") + std::strerror(errno);
      for (size_t j = i; j < files.size(); ++j) ::unlink(temps[j].c_str());
      for (int s : slots) releaseSlot(s);
      throw InputError(files[i].path, 0, 0, "cannot write file: " + why);
    }
  }
  for (int s : slots) releaseSlot(s);
  if (exitRequested()) exitInterrupted();
}

void createDirectories(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir + ": cannot create the directory: " + ec.message());
}

std::string notAFileProblem(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) return ec.message();
  if (fs::is_regular_file(st)) return "";
  return fs::is_directory(st) ? "it is a directory" : fs::exists(st) ? "not a regular file" : "no such file";
}

void writeFileAtomically(const std::string& path, const std::string& content) { writeFilesAtomically({{path, content}}); }

bool sameFile(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec)) return fs::equivalent(a, b, ec);
  const fs::path pa = fs::weakly_canonical(fs::absolute(a, ec), ec), pb = fs::weakly_canonical(fs::absolute(b, ec), ec);
  return !ec && pa == pb;
}

void refuseToOverwrite(const std::vector<OutputFile>& outputs, const std::vector<std::string>& inputs, const std::string& out_name) {
  for (const auto& in : inputs)
    for (const auto& f : outputs)
      if (!in.empty() && sameFile(f.path, in))
        throw InputError(f.path + ": the output would overwrite the input " + in + ": choose another " + out_name);
}

std::string directoryWriteProblem(const std::string& dir_or_empty) {
  const std::string dir = dir_or_empty.empty() ? std::string(".") : dir_or_empty;
  std::error_code ec;
  if (!fs::exists(dir, ec)) return "the directory " + dir + " does not exist";
  if (!fs::is_directory(dir, ec)) return dir + " is not a directory";
  if (::access(dir.c_str(), W_OK | X_OK) != 0) return "the directory " + dir + " is not writable (" + std::strerror(errno) + ")";
  return "";
}

void refuseUnwritableOutputs(const std::vector<std::string>& outputs, const std::vector<std::string>& inputs,
                             const std::string& out_name) {
  std::vector<OutputFile> named;
  for (const std::string& path : outputs) {
    if (path.empty()) continue;
    named.push_back({path, ""});
    if (streamTarget(path) != -1) continue;  // (a stream is written into, not replaced: no directory of its own)
    std::error_code ec;
    if (fs::is_directory(path, ec)) throw InputError(path, 0, 0, "cannot write file: it is a directory");
    const std::string problem = directoryWriteProblem(fs::path(path).parent_path().string());
    if (!problem.empty()) throw InputError(path, 0, 0, "cannot write file: " + problem);
  }
  refuseToOverwrite(named, inputs, out_name);
}

}  // namespace accura::calib
