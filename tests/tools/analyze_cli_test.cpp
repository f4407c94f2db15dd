// `twin analyze` as a user runs it: exit status (0 ok, 1 a problem found or the state limit hit, 2 bad input) and
// the key figures of the report, on the PNML corpus in tests/controller/petri/data.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const fs::path kData = fs::path(CW_SOURCE_DIR) / "tests/controller/petri/data";

struct Outcome {
  int status = -1;
  std::string out;
  std::string err;
};

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string slurp(const fs::path& p) {
  std::ostringstream s;
  s << std::ifstream(p, std::ios::binary).rdbuf();
  return s.str();
}

class AnalyzeCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cw-analyze-cli-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs `twin analyze <args>`, capturing stdout and stderr separately.
  Outcome twin(const std::string& args) const {
    const fs::path out = dir_ / "stdout";
    const fs::path err = dir_ / "stderr";
    const std::string cmd = shell_quote(CW_TWIN_EXE) + " analyze " + args + " >" + shell_quote(out.string()) + " 2>" +
                            shell_quote(err.string());
    const int raw = std::system(cmd.c_str());
    Outcome r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  static std::string data(const char* file) { return shell_quote((kData / file).string()); }

  fs::path dir_;
};

TEST_F(AnalyzeCli, KanbanIsLiveAndBoundedWith160Markings) {
  const Outcome r = twin(data("kanban-1.pnml") + " --json");
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("states"), 160);  // facts.md: the Kanban closed form for N=1
  EXPECT_EQ(j.at("deadlocks"), 0);
  EXPECT_EQ(j.at("bounded"), true);
  EXPECT_EQ(j.at("complete"), true);
  EXPECT_EQ(r.err, "");
}

TEST_F(AnalyzeCli, PhilosophersDeadlockExitsOneWithThePath) {
  const Outcome json = twin(data("philosophers-2.pnml") + " --json");
  EXPECT_EQ(json.status, 1) << json.out << json.err;
  const nlohmann::json j = nlohmann::json::parse(json.out);
  EXPECT_GT(j.at("deadlocks").get<int>(), 0);
  EXPECT_EQ(j.at("states"), 6);

  const Outcome text = twin(data("philosophers-2.pnml"));
  EXPECT_EQ(text.status, 1);
  EXPECT_THAT(text.out, HasSubstr("philosophers-2.pnml: "));
  EXPECT_THAT(text.out, HasSubstr("deadlock"));
  EXPECT_THAT(text.out, HasSubstr("take_left1"));
  EXPECT_THAT(text.out, HasSubstr("take_left2"));
}

TEST_F(AnalyzeCli, FullByDefaultStubbornOnRequest) {
  const Outcome full = twin(data("philosophers-2.pnml") + " --json");
  const Outcome red = twin(data("philosophers-2.pnml") + " --json --reduction stubborn");
  EXPECT_EQ(red.status, full.status) << red.out << red.err;
  const nlohmann::json f = nlohmann::json::parse(full.out), r = nlohmann::json::parse(red.out);
  EXPECT_EQ(f.at("reduction"), "none");
  EXPECT_EQ(f.at("reduced"), false);
  EXPECT_EQ(r.at("reduction"), "stubborn");
  EXPECT_EQ(r.at("deadlocks"), f.at("deadlocks"));
  EXPECT_EQ(r.at("deadlock_path").size(), f.at("deadlock_path").size());

  const Outcome text = twin(data("kanban-1.pnml") + " --reduction stubborn");
  EXPECT_EQ(text.status, 0) << text.out << text.err;
  EXPECT_THAT(text.out, HasSubstr("markings explored (reduced)"));
  EXPECT_EQ(twin(data("kanban-1.pnml") + " --reduction all").status, 2);
}

TEST_F(AnalyzeCli, StateLimitIsNotASuccess) {
  const Outcome r = twin(data("kanban-1.pnml") + " --json --max-states 10");
  EXPECT_EQ(r.status, 1) << r.out << r.err;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("complete"), false);
  EXPECT_LE(j.at("states").get<int>(), 10);
}

TEST_F(AnalyzeCli, BadInputExitsTwoWithFileAndLine) {
  const Outcome bad = twin(data("bad-marking-overflow.pnml"));
  EXPECT_EQ(bad.status, 2);
  EXPECT_EQ(bad.out, "");
  EXPECT_THAT(bad.err, HasSubstr((kData / "bad-marking-overflow.pnml").string() + ":7: error: initial marking"));

  const Outcome missing = twin(shell_quote((dir_ / "absent.pnml").string()));
  EXPECT_EQ(missing.status, 2);
  EXPECT_THAT(missing.err, HasSubstr("absent.pnml: error: cannot read: no such file"));

  const Outcome usage = twin(data("kanban-1.pnml") + " --max-states 0");
  EXPECT_EQ(usage.status, 2);
  const Outcome no_args = twin("");
  EXPECT_EQ(no_args.status, 2);
}

TEST_F(AnalyzeCli, SeveralNetsNoteWhichOneAndPickById) {
  const Outcome first = twin(data("two-nets.pnml") + " --json");
  EXPECT_EQ(first.status, 1) << first.out << first.err;  // 'first' stops dead after one firing
  EXPECT_THAT(first.err, HasSubstr("holds 2 nets ('first', 'second'); analysing the first"));
  EXPECT_EQ(nlohmann::json::parse(first.out).at("states"), 2);

  const Outcome second = twin(data("two-nets.pnml") + " --json --net-id second");
  EXPECT_EQ(second.status, 0) << second.out << second.err;  // 'second' cycles between x and y
  EXPECT_EQ(second.err, "");
  EXPECT_EQ(nlohmann::json::parse(second.out).at("states"), 2);

  const Outcome unknown = twin(data("two-nets.pnml") + " --net-id third");
  EXPECT_EQ(unknown.status, 2);
  EXPECT_THAT(unknown.err, HasSubstr("no net with id 'third'"));
}

TEST_F(AnalyzeCli, WritesTheNetAsDot) {
  const fs::path dot = dir_ / "net.dot";
  const Outcome r = twin(data("producer-consumer.pnml") + " --dot " + shell_quote(dot.string()));
  EXPECT_EQ(r.status, 0) << r.out << r.err;
  const std::string text = slurp(dot);
  EXPECT_EQ(text.rfind("digraph \"producer_consumer\" {", 0), 0u) << text;
  EXPECT_THAT(text, HasSubstr("take_two"));

  const Outcome bad =
      twin(data("producer-consumer.pnml") + " --dot " + shell_quote((dir_ / "no/such/dir.dot").string()));
  EXPECT_EQ(bad.status, 2);
  EXPECT_THAT(bad.err, HasSubstr("dir.dot: error: cannot write"));
}

}  // namespace
