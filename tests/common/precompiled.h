// The header every test program's sources include first, precompiled once
// (tests/CMakeLists.txt skintune_test_pch): what most of them include and
// what takes a compiler longest to parse. Third-party and standard headers
// only, so that a change to skintune's own headers does not rebuild it.
#pragma once

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>
