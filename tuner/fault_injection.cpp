// skintune: the injected faults and the executor that makes them happen
// (tuner/fault_injection.h).
#include "tuner/fault_injection.h"

#include <algorithm>
#include <cstdlib>
#include <iterator>
#include <memory>
#include <utility>
#include <vector>

#include "generator/languages.h"
#include "base/error.h"

namespace skintune::internal {

namespace {

// "compile, wrong, hang, crash or lost"
std::string FaultKindList() {
  return OneOf(kInjectedFaultKinds, [](const char* kind) { return std::string(kind); });
}

}  // namespace

InjectedFault InjectedFaultFromEnvironment() {
  const char* env = std::getenv("SKINTUNE_INJECT_FAULT");
  if (!env || !*env) return {};
  const std::string text = env;
  const std::size_t at = text.rfind('=');
  const std::string why = "SKINTUNE_INJECT_FAULT='" + text + "': ";
  if (at == std::string::npos || at == 0) throw Error(why + "expected <variant key>=<kind>, the kind " + FaultKindList());
  InjectedFault fault;
  fault.kind = text.substr(at + 1);
  if (std::find(std::begin(kInjectedFaultKinds), std::end(kInjectedFaultKinds), fault.kind) == std::end(kInjectedFaultKinds))
    throw Error(why + "unknown fault '" + fault.kind + "' (" + FaultKindList() + ")");
  // The canonical key, so that the tokens may be given in any order.
  fault.variant_key = ParseVariantKey(text.substr(0, at)).Key();
  return fault;
}

namespace tuner_internal {

namespace {

// Replaces the one occurrence of `marker` (the last one) in the kernel text
// with `replacement`; throws when the template has none.
void EditAt(KernelSource& source, const std::string& marker, const std::string& before, const std::string& after,
            const std::string& kind) {
  const std::size_t at = source.text.rfind(marker);
  if (at == std::string::npos)
    throw Error("injected fault '" + kind + "': the " + Name(source.lang) + " kernel has no '" + marker +
                "' any more (update InjectFault in tuner/fault_injection.cpp)");
  const std::size_t line_start = source.text.rfind('\n', at) + 1;  // npos + 1 = 0
  std::size_t line_end = source.text.find('\n', at);
  if (line_end == std::string::npos) line_end = source.text.size();
  source.text.insert(line_end, after);
  source.text.insert(line_start, before);
}

// The injected hang: a loop no compiler can bound, with a side effect in
// every iteration. It spins while the first word of the first input is not
// 0xffffffff, which no input word ever is (a NaN position, joint 65535 in
// every slot...) and which the host never writes; the compiler cannot know
// that word. OpenCL and CUDA read it volatile and store to a volatile counter
// each iteration (C and C++ may assume that a loop without volatile access,
// atomics or I/O terminates).
//
// GLSL: Mesa's llvmpipe caps every shader invocation at 65535 loop
// iterations in all (gallivm's loop limiter, LP_MAX_TGSI_LOOP_ITERATIONS: a
// counter in the generated code), so no GLSL loop can spin forever there, and
// a spin on a volatile read alone finished in 0.6 s per run (5000 vertices)
// and passed as ok. Each iteration therefore makes 256 atomic adds to the
// input word after the one it tests, of 0, which the compiler cannot know:
// an atomic is never removed, and it makes the test be read again. Measured
// on 2 cores of llvmpipe: one atomic per iteration takes a run from 0.6 s to
// 2 s; 256 of them put a capped run at minutes (over 60 s measured), far
// beyond any variant time limit. Elsewhere the loop never ends.
std::string HangLoop(const KernelSource& source, const std::string& input) {
  const std::string mark = "  // skintune injected fault: hang\n";
  if (source.lang == Lang::kOpenCl) {
    return "    { volatile uint skintune_spins = 0u;\n"
           "      while (((volatile const __global uint*)" + input + ")[0] != 0xffffffffu) skintune_spins = skintune_spins + 1u; }" + mark;
  }
  if (source.lang == Lang::kCuda) {
    return "    { volatile unsigned int skintune_spins = 0u;\n"
           "      while (reinterpret_cast<const volatile unsigned int*>(" + input +
           ")[0] != 0xffffffffu) skintune_spins = skintune_spins + 1u; }" + mark;
  }
  std::string body;
  for (int i = 0; i < 256; ++i) body += "        atomicAdd(skintune_hang[1], skintune_zero);\n";
  return "    { const uint skintune_zero = skintune_hang[0] == 0xffffffffu ? 1u : 0u;\n"
         "      while (skintune_hang[0] != 0xffffffffu) {\n" + body + "      } }" + mark;
}

}  // namespace

void InjectFault(KernelSource& source, const Variant& variant, const std::string& kind) {
  if (source.lang == Lang::kCpu) {
    // The cpu kernel text is a parameter block (templates/skin.cpu): a line
    // that is not one fails its build; the wrong and hang faults are
    // parameters the cpu device honours (runtime/backends/cpu/cpu_runner.cpp).
    if (kind == "compile") {
      source.text += "\nskintune injected compile fault: this is not a parameter (\n";
    } else if (kind == "wrong" || kind == "hang") {
      source.text += std::string("#define ") + (kind == "wrong" ? "SKINTUNE_FAULT_WRONG" : "SKINTUNE_FAULT_HANG") +
                     " 1  // skintune injected fault: " + kind + "\n";
    } else {
      throw Error("injected fault: kind '" + kind + "' is not a kernel edit (compile, wrong or hang)");
    }
    source.source_hash = SourceHash(source.text);
    return;
  }
  const bool glsl = IsGlslText(source.lang);
  const std::string input = variant.layout == Layout::kAos ? "records" : "positions";
  // Every template skins a vertex with one call that ends with where the
  // skinned position goes and what normals and tangents are made from, in the
  // kernel's loop over its vertices (v in scope), after the shared helpers:
  // the last such line is in the kernel body or the function it calls per
  // vertex (skin.comp: skin_loaded in skin_and_store(); skin.vert: skin_vertex
  // in main(); OpenCL/CUDA: blend, then the blended matrix's rows).
  const std::string marker =
      glsl ? " skinned_position, skinned_normal, skinned_tangent);" : "&skinned_position, &a0, &a1, &a2);";
  if (kind == "compile") {
    source.text += "\nskintune injected compile fault: this is not a kernel language (\n";
  } else if (kind == "wrong") {
    const std::string one = glsl ? "1.0" : "1.0f";
    EditAt(source, marker, "", "\n    if (v == 0u) skinned_position.x += " + one + ";  // skintune injected fault: wrong",
           kind);
  } else if (kind == "hang") {
    const std::string loop = HangLoop(source, input);
    if (glsl) {
      // A writable view of binding 0 (the first input in every layout, at
      // least two words): its atomics add 0.
      const std::string block =
          "layout(std430, binding = 0) volatile buffer SkintuneHang { uint skintune_hang[]; };\n";
      // Declared before the function that skins (main(), or a helper of it).
      const std::size_t skins_at = source.text.rfind(marker);
      const std::size_t function_at =
          skins_at == std::string::npos ? std::string::npos : source.text.rfind("\nvoid ", skins_at);
      if (function_at == std::string::npos)
        throw Error("injected fault 'hang': the GLSL kernel skins in no function InjectFault finds (update InjectFault)");
      source.text.insert(function_at + 1, block);
    }
    EditAt(source, marker, loop, "", kind);
  } else {
    throw Error("injected fault: kind '" + kind + "' is not a kernel edit (compile, wrong or hang)");
  }
  source.source_hash = SourceHash(source.text);
}

namespace {

// An executor whose runs of one variant fail as the injected fault says;
// every other call goes to the executor it wraps.
class FaultyExecutor final : public Executor {
 public:
  FaultyExecutor(std::unique_ptr<Executor> inner, InjectedFault fault, std::string api)
      : inner_(std::move(inner)), fault_(std::move(fault)), api_(std::move(api)) {}

  Output Run(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::span<const std::uint8_t> palette,
             int instances) override {
    const std::vector<KernelSource> edited = Strike(mesh.variant, kernels);
    return inner_->Run(mesh, edited, palette, instances);
  }
  std::unique_ptr<Timed> Prepare(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                 std::span<const std::vector<std::uint8_t>> palettes, int instances) override {
    const std::vector<KernelSource> edited = Strike(mesh.variant, kernels);
    return inner_->Prepare(mesh, edited, palettes, instances);
  }
  Output RunAnimated(const PackedMesh& mesh, std::span<const KernelSource> kernels, std::span<const std::uint8_t> palette,
                     int instances, const AnimatedInputs& animated) override {
    const std::vector<KernelSource> edited = Strike(mesh.variant, kernels);
    return inner_->RunAnimated(mesh, edited, palette, instances, animated);
  }
  std::unique_ptr<Timed> PrepareAnimated(const PackedMesh& mesh, std::span<const KernelSource> kernels,
                                         std::span<const std::vector<std::uint8_t>> palettes, int instances,
                                         const AnimatedInputs& animated) override {
    const std::vector<KernelSource> edited = Strike(mesh.variant, kernels);
    return inner_->PrepareAnimated(mesh, edited, palettes, instances, animated);
  }
  std::unique_ptr<Timed> Copy(Lang lang, std::size_t bytes, int input_sets) override {
    ThrowWhenLost();
    return inner_->Copy(lang, bytes, input_sets);
  }
  std::string KernelClock() const override { return inner_->KernelClock(); }
  std::string ScheduleOf(const std::string& key) const override { return inner_->ScheduleOf(key); }
  std::string ContextChoice() const override { return inner_->ContextChoice(); }
  double LaunchStartMs() const override { return inner_->LaunchStartMs(); }
  std::size_t FlushReadBytes() const override { return inner_->FlushReadBytes(); }
  bool EvictsOwnBuffers() const override { return inner_->EvictsOwnBuffers(); }

 private:
  // The kernels a run of `variant` gets: the faulty variant's edited; at
  // the faulty variant "crash" ends the process and "lost" loses the device.
  std::vector<KernelSource> Strike(const Variant& variant, std::span<const KernelSource> kernels) {
    const bool faulty = variant.Key() == fault_.variant_key;
    if (faulty && fault_.kind == "crash") std::abort();  // the worker process must survive this
    if (faulty && fault_.kind == "lost") lost_ = true;
    ThrowWhenLost();
    std::vector<KernelSource> edited(kernels.begin(), kernels.end());
    if (faulty)
      for (KernelSource& k : edited) InjectFault(k, variant, fault_.kind);
    return edited;
  }
  // A runner's Error of stage "lost", as a driver's reset gives.
  void ThrowWhenLost() const {
    if (lost_) throw Error(api_ + " lost: the device was lost in this process (injected fault 'lost')");
  }

  std::unique_ptr<Executor> inner_;
  InjectedFault fault_;
  std::string api_;
  bool lost_ = false;
};

}  // namespace

ExecutorDecorator InjectingFault(InjectedFault fault) {
  return [fault](std::unique_ptr<Executor> inner, const DeviceIdentity& device) -> std::unique_ptr<Executor> {
    return std::make_unique<FaultyExecutor>(std::move(inner), fault, device.backend);
  };
}

ExecutorDecorator FaultsFromEnvironment() {
  InjectedFault fault = InjectedFaultFromEnvironment();
  if (fault.kind.empty()) return {};
  return InjectingFault(std::move(fault));
}

}  // namespace tuner_internal
}  // namespace skintune::internal
