// The 1-D speed profile: capped, smooth (bounded acceleration and jerk), reaches its end.
#include "hrc/kin/speed_profile.hpp"

#include <gtest/gtest.h>

#include <cmath>

using hrc::kin::ProfileLimits;
using hrc::kin::SpeedProfile;

namespace {
// Sample the profile at dt and check speed/acceleration/jerk bounds and monotonic progress.
void check_profile(const SpeedProfile& p, const ProfileLimits& lim, double v0) {
  const double dt = 1e-4;
  double s_prev = 0, v_prev = v0, a_prev = 0, peak = 0;
  double s, v;
  p.eval(0.0, s, v);
  EXPECT_NEAR(s, 0.0, 1e-12);
  EXPECT_NEAR(v, v0, 1e-12);
  const int n = static_cast<int>(p.duration() / dt) + 10;
  for (int k = 1; k <= n; ++k) {
    p.eval(k * dt, s, v);
    const double a = (v - v_prev) / dt;
    EXPECT_GE(s, s_prev - 1e-12) << "moves backwards at t=" << k * dt;
    EXPECT_LE(v, std::max(lim.max_speed, v0) + 1e-9);
    EXPECT_LE(std::abs(a), lim.max_accel * 1.001 + 1e-9) << "t=" << k * dt;
    if (k > 1) EXPECT_LE(std::abs(a - a_prev) / dt, lim.max_jerk * 1.01 + 1e-6) << "t=" << k * dt;
    // Consistency: distance increment matches the mean speed.
    EXPECT_NEAR(s - s_prev, 0.5 * (v + v_prev) * dt, 1e-7);
    peak = std::max(peak, v);
    s_prev = s;
    v_prev = v;
    a_prev = a;
  }
  EXPECT_NEAR(s, p.length(), 1e-12);
  EXPECT_EQ(v, 0.0);
  EXPECT_NEAR(peak, std::max(v0, p.peak_speed()), 1e-3);
}
}  // namespace

TEST(SpeedProfile, LongMoveCruisesAtTheCap) {
  const ProfileLimits lim{0.5, 2.0, 20.0};
  SpeedProfile p;
  ASSERT_TRUE(p.plan(1.0, 0.0, lim));
  EXPECT_DOUBLE_EQ(p.peak_speed(), 0.5);
  check_profile(p, lim, 0.0);
  // Ramps take pi v / (2 a) each; the rest cruises: duration = 2 T_ramp + (L - ramp distances) / v.
  const double tr = M_PI * 0.5 / (2 * 2.0);
  EXPECT_NEAR(p.duration(), 2 * tr + (1.0 - 0.5 * 0.5 * tr * 2) / 0.5, 1e-9);
}

TEST(SpeedProfile, ShortMoveStaysBelowTheCap) {
  const ProfileLimits lim{0.5, 2.0, 20.0};
  SpeedProfile p;
  ASSERT_TRUE(p.plan(0.02, 0.0, lim));
  EXPECT_LT(p.peak_speed(), 0.5);
  EXPECT_GT(p.peak_speed(), 0.0);
  check_profile(p, lim, 0.0);
}

TEST(SpeedProfile, StartsFromTheCurrentSpeed) {
  const ProfileLimits lim{0.5, 2.0, 20.0};
  SpeedProfile p;
  ASSERT_TRUE(p.plan(0.4, 0.3, lim));
  check_profile(p, lim, 0.3);
  // Faster than a lowered cap: slows down to it smoothly.
  const ProfileLimits slow{0.1, 2.0, 20.0};
  ASSERT_TRUE(p.plan(0.4, 0.3, slow));
  EXPECT_DOUBLE_EQ(p.peak_speed(), 0.1);
  check_profile(p, slow, 0.3);
}

TEST(SpeedProfile, TooShortToStopIsRefusedAndBrakingWorks) {
  const ProfileLimits lim{0.5, 2.0, 20.0};
  SpeedProfile p;
  const double d = SpeedProfile::braking_distance(0.5, lim);
  EXPECT_GT(d, 0.0);
  EXPECT_FALSE(p.plan(0.5 * d, 0.5, lim));
  EXPECT_TRUE(p.plan(1.01 * d, 0.5, lim));
  p.plan_brake(0.5, lim);
  EXPECT_NEAR(p.length(), d, 1e-12);
  check_profile(p, lim, 0.5);
}

TEST(SpeedProfile, ZeroLengthIsInstant) {
  SpeedProfile p;
  ASSERT_TRUE(p.plan(0.0, 0.0, ProfileLimits{}));
  EXPECT_EQ(p.duration(), 0.0);
}
