// Earliest-time simulation of a timed Petri net (timed_net.hpp).
#include "cellwright/cell/timed_net.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "cellwright/common/error.hpp"

namespace cellwright::cell {

TimedRun simulate_timed(const petri::Net& net, const std::vector<double>& place_duration, std::uint64_t max_firings,
                        task::LoopControl* loops) {
  CW_CHECK(place_duration.size() == net.num_places(), "{} place durations for a net of {} places",
           place_duration.size(), net.num_places());
  for (std::size_t p = 0; p < place_duration.size(); ++p) {
    CW_CHECK(std::isfinite(place_duration[p]) && place_duration[p] >= 0, "duration of place {} is {}",
             net.places()[p].id, place_duration[p]);
  }

  // Each place holds the times from which its tokens may leave, ascending.
  std::vector<std::vector<double>> available(net.num_places());
  for (std::size_t p = 0; p < net.num_places(); ++p) {
    available[p].assign(net.places()[p].initial, place_duration[p]);
  }

  TimedRun run;
  constexpr double kNever = std::numeric_limits<double>::infinity();
  std::vector<bool> allowed;
  while (run.firings.size() < max_firings) {
    petri::TransitionId best = 0;
    double best_time = kNever;
    if (loops != nullptr) {
      allowed.assign(net.num_transitions(), true);
      loops->restrict(allowed);
    }
    for (petri::TransitionId t = 0; t < net.num_transitions(); ++t) {
      if (!allowed.empty() && !allowed[t]) continue;
      double ready = 0;
      for (const petri::Arc& a : net.transitions()[t].inputs) {
        const auto& tokens = available[a.place];
        if (tokens.size() < a.weight) {
          ready = kNever;
          break;
        }
        ready = std::max(ready, tokens[a.weight - 1]);
      }
      if (ready < best_time) {
        best_time = ready;
        best = t;
      }
    }
    if (best_time == kNever) break;  // dead

    // Never earlier than the previous firing: time runs forward, and a token available earlier waited for this.
    const double now = run.firings.empty() ? best_time : std::max(best_time, run.firings.back().time);
    const petri::Transition& tr = net.transitions()[best];
    for (const petri::Arc& a : tr.inputs) {
      auto& tokens = available[a.place];
      tokens.erase(tokens.begin(), tokens.begin() + a.weight);
    }
    for (const petri::Arc& a : tr.outputs) {
      auto& tokens = available[a.place];
      const double from = now + place_duration[a.place];
      tokens.insert(std::upper_bound(tokens.begin(), tokens.end(), from), a.weight, from);
    }
    run.firings.push_back({best, now});
    if (loops != nullptr) loops->fired(best);
  }

  run.final_marking.assign(net.num_places(), 0);
  for (std::size_t p = 0; p < net.num_places(); ++p) {
    run.final_marking[p] = static_cast<petri::Tokens>(available[p].size());
  }
  run.finish = run.firings.empty() ? 0.0 : run.firings.back().time;
  run.finished = net.is_final(run.final_marking);
  return run;
}

}  // namespace cellwright::cell
