// A fixture of tests/floors.cmake: the upper floor includes the lower one, as it may.
#pragma once
#include "low/upward.h"
