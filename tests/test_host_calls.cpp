// What every host call does around its work (postproc/session.h, "Host calls"): the handle
// lookup, exceptions -> status and the calling thread's last error, the argument checks; and
// the one list formatter (calib/text.h). The plug-in's C functions are these calls
// (test_plugin*.cpp test them through the C interface).
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <new>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "accura/calib/errors.h"
#include "accura/calib/text.h"
#include "accura/postproc/session.h"

using namespace accura;
using namespace accura::postproc;

namespace {

std::string lastError(const SessionRegistry& r, std::uintptr_t key, CallStatus expected = CallStatus::kOk) {
  const char* m = nullptr;
  EXPECT_EQ(r.lastError(key, &m), expected);
  return m ? m : "(null)";
}

}  // namespace

TEST(HostCalls, IkStatusesAreTheCallStatusesOfTheSameName) {
  EXPECT_EQ(callStatus(calib::IkStatus::kOk), CallStatus::kOk);
  EXPECT_EQ(callStatus(calib::IkStatus::kUnreachable), CallStatus::kUnreachable);
  EXPECT_EQ(callStatus(calib::IkStatus::kJointLimits), CallStatus::kJointLimits);
  EXPECT_EQ(callStatus(calib::IkStatus::kSingular), CallStatus::kSingular);
  EXPECT_EQ(callStatus(calib::IkStatus::kNoConfiguration), CallStatus::kNoConfiguration);
  EXPECT_EQ(callStatus(calib::IkStatus::kNotConverged), CallStatus::kNotConverged);
  // the plug-in's accura_status values (accura_plugin.h)
  EXPECT_EQ(static_cast<int>(CallStatus::kInput), 4);
  EXPECT_EQ(static_cast<int>(CallStatus::kNotConverged), 9);
  EXPECT_EQ(static_cast<int>(CallStatus::kInternal), 12);
}

TEST(HostCalls, EachExceptionBecomesItsStatusAndTheCallersMessage) {
  SessionRegistry r;
  const std::uintptr_t key = r.create();
  EXPECT_NE(key, 0u);
  EXPECT_EQ(key % 16, 0u);
  EXPECT_EQ(lastError(r, key), "");
  const auto on = [&](auto thrower) { return r.runOn(key, "f", [&](SessionRegistry::Slot&) { thrower(); }); };
  EXPECT_EQ(on([] {}), CallStatus::kOk);
  EXPECT_EQ(on([] { throw calib::InputError("a.src", 3, 7, "expected END, found x"); }), CallStatus::kInput);
  EXPECT_EQ(lastError(r, key), "f: a.src:3:7: expected END, found x");
  EXPECT_EQ(on([] { throw calib::ArgumentError("tol_mm: expected > 0"); }), CallStatus::kInvalidArgument);
  EXPECT_EQ(lastError(r, key), "f: tol_mm: expected > 0");
  EXPECT_EQ(on([] { throw calib::NumericalError("collinear"); }), CallStatus::kNumerical);
  EXPECT_EQ(on([] { throw std::bad_alloc(); }), CallStatus::kOutOfMemory);
  EXPECT_EQ(lastError(r, key), "f: out of memory");
  EXPECT_EQ(on([] { throw std::logic_error("bug"); }), CallStatus::kInternal);
  EXPECT_EQ(lastError(r, key), "f: internal error: bug");
  EXPECT_EQ(on([] { throw 42; }), CallStatus::kInternal);
  EXPECT_EQ(lastError(r, key), "f: internal error: unknown exception");
  EXPECT_EQ(on([] { throw CallError(CallStatus::kSingular, "near A5 = 0"); }), CallStatus::kSingular);
  EXPECT_EQ(lastError(r, key), "f: near A5 = 0");
  // a success keeps the last error
  EXPECT_EQ(on([] {}), CallStatus::kOk);
  EXPECT_EQ(lastError(r, key), "f: near A5 = 0");
  // a call on the handle without a model; its pointers first
  const int x = 0;
  EXPECT_EQ(r.withSession(key, "g", {{&x, "a"}, {nullptr, "b"}}, [](const Session&) {}), CallStatus::kNullArgument);
  EXPECT_EQ(lastError(r, key), "g: b is NULL");
  EXPECT_EQ(r.withSession(key, "g", {{&x, "a"}}, [](const Session&) {}), CallStatus::kInvalidArgument);
  EXPECT_EQ(lastError(r, key), "g: no model loaded on this handle (call accura_model_load first)");
  r.release(key);
}

TEST(HostCalls, CallsWithoutALiveHandleKeepTheirMessagePerThread) {
  SessionRegistry r;
  EXPECT_EQ(r.runOn(0, "h", [](SessionRegistry::Slot&) {}), CallStatus::kNullArgument);
  EXPECT_EQ(lastError(r, 0), "h: model is NULL");
  const std::uintptr_t key = r.create();
  r.release(key);
  bool ran = false;
  EXPECT_EQ(r.runOn(key, "h", [&](SessionRegistry::Slot&) { ran = true; }), CallStatus::kInvalidArgument);
  EXPECT_FALSE(ran);
  const std::string dead = "h: not a live handle (freed by accura_model_free, or not made by accura_model_create)";
  EXPECT_EQ(lastError(r, key, CallStatus::kInvalidArgument), dead);
  EXPECT_EQ(lastError(r, 0), dead);
  EXPECT_EQ(SessionRegistry::run("free", [&] { r.release(key); }), CallStatus::kInvalidArgument);  // twice
  EXPECT_EQ(SessionRegistry::run("free", [&] { r.release(0); }), CallStatus::kOk);
  EXPECT_EQ(lastError(r, 0), "free: not a live handle (freed by accura_model_free, or not made by accura_model_create)");
  // another thread has its own
  std::string other;
  std::thread([&] { other = lastError(r, 0); }).join();
  EXPECT_EQ(other, "");
}

TEST(HostCalls, ArgumentChecksSayWhatWasExpectedAndFound) {
  const auto status = [](auto f) { return SessionRegistry::run("c", f); };
  const char* m = nullptr;
  EXPECT_EQ(status([] { requireCapacity(7, 7, "x"); }), CallStatus::kOk);
  EXPECT_EQ(status([] { requireCapacity(8, 7, "the path has 8 points"); }), CallStatus::kBufferTooSmall);
  SessionRegistry::instance().lastError(0, &m);
  EXPECT_STREQ(m, "c: the path has 8 points, the buffer holds 7");
  EXPECT_EQ(status([] { checkedInt(-1, false, "which", "0 or 1"); }), CallStatus::kInvalidArgument);
  SessionRegistry::instance().lastError(0, &m);
  EXPECT_STREQ(m, "c: which: expected 0 or 1, found -1");
  EXPECT_EQ(checkedInt(1, true, "which", "0 or 1"), 1);
  const int x = 0;
  EXPECT_NE(ifAny(0, nullptr), nullptr);  // an empty array may be NULL
  EXPECT_EQ(ifAny(2, &x), &x);
  EXPECT_EQ(ifAny(2, nullptr), nullptr);
}

TEST(HostCalls, OneListFormatterForJointValues) {
  EXPECT_EQ(calib::formatList(std::vector<double>{1.2345, -0.0001, 90}, 2), "{1.23, 0.00, 90.00}");
  Eigen::VectorXd q(3);
  q << -10.5, 0, 179.9996;
  EXPECT_EQ(calib::formatList(q, 3), "{-10.500, 0.000, 180.000}");
  EXPECT_EQ(calib::formatList(std::vector<double>{}, 3), "{}");
}
