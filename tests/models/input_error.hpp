// Test helper: the InputError a piece of code throws, so that a test can check its position and words.
#pragma once

#include <gtest/gtest.h>

#include "cellwright/common/error.hpp"

namespace cellwright::models {

// Runs f, expects an InputError, returns it (a test failure, and an empty error, if f throws none).
template <typename F>
InputError input_error(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no InputError thrown";
  return InputError({}, "none");
}

}  // namespace cellwright::models
