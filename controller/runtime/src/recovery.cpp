#include "cellwright/runtime/recovery.hpp"

#include <fmt/format.h>

#include <array>
#include <fstream>
#include <sstream>

#include "cellwright/common/files.hpp"
#include "cellwright/common/error.hpp"
#include "cellwright/models/yaml_fields.hpp"

namespace cellwright::runtime {

namespace {

constexpr std::array<std::string_view, kSymptoms> kSymptomNames = {
    "grip_lost",        "closed_on_nothing",  "closed_on_wrong_part", "part_shifted", "part_misplaced",
    "part_not_arrived", "target_unreachable", "driver_timeout",       "driver_fault", "link_lost",
    "position_refused", "position_missed",    "protective_stop",      "wait_timeout", "frame_lost",
    "obstacle_seen",    "no_progress",        "unknown_error",        "io_failed",    "device_timeout",
    "device_contradiction"};
constexpr std::array<std::string_view, 12> kQuestionNames = {
    "part_seen",          "part_at_rest",     "part_upright", "part_reachable", "part_in_hand", "driver_in_fault",
    "retries_left",       "obstacle_near",    "signal_fired", "motion_blocked", "waiting_for_part", "part_lost"};
constexpr std::array<std::string_view, 9> kActionNames = {"retry",  "reset_rehome", "pick_again",
                                                          "adopt_hold", "go_on", "wait_clear",
                                                          "set_aside",  "resignal",     "stop_cell"};

template <typename E, std::size_t N>
std::optional<E> find_name(const std::array<std::string_view, N>& names, std::string_view name) {
  for (std::size_t i = 0; i < N; ++i) {
    if (names[i] == name) return static_cast<E>(i);
  }
  return std::nullopt;
}

template <std::size_t N>
std::string list_of(const std::array<std::string_view, N>& names) {
  std::string out;
  for (const std::string_view n : names) {
    if (!out.empty()) out += ", ";
    out += n;
  }
  return out;
}

constexpr std::string_view kStandard = R"TREE(# Cellwright's decision tree: from what the controller senses (the symptom) to the cause and the remedial action.
# Format, symptoms, questions and actions: docs/faults.md section 3. A scenario may use its own with `recovery: FILE`.
grip_lost:
  ask: part_seen
  yes:
    ask: retries_left
    yes:
      ask: part_reachable
      yes: {cause: dropped, action: pick_again}
      no: {cause: dropped_out_of_reach, action: set_aside}
    no: {cause: dropped_again, action: set_aside}
  no: {cause: dropped_unseen, action: set_aside}
closed_on_nothing:
  ask: part_seen
  yes:
    ask: retries_left
    yes:
      ask: part_reachable
      yes: {cause: part_not_where_expected, action: pick_again}
      no: {cause: part_out_of_reach, action: set_aside}
    no: {cause: cannot_grasp, action: set_aside}
  no: {cause: part_gone, action: set_aside}
closed_on_wrong_part:
  ask: retries_left
  yes: {cause: wrong_part_in_the_way, action: pick_again}
  no: {cause: wrong_part_in_the_way, action: stop_cell}
part_shifted:
  ask: part_in_hand
  yes: {cause: slipped, action: adopt_hold}
  no: {cause: slipped_out, action: go_on}
part_misplaced:
  ask: part_reachable
  yes: {cause: misplaced, action: go_on}
  no: {cause: misplaced_out_of_reach, action: set_aside}
part_not_arrived: {cause: missing, action: set_aside}
target_unreachable:
  ask: part_seen
  yes: {cause: part_out_of_reach, action: set_aside}
  no: {cause: program_error, action: stop_cell}
driver_timeout:
  ask: driver_in_fault
  yes: {cause: controller_error, action: reset_rehome}
  no:
    ask: motion_blocked
    yes:
      ask: retries_left
      yes: {cause: obstructed, action: retry}
      no: {cause: obstruction, action: stop_cell}
    no:
      ask: retries_left
      yes: {cause: controller_timeout, action: retry}
      no: {cause: controller_not_answering, action: stop_cell}
driver_fault:
  ask: retries_left
  yes: {cause: controller_error, action: reset_rehome}
  no: {cause: controller_broken, action: stop_cell}
# An error text or code the driver does not know: what the controller's state is cannot be told, so no arm is moved.
unknown_error: {cause: unknown_controller_error, action: stop_cell}
link_lost:
  ask: retries_left
  yes: {cause: link_dropped, action: reset_rehome}
  no: {cause: link_down, action: stop_cell}
position_refused:
  ask: retries_left
  yes: {cause: controller_refused_position, action: retry}
  no: {cause: position_out_of_reach, action: stop_cell}
position_missed:
  ask: retries_left
  yes: {cause: arm_held_back, action: retry}
  no: {cause: arm_blocked, action: stop_cell}
protective_stop:
  ask: obstacle_near
  yes: {cause: obstacle, action: wait_clear}
  no: {cause: too_close_or_force, action: wait_clear}
wait_timeout:
  ask: signal_fired
  yes: {cause: signal_lost, action: resignal}
  no: {cause: signaller_still_busy, action: go_on}
frame_lost: {cause: camera_dropout, action: go_on}
obstacle_seen:
  ask: obstacle_near
  yes: {cause: obstacle, action: go_on}
  no: {cause: obstacle_far_away, action: go_on}
no_progress:
  ask: waiting_for_part
  yes:
    ask: part_lost
    yes: {cause: part_lost_upstream, action: set_aside}
    no: {cause: part_never_ready, action: stop_cell}
  no: {cause: livelock, action: stop_cell}
# Devices on the cell's I/O (device control, docs/devices.md): a request the unit did not carry out (timeout, Modbus
# exception, connection lost) is tried again after connecting anew; an input that never comes (a machine never done,
# a photo-eye never on) or that contradicts the environment model (an eye sees a part the model does not have) stops
# the cell: nothing the controller can do makes a machine finish or explains a part it does not know.
io_failed:
  ask: retries_left
  yes: {cause: io_request_failed, action: retry}
  no: {cause: io_unit_down, action: stop_cell}
device_timeout: {cause: device_not_answering, action: stop_cell}
device_contradiction: {cause: unknown_part_at_sensor, action: stop_cell}
)TREE";

}  // namespace

std::string_view to_string(Symptom s) { return kSymptomNames.at(static_cast<std::size_t>(s)); }
std::optional<Symptom> symptom_from(std::string_view name) { return find_name<Symptom>(kSymptomNames, name); }
std::string_view to_string(Question q) { return kQuestionNames.at(static_cast<std::size_t>(q)); }
std::optional<Question> question_from(std::string_view name) { return find_name<Question>(kQuestionNames, name); }
std::string_view to_string(Action a) { return kActionNames.at(static_cast<std::size_t>(a)); }
std::optional<Action> action_from(std::string_view name) { return find_name<Action>(kActionNames, name); }

DecisionTree DecisionTree::parse(std::string_view yaml_text, const std::string& source) {
  namespace y = models::yaml;
  const y::Doc doc(source);
  const YAML::Node root = y::load(yaml_text, doc, "the decision tree is not valid YAML");
  if (!root.IsMap()) doc.fail(root, fmt::format("a decision tree must be a mapping of symptoms, got {}", y::describe(root)));
  DecisionTree tree;
  // Depth-first; returns the node's index.
  std::function<int(const YAML::Node&, const std::string&)> node = [&](const YAML::Node& n, const std::string& what) {
    if (!n.IsMap()) doc.fail(n, fmt::format("{} must be {{ask, yes, no}} or {{cause, action}}, got {}", what, y::describe(n)));
    const bool inner = n["ask"].IsDefined();
    y::Fields f(doc, n, what, inner ? std::initializer_list<std::string_view>{"ask", "yes", "no"}
                                   : std::initializer_list<std::string_view>{"cause", "action"});
    const int index = static_cast<int>(tree.nodes_.size());
    tree.nodes_.emplace_back();
    if (inner) {
      const std::string q = f.word("ask");
      const std::optional<Question> question = question_from(q);
      if (!question) {
        doc.fail(n["ask"], fmt::format("unknown question '{}' in {} (expected one of: {})", q, what, list_of(kQuestionNames)));
      }
      if (!n["yes"].IsDefined() || !n["no"].IsDefined()) {
        doc.fail(n, fmt::format("{} asks '{}' but lacks {}", what, q, n["yes"].IsDefined() ? "'no'" : "'yes'"));
      }
      const int yes = node(n["yes"], fmt::format("the 'yes' of '{}'", q));
      const int no = node(n["no"], fmt::format("the 'no' of '{}'", q));
      tree.nodes_[static_cast<std::size_t>(index)].ask = question;
      tree.nodes_[static_cast<std::size_t>(index)].yes = yes;
      tree.nodes_[static_cast<std::size_t>(index)].no = no;
    } else {
      const std::string cause = f.word("cause");
      const std::string a = f.word("action");
      const std::optional<Action> action = action_from(a);
      if (!action) {
        doc.fail(n["action"], fmt::format("unknown action '{}' in {} (expected one of: {})", a, what, list_of(kActionNames)));
      }
      if (cause.empty()) doc.fail(n["cause"], fmt::format("the cause of {} is empty", what));
      tree.nodes_[static_cast<std::size_t>(index)].cause = cause;
      tree.nodes_[static_cast<std::size_t>(index)].action = *action;
    }
    return index;
  };
  for (const auto& entry : root) {
    const std::string name = entry.first.Scalar();
    const std::optional<Symptom> s = symptom_from(name);
    if (!s) doc.fail(entry.first, fmt::format("unknown symptom '{}' (expected one of: {})", name, list_of(kSymptomNames)));
    if (tree.roots_.count(*s) != 0) doc.fail(entry.first, fmt::format("symptom '{}' is given twice", name));
    tree.roots_[*s] = node(entry.second, fmt::format("symptom '{}'", name));
  }
  return tree;
}

DecisionTree DecisionTree::load(const std::filesystem::path& file) {
  std::string text;
  try {
    text = read_file(file);
  } catch (const InputError& e) {
    throw InputError({file.string(), 0, 0}, fmt::format("cannot read the decision tree file: {}", e.problem()));
  }
  return parse(text, file.string());
}

std::string_view DecisionTree::standard_text() { return kStandard; }

const DecisionTree& DecisionTree::standard() {
  static const DecisionTree tree = parse(kStandard, "the built-in decision tree");
  return tree;
}

Diagnosis DecisionTree::diagnose(Symptom symptom, const std::function<bool(Question)>& answer) const {
  Diagnosis d;
  d.symptom = symptom;
  const auto root = roots_.find(symptom);
  if (root == roots_.end()) {
    d.cause = "unknown";
    d.action = Action::stop_cell;
    return d;
  }
  int at = root->second;
  for (;;) {
    const Node& n = nodes_.at(static_cast<std::size_t>(at));
    if (!n.ask) {
      d.cause = n.cause;
      d.action = n.action;
      return d;
    }
    const bool yes = answer(*n.ask);
    if (!d.path.empty()) d.path += ' ';
    d.path += fmt::format("{}={}", to_string(*n.ask), yes ? "yes" : "no");
    at = yes ? n.yes : n.no;
  }
}

}  // namespace cellwright::runtime
