// skintune (internal): a kernel's error against the UNQUANTISED source mesh
// and the error budget, as the tuner measures them (tuner/measurement.h) and
// the winners database records them (runtime/winners_db.h): one struct, one
// JSON form, one budget rule (docs/TUNING.md "Precision").
#pragma once

#include <string>

#include <nlohmann/json_fwd.hpp>

namespace skintune::internal {

// The default error budget, relative to the bounding-box diagonal: the public
// header's kDefaultMaxError (skintune/skintune.h includes nothing of the tree,
// so it states the number itself; source_error.cpp asserts the two agree).
// It admits unorm16 and rejects unorm8 for float weights.
inline constexpr double kDefaultBudget = 1e-4;

// A verified kernel's output against the float64 gold computed on the
// unquantised source mesh (the weights as the dataset has them), and what the
// variant's weight quantisation alone costs. Distances are Euclidean, per
// vertex, the largest over the mesh; "rel" ones are divided by the diagonal of
// the source mesh's rest-pose bounding box.
struct SourceError {
  bool known = false;           // false: not measured (a record older than the measurement, a failure)
  double diagonal = 0.0;        // the bounding-box diagonal of the rest positions, mesh units
  double position_abs = 0.0;    // kernel positions vs the source gold, mesh units
  double position_rel = 0.0;    // position_abs / diagonal
  double normal_abs = 0.0;      // kernel normals vs the source gold's (unit vectors); 0 without normals
  // The gold of the variant's quantised weights vs the source gold, / diagonal:
  // the cost of the weight format on this mesh, without the kernel's float32
  // rounding. Exactly 0 when the format holds the source weights exactly (f32;
  // glTF unorm8 WEIGHTS in unorm8). The budget is compared with this.
  double quantisation_rel = 0.0;
};

// What the kernel's own float32 arithmetic may add to the weights'
// quantisation error, relative to the diagonal: 50x the most a verified
// kernel added on the H100 and PoCL (1.8e-7, docs/TUNING.md "Precision").
inline constexpr double kKernelRoundingAllowance = 1e-5;

// Whether the kernel's whole error against the source (position_rel) is at
// most what its weights cost (quantisation_rel) and its float32 rounding
// (kKernelRoundingAllowance): a kernel that verified under a loose
// tolerance, or a record that claims so, but is further off, is never within
// any budget, whatever its weight format. True when the error is not known.
constexpr bool KernelAddsOnlyRounding(const SourceError& e) {
  return !e.known || e.position_rel <= e.quantisation_rel + kKernelRoundingAllowance;
}

// Whether `e` fits a budget of `max_error`: known, its quantisation error at
// most max_error, and the kernel adding only its rounding to it
// (KernelAddsOnlyRounding). The budget is on the quantisation, so that it is
// the same on every device and 0 means "exact formats only".
constexpr bool WithinBudget(const SourceError& e, double max_error) {
  return e.known && e.quantisation_rel <= max_error && KernelAddsOnlyRounding(e);
}

// "" when `max_error` is a budget (finite and >= 0), else why not, for
// messages that name the flag or field: "is -1: must be a finite number >= 0 ...".
std::string BadMaxError(double max_error);

// {"diagonal", "position_abs", "position_rel", "normal_abs", "quantisation_rel"}
// (non-finite numbers as "inf" / "nan" strings); null when not known.
nlohmann::json SourceErrorJson(const SourceError& e);
// Reads that object (every field required); throws Error("'<field>' ...").
SourceError SourceErrorFromJson(const nlohmann::json& j);
// The first field that is not finite and >= 0, as NotFiniteNonNegative says
// it, or a position_rel that is not position_abs / diagonal; "" when possible.
std::string ImpossibleSourceError(const SourceError& e);

}  // namespace skintune::internal
