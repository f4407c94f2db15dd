// A GoogleTest fixture for tests that run MuJoCo: any MuJoCo warning fails the test, and a MuJoCo error (after
// which MuJoCo cannot continue) stops the test program with the message instead of MuJoCo's silent exit.
//
// MuJoCo's handlers are process-wide; GoogleTest runs the tests of one program on one thread, one at a time.
#pragma once

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace cellwright::testing {

class MujocoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    warnings().clear();
    mju_user_warning = &on_warning;
    mju_user_error = &on_error;
  }

  void TearDown() override {
    for (const std::string& w : warnings()) ADD_FAILURE() << "MuJoCo warning: " << w;
    mju_user_warning = nullptr;
    mju_user_error = nullptr;
  }

  // Fails the test if MuJoCo flagged a problem in this simulation (too many contacts, bad numbers, ...): those are
  // counted in mjData and reported through the warning handler only the first time.
  static void expect_no_data_warnings(const mjData* d) {
    for (int i = 0; i < mjNWARNING; ++i) {
      EXPECT_EQ(d->warning[i].number, 0) << "MuJoCo warning " << i << " raised " << d->warning[i].number
                                         << " times (last info " << d->warning[i].lastinfo << ")";
    }
  }

  static std::vector<std::string>& warnings() {
    static std::vector<std::string> w;
    return w;
  }

 private:
  static void on_warning(const char* msg) { warnings().emplace_back(msg); }
  [[noreturn]] static void on_error(const char* msg) {
    std::fprintf(stderr, "MuJoCo error (cannot continue): %s\n", msg);
    std::abort();
  }
};

}  // namespace cellwright::testing
