// PNML import/export (see pnml.hpp for what is accepted and how errors are reported).
#include "cellwright/petri/pnml.hpp"

#include <sys/stat.h>
#include <tinyxml2.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "cellwright/common/error.hpp"
#include "cellwright/common/files.hpp"
#include "cellwright/common/xml.hpp"

namespace cellwright::petri {
namespace {

using tinyxml2::XMLElement;

constexpr const char* kPnmlNamespace = "http://www.pnml.org/version-2009/grammar/pnml";
constexpr const char* kPtNetType = "http://www.pnml.org/version-2009/grammar/ptnet";
constexpr const char* kTool = "cellwright";
constexpr const char* kToolVersion = "1";
constexpr Tokens kMaxTokens = std::numeric_limits<Tokens>::max();

// ---------------------------------------------------------------------------------------------------------------
// Small helpers shared by import and export.

struct KindName {
  PlaceKind kind;
  const char* name;
};
// Spelled here rather than taken from to_string(PlaceKind) so that the file format cannot change by accident.
constexpr KindName kKindNames[] = {
    {PlaceKind::kPlain, "plain"},     {PlaceKind::kStart, "start"}, {PlaceKind::kExecuting, "executing"},
    {PlaceKind::kWaiting, "waiting"}, {PlaceKind::kDone, "done"},   {PlaceKind::kEvent, "event"},
    {PlaceKind::kRegion, "region"},
};

const char* kind_name(PlaceKind k) {
  for (const auto& kn : kKindNames) {
    if (kn.kind == k) return kn.name;
  }
  CW_CHECK(false, "unknown PlaceKind {}", static_cast<int>(k));
  return "";  // not reached
}

// A value quoted for an error message; hostile inputs (a 10^30-digit marking) are shortened.
std::string quote(std::string_view s) {
  constexpr std::size_t kMax = 60;
  if (s.size() <= kMax) return fmt::format("'{}'", s);
  return fmt::format("'{}...' ({} characters)", s.substr(0, kMax), s.size());
}

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// An element's name without its namespace prefix ("pnml:net" -> "net"); tinyxml2 does not process namespaces.
std::string_view local_name(const XMLElement* e) {
  std::string_view n = e->Name();
  const auto colon = n.find(':');
  return colon == std::string_view::npos ? n : n.substr(colon + 1);
}

const XMLElement* child(const XMLElement* e, std::string_view name) {
  for (const XMLElement* c = e->FirstChildElement(); c != nullptr; c = c->NextSiblingElement()) {
    if (local_name(c) == name) return c;
  }
  return nullptr;
}

std::string_view text_of(const XMLElement* e) {
  const char* t = e->GetText();
  return t == nullptr ? std::string_view{} : std::string_view{t};
}

// ---------------------------------------------------------------------------------------------------------------
// Import.

enum class NodeKind { kPlace, kTransition, kRefPlace, kRefTransition, kArc, kPage, kNet };

const char* node_kind_name(NodeKind k) {
  switch (k) {
    case NodeKind::kPlace:
      return "place";
    case NodeKind::kTransition:
      return "transition";
    case NodeKind::kRefPlace:
      return "referencePlace";
    case NodeKind::kRefTransition:
      return "referenceTransition";
    case NodeKind::kArc:
      return "arc";
    case NodeKind::kPage:
      return "page";
    case NodeKind::kNet:
      return "net";
  }
  return "element";
}

struct IdEntry {
  NodeKind kind;
  const XMLElement* element;
  std::uint32_t index;  // PlaceId / TransitionId for places and transitions
};

class Reader {
 public:
  explicit Reader(const std::string& file) : file_(file) {}

  PnmlDocument read(std::string_view xml, const PnmlReadOptions& options) {
    tinyxml2::XMLDocument doc(true, tinyxml2::PRESERVE_WHITESPACE);
    if (doc.Parse(xml.data(), xml.size()) != tinyxml2::XML_SUCCESS) {
      throw InputError({file_, doc.ErrorLineNum(), 0}, xml_error_message(doc));
    }
    const XMLElement* root = doc.RootElement();
    if (root == nullptr) throw InputError({file_, 0, 0}, "no XML element in the file");
    if (local_name(root) != "pnml") {
      fail(root, fmt::format("the root element is <{}>; a PNML file has <pnml>", root->Name()));
    }

    PnmlDocument out;
    const XMLElement* chosen = nullptr;
    for (const XMLElement* n = root->FirstChildElement(); n != nullptr; n = n->NextSiblingElement()) {
      if (local_name(n) != "net") continue;
      const char* id = n->Attribute("id");
      out.net_ids.emplace_back(id == nullptr ? "" : id);
      if (chosen == nullptr && (options.net_id.empty() || options.net_id == out.net_ids.back())) chosen = n;
    }
    if (out.net_ids.empty()) fail(root, "no <net> element in <pnml>");
    if (chosen == nullptr) {
      std::string ids;
      for (const auto& id : out.net_ids) ids += (ids.empty() ? "" : ", ") + quote(id);
      fail(root, fmt::format("no net with id {} in the file (it has: {})", quote(options.net_id), ids));
    }
    out.net = read_net(chosen);
    return out;
  }

 private:
  [[noreturn]] void fail(const XMLElement* e, const std::string& problem) const {
    throw InputError({file_, e == nullptr ? 0 : e->GetLineNum(), 0}, problem);
  }

  static std::string xml_error_message(const tinyxml2::XMLDocument& doc) {
    std::string what;
    switch (doc.ErrorID()) {
      case tinyxml2::XML_ERROR_EMPTY_DOCUMENT:
        return "not a PNML file: it holds no XML element";
      case tinyxml2::XML_ERROR_MISMATCHED_ELEMENT:
        what = "an end tag does not match its start tag";
        break;
      case tinyxml2::XML_ERROR_PARSING_ELEMENT:
        what = "malformed or unclosed element";
        break;
      case tinyxml2::XML_ERROR_PARSING_ATTRIBUTE:
        what = "malformed attribute";
        break;
      case tinyxml2::XML_ERROR_PARSING_TEXT:
        what = "malformed text";
        break;
      case tinyxml2::XML_ELEMENT_DEPTH_EXCEEDED:
        what = fmt::format("elements nested deeper than {}", TINYXML2_MAX_ELEMENT_DEPTH);
        break;
      default:
        what = doc.ErrorName();
        break;
    }
    // tinyxml2's own text ends with the detail ("...Line number=3: XMLElement name=net"); keep the detail.
    std::string_view detail = doc.ErrorStr() == nullptr ? "" : doc.ErrorStr();
    const auto at = detail.find("Line number=");
    const auto colon = at == std::string_view::npos ? std::string_view::npos : detail.find(": ", at);
    detail = colon == std::string_view::npos ? std::string_view{} : trim(detail.substr(colon + 2));
    return detail.empty() ? fmt::format("not well-formed XML: {}", what)
                          : fmt::format("not well-formed XML: {} ({})", what, detail);
  }

  // A non-negative decimal token count that fits in Tokens. `what` names the value in messages.
  Tokens parse_count(std::string_view raw, const XMLElement* where, const char* what) const {
    const std::string_view s = trim(raw);
    if (s.empty()) fail(where, fmt::format("empty {}", what));
    if (s.front() == '-' && s.size() > 1 &&
        std::all_of(s.begin() + 1, s.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      fail(where, fmt::format("negative {} {}", what, quote(s)));
    }
    std::uint64_t v = 0;
    for (char c : s) {
      if (c < '0' || c > '9') fail(where, fmt::format("{} {} is not a non-negative integer", what, quote(s)));
      v = v * 10 + static_cast<std::uint64_t>(c - '0');
      // Checked per digit, so a hostile 10^30 is reported and never wraps.
      if (v > kMaxTokens)
        fail(where, fmt::format("{} {} exceeds the largest token count {}", what, quote(s), kMaxTokens));
    }
    return static_cast<Tokens>(v);
  }

  // An integer attribute of our own toolspecific data, within [lo, hi]; `fallback` when absent.
  long long int_attr(const XMLElement* e, const char* name, long long lo, long long hi, long long fallback) const {
    const char* a = e->Attribute(name);
    if (a == nullptr) return fallback;
    const std::string_view s = trim(a);
    bool neg = !s.empty() && s.front() == '-';
    std::string_view digits = neg ? s.substr(1) : s;
    if (digits.empty() || !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      fail(e, fmt::format("attribute {}={} is not an integer", name, quote(s)));
    }
    long long v = 0;
    for (char c : digits) {
      v = v * 10 + (c - '0');
      if (v > hi + 1) break;  // out of range anyway; stop before overflow
    }
    if (neg) v = -v;
    if (v < lo || v > hi) fail(e, fmt::format("attribute {}={} is outside [{}, {}]", name, quote(s), lo, hi));
    return v;
  }

  // The value of a PNML annotation: <x><text>..</text></x> (ISO) or <x><value>..</value></x> (PIPE).
  // Returns the element holding the text (for line numbers), or nullptr when the annotation has neither.
  static const XMLElement* annotation_text(const XMLElement* annotation, std::string_view* text) {
    for (const char* tag : {"text", "value"}) {
      if (const XMLElement* t = child(annotation, tag)) {
        *text = text_of(t);
        return t;
      }
    }
    return nullptr;
  }

  // A marking or inscription: ISO <text>N</text>, or PIPE <value>N</value> / <value>Default,N</value>.
  Tokens count_annotation(const XMLElement* annotation, const char* what) const {
    std::string_view text;
    const XMLElement* t = annotation_text(annotation, &text);
    if (t == nullptr) fail(annotation, fmt::format("<{}> without <text>", annotation->Name()));
    if (local_name(t) == "value" && text.find(',') != std::string_view::npos) {
      // PIPE writes "<token class>,<count>" pairs; more than one class is a coloured net.
      const auto comma = text.find(',');
      if (text.find(',', comma + 1) != std::string_view::npos) {
        fail(t, fmt::format("{} {} uses several PIPE token classes (coloured tokens), which a P/T net cannot hold",
                            what, quote(trim(text))));
      }
      return parse_count(text.substr(comma + 1), t, what);
    }
    return parse_count(text, t, what);
  }

  std::string name_of(const XMLElement* node, const std::string& fallback) const {
    if (const XMLElement* n = child(node, "name")) {
      std::string_view text;
      // A <name> whose text is empty names the node "" (as Cellwright writes an empty name); no <name> at all
      // means the id.
      if (annotation_text(n, &text) != nullptr) return std::string(trim(text));
    }
    // Named by its id: white space around it is dropped as around a <name>, so that the name reads back the same.
    return std::string(trim(fallback));
  }

  std::string required_id(const XMLElement* e) const {
    const char* id = e->Attribute("id");
    if (id == nullptr || trim(id).empty()) fail(e, fmt::format("<{}> without an id", e->Name()));
    return id;
  }

  void register_id(const std::string& id, NodeKind kind, const XMLElement* e, std::uint32_t index) {
    const auto [it, inserted] = ids_.emplace(id, IdEntry{kind, e, index});
    if (!inserted) {
      fail(e, fmt::format("duplicate id {}: already used by the {} on line {}", quote(id),
                          node_kind_name(it->second.kind), it->second.element->GetLineNum()));
    }
  }

  static bool is_cellwright(const XMLElement* e) {
    const char* tool = e->Attribute("tool");
    return tool != nullptr && std::string_view(tool) == kTool;
  }

  // Our own <toolspecific>, or nullptr; other tools' blocks are ignored. A second block or another version is an
  // error rather than a guess.
  const XMLElement* cellwright_block(const XMLElement* node) const {
    const XMLElement* found = nullptr;
    for (const XMLElement* c = node->FirstChildElement(); c != nullptr; c = c->NextSiblingElement()) {
      if (local_name(c) != "toolspecific" || !is_cellwright(c)) continue;
      if (found != nullptr) fail(c, "a second <toolspecific tool=\"cellwright\"> in one element");
      const char* version = c->Attribute("version");
      if (version == nullptr || std::string_view(version) != kToolVersion) {
        fail(c, fmt::format("unsupported cellwright toolspecific version {} (this build reads version {})",
                            quote(version == nullptr ? "" : version), kToolVersion));
      }
      found = c;
    }
    return found;
  }

  Origin read_origin(const XMLElement* o) const {
    constexpr long long kIntMax = std::numeric_limits<int>::max();
    Origin origin;
    origin.line = static_cast<int>(int_attr(o, "line", 0, kIntMax, 0));
    origin.column = static_cast<int>(int_attr(o, "column", 0, kIntMax, 0));
    origin.primitive = static_cast<int>(int_attr(o, "primitive", -1, kIntMax, -1));
    if (const XMLElement* r = child(o, "robot")) origin.robot = std::string(text_of(r));
    if (const XMLElement* t = child(o, "task")) origin.task = std::string(text_of(t));
    if (const XMLElement* m = child(o, "motion")) origin.motion = std::string(text_of(m));
    return origin;
  }

  // Walks a <net> or <page>, registering nodes in document order (depth first through nested pages).
  void collect(const XMLElement* container) {
    for (const XMLElement* e = container->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
      const std::string_view tag = local_name(e);
      if (tag == "page") {
        if (const char* id = e->Attribute("id")) register_id(id, NodeKind::kPage, e, 0);
        collect(e);
      } else if (tag == "place") {
        read_place(e);
      } else if (tag == "transition") {
        read_transition(e);
      } else if (tag == "referencePlace" || tag == "referenceTransition") {
        const std::string id = required_id(e);
        const char* ref = e->Attribute("ref");
        if (ref == nullptr) fail(e, fmt::format("<{}> {} without a ref attribute", e->Name(), quote(id)));
        register_id(id, tag == "referencePlace" ? NodeKind::kRefPlace : NodeKind::kRefTransition, e, 0);
        refs_.push_back(e);
      } else if (tag == "arc") {
        if (const char* id = e->Attribute("id")) register_id(id, NodeKind::kArc, e, 0);
        arcs_.push_back(e);
      }
      // Anything else (graphics, toolspecific of other tools, PIPE's <token>, labels) carries no P/T meaning.
    }
  }

  void read_place(const XMLElement* e) {
    Place p;
    p.id = required_id(e);
    p.name = name_of(e, p.id);
    if (const XMLElement* m = child(e, "initialMarking")) p.initial = count_annotation(m, "initial marking");
    if (const XMLElement* cap = child(e, "capacity")) {
      // PIPE: 0 means unbounded; a real capacity changes the firing rule, so it cannot be dropped silently.
      if (count_annotation(cap, "capacity") != 0) {
        fail(cap, fmt::format("place {} has a capacity; P/T nets have unbounded places (model the capacity with a "
                              "complementary place)",
                              quote(p.id)));
      }
    }
    if (const XMLElement* ts = cellwright_block(e)) {
      if (const XMLElement* k = child(ts, "kind")) {
        const std::string_view name = trim(text_of(k));
        const auto* it = std::find_if(std::begin(kKindNames), std::end(kKindNames),
                                      [&](const KindName& kn) { return name == kn.name; });
        if (it == std::end(kKindNames)) fail(k, fmt::format("unknown place kind {}", quote(name)));
        p.kind = it->kind;
      }
      if (const XMLElement* o = child(ts, "origin")) p.origin = read_origin(o);
    }
    const auto index = static_cast<PlaceId>(places_.size());
    register_id(p.id, NodeKind::kPlace, e, index);
    places_.push_back(std::move(p));
  }

  void read_transition(const XMLElement* e) {
    Transition t;
    t.id = required_id(e);
    t.name = name_of(e, t.id);
    if (const XMLElement* ts = cellwright_block(e)) {
      if (const XMLElement* o = child(ts, "origin")) t.origin = read_origin(o);
      if (const XMLElement* s = child(ts, "starts")) {
        const long long robot = int_attr(s, "robot", 0, std::numeric_limits<std::uint32_t>::max() - 1LL, -1);
        if (robot >= 0) {
          t.starts_robot = static_cast<std::uint32_t>(robot);
          starts_.emplace_back(s, static_cast<TransitionId>(transitions_.size()));
        }
        t.starts_primitive = static_cast<int>(int_attr(s, "primitive", -1, std::numeric_limits<int>::max(), -1));
      }
    }
    const auto index = static_cast<TransitionId>(transitions_.size());
    register_id(t.id, NodeKind::kTransition, e, index);
    transitions_.push_back(std::move(t));
  }

  // Follows reference nodes to the place or transition they stand for. `user` is the element naming `id`.
  const IdEntry& resolve(const std::string& id, const XMLElement* user, const char* role) const {
    std::string current = id;
    // A chain longer than the number of ids must revisit one: a cycle.
    for (std::size_t steps = 0; steps <= ids_.size(); ++steps) {
      const auto it = ids_.find(current);
      if (it == ids_.end()) {
        if (current == id) fail(user, fmt::format("{} {} is not a node of this net", role, quote(id)));
        fail(user, fmt::format("{} {} refers to {}, which is not a node of this net", role, quote(id), quote(current)));
      }
      const IdEntry& entry = it->second;
      switch (entry.kind) {
        case NodeKind::kPlace:
        case NodeKind::kTransition:
          return entry;
        case NodeKind::kRefPlace:
        case NodeKind::kRefTransition:
          current = entry.element->Attribute("ref");
          break;
        case NodeKind::kArc:
        case NodeKind::kPage:
        case NodeKind::kNet:
          fail(user, fmt::format("{} {} is a{} {}, not a place or transition", role, quote(current),
                                 entry.kind == NodeKind::kArc ? "n" : "", node_kind_name(entry.kind)));
      }
    }
    fail(user, fmt::format("{} {} is a reference in a cycle of references", role, quote(id)));
  }

  // Checks that each reference node resolves to a node of its own kind, even when no arc uses it.
  void check_references() const {
    for (const XMLElement* ref : refs_) {
      const std::string id = ref->Attribute("id");
      const IdEntry& entry = ids_.at(id);
      const IdEntry& target = resolve(id, entry.element, entry.element->Name());
      const NodeKind want = entry.kind == NodeKind::kRefPlace ? NodeKind::kPlace : NodeKind::kTransition;
      if (target.kind != want) {
        fail(entry.element, fmt::format("{} {} refers to a {}, not a {}", entry.element->Name(), quote(id),
                                        node_kind_name(target.kind), node_kind_name(want)));
      }
    }
  }

  static void add_weight(std::vector<Arc>& arcs, PlaceId place, Tokens weight, bool* overflow) {
    for (Arc& a : arcs) {
      if (a.place == place) {
        // Parallel arcs add up; report rather than wrap.
        if (a.weight > kMaxTokens - weight) {
          *overflow = true;
          return;
        }
        a.weight += weight;
        return;
      }
    }
    arcs.push_back(Arc{place, weight});
  }

  void read_arc(const XMLElement* e) {
    const char* src = e->Attribute("source");
    const char* dst = e->Attribute("target");
    const char* id = e->Attribute("id");
    const std::string label = id == nullptr ? std::string("arc") : fmt::format("arc {}", quote(id));
    if (src == nullptr) fail(e, fmt::format("{} without a source attribute", label));
    if (dst == nullptr) fail(e, fmt::format("{} without a target attribute", label));
    if (const XMLElement* type = child(e, "type")) {
      // PIPE/TINA mark inhibitor, reset and test arcs so; dropping them would change the net's behaviour.
      std::string_view kind = type->Attribute("value") != nullptr ? type->Attribute("value") : "";
      if (kind.empty()) annotation_text(type, &kind);
      kind = trim(kind);
      if (!kind.empty() && kind != "normal") {
        fail(type, fmt::format("{} has type {}; only ordinary P/T arcs are supported", label, quote(kind)));
      }
    }
    const IdEntry& from = resolve(src, e, "arc source");
    const IdEntry& to = resolve(dst, e, "arc target");
    if (from.kind == to.kind) {
      fail(e, fmt::format("{} connects two {}s ({} -> {}); arcs go between a place and a transition", label,
                          node_kind_name(from.kind), quote(src), quote(dst)));
    }
    Tokens weight = 1;
    if (const XMLElement* ins = child(e, "inscription")) {
      weight = count_annotation(ins, "arc weight");
      if (weight == 0) fail(ins, fmt::format("{} has weight 0; arc weights are positive", label));
    }
    bool overflow = false;
    if (from.kind == NodeKind::kPlace) {
      add_weight(transitions_[to.index].inputs, from.index, weight, &overflow);
    } else {
      add_weight(transitions_[from.index].outputs, to.index, weight, &overflow);
    }
    if (overflow) {
      fail(e,
           fmt::format("the arcs between {} and {} weigh more than {} together", quote(src), quote(dst), kMaxTokens));
    }
  }

  PlaceId place_ref(const XMLElement* e, const char* attr) const {
    const char* id = e->Attribute(attr);
    if (id == nullptr) fail(e, fmt::format("<{}> without a {} attribute", e->Name(), attr));
    const IdEntry& entry = resolve(id, e, "place");
    if (entry.kind != NodeKind::kPlace) fail(e, fmt::format("{} is a transition, not a place", quote(id)));
    return entry.index;
  }

  void read_net_block(const XMLElement* ts, NetBuilder& builder) const {
    std::vector<std::string> robots;
    std::vector<Arc> final_places;
    for (const XMLElement* c = ts->FirstChildElement(); c != nullptr; c = c->NextSiblingElement()) {
      const std::string_view tag = local_name(c);
      if (tag == "robot") {
        const char* name = c->Attribute("name");
        if (name == nullptr || *name == '\0') fail(c, "<robot> without a name");
        robots.emplace_back(name);
      } else if (tag == "region") {
        Region r;
        const char* name = c->Attribute("name");
        if (name == nullptr) fail(c, "<region> without a name");
        r.name = name;
        r.capacity = c->Attribute("capacity") == nullptr ? 1 : parse_count(c->Attribute("capacity"), c, "capacity");
        for (const XMLElement* in = c->FirstChildElement(); in != nullptr; in = in->NextSiblingElement()) {
          if (local_name(in) == "inside") r.inside.push_back(place_ref(in, "place"));
        }
        builder.add_region(std::move(r));
      } else if (tag == "final") {
        const Tokens tokens =
            c->Attribute("tokens") == nullptr ? 1 : parse_count(c->Attribute("tokens"), c, "final tokens");
        final_places.push_back(Arc{place_ref(c, "place"), tokens});
      }
    }
    for (const auto& [element, t] : starts_) {
      if (*transitions_[t].starts_robot >= robots.size()) {
        fail(element,
             fmt::format("transition {} starts robot #{}, but the net lists {} robot{}", quote(transitions_[t].id),
                         *transitions_[t].starts_robot, robots.size(), robots.size() == 1 ? "" : "s"));
      }
    }
    builder.set_robots(std::move(robots));
    builder.set_final(std::move(final_places));
  }

  Net read_net(const XMLElement* net) {
    const char* id_attr = net->Attribute("id");
    const std::string id = id_attr == nullptr ? std::string() : std::string(id_attr);
    if (const char* type = net->Attribute("type")) {
      const std::string_view t = trim(type);
      const bool iso_pt = t.starts_with("http://www.pnml.org/version-") && t.ends_with("/grammar/ptnet");
      const bool ok = iso_pt || t == "P/T net" || t == "http://www.informatik.hu-berlin.de/top/pntd/ptNetb" ||
                      t == "http://www.pnml.org/version-2009/grammar/pnmlcoremodel";
      if (!ok) {
        fail(net, fmt::format("net {} has type {}; only place/transition nets ({}) are supported", quote(id), quote(t),
                              kPtNetType));
      }
    }
    if (!id.empty()) register_id(id, NodeKind::kNet, net, 0);
    collect(net);
    check_references();
    for (const XMLElement* a : arcs_) read_arc(a);

    NetBuilder builder(name_of(net, id.empty() ? std::string("net") : id));
    for (Place& p : places_) builder.add_place(std::move(p));
    if (const XMLElement* ts = cellwright_block(net)) {
      read_net_block(ts, builder);
    } else {
      for (const auto& [element, t] : starts_) {
        fail(element, fmt::format("transition {} starts robot #{}, but the net lists no robots",
                                  quote(transitions_[t].id), *transitions_[t].starts_robot));
      }
    }
    for (Transition& t : transitions_) builder.add_transition(std::move(t));
    try {
      return std::move(builder).build();
    } catch (const std::invalid_argument& e) {
      fail(net, fmt::format("invalid net: {}", e.what()));
    }
  }

  const std::string& file_;
  std::unordered_map<std::string, IdEntry> ids_;
  std::vector<Place> places_;
  std::vector<Transition> transitions_;
  std::vector<const XMLElement*> arcs_;
  std::vector<const XMLElement*> refs_;                             // reference nodes in document order
  std::vector<std::pair<const XMLElement*, TransitionId>> starts_;  // <starts robot=..> to check against robots
};

// ---------------------------------------------------------------------------------------------------------------
// Export.

class Writer {
 public:
  explicit Writer(const Net& net) : net_(net) {
    for (const Place& p : net.places()) used_.insert(p.id);
    for (const Transition& t : net.transitions()) used_.insert(t.id);
  }

  std::string write() {
    out_.declaration("xml version=\"1.0\" encoding=\"UTF-8\"");
    out_.open("pnml");
    out_.attribute("xmlns", kPnmlNamespace);
    out_.open("net");
    out_.attribute("id", fresh("net"));
    out_.attribute("type", kPtNetType);
    name(net_.name());
    net_block();
    out_.open("page");
    out_.attribute("id", fresh("page0"));
    for (const Place& p : net_.places()) place(p);
    for (const Transition& t : net_.transitions()) transition(t);
    // Arcs grouped by transition, inputs first, so that import rebuilds the same pre- and post-set order.
    for (const Transition& t : net_.transitions()) {
      for (const Arc& a : t.inputs) arc(net_.places().at(a.place).id, t.id, a.weight);
      for (const Arc& a : t.outputs) arc(t.id, net_.places().at(a.place).id, a.weight);
    }
    out_.close();  // page
    out_.close();  // net
    out_.close();  // pnml
    return out_.str();
  }

 private:
  // An id not used by any node, for the net, page and arcs.
  std::string fresh(const std::string& base) {
    std::string id = base;
    for (std::size_t k = 1; used_.count(id) != 0; ++k) id = fmt::format("{}-{}", base, k);
    used_.insert(id);
    return id;
  }

  void name(const std::string& n) {
    out_.open("name");
    out_.text_element("text", n);
    out_.close();
  }

  void open_tool() {
    out_.open("toolspecific");
    out_.attribute("tool", kTool);
    out_.attribute("version", kToolVersion);
  }

  static bool empty(const Origin& o) {
    return o.robot.empty() && o.line == 0 && o.column == 0 && o.task.empty() && o.motion.empty() && o.primitive == -1;
  }

  void origin(const Origin& o) {
    out_.open("origin");
    if (o.line != 0) out_.attribute("line", o.line);
    if (o.column != 0) out_.attribute("column", o.column);
    if (o.primitive != -1) out_.attribute("primitive", o.primitive);
    if (!o.robot.empty()) out_.text_element("robot", o.robot);
    if (!o.task.empty()) out_.text_element("task", o.task);
    if (!o.motion.empty()) out_.text_element("motion", o.motion);
    out_.close();
  }

  void net_block() {
    if (net_.robots().empty() && net_.regions().empty() && net_.final_places().empty()) return;
    open_tool();
    for (const std::string& r : net_.robots()) {
      out_.open("robot");
      out_.attribute("name", r);
      out_.close();
    }
    for (const Region& r : net_.regions()) {
      out_.open("region");
      out_.attribute("name", r.name);
      out_.attribute("capacity", r.capacity);
      for (PlaceId p : r.inside) {
        out_.open("inside");
        out_.attribute("place", net_.places().at(p).id);
        out_.close();
      }
      out_.close();
    }
    for (const Arc& f : net_.final_places()) {
      out_.open("final");
      out_.attribute("place", net_.places().at(f.place).id);
      out_.attribute("tokens", f.weight);
      out_.close();
    }
    out_.close();
  }

  void place(const Place& p) {
    out_.open("place");
    out_.attribute("id", p.id);
    name(p.name);
    if (p.initial != 0) {
      out_.open("initialMarking");
      out_.text_element("text", std::to_string(p.initial));
      out_.close();
    }
    if (p.kind != PlaceKind::kPlain || !empty(p.origin)) {
      open_tool();
      if (p.kind != PlaceKind::kPlain) out_.text_element("kind", kind_name(p.kind));
      if (!empty(p.origin)) origin(p.origin);
      out_.close();
    }
    out_.close();
  }

  void transition(const Transition& t) {
    out_.open("transition");
    out_.attribute("id", t.id);
    name(t.name);
    if (!empty(t.origin) || t.starts_robot.has_value() || t.starts_primitive != -1) {
      open_tool();
      if (!empty(t.origin)) origin(t.origin);
      if (t.starts_robot.has_value() || t.starts_primitive != -1) {
        out_.open("starts");
        if (t.starts_robot.has_value()) out_.attribute("robot", *t.starts_robot);
        if (t.starts_primitive != -1) out_.attribute("primitive", t.starts_primitive);
        out_.close();
      }
      out_.close();
    }
    out_.close();
  }

  void arc(const std::string& source, const std::string& target, Tokens weight) {
    out_.open("arc");
    out_.attribute("id", fresh(fmt::format("a{}", arc_count_++)));
    out_.attribute("source", source);
    out_.attribute("target", target);
    if (weight != 1) {
      out_.open("inscription");
      out_.text_element("text", std::to_string(weight));
      out_.close();
    }
    out_.close();
  }

  const Net& net_;
  xml::Writer out_;
  std::set<std::string> used_;
  std::size_t arc_count_ = 0;
};

std::string os_error(int err) {
  return std::strerror(err);
}

}  // namespace

PnmlDocument parse_pnml_document(std::string_view xml, const std::string& file, const PnmlReadOptions& options) {
  return Reader(file).read(xml, options);
}

Net parse_pnml(std::string_view xml, const std::string& file, const PnmlReadOptions& options) {
  return parse_pnml_document(xml, file, options).net;
}

PnmlDocument read_pnml_document(const std::filesystem::path& path, const PnmlReadOptions& options) {
  const std::string file = path.string();
  std::string text;
  try {
    text = read_file(path);
  } catch (const InputError& e) {
    throw InputError({file, 0, 0}, fmt::format("cannot read: {}", e.problem()));
  }
  return parse_pnml_document(text, file, options);
}

Net read_pnml(const std::filesystem::path& path, const PnmlReadOptions& options) {
  return read_pnml_document(path, options).net;
}

std::string to_pnml(const Net& net) {
  return Writer(net).write();
}

void write_pnml(const Net& net, const std::filesystem::path& path) {
  const std::string text = to_pnml(net);
  const std::string file = path.string();
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  // mkstemp in the target directory, so that the final rename stays within one file system and is atomic.
  std::string tmpl = (dir / ("." + path.filename().string() + ".XXXXXX")).string();
  const int fd = ::mkstemp(tmpl.data());
  if (fd < 0)
    throw InputError({file, 0, 0},
                     fmt::format("cannot create a temporary file in {}: {}", dir.string(), os_error(errno)));
  const auto give_up = [&](const char* step) {
    const int err = errno;
    ::close(fd);
    ::unlink(tmpl.c_str());
    throw InputError({file, 0, 0}, fmt::format("cannot write ({}): {}", step, os_error(err)));
  };
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      give_up("write");
    }
    done += static_cast<std::size_t>(n);
  }
  // mkstemp creates 0600; a PNML file is an ordinary document. Keep an existing file's mode.
  struct stat st {};
  const mode_t mode = ::stat(file.c_str(), &st) == 0 ? (st.st_mode & 07777) : 0644;
  if (::fchmod(fd, mode) != 0) give_up("chmod");
  if (::fsync(fd) != 0) give_up("fsync");
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmpl.c_str());
    throw InputError({file, 0, 0}, fmt::format("cannot write (close): {}", os_error(err)));
  }
  if (::rename(tmpl.c_str(), file.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmpl.c_str());
    throw InputError({file, 0, 0}, fmt::format("cannot write (rename): {}", os_error(err)));
  }
}

}  // namespace cellwright::petri
