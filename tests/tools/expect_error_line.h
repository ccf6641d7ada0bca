// The one-line error every command gives for bad input (docs/INPUTS.md).
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "tests/tools/run_command.h"

namespace skintune::internal::testing {

// One line on stderr starting with "skintune: error: " + `start`, exit
// `exit_code` (2: a setting that cannot work), and no internal error.
inline void ExpectOneErrorLine(const CommandResult& r, const std::string& start, int exit_code = 1) {
  EXPECT_EQ(r.exit_code, exit_code) << r.err;
  EXPECT_EQ(CountLines(r.err), 1) << r.err;
  EXPECT_EQ(r.err.rfind("skintune: error: " + start, 0), 0u) << r.err;
  EXPECT_EQ(r.err.find("internal error"), std::string::npos) << r.err;
}

}  // namespace skintune::internal::testing
