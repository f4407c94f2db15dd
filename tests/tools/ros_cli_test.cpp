// `twin run --ros-domain N` as a user runs it (the publishing itself, read by a subscriber in another process, is
// tested in tests/distributed/ros_publisher_test.cpp): the run and its event log are the same with and without it,
// and a domain DDS does not have is refused naming the option.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "tools/twin_cli.hpp"

namespace {

namespace fs = std::filesystem;
using cellwright::testing::Outcome;
using cellwright::testing::shell_quote;
using cellwright::testing::slurp;
using cellwright::testing::source_path;
using cellwright::testing::TwinCli;
using ::testing::HasSubstr;

TEST(RosCli, TheRunAndItsLogAreTheSameWithAndWithoutPublishingForRos) {
  TwinCli cli("cw-ros-cli");
  const fs::path without = cli.dir() / "without", with = cli.dir() / "with";
  const std::string scenario = shell_quote(source_path("scenes/exchange.yaml"));
  const Outcome a = cli.run("run " + scenario + " --quiet --final-png never -o " + shell_quote(without.string()));
  ASSERT_EQ(a.status, 0) << a.out << a.err;
  const std::string domain = std::to_string(20 + getpid() % 200);
  const Outcome b = cli.run("run " + scenario + " --quiet --final-png never --ros-domain " + domain + " -o " +
                            shell_quote(with.string()));
  ASSERT_EQ(b.status, 0) << b.out << b.err;
  EXPECT_EQ(slurp(with / "events.jsonl"), slurp(without / "events.jsonl"));
}

TEST(RosCli, ADomainOutsideDdsRangeIsRefusedNamingTheOption) {
  TwinCli cli("cw-ros-cli-bad");
  const Outcome r = cli.run("run " + shell_quote(source_path("scenes/exchange.yaml")) + " --quiet --ros-domain 233");
  EXPECT_EQ(r.status, 2) << r.out << r.err;
  EXPECT_THAT(r.err + r.out, HasSubstr("--ros-domain"));
}

}  // namespace
