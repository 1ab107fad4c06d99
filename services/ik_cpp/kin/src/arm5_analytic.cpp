#include "hrc/kin/arm5_analytic.hpp"

#include <cmath>
#include <limits>
#include <random>

namespace hrc::kin {
namespace {
constexpr double kGeomTol = 1e-7;
constexpr double kTwoPi = 2.0 * M_PI;
}  // namespace

bool Arm5Analytic::fit_angle(double angle, double lo, double hi, double ref, double& out) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) {
    out = angle + kTwoPi * std::round((ref - angle) / kTwoPi);
    return true;
  }
  const double k_lo = std::ceil((lo - angle) / kTwoPi - 1e-12);
  const double k_hi = std::floor((hi - angle) / kTwoPi + 1e-12);
  bool found = false;
  double best = 0, best_d = std::numeric_limits<double>::infinity();
  for (double k = k_lo; k <= k_hi; k += 1.0) {
    const double c = std::min(std::max(angle + k * kTwoPi, lo), hi);
    const double d = std::abs(c - ref);
    if (d < best_d) {
      best_d = d;
      best = c;
      found = true;
    }
  }
  if (found) out = best;
  return found;
}

std::optional<Arm5Analytic> Arm5Analytic::detect(const RobotModel& model, const ChainEval& eval) {
  if (model.dof() != 5) return std::nullopt;
  for (int i = 0; i < 5; ++i)
    if (!model.revolute(i)) return std::nullopt;
  const double q0[5] = {0, 0, 0, 0, 0};
  Eigen::Vector3d o[5], a[5];
  for (int i = 0; i < 5; ++i) eval.joint_frame(q0, i, o[i], a[i]);
  Eigen::Matrix3d Rt;
  Eigen::Vector3d pt;
  eval.fk(q0, Rt, pt);
  const Eigen::Vector3d X = Eigen::Vector3d::UnitX(), Y = Eigen::Vector3d::UnitY(),
                        Z = Eigen::Vector3d::UnitZ();
  const auto on_z = [](const Eigen::Vector3d& v) { return std::hypot(v.x(), v.y()) < kGeomTol; };
  if (a[0].cross(Z).norm() > kGeomTol || a[4].cross(Z).norm() > kGeomTol) return std::nullopt;
  for (int i = 1; i < 4; ++i)
    if (a[i].cross(Y).norm() > kGeomTol) return std::nullopt;
  for (int i = 0; i < 5; ++i)
    if (!on_z(o[i])) return std::nullopt;
  if (!on_z(pt) || Rt.col(2).dot(Z) < 1.0 - kGeomTol) return std::nullopt;
  (void)X;

  Arm5Analytic s(model, eval);
  s.s1_ = a[0].dot(Z) > 0 ? 1.0 : -1.0;
  s.s2_ = a[1].dot(Y) > 0 ? 1.0 : -1.0;
  s.s3_ = a[2].dot(Y) > 0 ? 1.0 : -1.0;
  s.s4_ = a[3].dot(Y) > 0 ? 1.0 : -1.0;
  s.s5_ = a[4].dot(Z) > 0 ? 1.0 : -1.0;
  s.h_ = o[1].z();
  s.l2_ = o[2].z() - o[1].z();
  s.l3_ = o[3].z() - o[2].z();
  s.l4_ = pt.z() - o[3].z();
  if (!(s.l2_ > kGeomTol && s.l3_ > kGeomTol && s.l4_ >= 0.0)) return std::nullopt;

  // Verify on FK samples: the detection above is necessary, this makes it sufficient.
  std::mt19937_64 rng(12345);
  const Eigen::VectorXd mid = model.mid_range();
  int ok = 0;
  constexpr int kSamples = 50;
  for (int k = 0; k < kSamples; ++k) {
    double q[5], sol[5];
    for (int i = 0; i < 5; ++i)
      q[i] =
          std::uniform_real_distribution<double>(model.sample_lower(i), model.sample_upper(i))(rng);
    Eigen::Matrix3d R, R2;
    Eigen::Vector3d p, p2;
    eval.fk(q, R, p);
    if (!s.solve(p, R.col(2), &R, mid.data(), sol)) continue;
    eval.fk(sol, R2, p2);
    if ((p2 - p).norm() < 1e-9 && rotation_angle(R, R2) < 1e-9) ++ok;
  }
  if (ok < kSamples * 9 / 10) return std::nullopt;
  return s;
}

bool Arm5Analytic::solve(const Eigen::Vector3d& p, const Eigen::Vector3d& axis_in,
                         const Eigen::Matrix3d* R, const double* seed, double* q_out) const {
  const Eigen::VectorXd& lo = model_->lower();
  const Eigen::VectorXd& hi = model_->upper();
  const Eigen::Vector3d a = axis_in.normalized();
  // Candidate azimuths of the arm plane.
  double phis[2];
  int n_phi = 0;
  const double r_xy = std::hypot(p.x(), p.y());
  if (r_xy > 1e-9) {
    phis[n_phi++] = std::atan2(p.y(), p.x());
    phis[n_phi++] = phis[0] + M_PI;
  } else if (std::hypot(a.x(), a.y()) > 1e-9) {
    phis[n_phi++] = std::atan2(a.y(), a.x());
    phis[n_phi++] = phis[0] + M_PI;
  } else {
    phis[n_phi++] = s1_ * seed[0];
  }

  bool found = false;
  double best_cost = std::numeric_limits<double>::infinity();
  double cand[5];
  for (int k = 0; k < n_phi; ++k) {
    const double phi = phis[k];
    const Eigen::Vector3d e(std::cos(phi), std::sin(phi), 0.0);
    const Eigen::Vector3d nrm(-std::sin(phi), std::cos(phi), 0.0);
    if (std::abs(a.dot(nrm)) > 1e-9 || std::abs(p.dot(nrm)) > 1e-9) continue;
    const double theta = std::atan2(a.dot(e), a.z());  // total pitch, from +z towards e
    const Eigen::Vector3d w = p - l4_ * a;
    const double rw = w.dot(e), zw = w.z() - h_;
    double D = (rw * rw + zw * zw - l2_ * l2_ - l3_ * l3_) / (2.0 * l2_ * l3_);
    if (std::abs(D) > 1.0 + 1e-12) continue;
    D = std::min(1.0, std::max(-1.0, D));
    for (int elbow = 0; elbow < 2; ++elbow) {
      const double t3 = (elbow == 0 ? 1.0 : -1.0) * std::acos(D);
      const double t2 =
          std::atan2(rw, zw) - std::atan2(l3_ * std::sin(t3), l2_ + l3_ * std::cos(t3));
      const double t4 = theta - t2 - t3;
      if (!fit_angle(s1_ * phi, lo[0], hi[0], seed[0], cand[0])) continue;
      if (!fit_angle(s2_ * t2, lo[1], hi[1], seed[1], cand[1])) continue;
      if (!fit_angle(s3_ * t3, lo[2], hi[2], seed[2], cand[2])) continue;
      if (!fit_angle(s4_ * t4, lo[3], hi[3], seed[3], cand[3])) continue;
      if (R) {
        cand[4] = 0.0;
        Eigen::Matrix3d R0;
        Eigen::Vector3d p0;
        eval_->fk(cand, R0, p0);
        const Eigen::Matrix3d rel = R0.transpose() * (*R);
        if (rel(2, 2) < 1.0 - 1e-9) continue;  // target axis not reachable in this branch
        const double gamma = std::atan2(rel(1, 0), rel(0, 0));
        if (!fit_angle(s5_ * gamma, lo[4], hi[4], seed[4], cand[4])) continue;
      } else {
        cand[4] = std::min(std::max(seed[4], lo[4]), hi[4]);
      }
      double c = 0;
      for (int i = 0; i < 5; ++i) c += (cand[i] - seed[i]) * (cand[i] - seed[i]);
      if (c < best_cost) {
        best_cost = c;
        for (int i = 0; i < 5; ++i) q_out[i] = cand[i];
        found = true;
      }
    }
  }
  return found;
}

}  // namespace hrc::kin
