// The checks every palette kernel passes (the CPU's, OpenCL's, GL's, CUDA's),
// written once: each API's test calls them with its way of running the kernel,
// `run(packed, instances)` giving the palette rows as RunPaletteKernel writes
// them. `api` names the runner in the printed ratios and failures.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cpu_kernels/palette_kernel.h"
#include "generator/clip_packer.h"
#include "generator/palette_kernel.h"
#include "tests/common/test_asset.h"
#include "tests/generator/deep_rig.h"
#include "tests/generator/palette_gold.h"

namespace skintune::internal::testing {

// What a test uploads for the palette kernel's buffer argument `name`
// (generator/palette_kernel.h): the packed buffer of that name, and the
// instances for both `instances` and `states` (a fresh frame takes them);
// empty for the palette it writes.
inline std::span<const std::uint8_t> PaletteInputBytes(const PackedAnimation& packed,
                                                       const std::vector<AnimInstance>& instances,
                                                       const std::string& name) {
  if (name == kAnimInputs[5] || name == kAnimStates) return BufferBytes(instances);
  if (name == kAnimOutput) return {};
  const std::span<const std::uint8_t> bytes = AnimationBufferBytes(packed.View(), name);
  if (bytes.empty() && name != kAnimInputs[2] && name != kAnimInputs[3])  // a model without keys has none
    throw std::runtime_error("the palette kernel takes an argument '" + name + "' the tests do not know");
  return bytes;
}

using RunPalettes = std::function<std::vector<float>(const PackedAnimation&, const std::vector<AnimInstance>&)>;

// A test's kernel object (its Run(packed, instances)) as a RunPalettes.
template <typename Kernel>
RunPalettes On(Kernel* kernel) {
  return [kernel](const PackedAnimation& packed, const std::vector<AnimInstance>& instances) {
    return kernel->Run(packed, instances);
  };
}

// Every clip of the shared models alone, at every kind of time (TimesOf).
inline void ExpectEveryClipOfTheGltfModelsMatchesTheGold(const RunPalettes& run, const std::string& api) {
  for (const char* model : {"CesiumMan.gltf", "Fox.gltf", "RiggedSimple.gltf"}) {
    const SkinnedAsset& asset = TestAsset(model);
    const PackedAnimation packed = PackAnimation(asset);
    const std::vector<AnimInstance> instances = EveryClipAlone(asset, packed);
    ExpectWithinBound(std::string(model) + " " + api, Compare(asset, packed, instances, run(packed, instances)));
  }
}

// The deep synthetic rig (DeepRig): every interpolation, chains 64 deep;
// and the same rig with every child before its parent (ReversedDeepRig).
inline void ExpectTheDeepRigMatchesTheGold(const RunPalettes& run, const std::string& api) {
  for (const SkinnedAsset* rig : {&DeepRig(), &ReversedDeepRig()}) {
    const PackedAnimation packed = PackAnimation(*rig);
    const std::vector<AnimInstance> instances = EveryClipAlone(*rig, packed);
    ExpectWithinBound(Name(*rig) + " " + api, Compare(*rig, packed, instances, run(packed, instances)));
  }
}

// Two clips blended in local space (Blends).
inline void ExpectBlendsMatchTheGold(const RunPalettes& run, const std::string& api) {
  for (const SkinnedAsset* asset : {&TestAsset("Fox.gltf"), &TestAsset("CesiumMan.gltf"), &DeepRig()}) {
    const PackedAnimation packed = PackAnimation(*asset);
    const std::vector<AnimInstance> instances = Blends(*asset, packed);
    ExpectWithinBound(Name(*asset) + " " + api + " blends", Compare(*asset, packed, instances, run(packed, instances)));
  }
}

// Baked clips (BakeAnimation at 30 frames a second, in every space): every
// clip alone at every kind of time, and two-clip blends, against the float64
// evaluation of the baked frames.
inline void ExpectBakedClipsMatchTheirFrames(const RunPalettes& run, const std::string& api) {
  for (const SkinnedAsset* asset :
       {&TestAsset("CesiumMan.gltf"), &TestAsset("Fox.gltf"), &TestAsset("RiggedSimple.gltf"), &DeepRig(),
        &ReversedDeepRig()}) {
    const PackedAnimation sampled = PackAnimation(*asset);
    const PackedAnimation baked = BakeAnimation(*asset, 30.0);
    const PackedAnimation local = BakeAnimation(*asset, 30.0, BakeSpace::kLocal);
    const PackedAnimation hybrid = BakeAnimation(*asset, 30.0, BakeSpace::kHybrid);
    std::vector<AnimInstance> instances = EveryClipAlone(*asset, sampled);
    const std::vector<AnimInstance> blends = Blends(*asset, sampled);
    instances.insert(instances.end(), blends.begin(), blends.end());
    ExpectWithinBound(Name(*asset) + " " + api + " baked", CompareBaked(baked, instances, run(baked, instances)));
    ExpectWithinBound(Name(*asset) + " " + api + " baked in local space",
                      CompareLocalBaked(*asset, local, instances, run(local, instances)));
    ExpectWithinBound(Name(*asset) + " " + api + " hybrid records",
                      CompareHybrid(*asset, hybrid, instances, run(hybrid, instances)));
  }
}

// A device kernel given a clip beyond the packed ones (first or second)
// writes NaN rows for that instance instead of reading beyond its buffers;
// the other instances are untouched.
inline void ExpectNanRowsForAClipOutOfRange(const RunPalettes& run, Animation form = Animation::kSampled) {
  const PackedAnimation packed = PackForm(TestAsset("Fox.gltf"), form);  // 3 clips
  const std::vector<AnimInstance> instances = {AnimInstance{1, kAnimRestPose, 0.5f, 0.0f, 0.0f},
                                               AnimInstance{3, kAnimRestPose, 0.5f, 0.0f, 0.0f},
                                               AnimInstance{0, 7, 0.5f, 0.5f, 0.5f}};
  const std::vector<float> rows = run(packed, instances);
  const std::size_t per_instance = packed.joints.size() * 12;
  for (std::size_t i = 0; i < instances.size(); ++i) {
    const auto first = rows.begin() + static_cast<std::ptrdiff_t>(i * per_instance);
    const auto nans =
        std::count_if(first, first + static_cast<std::ptrdiff_t>(per_instance), [](float v) { return std::isnan(v); });
    EXPECT_EQ(static_cast<std::size_t>(nans), i == 0 ? 0 : per_instance) << "instance " << i;
  }
}

}  // namespace skintune::internal::testing
