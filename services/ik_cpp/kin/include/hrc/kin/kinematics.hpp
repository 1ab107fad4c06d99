#pragma once
// Forward kinematics and Jacobians with Eigen at the interface.
//  - KdlKinematics: KDL's ChainFkSolverPos_recursive / ChainJntToJacSolver (reference, tests,
//  bench).
//  - ChainEval: the same chain flattened into Eigen matrices (one pass gives pose and Jacobian,
//    no allocation). IK inner loops call it thousands of times per solve.

#include "hrc/kin/robot_model.hpp"

#include <Eigen/Geometry>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainjnttojacsolver.hpp>

#include <memory>
#include <vector>

namespace hrc::kin {

// Largest chain the allocation-free solvers accept (fixed-capacity Eigen storage).
constexpr int kMaxDof = 12;
using JointVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxDof, 1>;
using Jacobian6 = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxDof>;

class KdlKinematics {
 public:
  explicit KdlKinematics(const RobotModel& model);
  Eigen::Isometry3d fk(const Eigen::VectorXd& q) const;
  // Rows 0-2 linear velocity of the tip origin, rows 3-5 angular velocity, base frame.
  Eigen::Matrix<double, 6, Eigen::Dynamic> jacobian(const Eigen::VectorXd& q) const;

 private:
  const KDL::Chain& chain_;
  std::unique_ptr<KDL::ChainFkSolverPos_recursive> fk_;
  std::unique_ptr<KDL::ChainJntToJacSolver> jac_;
  mutable KDL::JntArray q_;
};

class ChainEval {
 public:
  explicit ChainEval(const KDL::Chain& chain);
  int dof() const { return static_cast<int>(joints_.size()); }
  // Tip pose in the base frame.
  void fk(const double* q, Eigen::Matrix3d& R, Eigen::Vector3d& p) const;
  // Tip pose and geometric Jacobian (same layout as KdlKinematics::jacobian).
  void fk_jacobian(const double* q, Eigen::Matrix3d& R, Eigen::Vector3d& p, Jacobian6& J) const;
  // Joint origin and world axis of joint i at configuration q (used by the analytic solver).
  void joint_frame(const double* q, int i, Eigen::Vector3d& origin, Eigen::Vector3d& axis) const;

 private:
  struct Joint {
    Eigen::Matrix3d pre_R;  // fixed transform from the previous joint (after its motion) ...
    Eigen::Vector3d pre_p;  // ... to this joint's axis point
    Eigen::Vector3d axis;   // unit axis in the frame after pre
    double scale, offset;
    bool prismatic;
    int axis_index;  // 0/1/2 when axis is +x/+y/+z (fast path), -1 otherwise
    bool pre_R_identity;
  };
  // (R, p) = (R, p) * pre: the frame at the joint point, before its motion.
  static void apply_pre(const Joint& j, Eigen::Matrix3d& R, Eigen::Vector3d& p);
  // (R, p) = (R, p) * motion(v): rotation about / translation along the joint axis.
  static void apply_motion(const Joint& j, double v, Eigen::Matrix3d& R, Eigen::Vector3d& p);
  std::vector<Joint> joints_;
  Eigen::Matrix3d post_R_;
  Eigen::Vector3d post_p_;
};

// Helpers shared by solvers, tests and the motion generator.
// Rotation angle (rad) between two rotation matrices.
double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);
// Angle (rad) between two directions (normalised internally).
double axis_angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b);
// Tool pointing down (tool z = world -z) with yaw `yaw` (rad) of the tool x axis about world z:
// R = Rz(yaw) * Rx(pi).
Eigen::Matrix3d tool_down_rotation(double yaw);

}  // namespace hrc::kin
