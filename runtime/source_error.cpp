#include "runtime/source_error.h"

#include <cmath>
#include <limits>
#include <sstream>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "runtime/recorded_time.h"
#include "skintune/skintune.h"

namespace skintune::internal {

static_assert(kDefaultBudget == kDefaultMaxError, "the internal and the public default budget must agree");

namespace {

// The fields in JSON order, with their member.
struct FieldOf {
  const char* name;
  double SourceError::*member;
};
constexpr FieldOf kFields[] = {{"diagonal", &SourceError::diagonal},
                               {"position_abs", &SourceError::position_abs},
                               {"position_rel", &SourceError::position_rel},
                               {"normal_abs", &SourceError::normal_abs},
                               {"quantisation_rel", &SourceError::quantisation_rel}};

}  // namespace

std::string BadMaxError(double max_error) {
  if (std::isfinite(max_error) && max_error >= 0.0) return "";
  std::ostringstream text;
  text << "is " << max_error << ": must be a finite number >= 0 (an error relative to the bounding-box diagonal, e.g. "
       << kDefaultBudget << ")";
  return text.str();
}

nlohmann::json SourceErrorJson(const SourceError& e) {
  if (!e.known) return nullptr;
  nlohmann::json j = nlohmann::json::object();
  for (const FieldOf& f : kFields) {
    const double value = e.*f.member;
    if (std::isnan(value)) {
      j[f.name] = "nan";
    } else if (std::isinf(value)) {
      j[f.name] = value > 0 ? "inf" : "-inf";
    } else {
      j[f.name] = value;
    }
  }
  return j;
}

SourceError SourceErrorFromJson(const nlohmann::json& j) {
  if (!j.is_object()) throw Error("expected an object");
  SourceError e;
  e.known = true;
  for (const FieldOf& f : kFields) {
    if (!j.contains(f.name)) throw Error(std::string("missing '") + f.name + "'");
    const nlohmann::json& v = j[f.name];
    double value = 0.0;
    if (v.is_number()) {
      value = v.get<double>();
    } else if (v == "inf") {
      value = std::numeric_limits<double>::infinity();
    } else if (v == "-inf") {
      value = -std::numeric_limits<double>::infinity();
    } else if (v == "nan") {
      value = std::numeric_limits<double>::quiet_NaN();
    } else {
      throw Error(std::string("'") + f.name + "' must be a number");
    }
    e.*f.member = value;
  }
  return e;
}

std::string ImpossibleSourceError(const SourceError& e) {
  if (!e.known) return "";
  for (const FieldOf& f : kFields) {
    const std::string name = std::string("source_error.") + f.name;
    if (std::string problem = NotFiniteNonNegative(name.c_str(), e.*f.member); !problem.empty()) return problem;
  }
  // The writers divide (a diagonal of 0 makes any error 1); JSON keeps doubles exact.
  const double expected = e.diagonal > 0.0 ? e.position_abs / e.diagonal : (e.position_abs > 0.0 ? 1.0 : 0.0);
  if (!(std::fabs(e.position_rel - expected) <= 1e-9 * expected)) {
    std::ostringstream text;
    text.precision(17);
    text << "'source_error.position_rel' is " << e.position_rel << " but position_abs / diagonal is " << expected
         << ": they must agree";
    return text.str();
  }
  return "";
}

}  // namespace skintune::internal
