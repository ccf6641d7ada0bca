#include "runtime/backends/gl/gl_context.h"

#include <dlfcn.h>
#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <map>
#include <mutex>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/error.h"
#include "runtime/physical_device.h"

namespace skintune::internal {

namespace {

std::string Hex(unsigned value) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%04x", value);
  return text;
}

std::string EglErrorName(EGLint error) {
  switch (error) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    default: return "EGL error " + Hex(static_cast<unsigned>(error));
  }
}

std::string LastEglError() { return EglErrorName(eglGetError()); }

bool HasExtension(const char* list, const char* name) {
  if (!list) return false;
  std::istringstream in(list);
  std::string word;
  while (in >> word)
    if (word == name) return true;
  return false;
}

std::string GlString(GLenum name) {
  const auto* text = reinterpret_cast<const char*>(glGetString(name));
  return text ? text : "";
}

std::uint64_t GlInteger(GLenum name) {
  GLint64 value = 0;
  glGetInteger64v(name, &value);
  return value > 0 ? static_cast<std::uint64_t>(value) : 0;
}

std::uint64_t GlIndexedInteger(GLenum name, GLuint index) {
  GLint64 value = 0;
  glGetInteger64i_v(name, index, &value);
  return value > 0 ? static_cast<std::uint64_t>(value) : 0;
}

// libepoxy aborts the process when it cannot dlopen the EGL or GL library, so
// look for them first. Handles are kept open (epoxy opens the same files).
std::string MissingLibraries() {
  if (!dlopen("libEGL.so.1", RTLD_LAZY | RTLD_GLOBAL)) {
    const char* e = dlerror();
    return std::string("libEGL.so.1 cannot be loaded (") + (e ? e : "?") +
           "); install an EGL driver (Debian: libegl1 libegl-mesa0, or the GPU vendor's)";
  }
  if (!dlopen("libOpenGL.so.0", RTLD_LAZY | RTLD_GLOBAL) && !dlopen("libGL.so.1", RTLD_LAZY | RTLD_GLOBAL)) {
    return "neither libOpenGL.so.0 nor libGL.so.1 can be loaded; install libopengl0 or libgl1";
  }
  return "";
}

// Displays are process-wide: eglTerminate only when no live GlContext uses one.
std::mutex& DisplayMutex() {
  static std::mutex m;
  return m;
}
std::map<EGLDisplay, int>& DisplayUsers() {
  static std::map<EGLDisplay, int> users;
  return users;
}
void TerminateIfUnused(EGLDisplay display) {
  std::lock_guard<std::mutex> lock(DisplayMutex());
  if (DisplayUsers()[display] == 0) eglTerminate(display);
}

}  // namespace

struct GlContext::Impl {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  bool owned = true;  // false: AdoptCurrent
  std::string reason;
  GlContextInfo info;

  // Tries to make a GL 4.3+ core context on `display`; on failure leaves
  // nothing behind and returns why.
  std::string TryDisplay(EGLDisplay candidate, const std::string& platform, const std::string& device);
  void Query();
};

std::string GlContext::Impl::TryDisplay(EGLDisplay candidate, const std::string& platform,
                                        const std::string& device) {
  if (candidate == EGL_NO_DISPLAY) return "no display (" + LastEglError() + ")";
  EGLint egl_major = 0, egl_minor = 0;
  if (!eglInitialize(candidate, &egl_major, &egl_minor)) return "eglInitialize failed (" + LastEglError() + ")";
  auto fail = [&](const std::string& why) {
    TerminateIfUnused(candidate);
    return why;
  };
  const char* extensions = eglQueryString(candidate, EGL_EXTENSIONS);
  const bool egl15 = egl_major > 1 || (egl_major == 1 && egl_minor >= 5);
  if (!HasExtension(extensions, "EGL_KHR_surfaceless_context"))
    return fail("EGL " + std::to_string(egl_major) + "." + std::to_string(egl_minor) +
                " without EGL_KHR_surfaceless_context");
  if (!egl15 && !HasExtension(extensions, "EGL_KHR_create_context"))
    return fail("EGL " + std::to_string(egl_major) + "." + std::to_string(egl_minor) +
                " without EGL_KHR_create_context (needed to ask for a GL 4.3 core context)");
  if (!eglBindAPI(EGL_OPENGL_API)) return fail("eglBindAPI(EGL_OPENGL_API) failed (" + LastEglError() + ")");

  // A config only matters for surfaces; use none when the display allows it.
  std::vector<EGLConfig> configs;
  if (HasExtension(extensions, "EGL_KHR_no_config_context") || HasExtension(extensions, "EGL_MESA_configless_context")) {
    configs.push_back(EGL_NO_CONFIG_KHR);
  }
  for (const EGLint surface : {EGLint{EGL_PBUFFER_BIT}, EGLint{0}}) {
    const EGLint attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, surface, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint count = 0;
    if (eglChooseConfig(candidate, attributes, &config, 1, &count) && count > 0) configs.push_back(config);
  }
  if (configs.empty()) return fail("no EGL config renders with desktop OpenGL (EGL_OPENGL_BIT)");

  // First with reset notification (EGL 1.5, else EGL_EXT_create_context_robustness),
  // so that a context the driver resets says so (GlContextInfo::reset_notification);
  // then without, where the driver refuses it.
  const EGLint reset_strategy = egl15 ? EGL_CONTEXT_OPENGL_RESET_NOTIFICATION_STRATEGY
                                : HasExtension(extensions, "EGL_EXT_create_context_robustness")
                                    ? EGL_CONTEXT_OPENGL_RESET_NOTIFICATION_STRATEGY_EXT
                                    : EGL_NONE;
  const EGLint with_reset[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 3,
                               EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                               reset_strategy, EGL_LOSE_CONTEXT_ON_RESET, EGL_NONE};
  const EGLint plain[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 3,
                          EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  std::string errors;
  EGLContext created = EGL_NO_CONTEXT;
  bool reset_notification = false;
  for (const EGLint* context_attributes : {with_reset, plain}) {
    if (context_attributes == with_reset && reset_strategy == EGL_NONE) continue;
    for (EGLConfig config : configs) {
      created = eglCreateContext(candidate, config, EGL_NO_CONTEXT, context_attributes);
      if (created != EGL_NO_CONTEXT) break;
      errors += (errors.empty() ? "" : ", ") + LastEglError();
    }
    if (created != EGL_NO_CONTEXT) {
      reset_notification = context_attributes == with_reset;
      break;
    }
  }
  if (created == EGL_NO_CONTEXT)
    return fail("eglCreateContext(OpenGL 4.3 core) failed (" + errors + "): the driver offers no GL 4.3 core");
  if (!eglMakeCurrent(candidate, EGL_NO_SURFACE, EGL_NO_SURFACE, created)) {
    const std::string why = "eglMakeCurrent without a surface failed (" + LastEglError() + ")";
    eglDestroyContext(candidate, created);
    return fail(why);
  }
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (major < 4 || (major == 4 && minor < 3)) {
    const std::string why = "the context is GL " + std::to_string(major) + "." + std::to_string(minor) + " (" +
                            GlString(GL_VERSION) + ", " + GlString(GL_RENDERER) + "), 4.3 is needed";
    eglMakeCurrent(candidate, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(candidate, created);
    return fail(why);
  }
  {
    std::lock_guard<std::mutex> lock(DisplayMutex());
    ++DisplayUsers()[candidate];
  }
  display = candidate;
  context = created;
  info.reset_notification = reset_notification;
  info.egl_platform = platform;
  info.egl_device = device;
  const char* vendor = eglQueryString(candidate, EGL_VENDOR);
  info.egl_vendor = vendor ? vendor : "";
  info.egl_version = std::to_string(egl_major) + "." + std::to_string(egl_minor);
  info.major = major;
  info.minor = minor;
  return "";
}

void GlContext::Impl::Query() {
  info.vendor = GlString(GL_VENDOR);
  info.renderer = GlString(GL_RENDERER);
  info.version = GlString(GL_VERSION);
  info.glsl_version = GlString(GL_SHADING_LANGUAGE_VERSION);
  info.max_compute_work_group_invocations = GlInteger(GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS);
  info.max_compute_work_group_size_x = GlIndexedInteger(GL_MAX_COMPUTE_WORK_GROUP_SIZE, 0);
  info.max_compute_work_group_count_x = GlIndexedInteger(GL_MAX_COMPUTE_WORK_GROUP_COUNT, 0);
  info.max_compute_work_group_count_y = GlIndexedInteger(GL_MAX_COMPUTE_WORK_GROUP_COUNT, 1);
  info.max_compute_shared_memory_bytes = GlInteger(GL_MAX_COMPUTE_SHARED_MEMORY_SIZE);
  info.max_uniform_block_bytes = GlInteger(GL_MAX_UNIFORM_BLOCK_SIZE);
  info.max_texture_buffer_texels = GlInteger(GL_MAX_TEXTURE_BUFFER_SIZE);
  info.max_vertex_shader_storage_blocks = GlInteger(GL_MAX_VERTEX_SHADER_STORAGE_BLOCKS);
  info.max_compute_shader_storage_blocks = GlInteger(GL_MAX_COMPUTE_SHADER_STORAGE_BLOCKS);
  info.max_shader_storage_block_bytes = GlInteger(GL_MAX_SHADER_STORAGE_BLOCK_SIZE);
  info.max_transform_feedback_separate_attribs = GlInteger(GL_MAX_TRANSFORM_FEEDBACK_SEPARATE_ATTRIBS);
  // The chip, so the same GPU seen through other APIs is recognised (runtime/physical_device.h).
  if (epoxy_has_gl_extension("GL_EXT_memory_object") && GlInteger(GL_NUM_DEVICE_UUIDS_EXT) > 0) {
    GLubyte uuid[GL_UUID_SIZE_EXT] = {};
    glGetUnsignedBytei_vEXT(GL_DEVICE_UUID_EXT, 0, uuid);
    if (glGetError() == GL_NO_ERROR) info.device_uuid = UuidHex(uuid);
  }
  while (glGetError() != GL_NO_ERROR) {
  }
}

GlContext::GlContext(int device_index) : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  const std::string missing = MissingLibraries();
  if (!missing.empty()) {
    im.reason = "no OpenGL context: " + missing;
    return;
  }
  std::vector<std::string> tried;
  const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);  // null without EGL_EXT_client_extensions
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      HasExtension(client, "EGL_EXT_platform_base") ? eglGetProcAddress("eglGetPlatformDisplayEXT") : nullptr);

  // 1. EGL devices.
  if (!get_platform_display || !HasExtension(client, "EGL_EXT_platform_device") ||
      !(HasExtension(client, "EGL_EXT_device_enumeration") || HasExtension(client, "EGL_EXT_device_base"))) {
    tried.push_back("platform device: EGL_EXT_platform_device / EGL_EXT_device_enumeration not offered");
  } else {
    auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    auto query_device_string =
        reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
    EGLint count = 0;
    if (!query_devices || !query_devices(0, nullptr, &count) || count <= 0) {
      tried.push_back("platform device: no EGL device (" + LastEglError() + ")");
    } else {
      std::vector<EGLDeviceEXT> devices(static_cast<std::size_t>(count));
      query_devices(count, devices.data(), &count);
      devices.resize(static_cast<std::size_t>(count));
      // Hardware devices first, software rasterisers (EGL_MESA_device_software) last.
      std::vector<std::pair<std::size_t, std::string>> order, software;
      for (std::size_t d = 0; d < devices.size(); ++d) {
        if (device_index >= 0 && static_cast<std::size_t>(device_index) != d) continue;
        std::string name = "device " + std::to_string(d);
        const char* dev_ext = query_device_string ? query_device_string(devices[d], EGL_EXTENSIONS) : nullptr;
        if (HasExtension(dev_ext, "EGL_MESA_device_software")) {
          software.emplace_back(d, name + " (software)");
          continue;
        }
        if (HasExtension(dev_ext, "EGL_EXT_device_drm")) {
          const char* file = query_device_string(devices[d], EGL_DRM_DEVICE_FILE_EXT);
          if (file) name += " (" + std::string(file) + ")";
        }
        order.emplace_back(d, name);
      }
      order.insert(order.end(), software.begin(), software.end());
      for (const auto& [d, name] : order) {
        const std::string why = im.TryDisplay(get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[d], nullptr),
                                              "device", name);
        if (why.empty()) break;
        tried.push_back("platform device, " + name + ": " + why);
      }
      if (device_index >= 0 && static_cast<std::size_t>(device_index) >= devices.size())
        tried.push_back("platform device: no device " + std::to_string(device_index) + " (" +
                        std::to_string(devices.size()) + " devices)");
    }
  }
  // 2. Mesa's surfaceless platform, 3. the default display (any device only).
  if (im.context == EGL_NO_CONTEXT && device_index < 0) {
    if (get_platform_display && HasExtension(client, "EGL_MESA_platform_surfaceless")) {
      const std::string why = im.TryDisplay(
          get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr), "surfaceless", "");
      if (!why.empty()) tried.push_back("platform surfaceless: " + why);
    } else {
      tried.push_back("platform surfaceless: EGL_MESA_platform_surfaceless not offered");
    }
  }
  if (im.context == EGL_NO_CONTEXT && device_index < 0) {
    const std::string why = im.TryDisplay(eglGetDisplay(EGL_DEFAULT_DISPLAY), "default", "");
    if (!why.empty()) tried.push_back("default display: " + why);
  }
  if (im.context == EGL_NO_CONTEXT) {
    im.reason = "no OpenGL 4.3 core context through EGL:";
    for (const std::string& t : tried) im.reason += " [" + t + "]";
    im.reason +=
        "; is an EGL driver installed? (Mesa: libegl-mesa0 libgl1-mesa-dri; NVIDIA: the driver's EGL library, with "
        "__EGL_VENDOR_LIBRARY_FILENAMES naming its JSON when that is not in /usr/share/glvnd/egl_vendor.d)";
    return;
  }
  im.Query();
}

GlContext::GlContext(AdoptTag) : impl_(std::make_unique<Impl>()) {
  const std::string missing = MissingLibraries();
  if (!missing.empty()) impl_->reason = "no OpenGL context: " + missing;
}

std::unique_ptr<GlContext> GlContext::AdoptCurrent() {
  std::unique_ptr<GlContext> adopted(new GlContext(AdoptTag{}));
  Impl& im = *adopted->impl_;
  im.owned = false;
  if (!im.reason.empty()) return adopted;
  im.display = eglGetCurrentDisplay();
  const EGLContext current = eglGetCurrentContext();
  if (current == EGL_NO_CONTEXT) {
    im.reason = "no EGL context is current on this thread";
    return adopted;
  }
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (major < 4 || (major == 4 && minor < 3)) {
    im.reason = "the current context is GL " + std::to_string(major) + "." + std::to_string(minor) + " (" +
                GlString(GL_VERSION) + ", " + GlString(GL_RENDERER) +
                "); skintune's shaders need GL 4.3 (compute shaders, storage buffers)";
    return adopted;
  }
  im.context = current;
  im.info.egl_platform = "current";
  EGLint egl_major = 0, egl_minor = 0;
  const char* version = eglQueryString(im.display, EGL_VERSION);
  if (version && std::sscanf(version, "%d.%d", &egl_major, &egl_minor) == 2)
    im.info.egl_version = std::to_string(egl_major) + "." + std::to_string(egl_minor);
  const char* vendor = eglQueryString(im.display, EGL_VENDOR);
  im.info.egl_vendor = vendor ? vendor : "";
  im.info.major = major;
  im.info.minor = minor;
  im.Query();
  return adopted;
}

GlContext::~GlContext() {
  Impl& im = *impl_;
  if (im.context == EGL_NO_CONTEXT || !im.owned) return;
  if (eglGetCurrentContext() == im.context) eglMakeCurrent(im.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(im.display, im.context);
  {
    std::lock_guard<std::mutex> lock(DisplayMutex());
    --DisplayUsers()[im.display];
  }
  TerminateIfUnused(im.display);
}

bool GlContext::ok() const { return impl_->context != EGL_NO_CONTEXT; }
const std::string& GlContext::reason() const { return impl_->reason; }
const GlContextInfo& GlContext::info() const { return impl_->info; }

bool GlContext::IsCurrent() const { return ok() && eglGetCurrentContext() == impl_->context; }

void GlContext::MakeCurrent() {
  if (!ok()) throw Error("GL setup: " + impl_->reason);
  if (IsCurrent()) return;
  if (!impl_->owned)
    throw Error("GL setup: the GL context skintune was given (the one current at Device::FromCurrentGl) is not "
                "current on this thread, or no longer exists");
  if (!eglMakeCurrent(impl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, impl_->context))
    throw Error("GL setup: eglMakeCurrent failed (" + LastEglError() + ")");
}

CurrentGlRestorer::CurrentGlRestorer() {
  if (!MissingLibraries().empty()) return;
  active_ = true;
  display_ = eglGetCurrentDisplay();
  context_ = eglGetCurrentContext();
  draw_ = eglGetCurrentSurface(EGL_DRAW);
  read_ = eglGetCurrentSurface(EGL_READ);
}

CurrentGlRestorer::~CurrentGlRestorer() {
  if (!active_) return;
  if (context_ == EGL_NO_CONTEXT) {
    const EGLDisplay current = eglGetCurrentDisplay();
    if (eglGetCurrentContext() != EGL_NO_CONTEXT)
      eglMakeCurrent(current, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    return;
  }
  if (eglGetCurrentContext() != context_) eglMakeCurrent(display_, draw_, read_, context_);
}

std::string GlDeviceType(const std::string& renderer) {
  std::string lower = renderer;
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const char* cpu : {"llvmpipe", "softpipe", "swrast", "software"})
    if (lower.find(cpu) != std::string::npos) return "cpu";
  return "gpu";
}

DeviceIdentity IdentityOf(const GlContextInfo& info) {
  DeviceIdentity d;
  d.backend = "gl";
  d.platform = info.egl_platform;
  d.vendor = info.vendor;
  d.name = info.renderer;
  d.driver_version = info.version;  // GL_VERSION names the driver: "4.5 (Core Profile) Mesa 22.3.6"
  d.api_version = info.version;
  d.type = GlDeviceType(info.renderer);
  d.local_memory_bytes = info.max_compute_shared_memory_bytes;
  d.constant_memory_bytes = info.max_uniform_block_bytes;
  d.uuid = info.device_uuid;
  return d;  // compute units, global memory, last-level cache: GL does not say (0)
}

DeviceLimits LimitsOf(const GlContextInfo& info) {
  DeviceLimits limits;
  limits.max_wg_size = static_cast<std::size_t>(
      std::min(info.max_compute_work_group_invocations, info.max_compute_work_group_size_x));
  limits.local_memory_bytes = info.max_compute_shared_memory_bytes;
  limits.constant_memory_bytes = info.max_uniform_block_bytes;
  limits.uniform_block_bytes = info.max_uniform_block_bytes;
  limits.image_support = info.max_texture_buffer_texels > 0;
  limits.image_buffer_max_texels = info.max_texture_buffer_texels;
  limits.vertex_shader_storage_blocks = info.max_vertex_shader_storage_blocks > 0;
  limits.max_grid_y = info.max_compute_work_group_count_y;
  return limits;
}

void to_json(nlohmann::json& out, const GlContextInfo& i) {
  out = {{"egl_platform", i.egl_platform},
         {"egl_device", i.egl_device},
         {"egl_vendor", i.egl_vendor},
         {"egl_version", i.egl_version},
         {"vendor", i.vendor},
         {"renderer", i.renderer},
         {"device_uuid", i.device_uuid},
         {"version", i.version},
         {"glsl_version", i.glsl_version},
         {"major", i.major},
         {"minor", i.minor},
         {"max_compute_work_group_invocations", i.max_compute_work_group_invocations},
         {"max_compute_work_group_size_x", i.max_compute_work_group_size_x},
         {"max_compute_work_group_count_x", i.max_compute_work_group_count_x},
         {"max_compute_work_group_count_y", i.max_compute_work_group_count_y},
         {"max_compute_shared_memory_bytes", i.max_compute_shared_memory_bytes},
         {"max_uniform_block_bytes", i.max_uniform_block_bytes},
         {"max_texture_buffer_texels", i.max_texture_buffer_texels},
         {"max_vertex_shader_storage_blocks", i.max_vertex_shader_storage_blocks},
         {"max_compute_shader_storage_blocks", i.max_compute_shader_storage_blocks},
         {"max_shader_storage_block_bytes", i.max_shader_storage_block_bytes},
         {"max_transform_feedback_separate_attribs", i.max_transform_feedback_separate_attribs}};
}

}  // namespace skintune::internal
