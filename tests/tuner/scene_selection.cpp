#include "tests/tuner/scene_selection.h"

#include "runtime/backend_table.h"
#include "runtime/winners_db.h"
#include "skintune/skintune.h"

namespace skintune::internal {

std::string SelectedVariant(const std::string& db_json, const DeviceIdentity& identity, const std::string& shape,
                            std::size_t vertices) {
  const Result<WinnersDb> db = WinnersDb::Parse(db_json, "db.json");
  if (!db.ok()) return "error: " + db.status().message();
  DeviceInfo device;
  device.backend = static_cast<Backend>(FindBackend(identity.backend) - Backends().data());
  device.id = identity.Id();
  device.platform = identity.platform;
  device.vendor = identity.vendor;
  device.name = identity.name;
  device.driver_version = identity.driver_version;
  device.type = identity.type;
  const Result<Selection> s = Selection::Find(*db, device, 4, vertices, 1.0,
                                              static_cast<SceneShape>(SceneKindFromName(shape)));
  if (!s.ok()) return "error: " + s.status().message();
  if (s->level != MatchLevel::kExactDevice) return std::string("level ") + MatchLevelName(s->level) + ": " + s->reason;
  return s->variant;
}

}  // namespace skintune::internal
