// The motion generator's own helpers, shared by its source files (motion.cpp: state and
// execution; motion_plan.cpp: planning; motion_brake.cpp: braking; motion_recover.cpp: leaving,
// detours and resuming after an interruption). Not part of the library's interface.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "hrc/kin/motion.hpp"

namespace hrc::kin::motion_detail {

inline std::string fmt_point(const Eigen::Vector3d& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.3f, %.3f, %.3f)", p.x(), p.y(), p.z());
  return buf;
}

inline bool finite(double v) { return std::isfinite(v); }

constexpr double kJointStep = 0.01;     // rad: spacing of the FK samples of a joint path
constexpr double kJointMeasure = 0.02;  // m per rad: a pure joint motion still takes time
// rad: how far the exact IK of a line may be from its interpolated samples (samples are
// check_step apart, so the true difference is far smaller; more means another branch)
constexpr double kSampleTolerance = 0.02;
constexpr double kAtLeavePoint = 1e-4;  // rad: an arm this close to its leave point stands there

inline bool same_move(const MoveCommand& a, const MoveCommand& b) {
  return a.target == b.target && a.yaw == b.yaw && a.approach_height == b.approach_height &&
         a.depart_height == b.depart_height && a.max_speed == b.max_speed;
}

inline std::string fmt_num(double v, int decimals) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// Why the closest IK solution is not one: how far the tool is off in position and pointing.
inline std::string closest(const IkResult& r) {
  return "(closest: " + fmt_num(r.position_error * 1000.0, 1) + " mm away, tool axis " +
         fmt_num(r.angle_error * 180.0 / M_PI, 1) + " deg off)";
}

}  // namespace hrc::kin::motion_detail
