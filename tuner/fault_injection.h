// skintune (internal to tuner/): breaking a variant on purpose, for the
// tuner's failure tests. A decorator around a device's executor
// (tuner/executor.h): the measurement itself has no idea that a fault exists.
//
// The hook outside the tests: when $SKINTUNE_INJECT_FAULT is
// "<variant key>=<kind>", the tune worker measures through the decorator
// (FaultsFromEnvironment), so that a whole `skintune tune` meets the fault:
//   compile  the variant's kernel fails to compile;
//   wrong    its kernel writes wrong results (one vertex off);
//   hang     its kernel loops forever;
//   crash    the (worker) process aborts when the variant runs;
//   lost     the device is lost in this process, as when a driver resets a GL
//            context: this run and every later one in the same process fail
//            with "<API> lost: ..." (DeviceLostIn), and so do copies.
#pragma once

#include <string>

#include "generator/emit.h"
#include "generator/variant.h"
#include "tuner/executor.h"

namespace skintune::internal {

inline constexpr const char* kInjectedFaultKinds[] = {"compile", "wrong", "hang", "crash", "lost"};
struct InjectedFault {
  std::string variant_key;  // canonical (Variant::Key)
  std::string kind;         // one of kInjectedFaultKinds, or empty
};
// $SKINTUNE_INJECT_FAULT, its key made canonical (the tokens may come in any
// order); no fault when unset or empty. Throws Error naming the variable for
// a value without '=', an unknown kind or a malformed key.
InjectedFault InjectedFaultFromEnvironment();

namespace tuner_internal {

// Edits an emitted kernel so that it fails as `kind` says ("compile": a
// syntax error; "wrong": vertex 0 of each launch gets x + 1; "hang": a loop
// on a volatile read of the first input that never ends), and updates its
// hash. Throws Error for another kind, or when the template no longer has
// the line the edit hooks on.
void InjectFault(KernelSource& source, const Variant& variant, const std::string& kind);

// The decorator that makes `fault` happen on whatever device it wraps
// (the kinds above); every other variant runs as it would without it.
ExecutorDecorator InjectingFault(InjectedFault fault);
// InjectingFault(InjectedFaultFromEnvironment()), or no decorator (an empty
// function) when $SKINTUNE_INJECT_FAULT is unset. Throws as
// InjectedFaultFromEnvironment does.
ExecutorDecorator FaultsFromEnvironment();

}  // namespace tuner_internal
}  // namespace skintune::internal
