#pragma once
// 1-D speed profile along a path of length L: ramp v0 -> vp, cruise at vp, ramp vp -> 0.
// Each ramp is a cosine blend of the speed, v(t) = va + (vb - va) (1 - cos(pi t / T)) / 2, so the
// acceleration is continuous (zero at both ends of a ramp) and bounded by max_accel, and the jerk
// is bounded by max_jerk: T = max(pi |dv| / (2 a), pi sqrt(|dv| / (2 j))).

namespace hrc::kin {

struct ProfileLimits {
  double max_speed = 0.5;  // m/s
  double max_accel = 2.0;  // m/s^2
  double max_jerk = 20.0;  // m/s^3
};

class SpeedProfile {
 public:
  // Plan from speed v0 >= 0 to rest at distance L >= 0. Returns false (profile unchanged) when
  // stopping within L is impossible from v0: the caller must brake first (see braking_distance).
  bool plan(double length, double v0, const ProfileLimits& limits);
  // A braking profile: from v0 to rest as fast as the limits allow; length = braking_distance.
  void plan_brake(double v0, const ProfileLimits& limits);

  // Distance and speed at time t >= 0 (t beyond the end: length, 0).
  void eval(double t, double& s, double& v) const;
  double duration() const { return t1_ + t2_ + t3_; }
  double length() const { return length_; }
  double peak_speed() const { return vp_; }

  static double ramp_time(double dv, const ProfileLimits& limits);
  static double braking_distance(double v0, const ProfileLimits& limits);

 private:
  double length_ = 0, v0_ = 0, vp_ = 0;
  double t1_ = 0, t2_ = 0, t3_ = 0;  // ramp, cruise, ramp durations
  double d1_ = 0, d2_ = 0;           // distances of the first ramp and the cruise
};

}  // namespace hrc::kin
