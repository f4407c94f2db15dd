#include "cellwright/common/error.hpp"

#include <gtest/gtest.h>

namespace cellwright {
namespace {

TEST(InputError, NamesFileLineColumnAndProblem) {
  InputError e({"prog.task", 12, 5}, "unknown robot 'r3'");
  EXPECT_STREQ(e.what(), "prog.task:12:5: error: unknown robot 'r3'");
  EXPECT_EQ(e.where().line, 12);
  EXPECT_EQ(e.problem(), "unknown robot 'r3'");
}

TEST(InputError, OmitsUnknownParts) {
  EXPECT_STREQ(InputError({"cell.yaml", 0, 0}, "missing").what(), "cell.yaml: error: missing");
  EXPECT_STREQ(InputError({"cell.yaml", 3, 0}, "bad").what(), "cell.yaml:3: error: bad");
}

TEST(Check, ThrowsInternalErrorWithValues) {
  int n = 7;
  try {
    CW_CHECK(n < 5, "n was {}", n);
    FAIL() << "CW_CHECK did not throw";
  } catch (const InternalError& e) {
    EXPECT_NE(std::string(e.what()).find("n < 5: n was 7"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(CW_CHECK(n > 5, "fine"));
}

}  // namespace
}  // namespace cellwright
