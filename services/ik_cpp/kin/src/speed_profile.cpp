#include "hrc/kin/speed_profile.hpp"

#include <algorithm>
#include <cmath>

namespace hrc::kin {
namespace {

// Distance covered by a cosine ramp from va to vb lasting T: the mean speed times T.
double ramp_distance(double va, double vb, double T) { return 0.5 * (va + vb) * T; }

// Position within a cosine ramp at time t in [0, T].
double ramp_position(double va, double vb, double T, double t) {
  if (T <= 0) return 0.0;
  return va * t + 0.5 * (vb - va) * (t - T / M_PI * std::sin(M_PI * t / T));
}

double ramp_speed(double va, double vb, double T, double t) {
  if (T <= 0) return vb;
  return va + 0.5 * (vb - va) * (1.0 - std::cos(M_PI * t / T));
}

}  // namespace

double SpeedProfile::ramp_time(double dv, const ProfileLimits& lim) {
  const double a = std::abs(dv);
  // Peak accel of the cosine ramp is pi dv / (2T); peak jerk is pi^2 dv / (2T^2).
  return std::max(M_PI * a / (2.0 * lim.max_accel), M_PI * std::sqrt(a / (2.0 * lim.max_jerk)));
}

double SpeedProfile::braking_distance(double v0, const ProfileLimits& lim) {
  return ramp_distance(v0, 0.0, ramp_time(v0, lim));
}

bool SpeedProfile::plan(double length, double v0, const ProfileLimits& lim) {
  length = std::max(0.0, length);
  v0 = std::max(0.0, v0);
  const double vmax = lim.max_speed;
  // Distance needed to go v0 -> vp -> 0 with no cruise.
  const auto needed = [&](double vp) {
    return ramp_distance(v0, vp, ramp_time(vp - v0, lim)) +
           ramp_distance(vp, 0.0, ramp_time(vp, lim));
  };
  double vp;
  if (v0 <= vmax) {
    if (needed(v0) > length + 1e-12) return false;
    if (needed(vmax) <= length) {
      vp = vmax;
    } else {
      double lo = v0, hi = vmax;  // needed() is increasing on [v0, vmax]
      for (int i = 0; i < 60; ++i) {
        const double mid = 0.5 * (lo + hi);
        (needed(mid) <= length ? lo : hi) = mid;
      }
      vp = lo;
    }
  } else {
    // Faster than the (lowered) limit: come down to it first, cruise, stop.
    if (needed(vmax) > length + 1e-12) return false;
    vp = vmax;
  }
  v0_ = v0;
  vp_ = vp;
  length_ = length;
  t1_ = ramp_time(vp - v0, lim);
  t3_ = ramp_time(vp, lim);
  d1_ = ramp_distance(v0, vp, t1_);
  const double d3 = ramp_distance(vp, 0.0, t3_);
  d2_ = std::max(0.0, length - d1_ - d3);
  t2_ = vp > 1e-12 ? d2_ / vp : 0.0;
  return true;
}

void SpeedProfile::plan_brake(double v0, const ProfileLimits& lim) {
  v0_ = vp_ = std::max(0.0, v0);
  t1_ = t2_ = 0.0;
  d1_ = d2_ = 0.0;
  t3_ = ramp_time(v0_, lim);
  length_ = ramp_distance(v0_, 0.0, t3_);
}

void SpeedProfile::eval(double t, double& s, double& v) const {
  if (t <= 0) {
    s = 0;
    v = v0_;
  } else if (t < t1_) {
    s = ramp_position(v0_, vp_, t1_, t);
    v = ramp_speed(v0_, vp_, t1_, t);
  } else if (t < t1_ + t2_) {
    s = d1_ + vp_ * (t - t1_);
    v = vp_;
  } else if (t < t1_ + t2_ + t3_) {
    const double tt = t - t1_ - t2_;
    s = d1_ + d2_ + ramp_position(vp_, 0.0, t3_, tt);
    v = ramp_speed(vp_, 0.0, t3_, tt);
  } else {
    s = length_;
    v = 0;
  }
  s = std::min(s, length_);
}

}  // namespace hrc::kin
