// skintune (internal): which variant runs on a device: the winners database's
// fallback chain (Selection::Find, Skinner::Create) and the built-in default.
//
// The chain, first level with a usable entry wins:
//   1. exact device: the entry's device id is the device's (backend, platform,
//      name and driver version);
//   2. same device name: same backend and device name, another driver (or
//      platform);
//   3. same vendor and type: same backend, vendor and device type (entries of
//      1.0.0 databases, which do not name vendor and type, never match here);
//   4. the built-in default (GenericDefault), correct on every device.
// An entry is usable when its language is one of the device's, its
// influences B hold the mesh's (B >= the largest per-vertex count), it is
// within the error budget (EntryWithinBudget: f32, a format exact for the
// caller's weights, or a recorded quantisation error <= max_error), the
// caller's check accepts it (Skinner::Create: the constraints on the real
// device and mesh), and its scene
// shape is the request's or single (a single-mesh entry is the fallback for
// every shape, at the scene's total vertex count). Among the usable entries
// of a level: the request's shape first, then the smallest B, then the
// nearest measured vertex count (nearest as a factor: 25k is as near 50k as
// 100k is), then within the shape the nearest instance or mesh count, then
// for a mesh with morph targets the nearest target count (the larger vertex
// count on a tie), then the newest `created` (the newest driver tuned), then
// the smallest median time (which chooses between glsl-compute and
// glsl-vertex on a GL device). The entry's variant is taken with its
// `normals` set to what the caller needs.
// The reason names the entries skipped for the budget or the check that
// could have served instead: those of an earlier level, and those of the
// chosen one's level that rank no worse than it (another B, vertex count or
// shape ranks worse and never applies); one over the budget says by how much
// raising it (max_error_name) admits it.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "generator/constraints.h"
#include "generator/variant.h"
#include "runtime/winners_db.h"
#include "skintune/skintune.h"

namespace skintune::internal {

struct SelectionRequest {
  DeviceInfo device;
  std::vector<Lang> langs;       // the device's languages, preferred first
  int influences = 1;            // the largest per-vertex count the variant must hold
  std::size_t vertex_count = 0;  // the scene's total: K x the mesh's for instances, the meshes' sum for a batch
  // The scene's shape: entries of that shape first, then single-mesh ones.
  SceneKind shape = SceneKind::kSingle;
  int instances = 1;             // K (an instances scene), the nearest first among the shape's entries; 0: unknown
  int meshes = 1;                // a batch's mesh count, likewise
  Normals normals = Normals::kNone;  // what the variant must skin beside positions
  // Dual-quaternion skinning (blend dq) or linear (matrix, point): entries of
  // the other kind never serve, as they compute something else.
  bool dual_quaternions = false;
  // The mesh has morph targets: only morph variants serve it (and only it),
  // the entries of the nearest target count first.
  bool morph = false;
  int morph_targets = 0;
  // The format of the skinned normals (with normals): entries tuned in it
  // first; another entry serves with its variant's format changed.
  NormalFormat normal_format = NormalFormat::kF32;
  // The Skinner makes its palettes on the device (Skinner::CreateAnimated):
  // entries tuned on animated scenes (animation sampled or baked) serve it
  // first, then the others (the skin kernel is the same); only it takes them,
  // as their times hold the palette kernel.
  bool animated = false;
  // An animated Skinner's crowd cross-fades clips (SkinnerOptions::cross_fades):
  // entries of crowds that did (did not) first. With `tuned_form` (the
  // palette kernel's form is the entry's: kBakeRateTuned), an entry of a crowd
  // that did not cross-fade never serves one that does where its form bakes
  // palette records: its recorded error holds no blend's, which palette
  // records mix in the model's space (docs/ANIMATION.md "Baked clips").
  bool cross_fades = false;
  bool tuned_form = false;
  double max_error = kDefaultBudget;     // the error budget, relative to the bounding-box diagonal
  std::string max_error_name = "max_error";  // how the caller names it in reasons ("SkinnerOptions::max_error")
  std::vector<WeightFormat> exact_formats;  // formats that hold the caller's weights exactly (HoldsWeightsExactly)
  DeviceLimits limits;           // sizes the built-in default's work-group
  // Why `variant` cannot run here, or "" when it can; unset: every variant can.
  std::function<std::string(const Variant&)> check;
};

struct Chosen {
  Selection selection;
  Variant variant;
};

// Throws ApiError(kUnavailable) only when not even the built-in default of
// any of the device's languages passes the check.
Chosen Select(const std::vector<WinnersEntry>& entries, const SelectionRequest& request);

// The built-in default of `lang`: padded (mesh order kept), soa, float4, i32
// indices (any joint count), f32 weights (no quantisation), mat4 palette (any
// matrix, affine or not), global palette storage (no size limit), matrix
// blend, one vertex per item, work-group 64 (32 on a device whose limit is
// below 64; wg0 for glsl-vertex). Every constraint of generator/constraints.h
// holds for it on every device except the vertex shader's storage blocks.
// `dual_quaternions`: its twin with the dualquat palette and blend dq.
Variant GenericDefault(Lang lang, int influences, Normals normals, const DeviceLimits& limits, bool morph = false,
                       bool dual_quaternions = false);

// A backend's languages, preferred first (its entry in runtime/backend_table.h).
std::vector<Lang> LanguagesOf(Backend backend);

}  // namespace skintune::internal

namespace skintune {

struct WinnersDb::Impl {
  std::vector<internal::WinnersEntry> entries;
};

}  // namespace skintune
