// Kinematic chains read from URDF files: forward kinematics, Jacobian and inverse kinematics of a serial arm.
//
// A KinematicChain is the serial chain of joints from one link of a URDF (the base) to another (the tip). It is a
// fixed model: immutable after construction, copyable, and every const method may be called from any thread at the
// same time. Joint vectors q are ordered from base to tip (joint_names()); revolute joints in radians, prismatic in
// metres. Poses are in the base link's frame, in metres.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "cellwright/common/error.hpp"  // InputError, thrown by the from_urdf_* factories

namespace cellwright::models {

// Directory holding the robot models (models/ in the source tree); the URDF files are in models_dir()/urdf.
constexpr const char* models_dir() {
  return CW_MODELS_DIR;
}

// A joint's travel: radians (revolute) or metres (prismatic). A continuous joint has lower = -inf, upper = +inf.
// velocity is the URDF's <limit velocity> (rad/s or m/s), 0 where the joint gives none.
struct JointLimit {
  double lower, upper;
  double velocity = 0;
};

class UrdfModel;  // urdf.hpp

// How hard inverse() tries. Tolerances are the largest errors of an answer it accepts: position in metres, orientation
// as the angle of the rotation between the reached and the wanted orientation, in radians.
struct IkOptions {
  double position_tolerance = 1e-5;
  double orientation_tolerance = 1e-4;
  int max_iterations = 200;  // per start
  int restarts = 8;          // further damped-least-squares starts from fixed pseudo-random joint vectors (see inverse)
};

enum class IkStatus { kOk, kUnreachable };

struct IkResult {
  IkStatus status;
  // kOk: the joint vector found (within limits). kUnreachable: the nearest miss the search tried, or the seed
  // (clamped into the limits) with infinite errors when the target was rejected before any search.
  Eigen::VectorXd q;
  double position_error;     // |p(q) - p_target| in metres, for q above
  double orientation_error;  // angle of R(q)^T R_target in radians, for q above
  // kUnreachable only: why, e.g. "out of reach: 1.513 m from joint1's origin > max reach 1.161 m", "outside the joint
  // limits: the pose has 8 joint solution(s) ignoring limits and none within them (e.g. joint3 = 1.950 outside
  // [-3.927, 0.785])" or "the wrist centre (...) m cannot be reached by joints joint1, joint2, joint3".
  std::string reason;
};

class KinematicChain {
 public:
  // Reads a URDF file with the URDF loader (urdf.hpp) and builds the chain from link `base` to link `tip`.
  // Throws InputError naming the file (and the line where one applies) if the file cannot be read, is not well-formed
  // XML, is not a valid URDF (as load_urdf_file), lacks either link, `base` is not an ancestor of `tip`, the chain
  // holds a joint type other than fixed/revolute/continuous/prismatic or a mimic joint, has no movable joint, or has
  // invalid numbers (a zero axis, a non-finite origin, lower limit > upper limit). Parses are serialized internally
  // (urdfdom's logger is global); any thread may call it.
  static KinematicChain from_urdf_file(const std::filesystem::path& urdf, const std::string& base = "base_link",
                                       const std::string& tip = "tcp");
  // As from_urdf_file, for URDF text already in memory; errors name `file_label` as the file.
  static KinematicChain from_urdf_string(const std::string& xml, const std::string& file_label,
                                         const std::string& base = "base_link", const std::string& tip = "tcp");
  // As from_urdf_file, for a robot the URDF loader (urdf.hpp) has read already; errors name its file.
  static KinematicChain from_urdf(const UrdfModel& robot, const std::string& base = "base_link",
                                  const std::string& tip = "tcp");

  // This chain with a tool fixed to its tip: the new tip, named `tip`, is at `tool` in the old tip's frame (a gripper
  // mounted on a flange). The maximum reach and the spherical wrist are found again.
  KinematicChain mounted(const Eigen::Isometry3d& tool, const std::string& tip) const;

  // Number of revolute, continuous and prismatic joints between base and tip.
  std::size_t dof() const { return joints_.size(); }
  // Their names, base to tip.
  const std::vector<std::string>& joint_names() const { return names_; }
  // Their limits, in the same order.
  const std::vector<JointLimit>& limits() const { return limits_; }
  const std::string& base_link() const { return base_; }
  const std::string& tip_link() const { return tip_; }
  // True if q has dof() entries, all finite and within limits() (inclusive).
  bool within_limits(const Eigen::VectorXd& q) const;

  // The tip's pose in the base frame at joint vector q. q.size() must equal dof() (else InternalError); limits are
  // not enforced here.
  // The moving frame of joint `count` (1-based, after its motion) in the base frame: the product of the first `count`
  // joint transforms. The safety layer watches the wrist through it.
  Eigen::Isometry3d joint_frame(const Eigen::VectorXd& q, std::size_t count) const { return partial_forward(q, count); }
  Eigen::Isometry3d forward(const Eigen::VectorXd& q) const;
  // joint_frame(q, k) for every k = 1..dof() (element k - 1), then forward(q) (element dof()), in one walk down the
  // chain: the same products in the same order, so the same bits as those calls, at the cost of one of them.
  // q.size() must equal dof() (else InternalError).
  std::vector<Eigen::Isometry3d> frames(const Eigen::VectorXd& q) const;
  // The geometric Jacobian of the tip at q, in the base frame: rows 0-2 map joint velocities to the tip origin's
  // linear velocity, rows 3-5 to its angular velocity. q.size() must equal dof() (else InternalError).
  Eigen::Matrix<double, 6, Eigen::Dynamic> jacobian(const Eigen::VectorXd& q) const;

  // A joint vector within limits whose tip pose is `target` within the tolerances, the one closest to q_seed
  // (Euclidean distance in joint space) among those found. For a 6-joint chain whose last three axes meet in a point
  // (a spherical wrist, as both cell arms have) it lists every solution: the wrist-centre position problem of the
  // first three joints is solved from many starts, the wrist in closed form (Paden-Kahan subproblems), and revolute
  // joints are shifted by whole turns towards q_seed where the limits allow. Any chain also gets damped least squares
  // (Levenberg-Marquardt) from q_seed and, if nothing was found yet, from options.restarts fixed pseudo-random starts.
  // The answer's forward kinematics is checked before kOk is returned. Never throws for an unreachable or non-finite
  // target: returns kUnreachable with a reason. Deterministic: the same arguments give the same result.
  // q_seed.size() must equal dof() and the options must have positive tolerances and iterations and restarts >= 0
  // (else InternalError); a seed outside the limits is clamped into them. Any thread may call it.
  IkResult inverse(const Eigen::Isometry3d& target, const Eigen::VectorXd& q_seed, const IkOptions& options = {}) const;

  // An upper bound on the distance from joint 1's origin (a point on its axis; it does not move with q) to the tip:
  // the sum of the distances between successive joint origins and to the tip, plus prismatic travel.
  double max_reach() const { return max_reach_; }
  // Joint 1's origin in the base frame.
  const Eigen::Vector3d& first_joint_origin() const { return first_joint_origin_; }

 private:
  struct Joint {
    Eigen::Isometry3d origin;  // from the previous joint's moving frame (or the base) to this joint's frame at q = 0
    Eigen::Vector3d axis;      // unit axis in this joint's frame
    bool prismatic;
    // Moves t, the frame before this joint's origin, to the frame after its motion q: every walk's one step.
    void advance(Eigen::Isometry3d& t, double q) const;
  };

  // A spherical wrist: joints 4-6 (indices 3-5) are revolute with axes meeting at one point, the wrist centre.
  struct Wrist {
    bool present = false;
    // The wrist centre in the moving frame of joint 3.
    Eigen::Vector3d centre_in_arm = Eigen::Vector3d::Zero();
    // The wrist centre in the tip frame (constant, as the wrist is spherical).
    Eigen::Vector3d centre_in_tip = Eigen::Vector3d::Zero();
    // Joint 4-6 axes in joint 3's moving frame, with the wrist joints at 0.
    Eigen::Vector3d axis[3] = {Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()};
    // The tip's orientation in joint 3's moving frame, with the wrist joints at 0.
    Eigen::Matrix3d tip_rotation = Eigen::Matrix3d::Identity();
  };

  KinematicChain() = default;
  // Fills wrist_ if the chain has a spherical wrist.
  void find_spherical_wrist();
  // Moving frame of joint `count - 1` (after its motion), i.e. the product of the first `count` joint transforms.
  Eigen::Isometry3d partial_forward(const Eigen::VectorXd& q, std::size_t count) const;
  // Joint vectors (limits ignored) putting the tip at `target`, through the spherical wrist decomposition; `complete`
  // is set when the search provably found them all (four isolated wrist-centre solutions, the most three joints
  // can have).
  std::vector<Eigen::VectorXd> wrist_solutions(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed,
                                               bool& complete) const;

  std::string base_, tip_;
  std::vector<Joint> joints_;
  std::vector<std::string> names_;
  std::vector<JointLimit> limits_;
  Eigen::Isometry3d tip_offset_ = Eigen::Isometry3d::Identity();  // from the last joint's moving frame to the tip
  double max_reach_ = 0;
  Eigen::Vector3d first_joint_origin_ = Eigen::Vector3d::Zero();
  Wrist wrist_;
};

}  // namespace cellwright::models
