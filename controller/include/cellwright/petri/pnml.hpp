// PNML (ISO/IEC 15909-2) import and export of place/transition nets, the interchange format of TINA, LoLA, PIPE,
// ePNK and the Model Checking Contest.
//
// Export writes a standard P/T net (`.../grammar/ptnet`) that those tools read: one page, places with name and
// initial marking (omitted when 0), transitions with name, arcs with inscription (omitted when 1). Everything the P/T
// grammar has no room for (PlaceKind, Origin, Transition::starts_robot/starts_primitive, regions, robots, final
// places) goes into <toolspecific tool="cellwright" version="1"> elements, which other tools ignore; so
// to_pnml -> parse_pnml gives back an equal Net (same ids, order, names, markings, arcs and Cellwright data).
// One exception: leading and trailing white space of names is not significant in PNML files and is dropped on import.
//
// Import reads P/T nets written by other tools:
//  - with or without the PNML namespace (and with a namespace prefix such as <pnml:net>);
//  - nodes on nested pages, which are flattened in document order (depth first), and nodes directly under <net>
//    (older PIPE files);
//  - referencePlace / referenceTransition nodes, which stand for the node they refer to (chains are followed); arcs
//    may name them;
//  - names in <name><text> (or PIPE's <name><value>); a node without <name> is named by its id (an empty <name>
//    gives an empty name);
//  - markings and inscriptions in <text> with surrounding white space, or PIPE's <value>Default,N</value>;
//  - graphics, and toolspecific elements of other tools, which are ignored;
//  - parallel arcs between the same place and transition, whose weights add up (a multiset of arcs);
//  - a net without a type attribute, read as a P/T net. Accepted types: the ISO ptnet grammar (any version year),
//    PIPE's "P/T net", and the older PNML P/T types (.../pntd/ptNetb, .../pnmlcoremodel).
// A file may hold several <net> elements: by default the first one is read; PnmlReadOptions::net_id picks another,
// and PnmlDocument::net_ids lists them all so that a tool can say which one it took.
//
// Everything else is an InputError naming the file, the line (from the XML parser; columns are not known) and the
// problem: text that is not XML, no <pnml> root, no <net>, a net of another type (named), a node or arc without id,
// duplicate ids, arcs between two places or two transitions, arcs naming unknown nodes, references to unknown or
// wrong-kind nodes or in a cycle, markings or inscriptions that are not decimal integers, negative, larger than
// 4294967295 (the Tokens range: a hostile 10^30 is reported, never wrapped), zero arc weights, and constructs that
// would change the meaning of a P/T net if dropped (inhibitor/reset/test arcs, place capacities, coloured tokens),
// and malformed Cellwright toolspecific data.
//
// Thread safety: all functions are re-entrant; they share no state.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "cellwright/petri/net.hpp"

namespace cellwright::petri {

struct PnmlReadOptions {
  std::string net_id;  // the id of the <net> to read; empty reads the first net in the file
};

// A parsed file: the chosen net and the ids of every <net> in the file, in document order.
struct PnmlDocument {
  Net net;
  std::vector<std::string> net_ids;
};

// Parses PNML text. `file` names the source in error messages (it is not opened). Throws InputError as described
// above; std::bad_alloc only if memory runs out.
PnmlDocument parse_pnml_document(std::string_view xml, const std::string& file, const PnmlReadOptions& options = {});
Net parse_pnml(std::string_view xml, const std::string& file, const PnmlReadOptions& options = {});

// Reads and parses a PNML file. Throws InputError when the file cannot be read (naming the OS error) or is invalid.
PnmlDocument read_pnml_document(const std::filesystem::path& path, const PnmlReadOptions& options = {});
Net read_pnml(const std::filesystem::path& path, const PnmlReadOptions& options = {});

// The net as a PNML document (UTF-8, indented, with an XML declaration). Arc and page ids are generated ("a0",
// "a1", ..., "page0") and made distinct from the net's node ids.
std::string to_pnml(const Net& net);

// Writes to_pnml(net) to `path` atomically: the text goes to a temporary file in the same directory, which is then
// renamed over `path`, so a failure never leaves a half-written file. Throws InputError (naming the path and the OS
// error) when the file cannot be written; the temporary file is removed in that case.
void write_pnml(const Net& net, const std::filesystem::path& path);

}  // namespace cellwright::petri
