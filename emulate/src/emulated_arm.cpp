// The shared target check of the emulated arms (emulated_arm.hpp).
#include "cellwright/emulate/emulated_arm.hpp"

#include <fmt/format.h>

namespace cellwright::emulate {

ArmResult check_target(const models::KinematicChain& chain, const std::vector<double>& target) {
  if (target.size() != chain.dof()) {
    return {ArmStatus::unreachable, fmt::format("{} joints for an arm of {}", target.size(), chain.dof())};
  }
  const Eigen::VectorXd q = Eigen::Map<const Eigen::VectorXd>(target.data(), static_cast<Eigen::Index>(target.size()));
  if (!chain.within_limits(q)) return {ArmStatus::unreachable, "outside the joint limits"};
  return {};
}

}  // namespace cellwright::emulate
