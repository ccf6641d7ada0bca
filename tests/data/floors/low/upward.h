// A fixture of tests/floors.cmake (Floors.AnUpwardIncludeFailsNamingFileAndLine): the
// lower floor includes the upper one, which the check must refuse by file and line.
#pragma once
#include "high/top.h"
