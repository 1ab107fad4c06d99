#pragma once
// A serial chain loaded from a URDF: the KDL chain base -> tip plus joint names and limits.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <kdl/chain.hpp>

#include <map>
#include <optional>
#include <string>
#include <vector>

namespace hrc::kin {

// An Eigen pose as KDL's frame (the chain's fixed segments, KDL's solvers' targets).
KDL::Frame to_kdl(const Eigen::Isometry3d& X);

class RobotModel {
 public:
  // Parse a URDF file (urdfdom) and extract the chain from `base` to `tip`.
  // Throws std::runtime_error naming the file and what is wrong (unreadable, bad XML, unknown link,
  // tip not below base, unsupported joint type, missing limits).
  static RobotModel from_urdf_file(const std::string& path, const std::string& base = "base_link",
                                   const std::string& tip = "tool");
  static RobotModel from_urdf_string(const std::string& xml, const std::string& base = "base_link",
                                     const std::string& tip = "tool",
                                     const std::string& source = "<string>");

  // Appends the tool centre point, a fixed pose in the tip link's frame (a gripper's
  // fingertips): the chain then ends at the TCP, so FK and IK speak of it.
  void attach_tcp(const Eigen::Isometry3d& tip_T_tcp);

  const std::string& name() const { return name_; }
  const std::string& base_link() const { return base_; }
  const std::string& tip_link() const { return tip_; }
  const KDL::Chain& chain() const { return chain_; }
  int dof() const { return static_cast<int>(joint_names_.size()); }
  const std::vector<std::string>& joint_names() const { return joint_names_; }

  // Position limits; unbounded (continuous) joints have -inf / +inf.
  const Eigen::VectorXd& lower() const { return lower_; }
  const Eigen::VectorXd& upper() const { return upper_; }
  // Velocity limits (rad/s or m/s); +inf where the URDF gives none.
  const Eigen::VectorXd& max_velocity() const { return max_velocity_; }
  bool bounded(int i) const { return bounded_[static_cast<std::size_t>(i)]; }
  bool revolute(int i) const { return revolute_[static_cast<std::size_t>(i)]; }

  // Any movable joint of the URDF, in the chain or not (a gripper's fingers): its limits.
  struct JointLimit {
    double lower, upper, velocity;  // velocity +inf where the URDF gives none
  };
  std::optional<JointLimit> joint_limit(const std::string& name) const;

  // base_T_links[j]: the frame of movable joint j's child link (joint_names' order) in the chain's
  // base frame at q, the URDF's link frame (its origin on the joint's axis). How fast these move
  // bounds how fast any point of the arm moves (RobotState.link_*_speed_bounds).
  void joint_child_frames(const Eigen::VectorXd& q,
                          std::vector<Eigen::Isometry3d>& base_T_links) const;

  bool within_limits(const Eigen::VectorXd& q, double tol = 1e-9) const;
  Eigen::VectorXd clamp(const Eigen::VectorXd& q) const;
  // Middle of each joint range (0 for unbounded joints): the benchmark's seed.
  Eigen::VectorXd mid_range() const;
  // Bounds used for random sampling: the limits, or [-pi, pi] for unbounded joints.
  double sample_lower(int i) const;
  double sample_upper(int i) const;

 private:
  std::string name_, base_, tip_;
  KDL::Chain chain_;
  std::vector<std::string> joint_names_;
  Eigen::VectorXd lower_, upper_, max_velocity_;
  std::vector<bool> bounded_;
  std::vector<bool> revolute_;
  std::map<std::string, JointLimit> all_limits_;
};

}  // namespace hrc::kin
