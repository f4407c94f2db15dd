#include "cellwright/common/files.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include "cellwright/common/error.hpp"

namespace cellwright {
namespace {

namespace fs = std::filesystem;

class Files : public ::testing::Test {
 protected:
  void SetUp() override {
    // Named by the process (ctest runs each test in a process of its own, two at a time): gtest's random seed, taken
    // from the clock, was the same for two tests started in the same millisecond, which then shared the directory.
    dir_ = fs::temp_directory_path() /
           fmt::format("cw_files_{}_{}", ::getpid(), ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(Files, WriteThenReadRoundTripsBytes) {
  const std::string bytes("a\0b\nc", 5);
  write_file_atomically(dir_ / "x.bin", bytes);
  EXPECT_EQ(read_file(dir_ / "x.bin"), bytes);
  write_file_atomically(dir_ / "x.bin", "second");
  EXPECT_EQ(read_file(dir_ / "x.bin"), "second");
  // No temporary file is left beside it.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(Files, MissingFileNamesThePath) {
  try {
    (void)read_file(dir_ / "nope.txt");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nope.txt"), std::string::npos);
  }
  EXPECT_THROW((void)read_file(dir_), InputError);
}

TEST_F(Files, UnwritableDirectoryLeavesTheOldFileIntact) {
  write_file_atomically(dir_ / "keep.txt", "old");
  EXPECT_THROW(write_file_atomically(dir_ / "missing_dir" / "f.txt", "x"), InputError);
  EXPECT_EQ(read_file(dir_ / "keep.txt"), "old");
}

TEST_F(Files, MoveFileReplacesTheTargetAndLeavesNothingBehind) {
  write_file_atomically(dir_ / "a.jsonl", "new");
  write_file_atomically(dir_ / "b.jsonl", "old");
  move_file(dir_ / "a.jsonl", dir_ / "b.jsonl");
  EXPECT_EQ(read_file(dir_ / "b.jsonl"), "new");
  EXPECT_FALSE(fs::exists(dir_ / "a.jsonl"));
  try {
    move_file(dir_ / "gone.jsonl", dir_ / "b.jsonl");
    FAIL() << "a missing file was moved";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("gone.jsonl"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read_file(dir_ / "b.jsonl"), "new");  // unchanged
}

TEST_F(Files, TemporaryFileIsNewEmptyAndRemovedWhenItGoes) {
  fs::path kept;
  {
    TemporaryFile a("cw-files-", ".jsonl");
    const TemporaryFile b("cw-files-", ".jsonl");
    kept = a.path();
    EXPECT_NE(a.path(), b.path());
    EXPECT_TRUE(fs::is_regular_file(a.path()));
    EXPECT_EQ(fs::file_size(a.path()), 0u);
    EXPECT_EQ(a.path().extension(), ".jsonl");
    EXPECT_EQ(a.path().filename().string().rfind("cw-files-", 0), 0u);
  }
  EXPECT_FALSE(fs::exists(kept));
}

// An output directory is checked before anything runs, and checking it creates nothing.
TEST_F(Files, OutputDirectoryCheckedCreatingNothing) {
  EXPECT_NO_THROW(check_writable_dir(dir_));                  // exists, writable
  EXPECT_NO_THROW(check_writable_dir(dir_ / "new" / "deep"));  // can be created
  EXPECT_FALSE(fs::exists(dir_ / "new"));
  write_file_atomically(dir_ / "file", "x");
  try {
    check_writable_dir(dir_ / "file");
    ADD_FAILURE() << "a file taken for a directory";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, (dir_ / "file").string());
    EXPECT_EQ(e.problem(), "exists and is not a directory");
  }
  try {
    check_writable_dir(dir_ / "file" / "out");
    ADD_FAILURE() << "a directory under a file";
  } catch (const InputError& e) {
    EXPECT_EQ(e.problem(), fmt::format("cannot be created: {} is not a directory", (dir_ / "file").string()));
  }
  EXPECT_THROW(check_writable_dir(""), InputError);
}

}  // namespace
}  // namespace cellwright
