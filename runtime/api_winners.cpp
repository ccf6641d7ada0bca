// The public winners database and lookup (skintune/skintune.h): WinnersDb,
// Selection::Find, and the names of backends, match levels and scene shapes.
#include <nlohmann/json.hpp>

#include "base/input_file.h"
#include "runtime/api_errors.h"
#include "runtime/backend_table.h"
#include "runtime/selection.h"
#include "runtime/winners_db.h"
#include "skintune/skintune.h"

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

// The backend table lists the APIs in Backend's order (runtime/backend_table.h).
const char* BackendName(Backend backend) {
  const auto index = static_cast<std::size_t>(backend);
  return index < Backends().size() ? Backends()[index].name : "unknown";
}

const char* MatchLevelName(MatchLevel level) {
  switch (level) {
    case MatchLevel::kExactDevice: return "exact-device";
    case MatchLevel::kSameDeviceName: return "same-device-name";
    case MatchLevel::kSameVendorType: return "same-vendor-type";
    case MatchLevel::kGenericDefault: return "generic-default";
    case MatchLevel::kForced: return "forced";
  }
  return "unknown";
}

// The public SceneShape is the database's SceneKind (runtime/winners_db.h), value for value.
static_assert(static_cast<int>(SceneShape::kSingle) == static_cast<int>(SceneKind::kSingle) &&
              static_cast<int>(SceneShape::kInstances) == static_cast<int>(SceneKind::kInstances) &&
              static_cast<int>(SceneShape::kBatch) == static_cast<int>(SceneKind::kBatch) && kSceneKinds.size() == 3,
              "SceneShape (skintune.h) and SceneKind (winners_db.h) must list the same shapes in the same order");

const char* SceneShapeName(SceneShape shape) { return SceneKindName(static_cast<SceneKind>(shape)); }

WinnersDb::WinnersDb() : impl_(std::make_unique<Impl>()) {}
WinnersDb::~WinnersDb() = default;
WinnersDb::WinnersDb(const WinnersDb& other)
    : impl_(other.impl_ ? std::make_unique<Impl>(*other.impl_) : nullptr) {}
WinnersDb& WinnersDb::operator=(const WinnersDb& other) {
  if (this != &other) impl_ = other.impl_ ? std::make_unique<Impl>(*other.impl_) : nullptr;
  return *this;
}
WinnersDb::WinnersDb(WinnersDb&&) noexcept = default;
WinnersDb& WinnersDb::operator=(WinnersDb&&) noexcept = default;

std::size_t WinnersDb::size() const { return impl_ ? impl_->entries.size() : 0; }

WinnersDb WinnersDb::Empty() { return WinnersDb(); }

Result<WinnersDb> WinnersDb::Parse(const std::string& json_text, const std::string& name_for_errors) {
  return GuardedResult<WinnersDb>(ErrorCode::kInvalidArgument, [&] {
    WinnersDb db;
    db.impl_->entries = WinnersDbFromJson(ParseJson(json_text, name_for_errors), name_for_errors);
    return db;
  });
}

Result<WinnersDb> WinnersDb::Load(const std::string& path) {
  std::string text;
  try {
    text = ReadInputFile(path, kJsonInput);  // a regular file, not too large: not a FIFO, /dev/zero or a folder
  } catch (const Error& e) {
    return Status(ErrorCode::kIoError, std::string("winners database ") + e.what());
  }
  return Parse(text, path);
}

Result<Selection> Selection::Find(const WinnersDb& db, const DeviceInfo& device, int influences,
                                  std::size_t vertex_count, double max_error, SceneShape shape) {
  return GuardedResult<Selection>(ErrorCode::kInvalidArgument, [&] {
    if (!db.impl_) FailWith(ErrorCode::kInvalidState, "Selection::Find: the WinnersDb was used after move");
    if (influences < 1 || influences > 8)
      FailWith(ErrorCode::kInvalidArgument,
               "Selection::Find: influences " + std::to_string(influences) + " outside 1..8");
    if (const std::string bad = BadMaxError(max_error); !bad.empty())
      FailWith(ErrorCode::kInvalidArgument, "Selection::Find: max_error " + bad);
    SelectionRequest request;
    request.max_error = max_error;
    request.device = device;
    request.langs = LanguagesOf(device.backend);
    request.influences = influences;
    request.vertex_count = vertex_count;
    request.shape = static_cast<SceneKind>(shape);
    request.instances = 0;  // Find is not told K or the mesh count: the shape's entries rank by size alone
    request.meshes = 0;
    return Select(db.impl_->entries, request).selection;
  });
}

}  // namespace skintune
