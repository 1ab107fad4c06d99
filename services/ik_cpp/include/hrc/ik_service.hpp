// The ik_cpp service logic behind hrc-ik (services/ik_cpp/README.md, "hrc-ik").
//
// IkEngine: the robots of a scenario, one hrc::kin::MotionGenerator each, and the mapping between
// the wire contract and the kinematics (RobotCommand -> MoveCommand / hold, MotionState ->
// RobotState, ReachRequest -> ReachReply). No bus: unit tests drive it directly.
// IkService: wires an engine to the bus: commands through the LockstepParticipant's inbox, one
// engine step + one RobotState per robot per tick, the robot/reach queryable, and the standalone
// timer mode (--standalone-hz).
#pragma once

#include <Eigen/Geometry>

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "hrc/kin/motion.hpp"
#include "hrc/kin/robot_model.hpp"
#include "hrc/lockstep.hpp"
#include "hrc/typed_bus.hpp"

namespace hrc {

/// The tool's yaw at the home pose (rad): the orchestrator sends its home moves with yaw 0.
constexpr double kHomeYaw = 0.0;

/// One robot as the service needs it (from a RobotConfig of the scenario).
struct RobotSpec {
  std::string id;
  std::string urdf_path;
  std::string base_link = "base_link";  // the chain base_link -> tip_link, then the TCP
  std::string tip_link = "tool";
  Eigen::Isometry3d tip_T_tcp = Eigen::Isometry3d::Identity();
  // The description's own fingers (RobotConfig.gripper): none, or joints set to open / closed.
  std::vector<std::string> gripper_joints;
  double gripper_open = 0.0;
  double gripper_closed = 0.0;
  Eigen::Isometry3d world_T_base = Eigen::Isometry3d::Identity();
  double max_tcp_speed = 0.0;                      // m/s
  Eigen::Vector3d home = Eigen::Vector3d::Zero();  // reached tool down, with kHomeYaw
};

/// The robots of `scenario` (possibly none). Throws std::invalid_argument naming the robot and the
/// bad field (bad id, duplicate id, empty urdf_path, non-finite base/home, max_tcp_speed <= 0).
std::vector<RobotSpec> robots_from_scenario(const v2::Scenario& scenario);
/// Seconds per tick of `scenario` (1 / info.tick_hz). Throws std::invalid_argument if tick_hz <= 0.
double tick_dt(const v2::Scenario& scenario);

class IkEngine {
 public:
  /// Loads each URDF (base_link -> tool), builds its motion generator (max_tcp_speed, tick `dt`)
  /// and puts the arm at its home pose, tool down. Throws std::runtime_error naming the robot if a
  /// URDF does not load or a home pose is not reachable.
  IkEngine(std::vector<RobotSpec> robots, double dt);
  IkEngine(const IkEngine&) = delete;
  IkEngine& operator=(const IkEngine&) = delete;

  /// Robot ids in sorted order (the order of step() and of the published states).
  const std::vector<std::string>& robot_ids() const { return ids_; }
  std::size_t size() const { return arms_.size(); }
  /// Index of `robot` in robot_ids(), or -1.
  int index_of(const std::string& robot) const;
  double dt() const { return dt_; }

  /// Applies a command for `robot`: KIND_MOVE -> move (yaw deg -> rad, max_speed capped at the
  /// robot's max_tcp_speed, 0 = max), KIND_HOLD -> hold, KIND_SPEED_SCALE -> the arm's speed
  /// scale (speed_scale in [0, 1]; command_id unchanged). Returns "" when applied, else what is
  /// wrong (unknown robot, NaN/inf numbers in any kind, negative heights/speed, unknown kind); a
  /// refused command changes nothing. An unreachable target is applied (the arm reports
  /// UNREACHABLE). The one place a command's content is checked.
  std::string apply(const std::string& robot, const v2::RobotCommand& command);
  /// Advances every arm by one tick.
  void step();
  /// Writes arm `index`'s state (everything but the header) into `out`; reuses out's storage,
  /// so a caller that keeps its RobotState does not allocate per tick.
  void fill_state(std::size_t index, v2::RobotState& out) const;
  const kin::MotionState& state(std::size_t index) const;
  /// Ticks, at least, until arm `index`'s motion in progress ends; 0 if none
  /// (kin::MotionGenerator::min_ticks_to_end).
  uint64_t min_ticks_to_end(std::size_t index) const;
  /// fill_state declares, per joint, the most it moves as a fraction of its velocity limit
  /// (RobotState.joint_speed_fraction_bounds) and the most its child link's frame moves and
  /// turns (link_linear_speed_bounds, link_angular_speed_bounds) on the next `ticks` ticks (the
  /// longest exchange: the scenario's max_exchange_ticks; 0, the default: until the motion
  /// ends) unless a new command reaches the arm; nothing when not known (under a speed scale
  /// < 1, or a motion longer than the lookahead). Set before any command.
  void set_speed_window(uint32_t ticks) { speed_window_ = ticks; }
  uint32_t speed_window() const { return speed_window_; }
  /// Whether commands get the lookahead at all (default on). Realtime exchanges are one tick,
  /// so nothing reads the declaration there, and a long motion's lookahead would cost the tick
  /// it is commanded in a deadline; off, states declare nothing.
  void set_declare_speeds(bool on) { declare_speeds_ = on; }
  /// Puts arm `index` at joints `q` at rest (the motion check starts moves from recorded poses).
  void reset(std::size_t index, const Eigen::VectorXd& q);
  const kin::RobotModel& model(std::size_t index) const;
  uint64_t command_id(std::size_t index) const;

  /// One result per item (reachable tool-down with the item's yaw, position error, detail).
  /// Thread-safe with respect to step(): it uses solvers of its own.
  v2::ReachReply reach(const v2::ReachRequest& request);

 private:
  struct Arm {
    RobotSpec spec;
    std::unique_ptr<kin::RobotModel> model;        // owned here: the generators keep a reference
    std::unique_ptr<kin::MotionGenerator> motion;  // the arm (tick thread only)
    std::unique_ptr<kin::MotionGenerator> probe;   // reach queries (under reach_mutex_)
    uint64_t command_id = 0;
    // The fingers: where they are, where the last command sends them, how fast (per tick).
    Eigen::VectorXd grip, grip_target, grip_step;
    // The motion's joint speed fractions, then its links' linear and angular speeds
    // (kin::MotionGenerator::SpeedForecast, 3 x dof columns), row i the max over the speed
    // window's steps from i on, for the exchange step's gap rules; steps_taken since it was
    // computed. speed_known is false when the table does not hold (speed scale < 1, motion past
    // the lookahead).
    Eigen::MatrixXd speed_table;
    std::size_t steps_taken = 0;
    bool speed_known = true;
  };
  // Recomputes arm's speed_table for the motion just commanded (kin::speed_forecast).
  void plan_speed_bound(Arm& arm) const;
  // The speed_table's row for the next step (zeros past its end: nothing moves), if known:
  // what fill_state declares.
  std::optional<Eigen::VectorXd> speed_row(std::size_t index) const;

  double dt_;
  uint32_t speed_window_ = 0;
  bool declare_speeds_ = true;
  std::vector<Arm> arms_;  // sorted by id
  std::vector<std::string> ids_;
  std::mutex reach_mutex_;
};

/// The motion check (hrc-ik --check-moves): builds an engine for the request's scenario (its
/// tick), then for each move puts the arm at its start (see MoveCheck.start), applies the command
/// exactly as the service does and steps until the arm stops moving (at most `max_move_s` of
/// simulated time). Throws like IkEngine's constructor for a scenario whose robots do not load.
v2::MotionCheckReply check_moves(const v2::MotionCheckRequest& request, double max_move_s = 120.0);

/// Per-tick durations in a fixed histogram (1 µs bins up to 20 ms): recording never allocates.
class TickTimes {
 public:
  void add(double us);
  uint64_t count() const { return count_; }
  /// Quantile q in [0, 1] in µs (upper edge of its bin; the max beyond the histogram).
  double quantile(double q) const;
  double max() const { return max_; }
  double mean() const { return count_ ? sum_ / static_cast<double>(count_) : 0.0; }
  /// "n N, p50 X us, p99 Y us, max Z us" (or "no ticks").
  std::string summary() const;

 private:
  static constexpr std::size_t kBins = 20000;
  std::array<uint32_t, kBins + 1> bins_{};  // last bin: overflow
  uint64_t count_ = 0;
  double sum_ = 0.0;
  double max_ = 0.0;
};

class IkService {
 public:
  /// Registers robot/*/command as an input of `participant` (through its inbox), the step, one
  /// publisher per robot/<id>/state and the robot/reach queryable. Call before
  /// participant.start() (which declares alive/<name>) or run_standalone().
  IkService(Bus& bus, LockstepParticipant& participant, IkEngine& engine);
  /// Closes the bus: the robot/reach queryable calls into this object, so it may not outlive it.
  ~IkService() { bus_.close(); }
  IkService(const IkService&) = delete;
  IkService& operator=(const IkService&) = delete;

  /// A command delivered by the inbox: validated, applied, or counted as malformed and logged with
  /// key and sender (the arm keeps what it was doing).
  void on_command(const std::string& key, const v2::RobotCommand& command);
  /// Tick k: advance every arm one step, publish RobotState per robot in sorted id order.
  void step(const v2::ClockTick& tick);
  /// Steps at `hz` by its own timer (no clock master): each step first takes every command that
  /// has arrived. Runs until keep_going() is false or run/end arrives. Declares alive/<name>.
  /// Returns the number of steps.
  uint64_t run_standalone(double hz, const std::function<bool()>& keep_going);
  /// After the last step: the first tick at which an arm may end its motion (REACHED), from the
  /// motion in progress; 0 if no arm moves (TickAck.next_event_tick).
  uint64_t next_event_tick() const;

  /// Rejects commands whose robot field disagrees with the key (the content is the engine's to
  /// check, in IkEngine::apply).
  static std::string validate_command(const std::string& key, const v2::RobotCommand& command);

  uint64_t commands_received() const { return commands_received_; }
  uint64_t commands_rejected() const { return commands_rejected_; }
  /// Time of the kinematics (the tick's commands + engine step) and of the whole step including
  /// publishing, per tick.
  const TickTimes& compute_times() const { return compute_times_; }
  const TickTimes& step_times() const { return step_times_; }
  /// Timer overruns in standalone mode (a step started more than one period late).
  uint64_t overruns() const { return overruns_; }
  /// The lines main() logs at exit.
  std::string timing_summary() const;

 private:
  /// Publishes each arm's state when it differs from the last one published, and at least
  /// once per simulated second (a keyframe for late joiners); receivers hold the last state.
  void publish_states(uint64_t tick, double sim_time);

  Bus& bus_;
  LockstepParticipant& participant_;
  IkEngine& engine_;
  // Touched only from the tick processing (one tick at a time): no lock needed.
  std::vector<TypedPublisher*> state_pubs_;  // per engine index
  std::vector<v2::RobotState> states_;       // reused every tick
  std::vector<std::string> last_sent_;       // per engine index: last published state, header-less
  uint64_t commands_received_ = 0;
  uint64_t commands_rejected_ = 0;
  bool dt_warned_ = false;
  uint64_t last_tick_ = 0;   // the last tick stepped
  double command_us_ = 0.0;  // time spent applying the commands delivered for the coming step
  TickTimes compute_times_;
  TickTimes step_times_;
  uint64_t overruns_ = 0;
  std::atomic<bool> run_ended_{false};
};

}  // namespace hrc
