// Kinematics speed: forward kinematics, Jacobian and inverse kinematics solves per second for the cell's arms.
// Run: build/tools/kinematics_bench. Items/s is the figure to read (solves per second on one thread).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "cellwright/models/kinematics.hpp"

namespace {

using cellwright::models::IkStatus;
using cellwright::models::KinematicChain;

const char* const kArms[] = {"puma560.urdf", "melfa_rve2.urdf"};

KinematicChain load(const benchmark::State& state) {
  return KinematicChain::from_urdf_file(std::filesystem::path(cellwright::models::models_dir()) / "urdf" /
                                        kArms[state.range(0)]);
}

Eigen::VectorXd random_q(const KinematicChain& c, std::mt19937_64& rng) {
  Eigen::VectorXd q(static_cast<Eigen::Index>(c.dof()));
  for (std::size_t i = 0; i < c.dof(); ++i) {
    std::uniform_real_distribution<double> u(c.limits()[i].lower, c.limits()[i].upper);
    q[static_cast<Eigen::Index>(i)] = u(rng);
  }
  return q;
}

void BM_Forward(benchmark::State& state) {
  const KinematicChain chain = load(state);
  std::mt19937_64 rng(1);
  const Eigen::VectorXd q = random_q(chain, rng);
  for (auto _ : state) benchmark::DoNotOptimize(chain.forward(q));
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(kArms[state.range(0)]);
}

void BM_Jacobian(benchmark::State& state) {
  const KinematicChain chain = load(state);
  std::mt19937_64 rng(1);
  const Eigen::VectorXd q = random_q(chain, rng);
  for (auto _ : state) benchmark::DoNotOptimize(chain.jacobian(q));
  state.SetItemsProcessed(state.iterations());
  state.SetLabel(kArms[state.range(0)]);
}

// Random reachable targets, seeded far away (another random joint vector): the planner's worst ordinary case.
void BM_InverseDistantSeed(benchmark::State& state) {
  const KinematicChain chain = load(state);
  std::mt19937_64 rng(2);
  std::vector<std::pair<Eigen::Isometry3d, Eigen::VectorXd>> cases;
  for (int k = 0; k < 256; ++k) cases.emplace_back(chain.forward(random_q(chain, rng)), random_q(chain, rng));
  std::size_t k = 0, failed = 0;
  for (auto _ : state) {
    const auto& [target, seed] = cases[k++ % cases.size()];
    failed += chain.inverse(target, seed).status != IkStatus::kOk;
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["failed"] = static_cast<double>(failed);
  state.SetLabel(kArms[state.range(0)]);
}

// Following a path: each target 5 mrad per joint from the last solution, seeded with it.
void BM_InverseNearbySeed(benchmark::State& state) {
  const KinematicChain chain = load(state);
  std::mt19937_64 rng(3);
  std::vector<std::pair<Eigen::Isometry3d, Eigen::VectorXd>> cases;
  for (int k = 0; k < 256; ++k) {
    const Eigen::VectorXd q = random_q(chain, rng);
    Eigen::VectorXd seed = q;
    seed.array() += 0.005;
    cases.emplace_back(chain.forward(q), seed);
  }
  std::size_t k = 0, failed = 0;
  for (auto _ : state) {
    const auto& [target, seed] = cases[k++ % cases.size()];
    failed += chain.inverse(target, seed).status != IkStatus::kOk;
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["failed"] = static_cast<double>(failed);
  state.SetLabel(kArms[state.range(0)]);
}

// A target within reach but outside the joint limits: the full search runs before kUnreachable.
void BM_InverseUnreachable(benchmark::State& state) {
  const KinematicChain chain = load(state);
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.linear() = Eigen::AngleAxisd(3.14159265358979, Eigen::Vector3d::UnitX()).toRotationMatrix();
  // Within reach but outside the limits (see kinematics_test.cpp): for the PUMA 0.2 m in front of and below the
  // shoulder, which needs the elbow folded past its limit; for the MELFA straight behind joint 1 and low.
  const Eigen::Vector3d offset[] = {{0.2, 0, -0.2}, {-0.35, 0, -0.25}};
  target.translation() = chain.first_joint_origin() + offset[state.range(0)];
  const Eigen::VectorXd seed = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(chain.dof()));
  std::size_t solved = 0;
  for (auto _ : state) solved += chain.inverse(target, seed).status == IkStatus::kOk;
  state.SetItemsProcessed(state.iterations());
  state.counters["solved"] = static_cast<double>(solved);
  state.SetLabel(kArms[state.range(0)]);
}

BENCHMARK(BM_Forward)->DenseRange(0, 1);
BENCHMARK(BM_Jacobian)->DenseRange(0, 1);
BENCHMARK(BM_InverseDistantSeed)->DenseRange(0, 1);
BENCHMARK(BM_InverseNearbySeed)->DenseRange(0, 1);
BENCHMARK(BM_InverseUnreachable)->DenseRange(0, 1);

}  // namespace

BENCHMARK_MAIN();
