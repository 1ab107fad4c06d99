#pragma once
// Closed-form IK for "yaw - pitch - pitch - pitch - roll" arms such as robots/arm5.urdf.
// Detected from the chain (axes and joint origins at q = 0) and verified on sample poses at
// construction; chains that do not match get no analytic solver and use the numeric one.
//
// Geometry: q1 turns about the base z axis; the three pitch joints are parallel and
// perpendicular to it; at q = 0 all joint points and the tool lie on the base z axis; the roll
// joint turns about the tool z axis.  Then: q1 = atan2(y, x) (or + pi), the wrist point is the tool
// point minus L4 * tool axis, a planar two-link solves shoulder/elbow (elbow up/down) and the
// wrist pitch makes the total pitch equal to the tool-axis pitch; the roll sets the yaw.

#include "hrc/kin/kinematics.hpp"
#include "hrc/kin/robot_model.hpp"

#include <Eigen/Geometry>

#include <optional>

namespace hrc::kin {

class Arm5Analytic {
 public:
  // nullopt when the chain does not have the required structure.
  static std::optional<Arm5Analytic> detect(const RobotModel& model, const ChainEval& eval);

  // Tool point `p`, tool axis `axis` (unit, base frame), and optionally the full rotation
  // (`R` != nullptr: roll chosen to match it).  Picks, among the solutions within limits, the one
  // closest to `seed`.  Returns false when no exact solution within limits exists.
  bool solve(const Eigen::Vector3d& p, const Eigen::Vector3d& axis, const Eigen::Matrix3d* R,
             const double* seed, double* q_out) const;

  double shoulder_height() const { return h_; }
  double upper_arm() const { return l2_; }
  double forearm() const { return l3_; }
  double wrist_to_tool() const { return l4_; }

 private:
  Arm5Analytic(const RobotModel& model, const ChainEval& eval) : model_(&model), eval_(&eval) {}
  // Closest value to `ref` of angle + 2*pi*k within [lo, hi]; false if none.
  static bool fit_angle(double angle, double lo, double hi, double ref, double& out);

  const RobotModel* model_;
  const ChainEval* eval_;
  double h_ = 0, l2_ = 0, l3_ = 0, l4_ = 0;
  double s1_ = 1, s2_ = 1, s3_ = 1, s4_ = 1, s5_ = 1;  // joint axis signs
};

}  // namespace hrc::kin
