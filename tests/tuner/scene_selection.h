// The runtime's Selection::Find for the tuner's tests, in a translation unit
// of its own: the public header's Backend enum and the tuner's Backend class
// cannot meet in one.
#pragma once

#include <cstddef>
#include <string>

#include "runtime/device_identity.h"

namespace skintune::internal {

// The variant key Selection::Find picks from the database `db_json` for
// `device`, B 4, a scene of shape `shape` ("single", "instances", "batch")
// and `vertices` in all, at any error budget; "error: ..." when it fails,
// "level <name>: ..." when the entry is not this device's own.
std::string SelectedVariant(const std::string& db_json, const DeviceIdentity& device, const std::string& shape,
                            std::size_t vertices);

}  // namespace skintune::internal
