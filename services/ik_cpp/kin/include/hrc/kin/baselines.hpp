#pragma once
// Baseline IK solvers for hrc-ik-bench: KDL's NR_JL and LMA, and the gradient descent of the
// thesis (chapter 4: Zucconi-style per-joint finite-difference descent).

#include "hrc/kin/ik.hpp"
#include "hrc/kin/robot_model.hpp"

#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_lma.hpp>
#include <kdl/chainiksolverpos_nr_jl.hpp>
#include <kdl/chainiksolvervel_pinv.hpp>

#include <memory>

namespace hrc::kin {

// KDL ChainIkSolverPos_NR_JL with ChainIkSolverVel_pinv, KDL defaults (100 iterations, eps 1e-6).
class KdlNrJlSolver {
 public:
  explicit KdlNrJlSolver(const RobotModel& model);
  // Full-pose target (KDL solvers are 6-D). Returns KDL's error code (0 = converged).
  int solve(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed, Eigen::VectorXd& q_out);

 private:
  std::unique_ptr<KDL::ChainFkSolverPos_recursive> fk_;
  std::unique_ptr<KDL::ChainIkSolverVel_pinv> vel_;
  std::unique_ptr<KDL::ChainIkSolverPos_NR_JL> ik_;
  KDL::JntArray q_init_, q_out_;
};

// KDL ChainIkSolverPos_LMA with its defaults (weights 1,1,1,0.01,0.01,0.01; eps 1e-5; 500 iter).
// LMA ignores joint limits; revolute results are wrapped by 2*pi into the limits where possible.
class KdlLmaSolver {
 public:
  explicit KdlLmaSolver(const RobotModel& model);
  int solve(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed, Eigen::VectorXd& q_out);

 private:
  const RobotModel& model_;
  std::unique_ptr<KDL::ChainIkSolverPos_LMA> ik_;
  KDL::JntArray q_init_, q_out_;
};

// The thesis's inverse kinematics (chapter 4.3/4.4 and its RobotController listing):
//  - angles in degrees; each sweep visits the joints from the last to the first;
//  - gradient_i = (F(x + delta e_i) - F(x)) / delta with delta = DeltaGradient = 0.1 deg
//    (forward difference, one-sided);
//  - Solution[i] -= LearningRate * gradient_i, then clamped to the joint limits;
//  - early termination as soon as F <= StopThreshold;
//  - one sweep per frame, so a move is capped by frames: here max_sweeps.
// F is the thesis's DistanceFromTarget (m) plus, because the benchmark also asks for orientation,
// orientation_weight * angle error (rad) (tool-axis angle for PositionAxis targets).
struct GradientDescentOptions {
  double learning_rate = 50.0;      // deg per (m/deg); best of 1..400 on arm5/UR5, bench/README.md
  double delta_deg = 0.1;           // DeltaGradient
  double stop_threshold = 0.5e-4;   // m-equivalent; the thesis used 0.1 (tuned for Unity metres)
  double orientation_weight = 0.1;  // m per rad
  int max_sweeps = 2000;
};

class GradientDescentSolver {
 public:
  GradientDescentSolver(const RobotModel& model, GradientDescentOptions options = {});
  // Returns true when F <= stop_threshold was reached.
  bool solve(const IkTarget& target, const Eigen::VectorXd& seed, Eigen::VectorXd& q_out);

 private:
  double error(const IkTarget& target, const double* q_rad) const;
  const RobotModel& model_;
  GradientDescentOptions options_;
  ChainEval eval_;
  JointVec sol_deg_, q_rad_;
};

}  // namespace hrc::kin
