// The plug-in under misuse (issue 14: "nothing a CAD host can crash on"): NULL pointers on every
// entry point, wrong struct sizes and counts, handles used after accura_model_free (or never
// made), and calls from several threads on separate handles and on one handle that another
// thread frees. Each misuse must give its status and a message naming what was wrong, never a
// crash; the sanitizer build (scripts/sanitize.sh) runs these tests under AddressSanitizer and
// UndefinedBehaviorSanitizer, so that a read of freed memory or a data race on the handle
// registry is a failure too.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>

#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "accura_plugin.h"
#include "test_util.h"

namespace accura {
namespace {

const std::string kModel = "tests/data/plugin/kr16_calibrated.xml";

/// The message accura_last_error gives for `m` on this thread (NULL: the calls without a live
/// handle), and the status it returned.
std::string messageOf(const accura_model* m, accura_status* status = nullptr) {
  const char* msg = nullptr;
  const accura_status s = accura_last_error(m, &msg);
  if (status) *status = s;
  return msg ? msg : "(null)";
}

accura_model* loaded() {
  accura_model* m = nullptr;
  EXPECT_EQ(accura_model_create(&m), ACCURA_OK);
  EXPECT_EQ(accura_model_load(m, test::sourcePath(kModel).c_str(), nullptr), ACCURA_OK) << messageOf(m);
  return m;
}

/// Valid arguments for every entry point (the misuse is in the one argument a test changes).
struct Args {
  const accura_pose p = {1100, -250, 500, 0, 180, 0};
  accura_pose_result r{};
  accura_pose out{};
  const double q[6] = {0, -90, 90, 0, 0, 0};
  accura_path_result pr{};
  accura_path_motion lin = {ACCURA_LIN, {}, {1100, -50, 500, 0, 180, 0}};
  accura_check_summary cs{};
  accura_model_info info{};
  accura_write_options wo = [] {
    accura_write_options o;
    EXPECT_EQ(accura_write_options_init(&o, sizeof(o)), ACCURA_OK);
    return o;
  }();
  const accura_program_motion pm = {ACCURA_PTP, {}, p, 0, 0, 0, {}};
  size_t n = 0;
};

/// Expects `status` from a call on `m` and a message of the calling thread holding `what`.
#define EXPECT_MISUSE(m, call, status, what)                                             \
  do {                                                                                   \
    EXPECT_EQ((call), (status)) << #call;                                                \
    EXPECT_NE(messageOf(m).find(what), std::string::npos) << #call << ": " << messageOf(m); \
  } while (0)

// Every entry point with each required pointer NULL: ACCURA_ERROR_NULL_ARGUMENT and a message
// naming the parameter; nothing is written through the other pointers.
TEST(PluginMisuse, NullPointersOnEveryEntryPoint) {
  accura_model* m = loaded();
  Args a;

  // without a handle: the message of the calling thread through accura_last_error(NULL)
  EXPECT_MISUSE(nullptr, accura_model_create(nullptr), ACCURA_ERROR_NULL_ARGUMENT, "model_out is NULL");
  EXPECT_MISUSE(nullptr, accura_status_name(ACCURA_OK, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "name_out is NULL");
  EXPECT_MISUSE(nullptr, accura_load_options_init(nullptr, sizeof(accura_load_options)), ACCURA_ERROR_NULL_ARGUMENT, "options is NULL");
  EXPECT_MISUSE(nullptr, accura_program_options_init(nullptr, sizeof(accura_program_options)), ACCURA_ERROR_NULL_ARGUMENT,
                "accura_program_options_init: options is NULL");
  EXPECT_MISUSE(nullptr, accura_check_options_init(nullptr, sizeof(accura_check_options)), ACCURA_ERROR_NULL_ARGUMENT,
                "accura_check_options_init: options is NULL");
  EXPECT_MISUSE(nullptr, accura_write_options_init(nullptr, sizeof(accura_write_options)), ACCURA_ERROR_NULL_ARGUMENT,
                "accura_write_options_init: options is NULL");
  EXPECT_EQ(accura_last_error(m, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_last_error(nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT);
  EXPECT_EQ(accura_version(nullptr, nullptr, nullptr, nullptr), ACCURA_OK);  // every output optional
  EXPECT_EQ(accura_model_free(nullptr), ACCURA_OK);                           // free(NULL) does nothing

  // the handle NULL, on every call that takes one
  EXPECT_MISUSE(nullptr, accura_model_load(nullptr, "kuka_kr16", nullptr), ACCURA_ERROR_NULL_ARGUMENT, "accura_model_load: model is NULL");
  EXPECT_MISUSE(nullptr, accura_model_get_info(nullptr, &a.info), ACCURA_ERROR_NULL_ARGUMENT, "accura_model_get_info: model is NULL");
  EXPECT_MISUSE(nullptr, accura_model_get_joints(nullptr, nullptr, 0, &a.n), ACCURA_ERROR_NULL_ARGUMENT, "model is NULL");
  EXPECT_MISUSE(nullptr, accura_forward_kinematics(nullptr, ACCURA_REAL, a.q, 6, &a.out), ACCURA_ERROR_NULL_ARGUMENT, "model is NULL");
  EXPECT_MISUSE(nullptr, accura_compensate_pose(nullptr, &a.p, nullptr, &a.r), ACCURA_ERROR_NULL_ARGUMENT, "model is NULL");
  EXPECT_MISUSE(nullptr, accura_compensate_poses(nullptr, &a.p, nullptr, 1, 0, &a.r, &a.n), ACCURA_ERROR_NULL_ARGUMENT, "model is NULL");
  EXPECT_MISUSE(nullptr, accura_compensate_path(nullptr, &a.p, nullptr, &a.lin, 1, 0.05, nullptr, 0, &a.pr, nullptr),
                ACCURA_ERROR_NULL_ARGUMENT, "accura_compensate_path: model is NULL");
  EXPECT_MISUSE(nullptr, accura_compensate_program(nullptr, "a.src", "out", nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "model is NULL");
  EXPECT_MISUSE(nullptr, accura_check_program(nullptr, "c.xml", "a.src", nullptr, &a.cs, nullptr, 0), ACCURA_ERROR_NULL_ARGUMENT,
                "model is NULL");
  EXPECT_MISUSE(nullptr, accura_write_program(nullptr, "a.src", &a.pm, 1, &a.wo), ACCURA_ERROR_NULL_ARGUMENT, "model is NULL");
  EXPECT_MISUSE(nullptr, accura_write_file(nullptr, "a.txt", "x", 1), ACCURA_ERROR_NULL_ARGUMENT, "accura_write_file: model is NULL");

  // each other required pointer NULL: the message in the handle names it
  EXPECT_MISUSE(m, accura_model_load(m, nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "calibrated_model is NULL");
  EXPECT_MISUSE(m, accura_model_get_info(m, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "info is NULL");
  EXPECT_MISUSE(m, accura_model_get_joints(m, nullptr, 6, &a.n), ACCURA_ERROR_NULL_ARGUMENT, "joints is NULL");
  EXPECT_MISUSE(m, accura_forward_kinematics(m, ACCURA_REAL, nullptr, 6, &a.out), ACCURA_ERROR_NULL_ARGUMENT, "q is NULL");
  EXPECT_MISUSE(m, accura_forward_kinematics(m, ACCURA_REAL, a.q, 6, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "pose_out is NULL");
  EXPECT_MISUSE(m, accura_compensate_pose(m, nullptr, nullptr, &a.r), ACCURA_ERROR_NULL_ARGUMENT, "target is NULL");
  EXPECT_MISUSE(m, accura_compensate_pose(m, &a.p, nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "result is NULL");
  EXPECT_MISUSE(m, accura_compensate_poses(m, nullptr, nullptr, 1, 0, &a.r, &a.n), ACCURA_ERROR_NULL_ARGUMENT, "targets is NULL");
  EXPECT_MISUSE(m, accura_compensate_poses(m, &a.p, nullptr, 1, 0, nullptr, &a.n), ACCURA_ERROR_NULL_ARGUMENT, "results is NULL");
  EXPECT_MISUSE(m, accura_compensate_path(m, nullptr, nullptr, &a.lin, 1, 0.05, nullptr, 0, &a.pr, nullptr), ACCURA_ERROR_NULL_ARGUMENT,
                "start is NULL");
  EXPECT_MISUSE(m, accura_compensate_path(m, &a.p, nullptr, &a.lin, 1, 0.05, nullptr, 0, nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT,
                "result is NULL");
  EXPECT_MISUSE(m, accura_compensate_path(m, &a.p, nullptr, nullptr, 1, 0.05, nullptr, 0, &a.pr, nullptr), ACCURA_ERROR_NULL_ARGUMENT,
                "motions is NULL");
  EXPECT_MISUSE(m, accura_compensate_path(m, &a.p, nullptr, &a.lin, 1, 0.05, nullptr, 4, &a.pr, nullptr), ACCURA_ERROR_NULL_ARGUMENT,
                "points is NULL");
  EXPECT_MISUSE(m, accura_compensate_program(m, nullptr, "out", nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "program_path is NULL");
  EXPECT_MISUSE(m, accura_compensate_program(m, "a.src", nullptr, nullptr, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "out_dir is NULL");
  EXPECT_MISUSE(m, accura_check_program(m, nullptr, "a.src", nullptr, &a.cs, nullptr, 0), ACCURA_ERROR_NULL_ARGUMENT, "cell_path is NULL");
  EXPECT_MISUSE(m, accura_check_program(m, "c.xml", nullptr, nullptr, &a.cs, nullptr, 0), ACCURA_ERROR_NULL_ARGUMENT,
                "program_path is NULL");
  EXPECT_MISUSE(m, accura_check_program(m, "c.xml", "a.src", nullptr, nullptr, nullptr, 0), ACCURA_ERROR_NULL_ARGUMENT,
                "summary is NULL");
  EXPECT_MISUSE(m, accura_check_program(m, "c.xml", "a.src", nullptr, &a.cs, nullptr, 3), ACCURA_ERROR_NULL_ARGUMENT, "violations is NULL");
  EXPECT_MISUSE(m, accura_write_program(m, nullptr, &a.pm, 1, &a.wo), ACCURA_ERROR_NULL_ARGUMENT, "path is NULL");
  EXPECT_MISUSE(m, accura_write_program(m, "a.src", nullptr, 1, &a.wo), ACCURA_ERROR_NULL_ARGUMENT, "motions is NULL");
  EXPECT_MISUSE(m, accura_write_program(m, "a.src", &a.pm, 1, nullptr), ACCURA_ERROR_NULL_ARGUMENT, "options is NULL");
  EXPECT_MISUSE(m, accura_write_file(m, nullptr, "x", 1), ACCURA_ERROR_NULL_ARGUMENT, "path is NULL");
  EXPECT_MISUSE(m, accura_write_file(m, "a.txt", nullptr, 1), ACCURA_ERROR_NULL_ARGUMENT, "data is NULL");
  // NULL with a count of 0 is no misuse: nothing to read (a pose list of none, an empty path)
  EXPECT_EQ(accura_compensate_poses(m, nullptr, nullptr, 0, 0, nullptr, &a.n), ACCURA_OK);
  EXPECT_EQ(a.n, 0u);
  EXPECT_EQ(accura_model_free(m), ACCURA_OK);
}

// Wrong struct sizes (a header of another version), wrong counts and buffers that are too small.
TEST(PluginMisuse, WrongSizes) {
  accura_model* m = loaded();
  // the *_options_init calls: the caller's sizeof must be the library's
  accura_load_options lo;
  accura_program_options po;
  accura_check_options co;
  accura_write_options wo;
  EXPECT_MISUSE(nullptr, accura_load_options_init(&lo, sizeof(lo) + 8), ACCURA_ERROR_INVALID_ARGUMENT,
                "struct_size " + std::to_string(sizeof(lo) + 8) + ", expected " + std::to_string(sizeof(lo)));
  EXPECT_MISUSE(nullptr, accura_program_options_init(&po, sizeof(po) - 8), ACCURA_ERROR_INVALID_ARGUMENT, "accura_program_options_init");
  EXPECT_MISUSE(nullptr, accura_check_options_init(&co, 0), ACCURA_ERROR_INVALID_ARGUMENT, "struct_size 0");
  EXPECT_MISUSE(nullptr, accura_write_options_init(&wo, 1), ACCURA_ERROR_INVALID_ARGUMENT, "struct_size 1");
  // options filled by a header of another version: struct_size disagrees
  ASSERT_EQ(accura_load_options_init(&lo, sizeof(lo)), ACCURA_OK);
  ASSERT_EQ(accura_program_options_init(&po, sizeof(po)), ACCURA_OK);
  ASSERT_EQ(accura_check_options_init(&co, sizeof(co)), ACCURA_OK);
  ASSERT_EQ(accura_write_options_init(&wo, sizeof(wo)), ACCURA_OK);
  lo.struct_size = po.struct_size = co.struct_size = wo.struct_size = 16;
  EXPECT_MISUSE(m, accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT, "accura_load_options: struct_size 16");
  EXPECT_MISUSE(m, accura_compensate_program(m, "a.src", "out", &po, nullptr), ACCURA_ERROR_INVALID_ARGUMENT,
                "accura_program_options: struct_size 16");
  accura_check_summary cs;
  EXPECT_MISUSE(m, accura_check_program(m, "c.xml", "a.src", &co, &cs, nullptr, 0), ACCURA_ERROR_INVALID_ARGUMENT,
                "accura_check_options: struct_size 16");
  const accura_program_motion pm = {ACCURA_PTP, {}, {1100, 0, 500, 0, 180, 0}, 0, 0, 0, {}};
  EXPECT_MISUSE(m, accura_write_program(m, "a.src", &pm, 1, &wo), ACCURA_ERROR_INVALID_ARGUMENT, "accura_write_options: struct_size 16");
  // the joint count of forward kinematics: the KR 16 has 6 (q holds 12, so nothing is read beyond)
  const double q[12] = {0, -90, 90, 0, 0, 0};
  accura_pose out;
  for (size_t n : {size_t(0), size_t(5), size_t(7), size_t(12)})
    EXPECT_MISUSE(m, accura_forward_kinematics(m, ACCURA_REAL, q, n, &out), ACCURA_ERROR_INVALID_ARGUMENT,
                  "expected 6 joint values, got " + std::to_string(n));
  // an enum value outside its range
  EXPECT_MISUSE(m, accura_forward_kinematics(m, static_cast<accura_which_model>(-1), q, 6, &out), ACCURA_ERROR_INVALID_ARGUMENT,
                "expected ACCURA_CONTROLLER (0) or ACCURA_REAL (1), found -1");
  // buffers too small: the count needed comes back, nothing is written beyond the capacity
  accura_joint joints[3];
  size_t n_joints = 0;
  EXPECT_MISUSE(m, accura_model_get_joints(m, joints, 3, &n_joints), ACCURA_ERROR_BUFFER_TOO_SMALL, "the robot has 6 joints, the buffer holds 3");
  EXPECT_EQ(n_joints, 6u);
  const accura_pose start = {1260, -250, 500, 0, 180, 0};
  const accura_path_motion lin = {ACCURA_LIN, {}, {1000, 1000, 700, 40, 120, -20}};
  accura_path_result pr;
  accura_path_point one[1];
  std::memset(one, 0x5a, sizeof one);
  const accura_status s = accura_compensate_path(m, &start, nullptr, &lin, 1, 0.05, one, 1, &pr, nullptr);
  EXPECT_EQ(s, ACCURA_ERROR_BUFFER_TOO_SMALL) << messageOf(m);
  EXPECT_GT(pr.n_points, 1u);  // a 1.4 m LIN with a 0.05 mm tolerance needs auxiliary points
  EXPECT_NE(messageOf(m).find("the path has " + std::to_string(pr.n_points) + " points, the buffer holds 1"), std::string::npos);
  std::vector<accura_path_point> all(pr.n_points);
  EXPECT_EQ(accura_compensate_path(m, &start, nullptr, &lin, 1, 0.05, all.data(), all.size(), &pr, nullptr), ACCURA_OK) << messageOf(m);
  EXPECT_EQ(accura_model_free(m), ACCURA_OK);
}

// A handle used after accura_model_free, freed twice, or never made: ACCURA_ERROR_INVALID_ARGUMENT
// with a message, on every entry point, and no read through the pointer (AddressSanitizer would
// report one).
// Options beyond what the command line accepts are refused with the field named, not taken
// (before: a payload of 1e300 kg or a $ROBROOT at x = 1e300 loaded, and the calls that followed
// returned nonsense as ACCURA_OK); a path tolerance below 0.001 mm is refused at the call.
TEST(PluginMisuse, OptionsOutOfRangeAreRefused) {
  accura_model* m = loaded();
  accura_load_options lo;
  auto reset = [&] { ASSERT_EQ(accura_load_options_init(&lo, sizeof(lo)), ACCURA_OK); };
  reset();
  lo.payload_kg = 1e6;
  EXPECT_MISUSE(m, accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT,
                "accura_model_load: payload_kg: expected a finite mass in [0, 10000] kg, found 1000000.000");
  reset();
  lo.temp_c = -1000;
  EXPECT_MISUSE(m, accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT,
                "accura_model_load: temp_c: expected a finite temperature in [-50, 150] deg C, found -1000.000");
  // NaN and infinities: the field and the value named (before: "formatFixed: not a finite number")
  for (const double v : {std::nan(""), HUGE_VAL, -HUGE_VAL}) {
    const std::string shown = std::isnan(v) ? "nan" : v > 0 ? "inf" : "-inf";
    reset();
    lo.payload_kg = v;
    EXPECT_EQ(accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(messageOf(m), "accura_model_load: payload_kg: expected a finite mass in [0, 10000] kg, found " + shown);
    reset();
    lo.temp_c = v;
    EXPECT_EQ(accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(messageOf(m), "accura_model_load: temp_c: expected a finite temperature in [-50, 150] deg C, found " + shown);
  }
  reset();
  lo.has_robroot_in_kukaworld = 1;
  lo.robroot_in_kukaworld = {1e300, 0, 0, 0, 0, 0};
  EXPECT_MISUSE(m, accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT, "expected x, y, z within +-100000 mm");
  reset();
  lo.has_program_tool = 1;
  lo.program_tool = {0, 0, 100, 0, 400, 0};
  EXPECT_MISUSE(m, accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT, "expected A, B, C within +-360 deg");
  // the handle keeps the model it had, and its limits hold at the boundaries
  reset();
  lo.payload_kg = 10000;
  lo.temp_c = 150;
  EXPECT_EQ(accura_model_load(m, "kuka_kr16", &lo), ACCURA_OK) << messageOf(m);
  Args a;
  EXPECT_MISUSE(m, accura_compensate_path(m, &a.p, nullptr, &a.lin, 1, 1e-9, nullptr, 0, &a.pr, nullptr), ACCURA_ERROR_INVALID_ARGUMENT,
                "tol_mm: expected a path tolerance in [0.001, 100] mm, found 1e-09");
  // accura_write_program: a program name that is not an identifier (it becomes the DEF line:
  // a newline in it wrote a second program that moved A1), from the option or the file's name,
  // and absurd numbers are refused; nothing is written
  const std::string dir = test::tempDir("plugin_write_names");
  a.wo.program_name = "weld()\nPTP {A1 90}\nEND\nDEF weld2";
  EXPECT_MISUSE(m, accura_write_program(m, (dir + "/weld.src").c_str(), &a.pm, 1, &a.wo), ACCURA_ERROR_INVALID_ARGUMENT,
                "program_name: expected a program name");
  a.wo.program_name = nullptr;
  for (const char* file : {"/123.src", "/my prog-1.src"})
    EXPECT_MISUSE(m, accura_write_program(m, (dir + file).c_str(), &a.pm, 1, &a.wo), ACCURA_ERROR_INVALID_ARGUMENT,
                  "the file's name: expected a program name");
  accura_program_motion far = a.pm;
  far.end.x_mm = 1e300;
  EXPECT_MISUSE(m, accura_write_program(m, (dir + "/far.src").c_str(), &far, 1, &a.wo), ACCURA_ERROR_INVALID_ARGUMENT,
                "expected x, y, z within +-100000 mm");
  accura_program_motion fast = a.pm;
  fast.type = ACCURA_LIN;
  fast.vel_m_s = 1e300;
  EXPECT_MISUSE(m, accura_write_program(m, (dir + "/fast.src").c_str(), &fast, 1, &a.wo), ACCURA_ERROR_INVALID_ARGUMENT,
                "vel_m_s: expected a path speed up to 10 m/s");
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  // a count too large to hold (SIZE_MAX: out of memory, as 2^40 is) and an empty output directory
  EXPECT_MISUSE(m, accura_compensate_poses(m, &a.p, nullptr, SIZE_MAX, 0, &a.r, &a.n), ACCURA_ERROR_OUT_OF_MEMORY,
                "out of memory (a count too large to hold)");
  EXPECT_MISUSE(m, accura_compensate_path(m, &a.p, nullptr, &a.lin, SIZE_MAX, 0.05, nullptr, 0, &a.pr, nullptr),
                ACCURA_ERROR_OUT_OF_MEMORY, "out of memory");
  EXPECT_MISUSE(m, accura_compensate_program(m, "a.src", "", nullptr, nullptr), ACCURA_ERROR_INVALID_ARGUMENT,
                "out_dir: expected an output directory, found an empty string");
  accura_model_free(m);
}

TEST(PluginMisuse, HandlesUsedAfterFreeAreDetected) {
  accura_model* m = loaded();
  ASSERT_EQ(accura_model_free(m), ACCURA_OK);
  // a pointer the library never made: a 4-byte heap block (reading a handle there would be a
  // heap-buffer-overflow under AddressSanitizer)
  const auto block = std::make_unique<int>(7);
  accura_model* never_made = reinterpret_cast<accura_model*>(block.get());
  for (accura_model* bad : {m, never_made}) {
    Args a;
    const std::string live = "not a live handle";
    EXPECT_MISUSE(nullptr, accura_model_load(bad, "kuka_kr16", nullptr), ACCURA_ERROR_INVALID_ARGUMENT, "accura_model_load: " + live);
    EXPECT_MISUSE(nullptr, accura_model_get_info(bad, &a.info), ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_model_get_joints(bad, nullptr, 0, &a.n), ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_forward_kinematics(bad, ACCURA_REAL, a.q, 6, &a.out), ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_compensate_pose(bad, &a.p, nullptr, &a.r), ACCURA_ERROR_INVALID_ARGUMENT, "accura_compensate_pose: " + live);
    EXPECT_MISUSE(nullptr, accura_compensate_poses(bad, &a.p, nullptr, 1, 0, &a.r, &a.n), ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_compensate_path(bad, &a.p, nullptr, nullptr, 0, 0.05, nullptr, 0, &a.pr, nullptr),
                  ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_compensate_program(bad, "a.src", "out", nullptr, nullptr), ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_check_program(bad, "c.xml", "a.src", nullptr, &a.cs, nullptr, 0), ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_write_program(bad, "a.src", &a.pm, 1, &a.wo), ACCURA_ERROR_INVALID_ARGUMENT, live);
    EXPECT_MISUSE(nullptr, accura_write_file(bad, "a.txt", "x", 1), ACCURA_ERROR_INVALID_ARGUMENT, "accura_write_file: " + live);
    // the handle's own last error: the same message, and the status says the handle is not live
    accura_status s = ACCURA_OK;
    EXPECT_NE(messageOf(bad, &s).find("accura_write_file: " + live), std::string::npos) << messageOf(bad);
    EXPECT_EQ(s, ACCURA_ERROR_INVALID_ARGUMENT);
    // freed twice (or a pointer never made): refused, not a double free
    EXPECT_MISUSE(nullptr, accura_model_free(bad), ACCURA_ERROR_INVALID_ARGUMENT, "accura_model_free: " + live);
  }
  // keys are never reused: 64 handles made and freed, then 64 more, all different; a handle
  // freed earlier stays dead although new ones exist
  std::set<std::uintptr_t> seen = {reinterpret_cast<std::uintptr_t>(m)};
  for (int round = 0; round < 2; ++round) {
    std::vector<accura_model*> hs(64);
    for (auto& h : hs) {
      ASSERT_EQ(accura_model_create(&h), ACCURA_OK);
      EXPECT_TRUE(seen.insert(reinterpret_cast<std::uintptr_t>(h)).second);
    }
    accura_model_info info;
    EXPECT_EQ(accura_model_get_info(m, &info), ACCURA_ERROR_INVALID_ARGUMENT);
    for (auto* h : hs) EXPECT_EQ(accura_model_free(h), ACCURA_OK);
  }
  EXPECT_EQ(seen.size(), 129u);
}

// Several threads, each with its own handle: the same results as one thread alone, each
// thread's messages its own.
TEST(PluginMisuse, SeparateHandlesOnSeveralThreads) {
  accura_model* ref = loaded();
  const accura_pose t = {1100, -250, 500, 0, 180, 0};
  accura_pose_result expected;
  ASSERT_EQ(accura_compensate_pose(ref, &t, nullptr, &expected), ACCURA_OK);
  ASSERT_EQ(accura_model_free(ref), ACCURA_OK);
  constexpr int kThreads = 4;
  std::atomic<int> wrong{0};
  std::vector<std::thread> threads;
  for (int k = 0; k < kThreads; ++k) {
    threads.emplace_back([&, k]() {
      for (int round = 0; round < 3; ++round) {
        accura_model* m = nullptr;
        if (accura_model_create(&m) != ACCURA_OK) ++wrong;
        if (accura_model_load(m, test::sourcePath(kModel).c_str(), nullptr) != ACCURA_OK) ++wrong;
        accura_pose_result r;
        if (accura_compensate_pose(m, &t, nullptr, &r) != ACCURA_OK || std::memcmp(&r, &expected, sizeof r) != 0) ++wrong;
        // a misuse of this thread's own, and its message on this thread only
        const double q[6] = {};
        accura_pose out;
        if (accura_forward_kinematics(m, ACCURA_REAL, q, static_cast<size_t>(k + 1), &out) != ACCURA_ERROR_INVALID_ARGUMENT) ++wrong;
        if (messageOf(m).find("got " + std::to_string(k + 1)) == std::string::npos) ++wrong;
        if (accura_model_free(m) != ACCURA_OK) ++wrong;
        if (accura_model_free(m) != ACCURA_ERROR_INVALID_ARGUMENT) ++wrong;  // the second free, detected
        if (messageOf(nullptr).find("accura_model_free: not a live handle") == std::string::npos) ++wrong;
      }
    });
  }
  for (auto& th : threads) th.join();
  EXPECT_EQ(wrong.load(), 0);
}

// One handle, several threads, and the main thread frees it while the others call: each call
// either runs on the model (ACCURA_OK, the reference result) or finds the handle gone
// (ACCURA_ERROR_INVALID_ARGUMENT with its message): no third outcome, no crash, no read of
// freed memory. Each thread calls until it sees the handle gone.
TEST(PluginMisuse, FreeWhileOtherThreadsCall) {
  accura_model* m = loaded();
  const accura_pose t = {1100, -250, 500, 0, 180, 0};
  accura_pose_result expected;
  ASSERT_EQ(accura_compensate_pose(m, &t, nullptr, &expected), ACCURA_OK);
  constexpr int kThreads = 4;
  std::atomic<int> running{0}, gone{0}, other{0};
  std::vector<std::thread> threads;
  for (int k = 0; k < kThreads; ++k) {
    threads.emplace_back([&]() {
      for (bool first = true;; first = false) {
        accura_pose_result r;
        const accura_status s = accura_compensate_pose(m, &t, nullptr, &r);
        if (first) ++running;
        if (s == ACCURA_ERROR_INVALID_ARGUMENT) {
          if (messageOf(nullptr).find("accura_compensate_pose: not a live handle") == std::string::npos) ++other;
          ++gone;
          return;
        }
        if (s != ACCURA_OK || std::memcmp(&r, &expected, sizeof r) != 0) ++other;
      }
    });
  }
  while (running.load() < kThreads) std::this_thread::yield();  // every thread has run a call
  EXPECT_EQ(accura_model_free(m), ACCURA_OK);
  for (auto& th : threads) th.join();
  EXPECT_EQ(other.load(), 0);
  EXPECT_EQ(gone.load(), kThreads);
  accura_pose_result r;
  EXPECT_EQ(accura_compensate_pose(m, &t, nullptr, &r), ACCURA_ERROR_INVALID_ARGUMENT);
}

// A value far out of range is named in a few characters: a target or frame at x = 1e300 was
// "found 1000000000000000052504760255204420248704468581108159...000.000" (305 characters in a
// host's error dialog), and a path speed beyond 10 m/s did not say what was found.
TEST(PluginMisuse, AnAbsurdValueIsNamedInAFewCharacters) {
  accura_model* m = loaded();
  Args a;
  accura_pose far = a.p;
  far.x_mm = 1e300;
  EXPECT_EQ(accura_compensate_pose(m, &far, nullptr, &a.r), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(messageOf(m), "accura_compensate_pose: target: expected x, y, z within +-100000 mm, found 1e+300");
  far = a.p;
  far.b_deg = -1e20;
  EXPECT_EQ(accura_compensate_pose(m, &far, nullptr, &a.r), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(messageOf(m), "accura_compensate_pose: target: expected A, B, C within +-360 deg, found -1e+20");
  far = a.p;
  far.y_mm = 100000.25;  // just beyond: its decimals are shown
  EXPECT_EQ(accura_compensate_pose(m, &far, nullptr, &a.r), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(messageOf(m), "accura_compensate_pose: target: expected x, y, z within +-100000 mm, found 100000.250");
  accura_load_options lo;
  ASSERT_EQ(accura_load_options_init(&lo, sizeof(lo)), ACCURA_OK);
  lo.payload_kg = 3e18;
  EXPECT_EQ(accura_model_load(m, "kuka_kr16", &lo), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(messageOf(m), "accura_model_load: payload_kg: expected a finite mass in [0, 10000] kg, found 3e+18");
  const std::string dir = test::tempDir("plugin_absurd");
  accura_program_motion fast = a.pm;
  fast.type = ACCURA_LIN;
  fast.vel_m_s = 12.5;
  EXPECT_EQ(accura_write_program(m, (dir + "/fast.src").c_str(), &fast, 1, &a.wo), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(messageOf(m), "accura_write_program: motions[0].vel_m_s: expected a path speed up to 10 m/s (0: not set), found 12.500");
  fast.vel_m_s = std::nan("");
  EXPECT_EQ(accura_write_program(m, (dir + "/fast.src").c_str(), &fast, 1, &a.wo), ACCURA_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(messageOf(m), "accura_write_program: motions[0].vel_m_s: expected a path speed up to 10 m/s (0: not set), found nan");
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  accura_model_free(m);
}

// A program that is a named pipe (a FIFO an OLP system left in its export folder):
// an XML program hung the host for good (the reader opened the pipe and waited for a writer;
// KRL, URScript and RAPID programs and the cell file were refused as "not a regular file"). Now
// an .xml program is refused the same way, at once. The test opens the pipe for writing after
// 2 s, which lets a reader that waits go on (it then read an empty file).
TEST(PluginMisuse, AProgramThatIsANamedPipeIsRefusedNotWaitedOn) {
  accura_model* m = loaded();
  const std::string dir = test::tempDir("plugin_fifo");
  const std::string fifo = dir + "/weld.xml";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  std::atomic<bool> done{false};
  std::thread unblock([&] {
    for (int i = 0; i < 20 && !done; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    while (!done) {  // a reader that waits on the pipe: let it go on
      const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
      if (fd >= 0) ::close(fd);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  accura_program_options po;
  ASSERT_EQ(accura_program_options_init(&po, sizeof(po)), ACCURA_OK);
  const accura_status compensated = accura_compensate_program(m, fifo.c_str(), (dir + "/out").c_str(), &po, nullptr);
  const std::string compensate_message = messageOf(m);
  accura_check_options co;
  ASSERT_EQ(accura_check_options_init(&co, sizeof(co)), ACCURA_OK);
  accura_check_summary cs{};
  const accura_status checked =
      accura_check_program(m, test::sourcePath("examples/cell/seam_cell.xml").c_str(), fifo.c_str(), &co, &cs, nullptr, 0);
  const std::string check_message = messageOf(m);
  done = true;
  unblock.join();
  EXPECT_EQ(compensated, ACCURA_ERROR_INPUT);
  EXPECT_EQ(compensate_message, "accura_compensate_program: " + fifo + ": cannot read the XML program: not a regular file");
  EXPECT_EQ(checked, ACCURA_ERROR_INPUT);
  EXPECT_EQ(check_message, "accura_check_program: " + fifo + ": cannot read the XML program: not a regular file");
  EXPECT_FALSE(std::filesystem::exists(dir + "/out/weld.xml"));
  accura_model_free(m);
}

}  // namespace
}  // namespace accura
