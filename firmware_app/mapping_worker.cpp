#include "firmware_app/mapping_worker.h"

#include <chrono>

#include "platform/alloc_counter.h"
#include "platform/clock.h"
#include "platform/realtime.h"

namespace st::app {

namespace {
constexpr double kUnboundedSolveS = 1e6;  // a solver time limit that never binds
}  // namespace

Status MappingWorker::configure(const TrackerConfig& config, const Mesh& mesh, const Pinhole& K) {
  stop();
  configured_ = false;
  config_ = config;
  BundleAdjusterOptions o = config.ba;
  o.now_ns = platform::monotonic_ns;  // the Schur solver's time limit and solver_ms
  if (config.ba_lag_frames > 0) {  // deterministic: iterations only (the solves' time limits vary with the machine)
    o.max_time_s = kUnboundedSolveS;
    config_.ba_global_max_time_s = kUnboundedSolveS;
  }
  if (Status s = job_.configure(config.max_keyframes, config.max_map_points, config.ba_max_observations); !s.ok())
    return make_error("mapping: " + s.message());
  if (Status s = adjuster_.configure(o, mesh, K, config.max_keyframes, config.max_map_points,
                                           config.ba_max_observations); !s.ok())
    return make_error("mapping: " + s.message());
  state_.store(kFree, std::memory_order_release);
  stats_ = MappingStats{};
  window_observations_ = window_fixed_observations_ = 0;
  solve_ms_.clear();
  configured_ = true;
  return Status::Ok();
}

void MappingWorker::start() {
  if (!configured_ || thread_.joinable()) return;
  state_.store(kFree, std::memory_order_release);
  thread_ = std::thread([this] { run(); });
}

void MappingWorker::stop() {
  if (!thread_.joinable()) return;
  queue_.push_wait(-1);
  thread_.join();
}

BaJob* MappingWorker::acquire_job() {
  return configured_ && thread_.joinable() && state_.load(std::memory_order_acquire) == kFree ? &job_ : nullptr;
}

void MappingWorker::submit_job(BaJob* job) {
  if (job != &job_) return;
  frames_out_ = 0;
  state_.store(kQueued, std::memory_order_release);
  // Capacity 2 and one job buffer: never full here (the stop marker comes
  // only from stop(), on this same thread).
  queue_.try_push(0);
}

const BaJob* MappingWorker::solved_job() {
  if (config_.ba_lag_frames <= 0) return state_.load(std::memory_order_acquire) == kSolved ? &job_ : nullptr;
  // A focal test writes nothing into the map: it comes back at the next
  // frame, so that it never holds a window's correction back.
  const int lag = job_.kind == BaKind::kFocalTest ? 1 : config_.ba_lag_frames;
  if (state_.load(std::memory_order_acquire) == kFree || ++frames_out_ < lag) return nullptr;
  while (state_.load(std::memory_order_acquire) != kSolved) std::this_thread::sleep_for(std::chrono::microseconds(50));
  return &job_;
}

void MappingWorker::release_job(const BaJob* job) {
  if (job == &job_) state_.store(kFree, std::memory_order_release);
}

void MappingWorker::run() {
  stats_.thread_nice = platform::become_background_thread();
  const std::uint64_t allocations0 = platform::thread_allocation_count();
  for (;;) {
    std::int32_t slot = -1;
    queue_.pop_wait(&slot);
    if (slot < 0) return;
    solve_one();
    stats_.thread_allocations = platform::thread_allocation_count() - allocations0;
    state_.store(kSolved, std::memory_order_release);
  }
}

void MappingWorker::solve_one() {
  const bool global = job_.kind == BaKind::kGlobal;
  const std::uint64_t allocs0 = platform::thread_allocation_count();
  const std::int64_t t0 = platform::monotonic_ns();
  const bool ok = global ? adjuster_.solve(&job_, config_.ba_global_max_iterations, config_.ba_global_max_time_s)
                         : adjuster_.solve(&job_);
  solve_ms_.add(static_cast<double>(platform::monotonic_ns() - t0) * 1e-6);
  const std::uint64_t allocs = platform::thread_allocation_count() - allocs0;
  if (allocs > stats_.max_allocations_per_solve) stats_.max_allocations_per_solve = allocs;
  (global ? stats_.global_solves : job_.kind == BaKind::kFocalTest ? stats_.focal_tests : stats_.window_solves) += 1;
  if (job_.kind == BaKind::kWindow) {
    window_observations_ += job_.summary.observations;
    window_fixed_observations_ += job_.summary.fixed_observations;
  }
  if (job_.summary.prior_tested) ++stats_.registration_tests;
  if (ok && job_.summary.prior_used) {
    ++stats_.registration_releases;
    const SE3 T0 = job_.pose(job_.prior.keyframe), T_init = pose_from_params(job_.prior.pose);
    stats_.registration_shift_deg = pose_delta(T_init, T0).angle_deg;
    stats_.registration_shift_mm =
        (T0.inverse().translation() - T_init.inverse().translation()).norm();
    stats_.registration_f = job_.summary.prior_f;
  }
  if (!ok) ++stats_.unusable;
  if (ok && job_.kind != BaKind::kFocalTest) stats_.mean_surface_distance_mm = job_.summary.mean_surface_distance_mm;
}

MappingStats MappingWorker::stats() const {
  MappingStats s = stats_;
  s.solve_median_ms = solve_ms_.quantile_ms(0.5);
  s.solve_p99_ms = solve_ms_.quantile_ms(0.99);
  s.solve_max_ms = solve_ms_.max_ms();
  if (s.window_solves > 0) {
    s.mean_window_observations = static_cast<double>(window_observations_) / s.window_solves;
    s.mean_window_fixed_observations = static_cast<double>(window_fixed_observations_) / s.window_solves;
  }
  return s;
}

void MappingWorker::append_summary(std::vector<std::pair<std::string, double>>* fields) const {
  const MappingStats s = stats();
  fields->emplace_back("ba_window_solves", s.window_solves);
  fields->emplace_back("ba_global_solves", s.global_solves);
  fields->emplace_back("ba_focal_tests", s.focal_tests);
  fields->emplace_back("ba_unusable", s.unusable);
  fields->emplace_back("ba_solve_median_ms", s.solve_median_ms);
  fields->emplace_back("ba_solve_p99_ms", s.solve_p99_ms);
  fields->emplace_back("ba_solve_max_ms", s.solve_max_ms);
  fields->emplace_back("ba_mean_window_observations", s.mean_window_observations);
  fields->emplace_back("ba_mean_window_fixed_observations", s.mean_window_fixed_observations);
  fields->emplace_back("ba_max_allocations_per_solve", static_cast<double>(s.max_allocations_per_solve));
  fields->emplace_back("ba_thread_allocations", static_cast<double>(s.thread_allocations));
  fields->emplace_back("ba_mean_surface_distance_mm", s.mean_surface_distance_mm);
  fields->emplace_back("ba_thread_nice", s.thread_nice);
  fields->emplace_back("ba_registration_tests", s.registration_tests);
  fields->emplace_back("ba_registration_releases", s.registration_releases);
  fields->emplace_back("ba_registration_shift_deg", s.registration_shift_deg);
  fields->emplace_back("ba_registration_shift_mm", s.registration_shift_mm);
  fields->emplace_back("ba_registration_f", s.registration_f);
}

}  // namespace st::app
