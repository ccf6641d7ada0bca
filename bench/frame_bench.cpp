// The frame, not the kernel: what a program pays per frame to skin
// a crowd through the public API (skintune/skintune.h), on one device:
//
//   one-mesh/skin-only            one mesh of K x N vertices, Skin only
//   one-mesh/set-skin-finish      SetPalette + Skin + Finish every frame
//   instanced/skin-only           K instances of N vertices in one launch, Skin only
//   instanced/set-skin-pipelined  SetPalette (K palettes) + Skin, no Finish between frames
//   instanced/set-skin-finish     SetPalette + Skin + Finish every frame
//   instanced/skin-finish         Skin + Finish every frame, no SetPalette: the
//                                 waited-for frame's floor without a palette
//   instanced/set-only            SetPalette (K palettes) alone: the uploads' own cost
//   skinners/skin-only            K Skinners of N vertices, K launches per frame
//   read-back                     ReadPositions of the one mesh's K x N float3 positions
//   animated/skin-only            the crowd animated on the device (Skinner::CreateAnimated):
//                                 Skin only, the states unchanged, so the palette kernel does
//                                 not run again (the skin kernel's own frame, on the same Skinner)
//   animated/set-skin-pipelined   SetAnimation (16 bytes an instance) + Skin, no Finish between
//   animated/set-skin-finish      SetAnimation + Skin + Finish every frame
//   animated/advance-skin-pipelined  AdvanceAnimation (the clocks move on the device,
//                                 nothing uploaded) + Skin, no Finish between
//   animated/advance-skin-finish  AdvanceAnimation + Skin + Finish every frame
//
// The animated rows play the instance model's own clip (the synthetic
// 25k-b4's 77-joint rig, or --animation-model's glTF, whose own mesh is then
// the instance), every instance at its own time; --blend makes every
// instance (--blend-every N: every N-th) a blend of two clips (weight 0.5);
// --bake-rate R bakes the clips, --bake-local and --bake-hybrid say as what
// (SkinnerOptions::bake_space), --fuse-palette makes the palettes from those
// records in the skin launch (SkinnerOptions::fuse_palette). The summary compares
// them with the instanced rows, whose palettes the host uploads.
//
// K = 64 and N = 25k-b4 (77 joints) by default: a crowd of 64 characters. Each
// benchmark iteration runs --frames frames (default 50) and ends with Finish,
// so the device time is in it; the reported time is per frame (manual time:
// the iteration's wall time / frames), with counters vertices/s, frames/s
// and, for the frame loops, of_skin_only: their throughput over the
// Skin-only loop of the same shape (1 = the palette costs nothing).
// read-back reports bytes/s. The one-mesh and instanced Skin-only rows and the
// pipelined loop also report the host's time inside Skin (and SetPalette) per frame; set-only
// also reports the palettes' bytes/s (host packing and the copy, which a
// pipelined frame can hide behind the kernel only where it is the shorter).
// --benchmark_min_time counts that per-frame time, so each repetition runs
// --frames times longer on the wall clock: 0.02 is ~1 s a row at 14 us frames
// (0.1 took ~70 s for three rows of three repetitions on the H200 machine).
// A summary on stderr gives pipelined /
// skin-only and finish-per-frame minus skin-only, from the medians of the
// repetitions (--benchmark_repetitions) with benchmarks interleaved
// (--benchmark_enable_random_interleaving) where the machine is noisy.
//
//   skintune_bench_frame [--device PATTERN] [--variant KEY] [--db FILE]
//                        [--instances K] [--scale S] [--frames F] [--poses P] [--submit-thread]
//                        [--palette-buffers N] [--palette-threads T]
//                        [google benchmark flags]
//
// --palette-buffers N gives every Skinner a ring of N palette buffers
// (SkinnerOptions::palette_buffers, default 3); --palette-threads T lets at
// most T threads pack its palettes (SkinnerOptions::palette_threads, default
// 0: skintune's choice).
// --submit-thread opens the device with DeviceOptions::submit_thread (the
// driver calls of SetPalette's upload and of Skin on a thread of its own).
//
// --scale multiplies N (0.01: 250-vertex instances), for a quick run on a
// CPU device; --device picks the device as Device::Open does (default
// OpenBest); --variant forces one variant for every Skinner (else --db's
// winner, else the built-in default).
#include <benchmark/benchmark.h>

#include <CLI/CLI.hpp>
#include <skintune/skintune.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace {

using namespace skintune;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string device, variant, db;
  int instances = 64;
  double scale = 1.0;
  int frames = 50;
  // Frames rotate through this many precomputed poses. 2 (the default): the
  // palettes SetPalette reads are in the core's cache, as an animation
  // system's output is right after it wrote them (64 x 77 matrices: 315 KB a
  // pose); 8 poses (2.5 MB) are read from the last-level cache instead.
  int poses = 2;
  bool submit_thread = false;
  int palette_buffers = kDefaultPaletteBuffers;
  int palette_threads = 0;
  std::string animation_model;  // a glTF for the animated rows (default: the instance mesh's synthetic rig)
  bool blend = false;
  int blend_every = 1;  // with blend: every N-th instance cross-fades (--blend-every)
  double bake_rate = 0.0;  // SkinnerOptions::bake_rate of the animated rows (0: sampled clips)
  bool bake_local = false;  // SkinnerOptions::bake_space kLocal
  bool bake_hybrid = false;  // SkinnerOptions::bake_space kHybrid
  bool fuse_palette = false;  // SkinnerOptions::fuse_palette
};
Options options;


[[noreturn]] void Die(const std::string& message) {
  std::fprintf(stderr, "skintune_bench_frame: %s\n", message.c_str());
  std::exit(1);
}

template <typename T>
T Must(Result<T> result, const std::string& what) {
  if (!result) Die(what + ": " + result.status().message());
  return std::move(*result);
}

void Must(const Status& status, const std::string& what) {
  if (!status) Die(what + ": " + status.message());
}

// The device and database, opened once, and each shape's meshes, Skinners and
// palettes, made on first use: a run filtered to some rows builds only what
// they need (the one mesh of K x N vertices and the K Skinners take most of a
// whole run's start-up).
struct Scene {
  Device device;
  WinnersDb db;
  std::size_t k = 0, n = 0;

  // K instances of N vertices in one Skinner, and per pose the K palettes
  // (instance k at its own phase).
  struct Crowd {
    Model instance;
    Skinner skinner;
    std::vector<std::vector<float>> palettes;
  };
  // The crowd animated on the device, and per pose the K instances' states.
  struct Animated {
    Model model;
    Skinner skinner;
    std::vector<std::vector<AnimationState>> states;
  };
  // One mesh of K x N vertices, and per pose its palette.
  struct OneMesh {
    Model whole;
    Skinner skinner;
    std::vector<std::vector<float>> palettes;
  };

  Scene() {
    k = static_cast<std::size_t>(options.instances);
    n = static_cast<std::size_t>(std::max(1.0, std::round(25000 * options.scale)));
    DeviceOptions device_options;
    device_options.submit_thread = options.submit_thread;
    device = Must(options.device.empty() ? Device::OpenBest(device_options)
                                         : Device::Open(options.device, nullptr, device_options),
                  "device");
    db = options.db.empty() ? WinnersDb::Empty() : Must(WinnersDb::Load(options.db), options.db);
    std::fprintf(stderr, "device: %s (%s)%s\n", device.info().name.c_str(), BackendName(device.info().backend),
                 device.info().submit_thread ? ", submit thread" : "");
  }

  // Each is made, given its first palette and run once (programs built,
  // buffers touched) on first use.
  Crowd& crowd() {
    if (crowd_) return *crowd_;
    auto c = std::make_unique<Crowd>();
    c->instance = Must(Model::Synthetic(std::to_string(n) + "-b4"), "instance mesh");
    SkinnerOptions crowd_options;
    crowd_options.variant = options.variant;
    crowd_options.instances = options.instances;
    crowd_options.palette_buffers = options.palette_buffers;
    crowd_options.palette_threads = options.palette_threads;
    c->skinner = Must(Skinner::Create(device, db, c->instance.mesh(), crowd_options), "instanced Skinner");
    const double duration = std::max(c->instance.animation_duration(0), 1e-3);
    std::vector<float> palette;
    for (int f = 0; f < options.poses; ++f) {
      std::vector<float>& frame = c->palettes.emplace_back();
      for (std::size_t i = 0; i < k; ++i) {
        Must(c->instance.Palette(0, std::fmod((double(i) / double(k) + f / 30.0) * duration, duration), &palette), "palette");
        frame.insert(frame.end(), palette.begin(), palette.end());
      }
    }
    FirstFrame(c->skinner, c->palettes[0]);
    std::fprintf(stderr, "instanced: %zu x %zu vertices, %s\n", k, n, c->skinner.selection().variant.c_str());
    crowd_ = std::move(c);
    return *crowd_;
  }
  Animated& animated() {
    if (animated_) return *animated_;
    auto a = std::make_unique<Animated>();
    a->model = options.animation_model.empty() ? Must(Model::Synthetic(std::to_string(n) + "-b4"), "instance mesh")
                                               : Must(Model::Load(options.animation_model), options.animation_model);
    if (a->model.animation_count() == 0) Die(a->model.source() + " has no animation to play");
    SkinnerOptions animated_options;
    animated_options.variant = options.variant;
    animated_options.instances = options.instances;
    animated_options.palette_buffers = options.palette_buffers;
    animated_options.bake_rate = options.bake_rate;
    if (options.bake_local) animated_options.bake_space = BakeSpace::kLocal;
    if (options.bake_hybrid) animated_options.bake_space = BakeSpace::kHybrid;
    animated_options.fuse_palette = options.fuse_palette;
    a->skinner = Must(Skinner::CreateAnimated(device, db, a->model, animated_options), "animated Skinner");
    const int clips = a->model.animation_count();
    for (int f = 0; f < options.poses; ++f) {
      std::vector<AnimationState>& frame = a->states.emplace_back(k);
      for (std::size_t i = 0; i < k; ++i) {
        const int clip = static_cast<int>(i) % clips;
        const double start = a->model.animation_start(clip), duration = std::max(a->model.animation_duration(clip), 1e-3);
        const double u = std::fmod(double(i) / double(k) + f / 30.0, 1.0);
        frame[i] = {clip, static_cast<float>(start + u * duration)};
        if (options.blend && i % static_cast<std::size_t>(options.blend_every) == 0) {
          frame[i].animation2 = (clip + 1) % clips;
          frame[i].time2 = static_cast<float>(a->model.animation_start(frame[i].animation2) +
                                              std::fmod(u + 0.5, 1.0) * a->model.animation_duration(frame[i].animation2));
          frame[i].weight = 0.5f;
        }
      }
    }
    Must(a->skinner.SetAnimation(a->states[0].data(), a->states[0].size()), "SetAnimation");
    Must(a->skinner.Skin(), "Skin");
    Must(a->skinner.Finish(), "Finish");
    double worst = 0.0;
    for (const BakedClip& clip : a->skinner.baked_clips()) worst = std::max(worst, clip.max_error);
    std::fprintf(stderr, "animated: %zu x %zu vertices, %d joints, %s%s; clips %s, %zu bytes on the device", k,
                 a->model.vertex_count(), a->model.joint_count(), a->skinner.selection().variant.c_str(),
                 !options.blend ? "" : options.blend_every == 1 ? ", two-clip blends" : ", two-clip blends in part",
                 options.bake_rate > 0.0 ? (std::string(options.bake_hybrid  ? "baked as hybrid records"
                                                       : options.bake_local ? "baked in local space"
                                                                            : "baked") +
                                            (options.fuse_palette ? ", made in the skin launch" : ""))
                                               .c_str()
                                         : "sampled",
                 a->skinner.animation_bytes());
    if (options.bake_rate > 0.0)
      std::fprintf(stderr, " (%g frames a second, largest error %.3g of the extent)", options.bake_rate, worst);
    std::fprintf(stderr, "\n");
    animated_ = std::move(a);
    return *animated_;
  }
  OneMesh& one_mesh() {
    if (one_mesh_) return *one_mesh_;
    auto o = std::make_unique<OneMesh>();
    o->whole = Must(Model::Synthetic(std::to_string(k * n) + "-b4"), "one mesh");
    SkinnerOptions one;
    one.variant = options.variant;
    one.palette_buffers = options.palette_buffers;
    one.palette_threads = options.palette_threads;
    o->skinner = Must(Skinner::Create(device, db, o->whole.mesh(), one), "one-mesh Skinner");
    std::vector<float> palette;
    for (int f = 0; f < options.poses; ++f) {
      Must(o->whole.Palette(0, f / 30.0, &palette), "palette");
      o->palettes.push_back(palette);
    }
    FirstFrame(o->skinner, o->palettes[0]);
    std::fprintf(stderr, "one mesh: %zu vertices, %s\n", k * n, o->skinner.selection().variant.c_str());
    one_mesh_ = std::move(o);
    return *one_mesh_;
  }
  // K Skinners of the crowd's mesh, each with instance 0's palette.
  std::vector<Skinner>& skinners() {
    if (!skinners_.empty()) return skinners_;
    Crowd& c = crowd();
    SkinnerOptions one;
    one.variant = options.variant;
    one.palette_buffers = options.palette_buffers;
    one.palette_threads = options.palette_threads;
    const std::vector<float> palette(c.palettes[0].begin(), c.palettes[0].begin() + c.palettes[0].size() / k);
    for (std::size_t i = 0; i < k; ++i) {
      skinners_.push_back(Must(Skinner::Create(device, db, c.instance.mesh(), one), "Skinner"));
      FirstFrame(skinners_.back(), palette);
    }
    return skinners_;
  }

 private:
  static void FirstFrame(Skinner& skinner, const std::vector<float>& palette) {
    Must(skinner.SetPalette(palette.data(), palette.size()), "SetPalette");
    Must(skinner.Skin(), "Skin");
    Must(skinner.Finish(), "Finish");
  }
  std::unique_ptr<Crowd> crowd_;
  std::unique_ptr<Animated> animated_;
  std::unique_ptr<OneMesh> one_mesh_;
  std::vector<Skinner> skinners_;
};

Scene& TheScene() {
  static Scene scene;
  return scene;
}

// Each benchmark's per-frame times, for the ratios: their medians. Google
// Benchmark also calls a benchmark with fewer iterations while it sizes the
// run (the palette ring still filling); only the runs of the most iterations
// (one per repetition) count.
struct PerFrame {
  long long iterations = 0;
  std::vector<double> us;
};
std::map<std::string, PerFrame> per_frame_us;

void Record(const std::string& name, long long iterations, double us) {
  PerFrame& p = per_frame_us[name];
  if (iterations > p.iterations) p = {iterations, {}};
  if (iterations == p.iterations) p.us.push_back(us);
}

double Median(const std::string& name) {
  std::vector<double> v = per_frame_us.at(name).us;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// Runs `frame(f)` --frames times then `finish`, per iteration; the time per frame is the iteration's.
template <typename Frame>
void Frames(benchmark::State& state, const std::string& name, Skinner& finish, Frame&& frame,
            const char* skin_only = nullptr) {
  Scene& scene = TheScene();
  int f = 0;
  double total_s = 0.0;
  for (auto _ : state) {
    const auto start = Clock::now();
    for (int i = 0; i < options.frames; ++i) frame(f++ % options.poses);
    Must(finish.Finish(), "Finish");
    const double s = std::chrono::duration<double>(Clock::now() - start).count();
    state.SetIterationTime(s / options.frames);
    total_s += s;
  }
  const double us = total_s / double(state.iterations() * options.frames) * 1e6;
  Record(name, static_cast<long long>(state.iterations()), us);
  state.counters["vertices/s"] = benchmark::Counter(double(scene.k * scene.n) / (us * 1e-6));
  state.counters["frames/s"] = benchmark::Counter(1e6 / us);
  if (skin_only && per_frame_us.count(skin_only)) state.counters["of_skin_only"] = Median(skin_only) / us;
}

// A counter of host time per frame, us: `seconds` over `frames` calls.
benchmark::Counter UsPerFrame(double seconds, std::size_t frames) {
  return benchmark::Counter(seconds / double(std::max<std::size_t>(frames, 1)) * 1e6);
}

// A Skin-only row, with the host's time inside Skin per frame (counter
// skin_us): where it is near the frame, the host's issue bounds the frame.
void SkinOnly(benchmark::State& state, const std::string& name, Skinner& skinner) {
  double skin_s = 0.0;
  std::size_t frames = 0;
  Frames(state, name, skinner, [&](int) {
    const auto start = Clock::now();
    Must(skinner.Skin(), "Skin");
    skin_s += std::chrono::duration<double>(Clock::now() - start).count();
    ++frames;
  });
  state.counters["skin_us"] = UsPerFrame(skin_s, frames);
}

void OneMeshSkinOnly(benchmark::State& state) { SkinOnly(state, "one-mesh/skin-only", TheScene().one_mesh().skinner); }

void OneMeshSetSkinFinish(benchmark::State& state) {
  Scene::OneMesh& o = TheScene().one_mesh();
  Frames(
      state, "one-mesh/set-skin-finish", o.skinner,
      [&](int f) {
        Must(o.skinner.SetPalette(o.palettes[f].data(), o.palettes[f].size()), "SetPalette");
        Must(o.skinner.Skin(), "Skin");
        Must(o.skinner.Finish(), "Finish");
      },
      "one-mesh/skin-only");
}

void InstancedSkinOnly(benchmark::State& state) { SkinOnly(state, "instanced/skin-only", TheScene().crowd().skinner); }

// Also the host's time inside each call (counters set_palette_us and
// skin_us, per frame): what the program's thread pays, apart from waiting.
void InstancedPipelined(benchmark::State& state) {
  Scene::Crowd& c = TheScene().crowd();
  double set_s = 0.0, skin_s = 0.0;
  std::size_t frames = 0;
  Frames(
      state, "instanced/set-skin-pipelined", c.skinner,
      [&](int f) {
        const auto start = Clock::now();
        Must(c.skinner.SetPalette(c.palettes[f].data(), c.palettes[f].size()), "SetPalette");
        const auto set = Clock::now();
        Must(c.skinner.Skin(), "Skin");
        set_s += std::chrono::duration<double>(set - start).count();
        skin_s += std::chrono::duration<double>(Clock::now() - set).count();
        ++frames;
      },
      "instanced/skin-only");
  state.counters["set_palette_us"] = UsPerFrame(set_s, frames);
  state.counters["skin_us"] = UsPerFrame(skin_s, frames);
}

void InstancedSetSkinFinish(benchmark::State& state) {
  Scene::Crowd& c = TheScene().crowd();
  Frames(
      state, "instanced/set-skin-finish", c.skinner,
      [&](int f) {
        Must(c.skinner.SetPalette(c.palettes[f].data(), c.palettes[f].size()), "SetPalette");
        Must(c.skinner.Skin(), "Skin");
        Must(c.skinner.Finish(), "Finish");
      },
      "instanced/skin-only");
}

// The waited-for frame without its palette: a launch and the wait for it.
// set-skin-finish minus this is what the palette adds to a waited-for frame.
void InstancedSkinFinish(benchmark::State& state) {
  Skinner& instanced = TheScene().crowd().skinner;
  Frames(
      state, "instanced/skin-finish", instanced,
      [&](int) {
        Must(instanced.Skin(), "Skin");
        Must(instanced.Finish(), "Finish");
      },
      "instanced/skin-only");
}

// No Skin: nothing reads the palettes, so SetPalette never waits on the
// ring, and the iteration's Finish waits for the last upload.
void InstancedSetOnly(benchmark::State& state) {
  Scene::Crowd& c = TheScene().crowd();
  double set_s = 0.0;
  std::size_t frames = 0;
  Frames(state, "instanced/set-only", c.skinner, [&](int f) {
    const auto start = Clock::now();
    Must(c.skinner.SetPalette(c.palettes[f].data(), c.palettes[f].size()), "SetPalette");
    set_s += std::chrono::duration<double>(Clock::now() - start).count();
    ++frames;
  });
  state.counters["set_palette_us"] = UsPerFrame(set_s, frames);
  // The bytes uploaded: 48 per matrix for mat3x4 blending (three rows), else 64.
  const bool rows3 = c.skinner.selection().variant.find(".mat3x4.") != std::string::npos;
  const double bytes = double(c.palettes[0].size() / 16) * (rows3 ? 48.0 : 64.0);
  state.counters["palette_bytes/s"] = benchmark::Counter(bytes / (per_frame_us["instanced/set-only"].us.back() * 1e-6));
}

void AnimatedSkinOnly(benchmark::State& state) {
  Skinner& animated = TheScene().animated().skinner;
  Frames(state, "animated/skin-only", animated, [&](int) { Must(animated.Skin(), "Skin"); }, "instanced/skin-only");
}

void AnimatedPipelined(benchmark::State& state) {
  Scene::Animated& a = TheScene().animated();
  double set_s = 0.0, skin_s = 0.0;
  std::size_t frames = 0;
  Frames(
      state, "animated/set-skin-pipelined", a.skinner,
      [&](int f) {
        const auto start = Clock::now();
        Must(a.skinner.SetAnimation(a.states[f].data(), a.states[f].size()), "SetAnimation");
        const auto set = Clock::now();
        Must(a.skinner.Skin(), "Skin");
        set_s += std::chrono::duration<double>(set - start).count();
        skin_s += std::chrono::duration<double>(Clock::now() - set).count();
        ++frames;
      },
      "instanced/skin-only");
  state.counters["set_animation_us"] = UsPerFrame(set_s, frames);
  state.counters["skin_us"] = UsPerFrame(skin_s, frames);
}

void AnimatedSetSkinFinish(benchmark::State& state) {
  Scene::Animated& a = TheScene().animated();
  Frames(
      state, "animated/set-skin-finish", a.skinner,
      [&](int f) {
        Must(a.skinner.SetAnimation(a.states[f].data(), a.states[f].size()), "SetAnimation");
        Must(a.skinner.Skin(), "Skin");
        Must(a.skinner.Finish(), "Finish");
      },
      "instanced/skin-only");
}

// A frame's delta: a 60 Hz step (the clocks loop on the device).
constexpr float kFrameSeconds = 1.0f / 60.0f;

void AnimatedAdvancePipelined(benchmark::State& state) {
  Scene::Animated& a = TheScene().animated();
  Frames(
      state, "animated/advance-skin-pipelined", a.skinner,
      [&](int) {
        Must(a.skinner.AdvanceAnimation(kFrameSeconds), "AdvanceAnimation");
        Must(a.skinner.Skin(), "Skin");
      },
      "instanced/skin-only");
}

void AnimatedAdvanceSkinFinish(benchmark::State& state) {
  Scene::Animated& a = TheScene().animated();
  Frames(
      state, "animated/advance-skin-finish", a.skinner,
      [&](int) {
        Must(a.skinner.AdvanceAnimation(kFrameSeconds), "AdvanceAnimation");
        Must(a.skinner.Skin(), "Skin");
        Must(a.skinner.Finish(), "Finish");
      },
      "instanced/skin-only");
}

void SkinnersSkinOnly(benchmark::State& state) {
  std::vector<Skinner>& skinners = TheScene().skinners();
  // The Skinners share the Device's queue: finishing the last waits for all of them.
  Frames(state, "skinners/skin-only", skinners.back(), [&](int) {
    for (Skinner& skinner : skinners) Must(skinner.Skin(), "Skin");
  }, "instanced/skin-only");
}

void ReadBack(benchmark::State& state) {
  Scene& s = TheScene();
  Skinner& one_mesh = s.one_mesh().skinner;
  std::vector<float> positions(s.k * s.n * 3);
  Must(one_mesh.Finish(), "Finish");
  for (auto _ : state) {
    const auto start = Clock::now();
    Must(one_mesh.ReadPositions(positions.data(), positions.size()), "ReadPositions");
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - start).count());
  }
  state.counters["bytes/s"] = benchmark::Counter(double(positions.size() * sizeof(float)),
                                                 benchmark::Counter::kIsIterationInvariantRate, benchmark::Counter::kIs1000);
}

void RegisterAll() {
  const struct {
    const char* name;
    void (*run)(benchmark::State&);
  } kBenchmarks[] = {{"frame/one-mesh/skin-only", OneMeshSkinOnly},
                     {"frame/one-mesh/set-skin-finish", OneMeshSetSkinFinish},
                     {"frame/instanced/skin-only", InstancedSkinOnly},
                     {"frame/instanced/set-skin-pipelined", InstancedPipelined},
                     {"frame/instanced/set-skin-finish", InstancedSetSkinFinish},
                     {"frame/instanced/skin-finish", InstancedSkinFinish},
                     {"frame/instanced/set-only", InstancedSetOnly},
                     {"frame/skinners/skin-only", SkinnersSkinOnly},
                     {"frame/read-back", ReadBack},
                     {"frame/animated/skin-only", AnimatedSkinOnly},
                     {"frame/animated/set-skin-pipelined", AnimatedPipelined},
                     {"frame/animated/set-skin-finish", AnimatedSetSkinFinish},
                     {"frame/animated/advance-skin-pipelined", AnimatedAdvancePipelined},
                     {"frame/animated/advance-skin-finish", AnimatedAdvanceSkinFinish}};
  for (const auto& b : kBenchmarks)
    benchmark::RegisterBenchmark(b.name, b.run)->UseManualTime()->Unit(benchmark::kMicrosecond);
}

// This harness's options (CLI11); whatever it does not know is left in argv
// for Google Benchmark, which rejects what it does not know either.
void ParseOptions(int& argc, char** argv) {
  CLI::App app{"skintune_bench_frame: frames of SetPalette, Skin and Finish through the public API"};
  app.allow_extras();
  app.add_option("--device", options.device, "device pattern (Device::Open)");
  app.add_option("--variant", options.variant, "force a variant key");
  app.add_option("--db", options.db, "winners database file");
  app.add_option("--instances", options.instances, "instances in the crowd")->check(CLI::Range(1, 1 << 20));
  app.add_option("--scale", options.scale, "vertex-count scale of the meshes")->check(CLI::Range(1e-6, 1e6));
  app.add_option("--frames", options.frames, "frames per case")->check(CLI::Range(1, 1 << 24));
  app.add_option("--poses", options.poses, "precomputed poses the frames rotate through")->check(CLI::Range(2, 1 << 16));
  app.add_flag("--submit-thread", options.submit_thread, "DeviceOptions::submit_thread");
  app.add_option("--palette-buffers", options.palette_buffers, "SkinnerOptions::palette_buffers");
  app.add_option("--palette-threads", options.palette_threads, "SkinnerOptions::palette_threads");
  app.add_option("--animation-model", options.animation_model, "a glTF whose mesh and clips the animated rows play");
  app.add_flag("--blend", options.blend, "animated rows: every instance a blend of two clips (weight 0.5)");
  app.add_option("--blend-every", options.blend_every,
                 "with --blend: only every N-th instance cross-fades (3: as the tuner's -animblend scenes)")
      ->check(CLI::Range(1, 1 << 16))
      ->needs("--blend");
  app.add_option("--bake-rate", options.bake_rate,
                 "animated rows: the clips baked at this many frames a second (SkinnerOptions::bake_rate)")
      ->check(CLI::Range(0.0, kMaxBakeRate));
  app.add_flag("--bake-local", options.bake_local,
               "animated rows: bake each node's local transform (SkinnerOptions::bake_space kLocal; with --bake-rate)");
  app.add_flag("--bake-hybrid", options.bake_hybrid,
               "animated rows: bake both records (SkinnerOptions::bake_space kHybrid; with --bake-rate)")
      ->excludes("--bake-local");
  app.add_flag("--fuse-palette", options.fuse_palette,
               "animated rows: the palettes made from the baked records in the skin launch, no palette kernel "
               "(SkinnerOptions::fuse_palette; with --bake-rate)");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    std::exit(app.exit(e));
  }
  // The extras, in order, after the program's name (their strings outlive argv's use).
  static std::vector<std::string> rest;
  rest = app.remaining();
  argc = 1;
  for (std::string& r : rest) argv[argc++] = r.data();
}

void Summary() {
  const auto ratio = [](const char* a, const char* b) {
    if (!per_frame_us.count(a) || !per_frame_us.count(b)) return;
    std::fprintf(stderr, "%s / %s throughput: %.3f\n", a, b, Median(b) / Median(a));
  };
  const auto minus = [](const char* a, const char* b) {
    if (!per_frame_us.count(a) || !per_frame_us.count(b)) return;
    std::fprintf(stderr, "%s - %s: %.1f us per frame\n", a, b, Median(a) - Median(b));
  };
  ratio("instanced/set-skin-pipelined", "instanced/skin-only");
  minus("instanced/set-skin-finish", "instanced/skin-only");
  minus("instanced/skin-finish", "instanced/skin-only");
  minus("instanced/set-skin-finish", "instanced/skin-finish");
  minus("one-mesh/set-skin-finish", "one-mesh/skin-only");
  ratio("skinners/skin-only", "instanced/skin-only");
  // Animation on the device against the frames with no palette work at all.
  ratio("animated/set-skin-pipelined", "instanced/skin-only");
  minus("animated/set-skin-finish", "instanced/skin-finish");
  ratio("animated/advance-skin-pipelined", "instanced/skin-only");
  minus("animated/advance-skin-finish", "instanced/skin-finish");
  minus("animated/skin-only", "instanced/skin-only");
}

}  // namespace

int main(int argc, char** argv) {
  ParseOptions(argc, argv);
  RegisterAll();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  std::cout.flush();  // the report first, then the summary (stderr)
  Summary();
  benchmark::Shutdown();
  return 0;
}
