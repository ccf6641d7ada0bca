// The public Model (skintune/skintune.h): a glTF model or synthetic dataset
// with its skeleton and animations, over reference/ (import, palettes, gold).
#include <cmath>
#include <cstring>

#include <glm/gtc/type_ptr.hpp>

#include "model/asset.h"
#include "model/gltf_import.h"
#include "base/input_file.h"
#include "reference/skinning.h"
#include "model/synthetic.h"
#include "runtime/api_errors.h"
#include "runtime/model_access.h"
#include "skintune/skintune.h"

namespace skintune {

using namespace internal;  // the public calls are written over the library's internals

struct Model::Impl {
  SkinnedAsset asset;
  std::vector<std::string> warnings;
  int influences = 0;                 // largest non-zero count of any vertex
  std::vector<float> positions;       // 3 per vertex
  std::vector<float> normals;         // 3 per vertex, or empty
  std::vector<std::uint32_t> joints;  // asset.mesh.influences per vertex
  // The morph targets as MeshView reads them: target after target, 3 floats a vertex.
  std::vector<float> morph_positions, morph_normals, morph_tangents, morph_weights;

  explicit Impl(SkinnedAsset a, std::vector<std::string> w) : asset(std::move(a)), warnings(std::move(w)) {
    const SkinnedMesh& mesh = asset.mesh;
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) influences = std::max(influences, mesh.InfluencesOf(v));
    positions.reserve(mesh.vertex_count() * 3);
    for (const glm::vec3& p : mesh.positions) positions.insert(positions.end(), {p.x, p.y, p.z});
    for (const glm::vec3& n : mesh.normals) normals.insert(normals.end(), {n.x, n.y, n.z});
    joints.assign(mesh.joints.begin(), mesh.joints.end());
    const auto flatten = [](const std::vector<std::vector<glm::vec3>>& targets, std::vector<float>& out) {
      for (const std::vector<glm::vec3>& target : targets)
        for (const glm::vec3& d : target) out.insert(out.end(), {d.x, d.y, d.z});
    };
    flatten(mesh.morph.positions, morph_positions);
    flatten(mesh.morph.normals, morph_normals);
    flatten(mesh.morph.tangents, morph_tangents);
    for (const double weight : mesh.morph.weights) morph_weights.push_back(static_cast<float>(weight));
  }
  bool HasAnimation(int a) const { return a >= 0 && a < static_cast<int>(asset.animations.size()); }
};

}  // namespace skintune

namespace skintune::internal {

const SkinnedAsset* ModelAccess::Asset(const Model& model) { return model.impl_ ? &model.impl_->asset : nullptr; }

namespace {

Model::Impl& Checked(const std::unique_ptr<Model::Impl>& impl, const char* call) {
  if (!impl) FailWith(ErrorCode::kInvalidState, std::string("Model::") + call + ": the Model is empty (moved from)");
  return *impl;
}

std::vector<glm::mat4> Matrices(const float* matrices, std::size_t float_count, int joints, const char* call) {
  if (!matrices) FailWith(ErrorCode::kInvalidArgument, std::string(call) + ": matrices is null");
  if (float_count != static_cast<std::size_t>(joints) * 16)
    FailWith(ErrorCode::kInvalidArgument, std::string(call) + ": " + std::to_string(float_count) +
                                              " floats given, the palette has " + std::to_string(joints) +
                                              " joints x 16 = " + std::to_string(joints * 16));
  std::vector<glm::mat4> palette(static_cast<std::size_t>(joints));
  for (std::size_t j = 0; j < palette.size(); ++j) palette[j] = glm::make_mat4(matrices + 16 * j);
  CheckPaletteFinite(palette, call);
  return palette;
}

}  // namespace

}  // namespace skintune::internal

namespace skintune {

Result<Model> Model::Load(const std::string& path) {
  try {
    CheckInputFile(path, kGltfInput);  // a regular file (a FIFO would block the import), not too large
  } catch (const Error& e) {
    return Status(ErrorCode::kIoError, e.what());
  }
  return GuardedResult<Model>(ErrorCode::kInvalidArgument, [&] {
    GltfImportOptions options;
    options.tangents_when_present = true;
    GltfImportResult imported = ImportGltf(path, options);
    Model model;
    model.impl_ = std::make_unique<Impl>(std::move(imported.asset), std::move(imported.warnings));
    return model;
  });
}

Result<Model> Model::Synthetic(const std::string& key) {
  return GuardedResult<Model>(ErrorCode::kInvalidArgument, [&] {
    Model model;
    model.impl_ = std::make_unique<Impl>(GenerateDataset(ParseDatasetKey(key)), std::vector<std::string>{});
    return model;
  });
}

Model::Model() = default;
Model::~Model() = default;
Model::Model(const Model& other) : impl_(other.impl_ ? std::make_unique<Impl>(*other.impl_) : nullptr) {}
Model& Model::operator=(const Model& other) {
  if (this != &other) impl_ = other.impl_ ? std::make_unique<Impl>(*other.impl_) : nullptr;
  return *this;
}
Model::Model(Model&&) noexcept = default;
Model& Model::operator=(Model&&) noexcept = default;

const std::string& Model::source() const {
  static const std::string kNone;
  return impl_ ? impl_->asset.source : kNone;
}
std::size_t Model::vertex_count() const { return impl_ ? impl_->asset.mesh.vertex_count() : 0; }
int Model::influences() const { return impl_ ? impl_->influences : 0; }
int Model::joint_count() const { return impl_ ? impl_->asset.mesh.joint_count : 0; }
bool Model::has_normals() const { return impl_ && !impl_->normals.empty(); }
bool Model::has_tangents() const { return impl_ && impl_->asset.mesh.has_tangents(); }

MeshView Model::mesh() const {
  MeshView view;
  if (!impl_) return view;
  const SkinnedMesh& mesh = impl_->asset.mesh;
  view.vertex_count = mesh.vertex_count();
  view.influences = mesh.influences;
  view.joint_count = mesh.joint_count;
  view.positions = impl_->positions.data();
  view.normals = impl_->normals.empty() ? nullptr : impl_->normals.data();
  view.tangents = mesh.has_tangents() ? &mesh.tangents.front().x : nullptr;  // glm::vec4: 4 packed floats
  view.joints = impl_->joints.data();
  view.weights = mesh.weights.data();
  view.morph_target_count = static_cast<int>(mesh.morph.count());
  if (mesh.has_morph()) {
    view.morph_positions = impl_->morph_positions.data();
    view.morph_normals = impl_->morph_normals.empty() ? nullptr : impl_->morph_normals.data();
    view.morph_tangents = impl_->morph_tangents.empty() ? nullptr : impl_->morph_tangents.data();
    view.morph_weights = impl_->morph_weights.data();
  }
  return view;
}

int Model::morph_target_count() const { return impl_ ? static_cast<int>(impl_->asset.mesh.morph.count()) : 0; }

Status Model::MorphWeights(int animation, double t, std::vector<float>* weights) const {
  return Guarded(ErrorCode::kInvalidArgument, [&] {
    const Impl& im = Checked(impl_, "MorphWeights");
    if (!weights) FailWith(ErrorCode::kInvalidArgument, "Model::MorphWeights: weights is null");
    if (animation != -1 && !im.HasAnimation(animation))
      FailWith(ErrorCode::kInvalidArgument, "Model::MorphWeights: animation " + std::to_string(animation) +
                                                " outside -1.." + std::to_string(im.asset.animations.size() - 1));
    if (!std::isfinite(t)) FailWith(ErrorCode::kInvalidArgument, "Model::MorphWeights: t is not finite");
    weights->clear();
    for (const double w : im.asset.MorphWeightsAt(animation, t)) weights->push_back(static_cast<float>(w));
  });
}

const std::vector<std::string>& Model::warnings() const {
  static const std::vector<std::string> kNone;
  return impl_ ? impl_->warnings : kNone;
}

int Model::animation_count() const { return impl_ ? static_cast<int>(impl_->asset.animations.size()) : 0; }

Result<int> Model::FindAnimation(const std::string& name) const {
  return GuardedResult<int>(ErrorCode::kNotFound, [&] { return Checked(impl_, "FindAnimation").asset.FindAnimation(name); });
}

std::string Model::animation_name(int animation) const {
  return impl_ && impl_->HasAnimation(animation) ? impl_->asset.animations[animation].name : std::string();
}
double Model::animation_start(int animation) const {
  return impl_ && impl_->HasAnimation(animation) ? impl_->asset.animations[animation].start : 0.0;
}
double Model::animation_duration(int animation) const {
  return impl_ && impl_->HasAnimation(animation) ? impl_->asset.animations[animation].duration() : 0.0;
}

Status Model::Palette(int animation, double t, std::vector<float>* matrices) const {
  return Guarded(ErrorCode::kInvalidArgument, [&] {
    const Impl& im = Checked(impl_, "Palette");
    if (!matrices) FailWith(ErrorCode::kInvalidArgument, "Model::Palette: matrices is null");
    if (animation != -1 && !im.HasAnimation(animation))
      FailWith(ErrorCode::kInvalidArgument, "Model::Palette: animation " + std::to_string(animation) + " outside -1.." +
                                                std::to_string(animation_count() - 1) + " of " + im.asset.source);
    if (!std::isfinite(t)) FailWith(ErrorCode::kInvalidArgument, "Model::Palette: t is not finite");
    const std::vector<glm::mat4> palette = im.asset.PaletteAt(animation, t);
    matrices->resize(palette.size() * 16);
    std::memcpy(matrices->data(), palette.data(), matrices->size() * sizeof(float));
  });
}

Status Model::SkinReference(const float* matrices, std::size_t float_count, std::vector<float>* positions) const {
  return SkinReference(matrices, float_count, nullptr, 0, positions);
}

Status Model::SkinReference(const float* matrices, std::size_t float_count, const float* morph_weights,
                            std::size_t weight_count, std::vector<float>* positions) const {
  return Guarded(ErrorCode::kInvalidArgument, [&] {
    const Impl& im = Checked(impl_, "SkinReference");
    if (!positions) FailWith(ErrorCode::kInvalidArgument, "Model::SkinReference: positions is null");
    const std::vector<glm::mat4> palette =
        Matrices(matrices, float_count, im.asset.mesh.joint_count, "Model::SkinReference");
    SkinnedMesh weighted;
    if (morph_weights) {
      if (weight_count != im.asset.mesh.morph.count())
        FailWith(ErrorCode::kInvalidArgument, "Model::SkinReference: " + std::to_string(weight_count) +
                                                  " morph weights given, the model has " +
                                                  std::to_string(im.asset.mesh.morph.count()) + " morph targets");
      weighted = im.asset.mesh;
      weighted.morph.weights.assign(morph_weights, morph_weights + weight_count);
      for (std::size_t k = 0; k < weight_count; ++k)
        if (!std::isfinite(morph_weights[k]))
          FailWith(ErrorCode::kInvalidArgument, "Model::SkinReference: morph weight " + std::to_string(k) + " is not finite");
    }
    const GoldResult gold = SkinGold(morph_weights ? weighted : im.asset.mesh, palette);
    for (std::size_t v = 0; v < gold.positions.size(); ++v) {
      const glm::vec3 p(gold.positions[v]);
      if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)))
        FailWith(ErrorCode::kInvalidArgument, "Model::SkinReference: vertex " + std::to_string(v) +
                                                  " is not finite in float32: the palette times its rest position "
                                                  "overflows");
    }
    positions->resize(gold.positions.size() * 3);
    for (std::size_t v = 0; v < gold.positions.size(); ++v)
      for (int c = 0; c < 3; ++c) (*positions)[v * 3 + c] = static_cast<float>(gold.positions[v][c]);
  });
}

}  // namespace skintune
