// The MuJoCo scene of the paper's cell: it compiles without warnings, nothing overlaps at the start, the arms hold
// their home pose under gravity, belts carry parts by friction, grippers hold parts, and the sensors read what the
// physics says.
#include "cellwright/twin/scene.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "cellwright/models/kinematics.hpp"

#include "twin/mujoco_fixture.hpp"

namespace cellwright::twin {
namespace {

using ::testing::HasSubstr;

const std::filesystem::path kSource = CW_SOURCE_DIR;

class SceneTest : public testing::MujocoTest {
 protected:
  static const models::CellDescription& paper_cell() {
    static const models::CellDescription cell = models::load_cell(kSource / "scenes/cell.yaml");
    return cell;
  }
};

std::string body_of_geom(const mjModel* m, int g) {
  const char* name = mj_id2name(m, mjOBJ_BODY, m->geom_bodyid[g]);
  return name != nullptr ? name : "world";
}

// Contacts deeper than `depth` (metres), as "body1 / body2: depth".
std::vector<std::string> penetrations(const Scene& s, double depth) {
  std::vector<std::string> out;
  const mjData* d = s.data();
  for (int i = 0; i < d->ncon; ++i) {
    const mjContact& c = d->contact[i];
    if (c.dist < -depth) {
      out.push_back(fmt::format("{} / {}: {:.4f} m", body_of_geom(s.model(), c.geom1), body_of_geom(s.model(), c.geom2),
                                -c.dist));
    }
  }
  return out;
}

Eigen::Vector3d body_pos(const Scene& s, int body) {
  return Eigen::Vector3d(s.data()->xpos[3 * body], s.data()->xpos[3 * body + 1], s.data()->xpos[3 * body + 2]);
}

Eigen::Vector3d sensor3(const Scene& s, int sensor) {
  const mjtNum* v = s.data()->sensordata + s.model()->sensor_adr[sensor];
  return {v[0], v[1], v[2]};
}

double sensor1(const Scene& s, int sensor) {
  return s.data()->sensordata[s.model()->sensor_adr[sensor]];
}

TEST_F(SceneTest, FixtureCatchesWarnings) {
  mju_warning("a test warning");
  ASSERT_EQ(warnings().size(), 1u);
  EXPECT_THAT(warnings()[0], HasSubstr("a test warning"));
  warnings().clear();
}

TEST_F(SceneTest, BuildsTheWholeCellWithNamedParts) {
  Scene s = build_scene(paper_cell());
  const mjModel* m = s.model();
  // Per robot: six arm joints and two fingers, each with a position servo; one velocity servo per belt.
  EXPECT_EQ(m->nu, 2 * 8 + 2);
  // Robots 2 x 8, belts 2 x 1, workpieces 4 x 7.
  EXPECT_EQ(m->nq, 16 + 2 + 28);
  ASSERT_EQ(s.robots().size(), 2u);
  const RobotIds& puma = *s.find_robot("puma");
  EXPECT_EQ(puma.joints, (std::vector<std::string>{"puma/joint1", "puma/joint2", "puma/joint3", "puma/joint4",
                                                   "puma/joint5", "puma/joint6"}));
  EXPECT_EQ(m->sensor_dim[puma.wrist_force_sensor], 3);
  EXPECT_EQ(m->sensor_dim[puma.wrist_torque_sensor], 3);
  EXPECT_EQ(m->sensor_type[puma.finger_touch_sensor[0]], mjSENS_TOUCH);
  EXPECT_EQ(m->sensor_type[puma.finger_pos_sensor[1]], mjSENS_JOINTPOS);
  EXPECT_DOUBLE_EQ(puma.finger_range[0], 0.0);
  EXPECT_DOUBLE_EQ(puma.finger_range[1], 0.04);
  EXPECT_STREQ(mj_id2name(m, mjOBJ_SITE, puma.tcp_site), "puma/tcp");
  for (int a : puma.actuator) EXPECT_EQ(m->actuator_trntype[a], mjTRN_JOINT);
  ASSERT_EQ(s.workpieces().size(), 4u);
  EXPECT_EQ(s.find_workpiece("C")->body, mj_name2id(m, mjOBJ_BODY, "workpiece/C"));
  EXPECT_EQ(s.find_conveyor("input")->belt_joint, mj_name2id(m, mjOBJ_JOINT, "conveyor/input/belt"));
  EXPECT_GE(s.camera_id("overhead"), 0);
  EXPECT_EQ(s.camera_id("nowhere"), -1);
  // The gripper pads grip with torsional friction; the friction cone is elliptic with a high impratio.
  EXPECT_EQ(m->geom_condim[mj_name2id(m, mjOBJ_GEOM, "puma/finger_left/finger_left_pad")], 4);
  EXPECT_EQ(m->opt.cone, mjCONE_ELLIPTIC);
  EXPECT_DOUBLE_EQ(m->opt.impratio, 10);
  // Euler without a noslip pass, sparse constraint Jacobians, and buffers sized to what a run needs: one mjData stays
  // a few MB (docs/simulation.md).
  EXPECT_EQ(m->opt.integrator, mjINT_EULER);
  EXPECT_EQ(m->opt.noslip_iterations, 0);
  EXPECT_EQ(m->opt.jacobian, mjJAC_SPARSE);
  EXPECT_LE(m->njmax, 500);
  EXPECT_LE(m->nconmax, 200);
  // The same description always gives the same model text.
  EXPECT_EQ(scene_mjcf(paper_cell()), s.mjcf());
  expect_no_data_warnings(s.data());
}

// Bodies fixed to the world are excluded from each other's collision tests (they can never touch in MuJoCo; the
// exclusion only saves the broadphase's geom tests), and nothing that moves is excluded from what it could hit: every
// excluded pair is two fixed bodies, two bodies of one robot, or a conveyor and its own belt.
TEST_F(SceneTest, OnlyPairsThatCannotTouchAreExcluded) {
  Scene s = build_scene(paper_cell());
  const mjModel* m = s.model();
  const auto name = [&](int b) { return std::string(mj_id2name(m, mjOBJ_BODY, b) ? mj_id2name(m, mjOBJ_BODY, b) : "world"); };
  const auto robot_of = [&](int b) {
    for (const RobotIds& r : s.robots()) {
      if (name(b).rfind(r.name + "/", 0) == 0) return r.name;
    }
    return std::string();
  };
  int fixed_pairs = 0;
  for (int i = 0; i < m->nexclude; ++i) {
    const int b1 = (m->exclude_signature[i] >> 16) - 1, b2 = (m->exclude_signature[i] & 0xFFFF) - 1;
    const bool fixed = m->body_weldid[b1] == 0 && m->body_weldid[b2] == 0 && m->body_mocapid[b1] < 0 &&
                       m->body_mocapid[b2] < 0;
    const bool same_robot = !robot_of(b1).empty() && robot_of(b1) == robot_of(b2);
    const bool own_belt = name(b2) == name(b1) + "/belt" || name(b1) == name(b2) + "/belt";
    EXPECT_TRUE(fixed || same_robot || own_belt) << name(b1) << " and " << name(b2) << " are excluded";
    fixed_pairs += fixed ? 1 : 0;
  }
  // The world, the floor, the MELFA's pedestal, two robot bases, two conveyor frames and the machine: every pair of
  // the eight.
  EXPECT_EQ(fixed_pairs, 8 * 7 / 2);
  // The world body holds no geom: MuJoCo would test each of them against every geom of the cell on every step.
  EXPECT_EQ(m->body_geomnum[0], 0);
  EXPECT_TRUE(is_scenery_body(m, mj_name2id(m, mjOBJ_BODY, "scenery/floor")));
  EXPECT_FALSE(is_scenery_body(m, mj_name2id(m, mjOBJ_BODY, "conveyor/input")));
}

// The arms in MuJoCo move exactly as their URDFs say: the tool centre point site agrees with the kinematics library's
// forward kinematics (a separate reading of the same URDF) at random configurations within the limits.
TEST_F(SceneTest, RobotsFollowTheirUrdfKinematics) {
  Scene s = build_scene(paper_cell());
  const mjModel* m = s.model();
  mjData* d = s.data();
  std::mt19937_64 rng(20240501);
  for (const RobotIds& r : s.robots()) {
    SCOPED_TRACE(r.name);
    const models::RobotSpec& spec = *paper_cell().find_robot(r.name);
    const auto chain = models::KinematicChain::from_urdf_file(spec.urdf);
    ASSERT_EQ(chain.dof(), r.joints.size());
    for (int trial = 0; trial < 20; ++trial) {
      Eigen::VectorXd q(static_cast<Eigen::Index>(chain.dof()));
      for (std::size_t j = 0; j < chain.dof(); ++j) {
        std::uniform_real_distribution<double> u(chain.limits()[j].lower, chain.limits()[j].upper);
        q[static_cast<Eigen::Index>(j)] = u(rng);
        d->qpos[r.qpos_adr[j]] = q[static_cast<Eigen::Index>(j)];
        // The servo limits are the joint limits.
        EXPECT_DOUBLE_EQ(m->actuator_ctrlrange[2 * r.actuator[j]], chain.limits()[j].lower);
      }
      mj_kinematics(m, d);
      const Eigen::Isometry3d expected = spec.base.transform() * chain.forward(q);
      const Eigen::Vector3d pos(d->site_xpos[3 * r.tcp_site], d->site_xpos[3 * r.tcp_site + 1],
                                d->site_xpos[3 * r.tcp_site + 2]);
      Eigen::Matrix3d rot;
      for (int i = 0; i < 9; ++i) rot(i / 3, i % 3) = d->site_xmat[9 * r.tcp_site + i];  // row-major
      EXPECT_LT((pos - expected.translation()).norm(), 1e-9) << "q = " << q.transpose();
      EXPECT_LT((rot - expected.linear()).norm(), 1e-9) << "q = " << q.transpose();
    }
  }
}

// place_free_body is the sweep's pose of a carried part after one kinematics pass: the same bits as a second pass.
TEST_F(SceneTest, PlacingAFreeBodyIsASecondKinematicsPassBitForBit) {
  Scene s = build_scene(paper_cell());
  const mjModel* m = s.model();
  mjData* placed = mj_makeData(m);
  mjData* whole = mj_makeData(m);
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto same = [&](const mjtNum* a, const mjtNum* b, int n, const char* what) {
    EXPECT_TRUE(std::equal(a, a + n, b)) << what;
  };
  for (int k = 0; k < 40; ++k) {
    const int w = k % static_cast<int>(s.workpieces().size());
    const int body = s.workpieces()[static_cast<std::size_t>(w)].body;
    // A pose whose quaternion is a little off unit length, as one computed from a rotation matrix is.
    Eigen::Quaterniond r(u(rng), u(rng), u(rng), u(rng));
    r.normalize();
    const double scale = 1.0 + 1e-9 * u(rng);
    const double pose[7] = {u(rng), u(rng), 1.0 + u(rng), scale * r.w(), scale * r.x(), scale * r.y(), scale * r.z()};
    for (int i = 0; i < m->nq; ++i) placed->qpos[i] = s.data()->qpos[i] + 0.1 * u(rng);
    mju_copy(whole->qpos, placed->qpos, m->nq);
    mj_kinematics(m, placed);
    twin::place_free_body(m, placed, body, pose);
    mju_copy(whole->qpos + s.workpieces()[static_cast<std::size_t>(w)].qpos_adr, pose, 7);
    mj_kinematics(m, whole);
    same(placed->qpos, whole->qpos, m->nq, "qpos");
    same(placed->xpos, whole->xpos, 3 * m->nbody, "xpos");
    same(placed->xquat, whole->xquat, 4 * m->nbody, "xquat");
    same(placed->xmat, whole->xmat, 9 * m->nbody, "xmat");
    same(placed->xipos, whole->xipos, 3 * m->nbody, "xipos");
    same(placed->ximat, whole->ximat, 9 * m->nbody, "ximat");
    same(placed->geom_xpos, whole->geom_xpos, 3 * m->ngeom, "geom_xpos");
    same(placed->geom_xmat, whole->geom_xmat, 9 * m->ngeom, "geom_xmat");
    same(placed->site_xpos, whole->site_xpos, 3 * m->nsite, "site_xpos");
    same(placed->site_xmat, whole->site_xmat, 9 * m->nsite, "site_xmat");
  }
  const double pose[7] = {0, 0, 0, 1, 0, 0, 0};
  EXPECT_THROW(twin::place_free_body(m, placed, m->body_parentid[s.workpieces()[0].body], pose), InternalError);
  EXPECT_THROW(twin::place_free_body(m, placed, m->site_bodyid[m->sensor_objid[s.robots()[0].wrist_force_sensor]],
                                     pose),
               InternalError);
  mj_deleteData(placed);
  mj_deleteData(whole);
}

TEST_F(SceneTest, NothingOverlapsAtTheStartAndTheRobotsTouchNothing) {
  Scene s = build_scene(paper_cell());
  EXPECT_THAT(penetrations(s, 1e-4), ::testing::IsEmpty());
  for (int i = 0; i < s.data()->ncon; ++i) {
    const mjContact& c = s.data()->contact[i];
    for (int g : {c.geom1, c.geom2}) {
      const std::string body = body_of_geom(s.model(), g);
      EXPECT_FALSE(body.rfind("puma/", 0) == 0 || body.rfind("melfa/", 0) == 0) << body << " touches something";
    }
  }
}

TEST_F(SceneTest, OverlapCheckSeesAPartInsideTheMachine) {
  // The check above can fail: a part placed inside the machine's body is reported.
  models::CellDescription cell = paper_cell();
  cell.workpieces[0].pose.xyz = Eigen::Vector3d(0.05, 0.6, 0.38);
  Scene s = build_scene(cell);
  const auto found = penetrations(s, 1e-4);
  ASSERT_FALSE(found.empty());
  EXPECT_THAT(found[0], HasSubstr("workpiece/A"));
}

// Names from the user's files reach the generated MJCF only through the XML writer, which escapes them: a cell name
// with quotes, markup, white space and control characters builds, and MuJoCo reads it back as written. (The names of
// the cell's objects are plain words, and robots cannot take the scene's prefixes: cell.cpp refuses the rest.)
TEST_F(SceneTest, ACellNameThatIsNotXmlIsEscapedAndReadBackAsWritten) {
  models::CellDescription cell = paper_cell();
  cell.name = "a \"quoted\" <cell> & 'co' --> ]]>\n\tend\x01";
  Scene s = build_scene(cell);
  EXPECT_EQ(std::string(s.model()->names), cell.name);
}

TEST_F(SceneTest, ArmsHoldTheirHomePoseUnderGravity) {
  Scene s = build_scene(paper_cell());
  const int steps = static_cast<int>(2.0 / s.model()->opt.timestep);
  double worst = 0;
  for (int i = 0; i < steps; ++i) {
    s.step();
    for (const RobotIds& r : s.robots()) {
      for (std::size_t j = 0; j < r.joints.size(); ++j) {
        worst = std::max(worst, std::abs(s.data()->qpos[r.qpos_adr[j]] - r.home[j]));
      }
    }
  }
  EXPECT_LT(worst, 0.005) << "largest deviation from home over 2 s, rad";
  for (const RobotIds& r : s.robots()) {
    for (std::size_t j = 0; j < r.joints.size(); ++j) {
      EXPECT_LT(std::abs(s.data()->qvel[r.dof_adr[j]]), 1e-3) << r.joints[j] << " still moving";
      EXPECT_NEAR(sensor1(s, r.joint_pos_sensor[j]), s.data()->qpos[r.qpos_adr[j]], 1e-12);
    }
    for (int side = 0; side < 2; ++side) {
      EXPECT_NEAR(sensor1(s, r.finger_pos_sensor[side]), r.finger_range[1], 1e-3) << r.name << " finger not open";
    }
  }
  expect_no_data_warnings(s.data());
}

TEST_F(SceneTest, SensorsAtRestReadTheWeightOfTheHand) {
  Scene s = build_scene(paper_cell());
  s.step(250);
  for (const RobotIds& r : s.robots()) {
    SCOPED_TRACE(r.name);
    // The flange carries the gripper: the wrist sensor reads its weight.
    const double weight = s.model()->body_subtreemass[r.flange_body] * s.model()->opt.gravity[2];
    EXPECT_NEAR(sensor3(s, r.wrist_force_sensor).norm(), std::abs(weight), 0.02 * std::abs(weight));
    EXPECT_DOUBLE_EQ(sensor1(s, r.finger_touch_sensor[0]), 0.0);
    EXPECT_DOUBLE_EQ(sensor1(s, r.finger_touch_sensor[1]), 0.0);
  }
}

TEST_F(SceneTest, TheBeltCarriesPartsAtItsSpeed) {
  Scene s = build_scene(paper_cell());
  const ConveyorIds& input = *s.find_conveyor("input");
  const int part = s.find_workpiece("A")->body;
  const double dt = s.model()->opt.timestep;
  s.step(static_cast<int>(0.5 / dt));  // settle on the belt
  const Eigen::Vector3d before = body_pos(s, part);
  const double seconds = 3.0;
  s.step(static_cast<int>(seconds / dt));
  const Eigen::Vector3d after = body_pos(s, part);
  // The input conveyor runs along +x.
  EXPECT_NEAR(after.x() - before.x(), input.speed * seconds, 0.05 * input.speed * seconds);
  EXPECT_NEAR(after.y(), before.y(), 0.002);
  EXPECT_NEAR(after.z(), before.z(), 0.002);
  // The belt was wrapped several times and stays within its travel.
  const double q = s.data()->qpos[input.belt_qpos_adr];
  EXPECT_GE(q, 0.0);
  EXPECT_LT(q, input.wrap);
  EXPECT_NEAR(s.data()->qvel[input.belt_dof_adr], input.speed, 0.01 * input.speed);
  expect_no_data_warnings(s.data());
}

TEST_F(SceneTest, TheStopHoldsPartsWhereTheRobotPicksThem) {
  Scene s = build_scene(paper_cell());
  // A travels 1.05 m at 0.05 m/s to the stop; give it 25 s.
  s.step(static_cast<int>(25.0 / s.model()->opt.timestep));
  const Eigen::Vector3d pick = paper_cell().find_location("input_pick")->pose.xyz;
  const Eigen::Vector3d a = body_pos(s, s.find_workpiece("A")->body);
  const Eigen::Vector3d b = body_pos(s, s.find_workpiece("B")->body);
  EXPECT_NEAR(a.x(), pick.x(), 0.003);
  EXPECT_NEAR(a.y(), pick.y(), 0.003);
  EXPECT_NEAR(a.z(), pick.z() + 0.03, 0.002);
  // B queues right behind A.
  EXPECT_NEAR(b.x(), a.x() - 0.04, 0.003);
  expect_no_data_warnings(s.data());
}

TEST_F(SceneTest, TheGripperHoldsAPartByFriction) {
  Scene s = build_scene(paper_cell());
  const RobotIds& puma = *s.find_robot("puma");
  const WorkpieceIds& part = *s.find_workpiece("B");
  mjData* d = s.data();
  const mjModel* m = s.model();
  // Put B (40 mm wide) between the fingers at the tool centre point, fingers 1 mm clear of it on each side, and
  // close them.
  const mjtNum* tcp = d->site_xpos + 3 * puma.tcp_site;
  mjtNum quat[4];
  mju_mat2Quat(quat, d->site_xmat + 9 * puma.tcp_site);
  for (int i = 0; i < 3; ++i) d->qpos[part.qpos_adr + i] = tcp[i];
  for (int i = 0; i < 4; ++i) d->qpos[part.qpos_adr + 3 + i] = quat[i];
  for (int side = 0; side < 2; ++side) {
    d->qpos[puma.finger_qpos_adr[side]] = 0.021;
    d->ctrl[puma.finger_actuator[side]] = puma.finger_range[0];
  }
  mj_forward(m, d);
  EXPECT_THAT(penetrations(s, 1e-4), ::testing::IsEmpty());
  const Eigen::Vector3d start = body_pos(s, part.body);
  s.step(static_cast<int>(0.2 / m->opt.timestep));
  const Eigen::Vector3d gripped = body_pos(s, part.body);
  s.step(static_cast<int>(1.5 / m->opt.timestep));
  const Eigen::Vector3d held = body_pos(s, part.body);
  EXPECT_LT((gripped - start).norm(), 0.003) << "the part fell before the fingers closed";
  EXPECT_LT((held - gripped).norm(), 0.001) << "the part slipped in the fingers";
  for (int side = 0; side < 2; ++side) {
    // Each finger presses with the robot's grip force and stands at half the part's width.
    EXPECT_NEAR(sensor1(s, puma.finger_touch_sensor[side]), paper_cell().robots[0].grip_force, 0.5);
    EXPECT_NEAR(sensor1(s, puma.finger_pos_sensor[side]), 0.02, 0.001);
  }
  // The wrist now carries the hand and the part.
  const double weight = (m->body_subtreemass[puma.flange_body] + m->body_mass[part.body]) * 9.81;
  EXPECT_NEAR(sensor3(s, puma.wrist_force_sensor).norm(), weight, 0.03 * weight);
  expect_no_data_warnings(d);
}

TEST_F(SceneTest, ResetRestoresTheInitialState) {
  Scene s = build_scene(paper_cell());
  std::vector<mjtNum> initial(s.data()->qpos, s.data()->qpos + s.model()->nq);
  s.step(500);
  s.reset();
  EXPECT_DOUBLE_EQ(s.data()->time, 0.0);
  for (int i = 0; i < s.model()->nq; ++i) EXPECT_DOUBLE_EQ(s.data()->qpos[i], initial[i]) << "qpos " << i;
  const RobotIds& melfa = *s.find_robot("melfa");
  for (std::size_t j = 0; j < melfa.joints.size(); ++j) {
    EXPECT_DOUBLE_EQ(s.data()->qpos[melfa.qpos_adr[j]], melfa.home[j]);
    EXPECT_DOUBLE_EQ(s.data()->ctrl[melfa.actuator[j]], melfa.home[j]);
  }
  EXPECT_DOUBLE_EQ(s.data()->ctrl[s.find_conveyor("output")->belt_actuator], 0.05);
}

// Meshes are read (tests/twin/vendor_robot_test.cpp); a mesh whose file is missing is refused at its line in the URDF.
TEST_F(SceneTest, AMeshWithoutItsFileIsRefusedAtItsLineInTheUrdf) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "cellwright_scene_test";
  std::filesystem::create_directories(dir);
  std::ifstream in(kSource / "models/urdf/puma560.urdf");
  std::string urdf((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string cylinder = R"(<geometry><cylinder radius="0.1" length="0.5"/></geometry>)";
  ASSERT_NE(urdf.find(cylinder), std::string::npos);
  const auto at = urdf.find(cylinder);
  const int line = 1 + static_cast<int>(std::count(urdf.begin(), urdf.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
  urdf.replace(at, cylinder.size(), R"(<geometry><mesh filename="pedestal.stl"/></geometry>)");
  std::ofstream(dir / "meshy.urdf") << urdf;
  models::CellDescription cell = paper_cell();
  cell.robots[0].urdf = dir / "meshy.urdf";
  try {
    scene_mjcf(cell);
    FAIL() << "a mesh without its file was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, (dir / "meshy.urdf").string());
    EXPECT_EQ(e.where().line, line);
    EXPECT_THAT(e.what(), HasSubstr("mesh 'pedestal.stl': no file " + (dir / "pedestal.stl").string()));
  }
  std::filesystem::remove_all(dir);
}

// MuJoCo's refusals of what a user's URDF says name the URDF's file and the line of the element it came from, and the
// cell file's robot entry, never the generated MJCF's line. Each case edits one element of the PUMA's URDF into
// something the URDF loader takes and MuJoCo's compiler refuses.
struct UrdfRefusal {
  const char* what;
  std::string from, to;   // the text replaced in puma560.urdf, and by what
  std::string at;         // where the error must be: the last line holding this text up to the end of `to`
  const char* problem;    // what MuJoCo says, as the error must say it
  const char* element;    // the URDF element it names
};

class UrdfRefusalTest : public SceneTest {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / fmt::format("cellwright_refusal_{}", ::getpid());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // The error building the paper cell with the PUMA's URDF edited as `c` says, and the line where `c.at` is.
  std::pair<InputError, int> refusal(const UrdfRefusal& c) {
    std::ifstream in(kSource / "models/urdf/puma560.urdf");
    std::string urdf((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto at = urdf.find(c.from);
    EXPECT_NE(at, std::string::npos) << c.from;
    urdf.replace(at, c.from.size(), c.to);
    const auto line_at = urdf.rfind(c.at, at + c.to.size());
    const int line =
        1 + static_cast<int>(std::count(urdf.begin(), urdf.begin() + static_cast<std::ptrdiff_t>(line_at), '\n'));
    std::ofstream(dir_ / "puma.urdf") << urdf;
    models::CellDescription cell = paper_cell();
    cell.robots[0].urdf = dir_ / "puma.urdf";
    try {
      build_scene(cell);
    } catch (const InputError& e) {
      return {e, line};
    }
    ADD_FAILURE() << c.what << ": the scene was built";
    return {InputError({}, ""), line};
  }

  // A binary STL file of these triangles in the test's directory.
  std::filesystem::path stl(const std::string& name, const std::vector<std::array<float, 9>>& triangles) {
    std::string bytes(80, '\0');
    const auto put = [&](const void* p, std::size_t n) { bytes.append(static_cast<const char*>(p), n); };
    const auto count = static_cast<std::uint32_t>(triangles.size());
    put(&count, 4);
    for (const auto& t : triangles) {
      const float normal[3] = {0, 0, 0};
      put(normal, sizeof normal);
      put(t.data(), 36);
      bytes.append(2, '\0');
    }
    std::ofstream(dir_ / name, std::ios::binary) << bytes;
    return dir_ / name;
  }

  std::filesystem::path dir_;
};

TEST_F(UrdfRefusalTest, MujocosRefusalsNameTheUrdfLineAndTheRobotsEntry) {
  stl("nan.stl", {{NAN, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 0, 0, 0, 1, 1, 0, 0}, {0, 0, 0, 0, 1, 0, 0, 0, 1},
                  {1, 0, 0, 0, 1, 0, 0, 0, 1}});
  stl("flat.stl", {{0, 0, 0, 0.1f, 0, 0, 0, 0.1f, 0}, {0, 0, 0, 0, 0.1f, 0, 0.1f, 0, 0}});
  const std::string link3_inertia =
      R"(<mass value="4.8"/>
      <inertia ixx="0.066" ixy="0" ixz="0" iyy="0.086" iyz="0" izz="0.021"/>)";
  const std::string link2_collision = R"(<collision>
      <origin xyz="0.21 0 0.05" rpy="0 0 0"/>
      <geometry><box size="0.58 0.14 0.10"/></geometry>)";
  const std::string link1_collision = R"(<geometry><cylinder radius="0.09" length="0.24"/></geometry>
    </collision>)";
  const std::vector<UrdfRefusal> cases = {
      {"a moving link of no mass", link3_inertia,
       R"(<mass value="0"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>)",
       "<link name=\"link3\"", "inertia must have positive eigenvalues", "link 'link3'"},
      {"an inertia just past the triangle inequality (within the loader's rounding tolerance)", link3_inertia,
       R"(<mass value="4.8"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.2000001"/>)",
       "<link name=\"link3\"", "inertia must satisfy A + B >= C", "link 'link3'"},
      {"a collision box of zero size", link2_collision,
       R"(<collision>
      <origin xyz="0.21 0 0.05" rpy="0 0 0"/>
      <geometry><box size="0 0.14 0.10"/></geometry>)",
       "<collision>", "sizes must be positive", "link 'link2' (its <collision>)"},
      {"a visual cylinder of zero radius", R"(<geometry><cylinder radius="0.09" length="0.24"/></geometry>)",
       R"(<geometry><cylinder radius="0" length="0.24"/></geometry>)", "<visual>", "sizes must be positive",
       "link 'link1' (its <visual>)"},
      {"two collisions of one name", link2_collision,
       R"(<collision name="c"><geometry><box size="0.1 0.1 0.1"/></geometry></collision>
    <collision name="c">
      <origin xyz="0.21 0 0.05" rpy="0 0 0"/>
      <geometry><box size="0.58 0.14 0.10"/></geometry>)",
       "<collision name=\"c\">\n", "repeated name", "link 'link2' (its <collision>)"},
      {"a mesh with a vertex that is not a number", link1_collision,
       R"(<geometry><mesh filename="nan.stl"/></geometry>
    </collision>)",
       "<geometry><mesh", "contains invalid vertices", "mesh 'nan.stl'"},
  };
  const std::string entry = paper_cell().robots[0].where.str();
  for (const UrdfRefusal& c : cases) {
    SCOPED_TRACE(c.what);
    const auto [e, line] = refusal(c);
    EXPECT_EQ(e.where().file, (dir_ / "puma.urdf").string());
    EXPECT_EQ(e.where().line, line);
    EXPECT_THAT(e.problem(), HasSubstr(fmt::format("robot 'puma' ({})", entry)));
    EXPECT_THAT(e.problem(), HasSubstr(c.element));
    EXPECT_THAT(e.problem(), HasSubstr(c.problem));
    EXPECT_THAT(e.problem(), ::testing::Not(HasSubstr("line")));  // no line of the generated MJCF
    EXPECT_THAT(e.problem(), ::testing::Not(HasSubstr("id =")));
  }
}

// A link without <inertial> gets its mass from its collision geometry; a flat mesh has none, and MuJoCo's refusal
// names the mesh's line.
TEST_F(UrdfRefusalTest, AFlatMeshOfALinkWithoutMassIsNamedAtItsLine) {
  stl("flat.stl", {{0, 0, 0, 0.1f, 0, 0, 0, 0.1f, 0}, {0, 0, 0, 0, 0.1f, 0, 0.1f, 0, 0}});
  std::ifstream in(kSource / "models/urdf/puma560.urdf");
  std::string urdf((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto link1 = urdf.find(R"(<link name="link1">)");
  const auto inertial = urdf.find("<inertial>", link1);
  const auto end = urdf.find("</inertial>", inertial) + std::string("</inertial>").size();
  urdf.erase(inertial, end - inertial);
  const std::string collision = R"(<geometry><cylinder radius="0.09" length="0.24"/></geometry>
    </collision>)";
  const auto at = urdf.find(collision, link1);
  ASSERT_NE(at, std::string::npos);
  urdf.replace(at, collision.size(), R"(<geometry><mesh filename="flat.stl"/></geometry>
    </collision>)");
  const int line = 1 + static_cast<int>(std::count(urdf.begin(), urdf.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
  std::ofstream(dir_ / "puma.urdf") << urdf;
  models::CellDescription cell = paper_cell();
  cell.robots[0].urdf = dir_ / "puma.urdf";
  try {
    build_scene(cell);
    FAIL() << "a massless link with a flat mesh was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, (dir_ / "puma.urdf").string());
    EXPECT_EQ(e.where().line, line);
    EXPECT_THAT(e.problem(), HasSubstr("mesh 'flat.stl': MuJoCo rejects it: mesh volume is too small"));
    EXPECT_THAT(e.problem(), ::testing::Not(HasSubstr("puma/mesh")));
  }
}

// Robots that overlap in their home poses: one overlap per pair, naming both bodies and the depth; the paper cell has
// none.
TEST_F(SceneTest, RobotsThatOverlapAtTheStartAreFoundOncePerPair) {
  EXPECT_THAT(start_overlaps(build_scene(paper_cell())), ::testing::IsEmpty());
  const models::CellDescription cell = models::load_cell(kSource / "tests/data/overlap/cell.yaml");
  const std::vector<StartOverlap> found = start_overlaps(build_scene(cell));
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].robot, "p1");
  EXPECT_EQ(found[0].other_robot, "p2");
  EXPECT_THAT(found[0].body, HasSubstr("link '"));
  EXPECT_THAT(found[0].other, HasSubstr("link '"));
  EXPECT_GT(found[0].depth, 0.01);
  const InputError e = start_overlap_error(found);
  EXPECT_EQ(e.where().file, cell.robots[0].where.file);
  EXPECT_EQ(e.where().line, cell.robots[0].where.line);
  EXPECT_THAT(e.problem(), HasSubstr(found[0].text()));
  EXPECT_THAT(e.problem(), HasSubstr(cell.robots[1].where.str()));
}

}  // namespace
}  // namespace cellwright::twin
