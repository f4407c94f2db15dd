// The one URDF loader: it parses a robot once, knows where each link and joint is, and reports broken files at their
// line with urdfdom's own words, never on stderr.
#include "cellwright/models/urdf.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <string>

#include "cellwright/common/files.hpp"
#include "cellwright/models/kinematics.hpp"
#include "models/input_error.hpp"

namespace cellwright::models {
namespace {

using ::testing::HasSubstr;

// joint "j1" starts on line 4, link "l1" on line 8.
constexpr const char* kToy = R"(<?xml version="1.0"?>
<robot name="toy">
  <link name="base_link"/>
  <joint name="j1" type="revolute">
    <parent link="base_link"/> <child link="l1"/>
    <axis xyz="0 0 1"/> <limit lower="-1" upper="1" effort="1" velocity="VELOCITY"/>
  </joint>
  <link name="l1"/>
  <joint name="j2" type="continuous">
    <parent link="l1"/> <child link="tcp"/> <axis xyz="1 0 0"/>
  </joint>
  <link name="tcp"/>
</robot>
)";

std::string toy(const std::string& velocity = "1.5") {
  std::string s = kToy;
  s.replace(s.find("VELOCITY"), 8, velocity);
  return s;
}

TEST(Urdf, KnowsWhereEachLinkAndJointIs) {
  const UrdfModel m = parse_urdf(toy(), "toy.urdf");
  EXPECT_EQ(m.file(), "toy.urdf");
  EXPECT_EQ(m.robot().getName(), "toy");
  EXPECT_EQ(m.joint_at("j1").str(), "toy.urdf:4");
  EXPECT_EQ(m.link_at("l1").str(), "toy.urdf:8");
  EXPECT_EQ(m.link_at("nowhere").line, 0);
}

// A file an editor saved with a UTF-8 byte-order mark reads as the same robot, its lines unchanged.
TEST(Urdf, ByteOrderMarkIsAccepted) {
  const UrdfModel m = parse_urdf("\xEF\xBB\xBF" + toy(), "bom.urdf");
  EXPECT_EQ(m.robot().getName(), "toy");
  EXPECT_EQ(m.robot().joints_.size(), 2u);
  EXPECT_EQ(m.joint_at("j1").str(), "bom.urdf:4");
}

TEST(Urdf, TheChainTakesItsVelocityLimitsFromTheLoadedRobot) {
  const KinematicChain c = KinematicChain::from_urdf(parse_urdf(toy(), "toy.urdf"), "base_link", "tcp");
  ASSERT_EQ(c.limits().size(), 2u);
  EXPECT_EQ(c.limits()[0].velocity, 1.5);
  EXPECT_EQ(c.limits()[1].velocity, 0.0);  // a continuous joint without <limit>
}

TEST(Urdf, BothArmsLoadWithAVelocityLimitOnEveryArmJoint) {
  for (const char* file : {"puma560.urdf", "melfa_rve2.urdf"}) {
    const UrdfModel m = load_urdf_file(std::filesystem::path(models_dir()) / "urdf" / file);
    const KinematicChain c = KinematicChain::from_urdf(m);
    ASSERT_EQ(c.dof(), 6u) << file;
    for (std::size_t j = 0; j < c.dof(); ++j) {
      EXPECT_GT(c.limits()[j].velocity, 0.0) << file << " " << c.joint_names()[j];
      EXPECT_EQ(c.limits()[j].velocity, m.robot().getJoint(c.joint_names()[j])->limits->velocity);
    }
  }
}

TEST(Urdf, InvalidUrdfIsReportedAtTheJointInUrdfdomsWordsNotOnStderr) {
  ::testing::internal::CaptureStderr();
  const InputError e = input_error([] { (void)parse_urdf(toy("fast"), "toy.urdf"); });
  const std::string stderr_text = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(e.where().file, "toy.urdf");
  EXPECT_EQ(e.where().line, 4);
  EXPECT_THAT(e.problem(), HasSubstr("invalid URDF: "));
  EXPECT_THAT(e.problem(), HasSubstr("j1"));
  EXPECT_EQ(stderr_text, "");
}

TEST(Urdf, MalformedXmlAndWrongRootAreReportedAtTheirLine) {
  std::string broken = toy();
  broken.replace(broken.find("<link name=\"l1\"/>"), 17, "<link name=\"l1\">");
  const InputError e = input_error([&] { (void)parse_urdf(broken, "toy.urdf"); });
  EXPECT_GT(e.where().line, 0);
  EXPECT_THAT(e.problem(), HasSubstr("malformed XML: "));

  const InputError root = input_error([] { (void)parse_urdf("<?xml version=\"1.0\"?>\n<sdf/>\n", "x.urdf"); });
  EXPECT_EQ(root.where().str(), "x.urdf:2");
  EXPECT_EQ(root.problem(), "the root element is <sdf>, a URDF needs <robot>");

  EXPECT_EQ(input_error([] { (void)parse_urdf("", "e.urdf"); }).problem(), "malformed XML: the file is empty");
}

// A joint whose parent is its child, a link with two parent joints, and a loop of joints: urdfdom takes them all, and
// a walk from the tip to the base never ended (found by tests/fuzz/urdf_fuzz: joint2 of the Melfa with parent and
// child link2 hung KinematicChain::from_urdf). Each is refused at the joint that breaks the tree.
TEST(Urdf, LinksThatAreNotATreeAreRefusedAtTheJoint) {
  const auto with_joint = [](const std::string& parent, const std::string& child) {
    std::string s = toy();
    s.replace(s.find("  <link name=\"tcp\"/>"), 0,
              "  <joint name=\"jx\" type=\"fixed\"><parent link=\"" + parent + "\"/><child link=\"" + child +
                  "\"/></joint>\n");
    return s;
  };
  const InputError self = input_error([&] { (void)parse_urdf(with_joint("l1", "l1"), "self.urdf"); });
  EXPECT_EQ(self.where().str(), "self.urdf:12");
  EXPECT_EQ(self.problem(), "joint 'jx' has link 'l1' as both its parent and its child");

  const InputError two = input_error([&] { (void)parse_urdf(with_joint("base_link", "tcp"), "two.urdf"); });
  EXPECT_EQ(two.where().str(), "two.urdf:12");
  EXPECT_THAT(two.problem(), HasSubstr("link 'tcp' is the child of joints 'j2' and 'jx'"));

  // base_link -> l1 -> tcp, and l2 <-> l3 off to the side (no second parent, no second root).
  std::string loop = toy();
  loop.replace(loop.find("  <link name=\"tcp\"/>"), 0,
               "  <link name=\"l2\"/><link name=\"l3\"/>\n"
               "  <joint name=\"ja\" type=\"fixed\"><parent link=\"l2\"/><child link=\"l3\"/></joint>\n"
               "  <joint name=\"jb\" type=\"fixed\"><parent link=\"l3\"/><child link=\"l2\"/></joint>\n");
  const InputError cycle = input_error([&] { (void)parse_urdf(loop, "loop.urdf"); });
  EXPECT_EQ(cycle.where().file, "loop.urdf");
  EXPECT_THAT(cycle.where().line, ::testing::AnyOf(13, 14));
  EXPECT_THAT(cycle.problem(), HasSubstr("closes a loop of joints"));
}

// Two links, each the other's child: urdfdom links them to each other, then refuses the file for want of a root, and
// the two links, holding each other, were never freed (tests/fuzz/urdf_fuzz's leak, which the ASan leg of CI would
// report here). Refused as a loop before urdfdom sees it.
TEST(Urdf, ALoopWithoutARootIsRefusedAsALoop) {
  const std::string loop =
      "<?xml version=\"1.0\"?>\n<robot name=\"loop\">\n  <link name=\"a\"/>\n  <link name=\"b\"/>\n"
      "  <joint name=\"ab\" type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/></joint>\n"
      "  <joint name=\"ba\" type=\"fixed\"><parent link=\"b\"/><child link=\"a\"/></joint>\n</robot>\n";
  const InputError e = input_error([&] { (void)parse_urdf(loop, "loop.urdf"); });
  EXPECT_EQ(e.where().file, "loop.urdf");
  EXPECT_THAT(e.where().line, ::testing::AnyOf(5, 6));
  EXPECT_THAT(e.problem(), HasSubstr("closes a loop of joints"));
}

TEST(Urdf, MissingFileNamesIt) {
  const InputError e = input_error([] { (void)load_urdf_file("/nonexistent/arm.urdf"); });
  EXPECT_EQ(e.where().file, "/nonexistent/arm.urdf");
  EXPECT_EQ(e.problem(), "cannot read the URDF file: no such file");
}

// Loading a file again gives the robot parsed before while its text is unchanged, and the edited robot once it changes.
TEST(Urdf, ALoadedFileIsParsedAgainOnlyWhenItsTextChanged) {
  const std::filesystem::path file =
      std::filesystem::temp_directory_path() / ("cw_urdf_reload_" + std::to_string(::getpid()) + ".urdf");
  write_file_atomically(file, toy("1.5"));
  const UrdfModel first = load_urdf_file(file);
  const UrdfModel again = load_urdf_file(file);
  EXPECT_EQ(&first.robot(), &again.robot());  // the same parse
  EXPECT_EQ(again.joint_at("j1").str(), file.string() + ":4");
  write_file_atomically(file, toy("2.5"));
  const UrdfModel edited = load_urdf_file(file);
  EXPECT_EQ(edited.robot().getJoint("j1")->limits->velocity, 2.5);
  std::filesystem::remove(file);
  EXPECT_EQ(input_error([&] { (void)load_urdf_file(file); }).problem(), "cannot read the URDF file: no such file");
}

// A folder given as the URDF is called a folder, not a missing file.
TEST(Urdf, AFolderIsCalledAFolder) {
  const std::string dir = std::filesystem::temp_directory_path().string();
  const InputError e = input_error([&] { (void)load_urdf_file(dir); });
  EXPECT_EQ(e.where().file, dir);
  EXPECT_EQ(e.problem(), "cannot read the URDF file: is a directory, not a file");
}

// The toy robot with link l1 (line 8) given an <inertial>.
std::string with_inertial(const std::string& mass, const std::string& inertia) {
  std::string s = toy();
  const std::string l1 = "<link name=\"l1\"/>";
  s.replace(s.find(l1), l1.size(),
            "<link name=\"l1\"><inertial><mass value=\"" + mass + "\"/><inertia " + inertia + "/></inertial></link>");
  return s;
}

constexpr const char* kUnitInertia = R"(ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1")";

TEST(Urdf, APhysicalInertialIsAccepted) {
  EXPECT_NO_THROW((void)parse_urdf(with_inertial("2.5", kUnitInertia), "toy.urdf"));
  // A massless link with no inertia (vendors' fixed links): nothing that cannot exist.
  EXPECT_NO_THROW((void)parse_urdf(with_inertial("0", R"(ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0")"),
                                   "toy.urdf"));
  // A rod along z: two equal moments, the third near zero, within the triangle inequality.
  EXPECT_NO_THROW((void)parse_urdf(with_inertial("1", R"(ixx="0.5" ixy="0" ixz="0" iyy="0.5" iyz="0" izz="0")"),
                                   "toy.urdf"));
}

// urdfdom reads any number as a mass, and MuJoCo simulated a link of -40 kg: the URDF is refused at the link.
TEST(Urdf, ANegativeOrNonFiniteMassIsRefusedAtTheLink) {
  const InputError e = input_error([&] { (void)parse_urdf(with_inertial("-40", kUnitInertia), "toy.urdf"); });
  EXPECT_EQ(e.where().str(), "toy.urdf:8");
  EXPECT_EQ(e.problem(), "link 'l1': mass -40 kg is not physical: a mass must be finite and not negative");
  // A number urdfdom cannot read: it logged an error, dropped the <inertial> and returned the link without it.
  for (const std::string mass : {"nan", "inf", "heavy"}) {
    const InputError n = input_error([&] { (void)parse_urdf(with_inertial(mass, kUnitInertia), "toy.urdf"); });
    EXPECT_EQ(n.where().str(), "toy.urdf:8") << mass;
    EXPECT_THAT(n.problem(), HasSubstr("invalid URDF: Could not parse inertial element for Link [l1]")) << mass;
    EXPECT_THAT(n.problem(), HasSubstr("mass [" + mass + "] is not a float")) << mass;
  }
}

TEST(Urdf, AnInertiaThatNoBodyHasIsRefusedAtTheLink) {
  struct Case {
    const char* inertia;
    const char* why;
  };
  for (const Case& c : {Case{R"(ixx="-1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1")", "must not be negative"},
                        Case{R"(ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="3")", "break the triangle inequality"},
                        Case{R"(ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1")", "must not be negative"}}) {
    const InputError e = input_error([&] { (void)parse_urdf(with_inertial("1", c.inertia), "toy.urdf"); });
    EXPECT_EQ(e.where().str(), "toy.urdf:8") << c.inertia;
    EXPECT_THAT(e.problem(), HasSubstr("link 'l1': the inertia")) << c.inertia;
    EXPECT_THAT(e.problem(), HasSubstr(c.why)) << c.inertia;
  }
}

}  // namespace
}  // namespace cellwright::models
