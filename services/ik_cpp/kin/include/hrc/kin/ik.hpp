#pragma once
// The service's inverse kinematics: closed form where the chain allows it (Arm5Analytic), else
// damped least squares / Levenberg-Marquardt with a weighted task space, joint-limit clamping with
// an active set, and seeded random restarts out of joint-limit minima.

#include "hrc/kin/arm5_analytic.hpp"
#include "hrc/kin/kinematics.hpp"
#include "hrc/kin/robot_model.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <random>

namespace hrc::kin {

enum class TaskMode {
  Position,      // tool point only (3 rows)
  PositionAxis,  // tool point + tool z axis direction (5 rows; free rotation about the axis)
  Pose,          // tool point + full orientation (6 rows)
};

struct IkTarget {
  TaskMode mode = TaskMode::Pose;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // Pose
  Eigen::Vector3d axis = -Eigen::Vector3d::UnitZ();        // PositionAxis (unit)

  static IkTarget pose(const Eigen::Isometry3d& T);
  static IkTarget position_axis(const Eigen::Vector3d& p, const Eigen::Vector3d& axis);
  static IkTarget position_only(const Eigen::Vector3d& p);
};

enum class IkStatus { Ok, Unreachable, InvalidInput };
const char* to_string(IkStatus s);

struct IkResult {
  IkStatus status = IkStatus::InvalidInput;
  Eigen::VectorXd q;            // solution, or the best joints found (finite, within limits)
  double position_error = 0.0;  // m
  double angle_error = 0.0;     // rad (tool axis angle for PositionAxis, 0 for Position)
  int iterations = 0;
  int restarts = 0;
  bool analytic = false;
};

struct IkOptions {
  double position_tolerance = 1e-6;  // m
  double angle_tolerance = 1e-5;     // rad
  int max_iterations = 60;           // per attempt
  int max_restarts = 40;             // random restarts after the seeded attempt
  double rotation_weight = 0.3;      // m per rad: orientation rows relative to position rows
  double max_step = 0.6;             // rad, trust region on one joint update (inf-norm)
  double damping = 0.3;              // lambda = damping * cost + 1e-9 (error-based damping)
  double stall_ratio = 1e-2;         // an attempt is stuck after stall_count steps that each
  int stall_count = 5;               //   reduce the cost by less than this fraction
  std::uint64_t seed = 0x5eed;       // restarts are reseeded per solve: pure function of inputs
  bool use_analytic = true;
};

class IkSolver {
 public:
  explicit IkSolver(const RobotModel& model, IkOptions options = {});

  // Solve for `target` (base frame) starting at `seed`. `out.q` is resized once and reused, so a
  // caller that keeps its IkResult does not allocate. Returns out.status == IkStatus::Ok.
  bool solve(const IkTarget& target, const Eigen::VectorXd& seed, IkResult& out);
  IkResult solve(const IkTarget& target, const Eigen::VectorXd& seed);

  // Numeric path only (tests compare it with the closed form).
  bool solve_numeric(const IkTarget& target, const Eigen::VectorXd& seed, IkResult& out);

  const RobotModel& model() const { return model_; }
  const ChainEval& eval() const { return eval_; }
  bool has_analytic() const { return analytic_.has_value(); }
  const IkOptions& options() const { return options_; }

  // Task errors of configuration q for target (position m, angle rad).
  void errors(const IkTarget& target, const double* q, double& pos_err, double& ang_err) const;

 private:
  // One damped least-squares descent from q (in/out). Returns true on convergence.
  bool descend(const IkTarget& target, JointVec& q, int& iterations, double& cost);
  double cost(const IkTarget& target, const Eigen::Matrix3d& R, const Eigen::Vector3d& p,
              Eigen::Matrix<double, 6, 1>& e, double& pos_err, double& ang_err) const;

  const RobotModel& model_;
  IkOptions options_;
  ChainEval eval_;
  std::optional<Arm5Analytic> analytic_;
  JointVec lower_, upper_, slo_, shi_;
  std::mt19937_64 rng_;
};

// Map revolute angles by multiples of 2*pi into the limits where possible (closest to the range
// middle otherwise untouched). Used to normalise solutions of limit-unaware solvers.
void wrap_into_limits(const RobotModel& model, Eigen::VectorXd& q);

}  // namespace hrc::kin
