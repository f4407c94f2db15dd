// The JSON schemas of the Foxglove messages (https://github.com/foxglove/foxglove-sdk, the npm package
// @foxglove/schemas) that a channel of the live view's server may carry (live_server.hpp, "Foxglove"): its
// "advertise" message names the schema and gives its text. Read from the package at build time
// (serve/page/bundle.cmake), at the version serve/page/package-lock.json pins; nothing is written by hand.
//
// Threads: any (constant data).
#pragma once

#include <string_view>

namespace cellwright::serve {

// The JSON schema (jsonschema encoding) of the Foxglove message `name`, e.g. "foxglove.SceneUpdate"; empty for a
// name this build does not carry (serve/page/bundle.cmake lists them).
std::string_view foxglove_schema(std::string_view name);

}  // namespace cellwright::serve
