// libFuzzer harness: URDF robots (models/urdf, models/kinematics). XML text -> parse_urdf -> the kinematic chain from
// base_link to tcp -> forward kinematics, the Jacobian and IK at the joints' lower limits, middles and upper limits.
// Only InputError may refuse it; an accepted chain must give finite poses. Seeds: models/urdf/*.urdf.
#include <Eigen/Core>

#include <cmath>

#include "cellwright/models/kinematics.hpp"
#include "cellwright/models/urdf.hpp"
#include "fuzz.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = cellwright::fuzz::text_of(data, size);
  cellwright::fuzz::refusing_only_with_input_errors([&] {
    using namespace cellwright::models;
    const UrdfModel robot = parse_urdf(text, "fuzz.urdf");
    const KinematicChain chain = KinematicChain::from_urdf(robot);
    CW_FUZZ_CHECK(chain.dof() > 0 && chain.dof() == chain.limits().size());
    CW_FUZZ_CHECK(std::isfinite(chain.max_reach()));
    const auto n = static_cast<Eigen::Index>(chain.dof());
    Eigen::VectorXd lower(n), upper(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      lower[i] = chain.limits()[static_cast<std::size_t>(i)].lower;
      upper[i] = chain.limits()[static_cast<std::size_t>(i)].upper;
    }
    for (const Eigen::VectorXd& q :
         {Eigen::VectorXd(lower), Eigen::VectorXd(upper), Eigen::VectorXd(0.5 * (lower + upper))}) {
      if (!q.allFinite()) continue;  // a continuous joint has infinite limits
      const Eigen::Isometry3d tip = chain.forward(q);
      CW_FUZZ_CHECK(tip.matrix().allFinite());
      (void)chain.jacobian(q);
      IkOptions few;
      few.restarts = 1;
      (void)chain.inverse(tip, q, few);
    }
  });
  return 0;
}
