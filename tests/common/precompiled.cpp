// The donor of the test programs' precompiled header (tests/CMakeLists.txt
// skintune_test_pch): built with their flags, it runs no test.
#include "tests/common/precompiled.h"
