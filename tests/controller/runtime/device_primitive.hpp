// A device primitive as task control sends it (compiled.hpp): the device tests' input.
#pragma once

#include <string>

#include "cellwright/task/compiled.hpp"

namespace cellwright::testing {

inline task::Primitive device_primitive(const std::string& device, task::DeviceOp op) {
  task::Primitive p;
  p.kind = task::PrimitiveKind::kDevice;
  p.device = device;
  p.op = op;
  return p;
}

}  // namespace cellwright::testing
