// hrc-ik-bench: IK solver benchmark (issue 3) and the 2-arm 1 kHz motion tick benchmark.
//
// For arm5 (position + tool axis), UR5 and Panda (full pose): N random reachable targets made by
// FK of uniform random joint vectors within the limits (fixed seed); every solver starts from the
// middle of the joint ranges. Success: position <= 0.1 mm, orientation <= 0.1 deg (arm5: tool-axis
// angle), joints within limits -- checked here with KDL's FK, independent of what a solver claims.

#include "hrc/kin/baselines.hpp"
#include "hrc/kin/ik.hpp"
#include "hrc/kin/kinematics.hpp"
#include "hrc/kin/motion.hpp"
#include "hrc/kin/robot_model.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <random>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using hrc::kin::IkTarget;
using hrc::kin::RobotModel;
using Clock = std::chrono::steady_clock;

namespace {

constexpr double kPosTol = 1e-4;                // 0.1 mm
constexpr double kAngTol = 0.1 * M_PI / 180.0;  // 0.1 deg

struct Options {
  int n = 10000;
  int gd_n = 1000;
  std::uint64_t seed = 1;
  std::string robots_dir;
  bool json = false;
  int tick_seconds = 30;
  std::vector<std::string> extra_chains;  // NAME=URDF:BASE:TIP (--chain)
  bool only = false;  // --only: the --chain chains alone, no tick benchmark (a lab's own arm)
};

struct Stats {
  double success = 0, mean_us = 0, p99_us = 0;
  double median_pos_mm = 0, median_ang_deg = 0;  // residuals, to show how far failures are
  int n = 0;
};

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

[[noreturn]] void usage(const std::string& err) {
  if (!err.empty()) std::cerr << "hrc-ik-bench: " << err << "\n";
  std::cerr
      << "usage: hrc-ik-bench [--n N] [--gd-n M] [--seed S] [--robots-dir DIR] "
         "[--tick-seconds T] [--chain NAME=URDF:BASE:TIP]... [--only] [--json]\n"
         "  --n N            targets per chain (default 10000)\n"
         "  --gd-n M         targets for the (slow) gradient descent baseline, <= N "
         "(default 1000)\n"
         "  --seed S         random seed (default 1)\n"
         "  --robots-dir DIR folder with arm5.urdf, ur5.urdf, panda.urdf (default: robots/ "
         "found from the cwd or the executable upwards)\n"
         "  --tick-seconds T simulated seconds of the 2-arm 1 kHz tick benchmark (default 30)\n"
         "  --chain NAME=URDF:BASE:TIP  also benchmark this chain (repeatable; a shipped real\n"
         "                   robot's description, e.g. hrc bench ik passes the scenarios' ones)\n"
         "  --only           benchmark the --chain chains alone (no arm5/UR5/Panda, no tick)\n"
         "  --json           print one JSON object instead of a table\n";
  std::exit(err.empty() ? 0 : 2);
}

long parse_int(const std::string& flag, const char* v, long lo) {
  char* end = nullptr;
  const long x = std::strtol(v, &end, 10);
  if (!end || *end || x < lo)
    usage(flag + " expects an integer >= " + std::to_string(lo) + ", got '" + v + "'");
  return x;
}

Options parse(int argc, char** argv) {
  Options o;
  bool gd_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> const char* {
      if (i + 1 >= argc) usage(a + " needs a value");
      return argv[++i];
    };
    if (a == "--n")
      o.n = static_cast<int>(parse_int(a, value(), 1));
    else if (a == "--gd-n") {
      o.gd_n = static_cast<int>(parse_int(a, value(), 0));
      gd_given = true;
    } else if (a == "--seed")
      o.seed = static_cast<std::uint64_t>(parse_int(a, value(), 0));
    else if (a == "--robots-dir")
      o.robots_dir = value();
    else if (a == "--tick-seconds")
      o.tick_seconds = static_cast<int>(parse_int(a, value(), 1));
    else if (a == "--chain")
      o.extra_chains.emplace_back(value());
    else if (a == "--json")
      o.json = true;
    else if (a == "--only")
      o.only = true;
    else if (a == "-h" || a == "--help")
      usage("");
    else
      usage("unknown option '" + a + "'");
  }
  if (gd_given && o.gd_n > o.n) usage("--gd-n must be <= --n");
  if (o.only && o.extra_chains.empty()) usage("--only needs at least one --chain");
  o.gd_n = std::min(o.gd_n, o.n);
  return o;
}

std::string find_robots_dir(const std::string& given) {
  const auto ok = [](const fs::path& d) { return fs::exists(d / "arm5.urdf"); };
  if (!given.empty()) {
    if (!ok(given)) usage("--robots-dir '" + given + "' has no arm5.urdf");
    return given;
  }
  std::vector<fs::path> starts{fs::current_path()};
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) starts.push_back(exe.parent_path());
  for (fs::path p : starts) {
    for (int up = 0; up < 8 && !p.empty(); ++up, p = p.parent_path()) {
      if (ok(p / "robots")) return (p / "robots").string();
      if (p == p.parent_path()) break;
    }
  }
  // (no path compiled in: the bench compiles the same in every clone, and ccache reuses it)
  usage("cannot find robots/arm5.urdf above the working folder or this program; pass --robots-dir");
}

Stats summarise(std::vector<double>& us, int successes) {
  Stats s;
  s.n = static_cast<int>(us.size());
  if (us.empty()) return s;
  double sum = 0;
  for (double v : us) sum += v;
  s.mean_us = sum / us.size();
  std::sort(us.begin(), us.end());
  const std::size_t idx =
      std::min(us.size() - 1, static_cast<std::size_t>(std::ceil(0.99 * us.size())) - 1);
  s.p99_us = us[idx];
  s.success = static_cast<double>(successes) / us.size();
  return s;
}

double micros(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::micro>(b - a).count();
}

struct Chain {
  std::string name;
  bool axis_only;                                      // arm5: position + tool axis
  std::string path, base = "base_link", tip = "tool";  // path empty: DIR/NAME.urdf
};

// NAME=URDF:BASE:TIP (the URDF path may not hold ':').
Chain parse_chain(const std::string& spec) {
  const auto eq = spec.find('=');
  const auto c1 = spec.find(':', eq == std::string::npos ? 0 : eq);
  const auto c2 = c1 == std::string::npos ? c1 : spec.find(':', c1 + 1);
  if (eq == std::string::npos || eq == 0 || c1 == std::string::npos || c2 == std::string::npos)
    usage("--chain expects NAME=URDF:BASE:TIP, got '" + spec + "'");
  return Chain{spec.substr(0, eq), false, spec.substr(eq + 1, c1 - eq - 1),
               spec.substr(c1 + 1, c2 - c1 - 1), spec.substr(c2 + 1)};
}

std::map<std::string, Stats> bench_chain(const RobotModel& model, bool axis_only,
                                         const Options& o) {
  const int dof = model.dof();
  hrc::kin::KdlKinematics kin(model);
  std::mt19937_64 rng(o.seed);
  std::vector<Eigen::Isometry3d> targets;
  targets.reserve(o.n);
  Eigen::VectorXd q(dof);
  for (int k = 0; k < o.n; ++k) {
    for (int i = 0; i < dof; ++i)
      q[i] =
          std::uniform_real_distribution<double>(model.sample_lower(i), model.sample_upper(i))(rng);
    targets.push_back(kin.fk(q));
  }
  const Eigen::VectorXd seed = model.mid_range();
  std::vector<double> pos_res, ang_res;
  const auto success = [&](const Eigen::VectorXd& sol, const Eigen::Isometry3d& T) {
    if (!sol.allFinite()) {
      pos_res.push_back(1e9);
      ang_res.push_back(180);
      return false;
    }
    const Eigen::Isometry3d F = kin.fk(sol);
    const double pos = (F.translation() - T.translation()).norm();
    const double ang = axis_only ? hrc::kin::axis_angle(F.linear().col(2), T.linear().col(2))
                                 : hrc::kin::rotation_angle(F.linear(), T.linear());
    pos_res.push_back(pos * 1e3);
    ang_res.push_back(ang * 180.0 / M_PI);
    return model.within_limits(sol, 1e-9) && pos <= kPosTol && ang <= kAngTol;
  };
  const auto finish = [&](const char* name, std::vector<double>& times, int good) {
    Stats st = summarise(times, good);
    st.median_pos_mm = median(pos_res);
    st.median_ang_deg = median(ang_res);
    pos_res.clear();
    ang_res.clear();
    return std::make_pair(std::string(name), st);
  };
  const auto to_target = [&](const Eigen::Isometry3d& T) {
    return axis_only ? IkTarget::position_axis(T.translation(), T.linear().col(2))
                     : IkTarget::pose(T);
  };

  std::map<std::string, Stats> out;
  std::vector<double> us;
  us.reserve(o.n);
  Eigen::VectorXd sol(dof);
  // Times `solve(prepare(T))` over the first `count` targets; `solve` returns the joints it found.
  // Only the solve is timed: converting the target to the solver's input is not.
  const auto measure = [&](const char* name, std::size_t count, auto&& prepare, auto&& solve) {
    us.clear();
    int good = 0;
    for (std::size_t k = 0; k < count; ++k) {
      const auto& T = targets[k];
      const auto input = prepare(T);
      const auto a = Clock::now();
      const Eigen::VectorXd& found = solve(input);
      const auto b = Clock::now();
      us.push_back(micros(a, b));
      good += success(found, T);
    }
    out.insert(finish(name, us, good));
  };
  const auto as_is = [](const Eigen::Isometry3d& T) { return T; };

  {
    hrc::kin::IkSolver ik(model);
    hrc::kin::IkResult res;
    res.q.resize(dof);
    measure("service", targets.size(), to_target, [&](const IkTarget& t) -> const Eigen::VectorXd& {
      ik.solve(t, seed, res);
      return res.q;
    });
  }
  {
    hrc::kin::KdlNrJlSolver ik(model);
    measure("kdl_nr_jl", targets.size(), as_is,
            [&](const Eigen::Isometry3d& T) -> const Eigen::VectorXd& {
              ik.solve(T, seed, sol);
              return sol;
            });
  }
  {
    hrc::kin::KdlLmaSolver ik(model);
    measure("kdl_lma", targets.size(), as_is,
            [&](const Eigen::Isometry3d& T) -> const Eigen::VectorXd& {
              ik.solve(T, seed, sol);
              return sol;
            });
  }
  {  // the thesis's gradient descent, on the first gd_n targets (it is slow)
    hrc::kin::GradientDescentSolver ik(model);
    measure("gradient_descent", static_cast<std::size_t>(o.gd_n), to_target,
            [&](const IkTarget& t) -> const Eigen::VectorXd& {
              ik.solve(t, seed, sol);
              return sol;
            });
  }
  return out;
}

// Two arm5 robots placed as in the default scenario, stepping at 1 kHz through pick/place-like
// moves (vertical approach/depart, yaw changes, a retarget mid-move every few moves).
double tick_bench(const RobotModel& arm5, const Options& o) {
  struct Arm {
    std::unique_ptr<hrc::kin::MotionGenerator> gen;
    std::vector<hrc::kin::MoveCommand> moves;
    std::size_t next = 0;
    int moves_done = 0;
  };
  const double dt = 1e-3;
  const auto base = [](double x, double y, double yaw_deg) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(x, y, 0.0);
    T.linear() =
        Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return T;
  };
  const auto mv = [](double x, double y, double z, double yaw_deg, double app, double dep) {
    hrc::kin::MoveCommand c;
    c.target = Eigen::Vector3d(x, y, z);
    c.yaw = yaw_deg * M_PI / 180.0;
    c.approach_height = app;
    c.depart_height = dep;
    return c;
  };
  hrc::kin::MotionLimits lim;
  lim.max_tcp_speed = 0.5;
  Arm arms[2];
  arms[0].gen = std::make_unique<hrc::kin::MotionGenerator>(arm5, base(0.45, 0.55, 180), dt, lim);
  arms[1].gen = std::make_unique<hrc::kin::MotionGenerator>(arm5, base(-0.45, 0.55, 180), dt, lim);
  arms[0].moves = {mv(0.55, 0.30, 0.05, 0, 0.05, 0.05), mv(0.20, 0.25, 0.25, 0, 0, 0.05),
                   mv(-0.10, 0.05, 0.03, 90, 0.05, 0), mv(0.20, 0.25, 0.25, 45, 0, 0.05),
                   mv(0.35, 0.30, 0.35, 0, 0, 0)};
  arms[1].moves = {mv(-0.60, 0.35, 0.05, 0, 0.05, 0.05), mv(-0.20, 0.25, 0.25, 30, 0, 0.05),
                   mv(0.05, 0.00, 0.06, -60, 0.05, 0), mv(-0.20, 0.25, 0.25, 0, 0, 0.05),
                   mv(-0.35, 0.30, 0.35, 0, 0, 0)};
  for (auto& a : arms) {
    const auto& home = a.moves.back();
    if (!a.gen->reset_to_pose(home.target, home.yaw)) {
      std::cerr << "hrc-ik-bench: tick benchmark home pose unreachable\n";
      std::exit(1);
    }
  }
  const int ticks = o.tick_seconds * 1000;
  std::vector<double> us;
  us.reserve(ticks);
  for (int k = 0; k < ticks; ++k) {
    const auto t0 = Clock::now();
    for (auto& a : arms) {
      const auto st = a.gen->state().status;
      const bool retarget = a.gen->state().status == hrc::kin::MotionStatus::Moving &&
                            a.moves_done % 4 == 3 && (k % 500) == 250;
      if (st != hrc::kin::MotionStatus::Moving || retarget) {
        a.gen->move(a.moves[a.next]);
        a.next = (a.next + 1) % a.moves.size();
        ++a.moves_done;
      }
      a.gen->step();
    }
    us.push_back(micros(t0, Clock::now()));
  }
  for (auto& a : arms)
    if (a.moves_done < 5) std::cerr << "hrc-ik-bench: warning: an arm completed few moves\n";
  return summarise(us, 0).p99_us;
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  const std::string dir = o.only ? std::string() : find_robots_dir(o.robots_dir);
  std::vector<Chain> chains;
  if (!o.only)
    chains = {{"arm5", true, "", "base_link", "tool"},
              {"ur5", false, "", "base_link", "tool"},
              {"panda", false, "", "base_link", "tool"}};
  for (const std::string& spec : o.extra_chains) chains.push_back(parse_chain(spec));
  std::map<std::string, std::map<std::string, Stats>> results;
  std::unique_ptr<RobotModel> arm5;
  try {
    for (const auto& c : chains) {
      const std::string path = c.path.empty() ? dir + "/" + c.name + ".urdf" : c.path;
      const RobotModel model = RobotModel::from_urdf_file(path, c.base, c.tip);
      if (!o.json) std::cerr << "benchmarking " << c.name << " (" << model.dof() << " DOF)...\n";
      results[c.name] = bench_chain(model, c.axis_only, o);
      if (c.name == "arm5") arm5 = std::make_unique<RobotModel>(model);
    }
  } catch (const std::exception& e) {
    std::cerr << "hrc-ik-bench: " << e.what() << "\n";
    return 1;
  }
  const double tick_p99 = arm5 ? tick_bench(*arm5, o) : -1.0;  // -1: not run (--only)
  const char* solvers[] = {"service", "kdl_nr_jl", "kdl_lma", "gradient_descent"};
  if (o.json) {
    std::printf("{\"chains\": {");
    bool first_chain = true;
    for (const auto& c : chains) {
      std::printf("%s\"%s\": {", first_chain ? "" : ", ", c.name.c_str());
      first_chain = false;
      bool first = true;
      for (const char* s : solvers) {
        const Stats& st = results[c.name][s];
        std::printf(
            "%s\"%s\": {\"success\": %.6f, \"mean_us\": %.3f, \"p99_us\": %.3f, \"n\": %d, "
            "\"median_pos_mm\": %.6g, \"median_ang_deg\": %.6g}",
            first ? "" : ", ", s, st.success, st.mean_us, st.p99_us, st.n, st.median_pos_mm,
            st.median_ang_deg);
        first = false;
      }
      std::printf("}");
    }
    if (tick_p99 >= 0)
      std::printf("}, \"tick_p99_us\": %.3f, \"seed\": %llu}\n", tick_p99,
                  static_cast<unsigned long long>(o.seed));
    else
      std::printf("}, \"tick_p99_us\": null, \"seed\": %llu}\n",
                  static_cast<unsigned long long>(o.seed));
  } else {
    std::printf("%-18s %-17s %9s %10s %10s %7s %12s %12s\n", "chain", "solver", "success",
                "mean_us", "p99_us", "n", "med_pos_mm", "med_ang_deg");
    for (const auto& c : chains)
      for (const char* s : solvers) {
        const Stats& st = results[c.name][s];
        std::printf("%-18s %-17s %8.2f%% %10.1f %10.1f %7d %12.2e %12.2e\n", c.name.c_str(), s,
                    100.0 * st.success, st.mean_us, st.p99_us, st.n, st.median_pos_mm,
                    st.median_ang_deg);
      }
    if (tick_p99 >= 0)
      std::printf("tick_p99_us (2 x arm5 motion generators at 1 kHz): %.1f\n", tick_p99);
  }
  return 0;
}
