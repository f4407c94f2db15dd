// `twin snapshot` as a user runs it: a PNG of the paper's cell without a display, the generated MJCF, and clear
// refusals of bad input.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "tools/twin_cli.hpp"

namespace cellwright::testing {
namespace {

using ::testing::HasSubstr;

const std::string kCell = shell_quote(source_path("scenes/cell.yaml"));

// Width and height from a PNG's header; {0, 0} if the file is not a PNG.
std::pair<int, int> png_size(const std::filesystem::path& file) {
  const std::string bytes = slurp(file);
  if (bytes.size() < 24 || bytes.compare(0, 8, "\x89PNG\r\n\x1a\n") != 0) return {0, 0};
  auto be32 = [&](std::size_t at) {
    int v = 0;
    for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
    return v;
  };
  return {be32(16), be32(20)};
}

// Files in the directory besides the runner's captured output (.stdout, .stderr, .stdin).
int files_in(const std::filesystem::path& dir) {
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name != ".stdout" && name != ".stderr" && name != ".stdin") ++n;
  }
  return n;
}

TEST(SnapshotCli, OverheadCameraAtItsResolution) {
  TwinCli cli("cw-snapshot");
  const auto out = cli.dir() / "top.png";
  const Outcome r = cli.run("snapshot " + kCell + " --camera overhead -o " + shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(png_size(out), std::make_pair(640, 480));
  // Only the picture: the temporary file was renamed into place.
  EXPECT_EQ(files_in(cli.dir()), 1);
}

TEST(SnapshotCli, OverviewAtAChosenSizeAfterSimulating) {
  TwinCli cli("cw-snapshot");
  const auto out = cli.dir() / "cell.png";
  std::ofstream(out) << "an old picture";
  const Outcome r =
      cli.run("snapshot " + kCell + " --width 320 --height 200 --after 1 -o " + shell_quote(out.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(png_size(out), std::make_pair(320, 200));
}

TEST(SnapshotCli, SavesTheGeneratedModel) {
  TwinCli cli("cw-snapshot");
  const auto xml = cli.dir() / "cell.xml";
  const Outcome r = cli.run("snapshot " + kCell + " --mjcf " + shell_quote(xml.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string text = slurp(xml);
  EXPECT_THAT(text, HasSubstr("<mujoco model=\"yasuda-cell\">"));
  EXPECT_THAT(text, HasSubstr("<key name=\"initial\""));
}

TEST(SnapshotCli, DetectionsAreFoundDrawnAndPrinted) {
  TwinCli cli("cw-snapshot");
  const auto plain = cli.dir() / "plain.png";
  const auto marked = cli.dir() / "marked.png";
  ASSERT_EQ(cli.run("snapshot " + kCell + " --camera overhead -o " + shell_quote(plain.string())).status, 0);
  const Outcome r = cli.run("snapshot " + kCell + " --camera overhead --detections -o " + shell_quote(marked.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  // One line per part of the cell, where it starts: A, B, C on the input belt, D (a cylinder) on the fixture.
  for (const char* part : {"A", "B", "C"}) {
    EXPECT_THAT(r.out, HasSubstr(std::string(part) + " at (")) << r.out;
  }
  EXPECT_THAT(r.out, HasSubstr("on conveyor input"));
  EXPECT_THAT(r.out, HasSubstr("no yaw (cylinder), on machine mill fixture"));
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("not seen")));
  // The picture has the drawings on it: not the plain picture.
  EXPECT_EQ(png_size(marked), std::make_pair(640, 480));
  EXPECT_NE(slurp(marked), slurp(plain));

  const Outcome overview = cli.run("snapshot " + kCell + " --detections -o " + shell_quote(marked.string()));
  EXPECT_EQ(overview.status, 2);
  EXPECT_THAT(overview.err, HasSubstr("--detections needs --camera"));
}

TEST(SnapshotCli, BadInputIsRefusedClearly) {
  TwinCli cli("cw-snapshot");
  const auto out = cli.dir() / "x.png";
  const Outcome camera = cli.run("snapshot " + kCell + " --camera side -o " + shell_quote(out.string()));
  EXPECT_EQ(camera.status, 2);
  EXPECT_THAT(camera.err, HasSubstr("the cell has no camera 'side' (cameras: overview, overhead)"));
  EXPECT_FALSE(std::filesystem::exists(out));

  const auto bad = cli.dir() / "bad.yaml";
  std::ofstream(bad) << "name: broken\nrobots:\n  - name: r1\n    urdf: [\n";
  const Outcome yaml = cli.run("snapshot " + shell_quote(bad.string()) + " -o " + shell_quote(out.string()));
  EXPECT_EQ(yaml.status, 2);
  EXPECT_THAT(yaml.err, HasSubstr(bad.string() + ":"));
  EXPECT_THAT(yaml.err, HasSubstr("error: not valid YAML"));

  const Outcome nothing = cli.run("snapshot " + kCell);
  EXPECT_EQ(nothing.status, 2);
  EXPECT_THAT(nothing.err, HasSubstr("nothing to write"));

  const Outcome dir = cli.run("snapshot " + kCell + " -o " + shell_quote((cli.dir() / "no" / "x.png").string()));
  EXPECT_EQ(dir.status, 2);
  EXPECT_THAT(dir.err, HasSubstr("does not exist"));

  const Outcome size = cli.run("snapshot " + kCell + " --width 0 -o " + shell_quote(out.string()));
  EXPECT_EQ(size.status, 2);
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace cellwright::testing
