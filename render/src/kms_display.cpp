#include "ultrasim/render/kms_display.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl3.h>
#include <fcntl.h>
#include <gbm.h>
#include <poll.h>
#include <unistd.h>
#include <xf86drm.h>
#include <xf86drmMode.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <vector>

#include "egl_error.hpp"
#include "ultrasim/render/display_error.hpp"

namespace ultrasim::render {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw DisplayError("KMS display: " + what);
}

std::string errno_text() {
  return std::strerror(errno);
}

// A property of a KMS object by name: its id and current value; id 0 when it has none.
struct Property {
  std::uint32_t id = 0;
  std::uint64_t value = 0;
};

Property find_property(int fd, std::uint32_t object, std::uint32_t type, const char* name) {
  drmModeObjectProperties* props = drmModeObjectGetProperties(fd, object, type);
  if (props == nullptr) return {};
  Property found;
  for (std::uint32_t i = 0; i < props->count_props && found.id == 0; ++i) {
    drmModePropertyRes* p = drmModeGetProperty(fd, props->props[i]);
    if (p != nullptr && std::strcmp(p->name, name) == 0)
      found = {p->prop_id, props->prop_values[i]};
    drmModeFreeProperty(p);
  }
  drmModeFreeObjectProperties(props);
  return found;
}

}  // namespace

struct KmsDisplay::Impl {
  int fd = -1;
  bool atomic = false;
  std::string connector_name;
  KmsMode mode;
  drmModeModeInfo mode_info{};
  std::uint32_t connector_id = 0, crtc_id = 0, plane_id = 0, mode_blob = 0;
  drmModeCrtc* saved_crtc = nullptr;
  gbm_device* gbm = nullptr;
  gbm_surface* surface = nullptr;
  EGLDisplay egl_display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface egl_surface = EGL_NO_SURFACE;
  FlipQueue flips;
  gbm_bo* on_screen = nullptr;
  bool mode_set = false;
  bool flip_done = false;
  std::int64_t last_flip_us = 0;

  // Atomic property ids.
  struct {
    std::uint32_t connector_crtc = 0, crtc_mode = 0, crtc_active = 0, plane_fb = 0, plane_crtc = 0,
                  src_x = 0, src_y = 0, src_w = 0, src_h = 0, crtc_x = 0, crtc_y = 0, crtc_w = 0,
                  crtc_h = 0;
  } prop;

  ~Impl() {
    // Put back what the output showed before us (the console, a splash).
    if (saved_crtc != nullptr && mode_set) {
      drmModeSetCrtc(fd, saved_crtc->crtc_id, saved_crtc->buffer_id, saved_crtc->x, saved_crtc->y,
                     &connector_id, 1, &saved_crtc->mode);
    }
    if (saved_crtc != nullptr) drmModeFreeCrtc(saved_crtc);
    if (egl_display != EGL_NO_DISPLAY) {
      eglMakeCurrent(egl_display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
      if (egl_surface != EGL_NO_SURFACE) eglDestroySurface(egl_display, egl_surface);
      if (context != EGL_NO_CONTEXT) eglDestroyContext(egl_display, context);
      eglTerminate(egl_display);
    }
    if (on_screen != nullptr) gbm_surface_release_buffer(surface, on_screen);
    if (surface != nullptr) gbm_surface_destroy(surface);
    if (gbm != nullptr) gbm_device_destroy(gbm);
    if (mode_blob != 0) drmModeDestroyPropertyBlob(fd, mode_blob);
    if (fd >= 0) close(fd);
  }

  static void on_flip(int, unsigned, unsigned sec, unsigned usec, void* data) {
    auto* self = static_cast<Impl*>(data);
    self->flip_done = true;
    self->last_flip_us = static_cast<std::int64_t>(sec) * 1'000'000 + usec;
  }

  void find_output(const KmsOptions& options) {
    drmModeRes* res = drmModeGetResources(fd);
    if (res == nullptr) fail(options.device + " is not a KMS device: " + errno_text());
    std::vector<KmsConnector> connectors;
    std::vector<drmModeConnector*> raw;
    for (int i = 0; i < res->count_connectors; ++i) {
      drmModeConnector* c = drmModeGetConnector(fd, res->connectors[i]);
      if (c == nullptr) continue;
      KmsConnector k;
      k.id = c->connector_id;
      const char* type = drmModeGetConnectorTypeName(c->connector_type);
      k.name = std::string(type ? type : "Unknown") + "-" + std::to_string(c->connector_type_id);
      k.connected = c->connection == DRM_MODE_CONNECTED;
      for (int m = 0; m < c->count_modes; ++m) {
        k.modes.push_back({c->modes[m].hdisplay, c->modes[m].vdisplay,
                           static_cast<int>(c->modes[m].vrefresh),
                           (c->modes[m].type & DRM_MODE_TYPE_PREFERRED) != 0, m});
      }
      connectors.push_back(k);
      raw.push_back(c);
    }
    try {
      const KmsChoice choice = choose_kms_output(connectors, options.output);
      drmModeConnector* c = raw[choice.connector];
      connector_id = c->connector_id;
      connector_name = connectors[choice.connector].name;
      mode = choice.mode;
      mode_info = c->modes[choice.mode.index];
      // A CRTC that can drive one of the connector's encoders; the one already driving it first.
      for (int e = 0; e < c->count_encoders && crtc_id == 0; ++e) {
        drmModeEncoder* enc = drmModeGetEncoder(fd, c->encoders[e]);
        if (enc == nullptr) continue;
        if (enc->crtc_id != 0) {
          crtc_id = enc->crtc_id;
        } else {
          for (int k = 0; k < res->count_crtcs && crtc_id == 0; ++k) {
            if (enc->possible_crtcs & (1u << k)) crtc_id = res->crtcs[k];
          }
        }
        drmModeFreeEncoder(enc);
      }
    } catch (const std::runtime_error& e) {
      for (auto* c : raw) drmModeFreeConnector(c);
      drmModeFreeResources(res);
      fail(options.device + ": " + e.what());
    }
    for (auto* c : raw) drmModeFreeConnector(c);
    // The CRTC's index, for the planes' possible_crtcs masks.
    int crtc_index = -1;
    for (int k = 0; k < res->count_crtcs; ++k)
      if (res->crtcs[k] == crtc_id) crtc_index = k;
    drmModeFreeResources(res);
    if (crtc_id == 0) fail(connector_name + ": no display controller (CRTC) can drive it");

    if (atomic) {
      // The CRTC's primary plane.
      drmModePlaneRes* planes = drmModeGetPlaneResources(fd);
      for (std::uint32_t i = 0; planes != nullptr && i < planes->count_planes && !plane_id; ++i) {
        drmModePlane* p = drmModeGetPlane(fd, planes->planes[i]);
        if (p != nullptr && crtc_index >= 0 && (p->possible_crtcs & (1u << crtc_index)) &&
            find_property(fd, p->plane_id, DRM_MODE_OBJECT_PLANE, "type").value ==
                DRM_PLANE_TYPE_PRIMARY) {
          plane_id = p->plane_id;
        }
        drmModeFreePlane(p);
      }
      drmModeFreePlaneResources(planes);
      const auto conn = [&](const char* n) {
        return find_property(fd, connector_id, DRM_MODE_OBJECT_CONNECTOR, n).id;
      };
      const auto crtc = [&](const char* n) {
        return find_property(fd, crtc_id, DRM_MODE_OBJECT_CRTC, n).id;
      };
      const auto plane = [&](const char* n) {
        return find_property(fd, plane_id, DRM_MODE_OBJECT_PLANE, n).id;
      };
      prop = {conn("CRTC_ID"), crtc("MODE_ID"), crtc("ACTIVE"), plane("FB_ID"), plane("CRTC_ID"),
              plane("SRC_X"),  plane("SRC_Y"),  plane("SRC_W"), plane("SRC_H"), plane("CRTC_X"),
              plane("CRTC_Y"), plane("CRTC_W"), plane("CRTC_H")};
      // Without every property the atomic path cannot run: fall back to legacy.
      if (plane_id == 0 || !prop.connector_crtc || !prop.crtc_mode || !prop.plane_fb ||
          drmModeCreatePropertyBlob(fd, &mode_info, sizeof mode_info, &mode_blob) != 0) {
        atomic = false;
      }
    }
  }

  void start_egl() {
    gbm = gbm_create_device(fd);
    if (gbm == nullptr) fail("gbm_create_device failed");
    surface = gbm_surface_create(gbm, mode.width_px, mode.height_px, GBM_FORMAT_XRGB8888,
                                 GBM_BO_USE_SCANOUT | GBM_BO_USE_RENDERING);
    if (surface == nullptr)
      fail("gbm_surface_create failed (" + std::to_string(mode.width_px) + "x" +
           std::to_string(mode.height_px) + ")");
    auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (get_platform_display == nullptr) fail("EGL lacks eglGetPlatformDisplayEXT");
    egl_display = get_platform_display(EGL_PLATFORM_GBM_KHR, gbm, nullptr);
    if (egl_display == EGL_NO_DISPLAY || !eglInitialize(egl_display, nullptr, nullptr)) {
      fail(std::string("eglInitialize on GBM failed: ") + detail::egl_error_name(eglGetError()));
    }
    eglBindAPI(EGL_OPENGL_ES_API);
    const EGLint attributes[] = {EGL_SURFACE_TYPE,
                                 EGL_WINDOW_BIT,
                                 EGL_RED_SIZE,
                                 8,
                                 EGL_GREEN_SIZE,
                                 8,
                                 EGL_BLUE_SIZE,
                                 8,
                                 EGL_RENDERABLE_TYPE,
                                 EGL_OPENGL_ES3_BIT,
                                 EGL_DEPTH_SIZE,
                                 24,
                                 EGL_NONE};
    EGLint count = 0;
    eglChooseConfig(egl_display, attributes, nullptr, 0, &count);
    std::vector<EGLConfig> configs(static_cast<std::size_t>(count));
    eglChooseConfig(egl_display, attributes, configs.data(), count, &count);
    // The config whose visual is the scan-out format GBM allocates.
    EGLConfig config = nullptr;
    for (EGLConfig c : configs) {
      EGLint visual = 0;
      eglGetConfigAttrib(egl_display, c, EGL_NATIVE_VISUAL_ID, &visual);
      if (static_cast<std::uint32_t>(visual) == GBM_FORMAT_XRGB8888) config = c;
    }
    if (config == nullptr) fail("no EGL config for XRGB8888 with depth");
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_NONE};
    context = eglCreateContext(egl_display, config, EGL_NO_CONTEXT, context_attributes);
    if (context == EGL_NO_CONTEXT) fail("eglCreateContext (GLES 3) failed");
    egl_surface = eglCreateWindowSurface(egl_display, config,
                                         reinterpret_cast<EGLNativeWindowType>(surface), nullptr);
    if (egl_surface == EGL_NO_SURFACE) {
      fail(std::string("eglCreateWindowSurface failed: ") + detail::egl_error_name(eglGetError()));
    }
    if (!eglMakeCurrent(egl_display, egl_surface, egl_surface, context)) {
      fail("eglMakeCurrent failed");
    }
  }

  // The framebuffer of a GBM buffer, made once and kept with it.
  std::uint32_t framebuffer(gbm_bo* bo) {
    if (auto* id = static_cast<std::uint32_t*>(gbm_bo_get_user_data(bo))) return *id;
    std::uint32_t handles[4] = {gbm_bo_get_handle(bo).u32};
    std::uint32_t pitches[4] = {gbm_bo_get_stride(bo)};
    std::uint32_t offsets[4] = {0};
    auto* id = new std::uint32_t(0);
    if (drmModeAddFB2(fd, gbm_bo_get_width(bo), gbm_bo_get_height(bo), GBM_FORMAT_XRGB8888, handles,
                      pitches, offsets, id, 0) != 0) {
      delete id;
      fail("drmModeAddFB2 failed: " + errno_text());
    }
    gbm_bo_set_user_data(bo, id, [](gbm_bo* b, void* data) {
      auto* fb = static_cast<std::uint32_t*>(data);
      drmModeRmFB(gbm_device_get_fd(gbm_bo_get_device(b)), *fb);
      delete fb;
    });
    return *id;
  }

  int atomic_commit(std::uint32_t fb, std::uint32_t flags) {
    drmModeAtomicReq* req = drmModeAtomicAlloc();
    if (flags & DRM_MODE_ATOMIC_ALLOW_MODESET) {
      drmModeAtomicAddProperty(req, connector_id, prop.connector_crtc, crtc_id);
      drmModeAtomicAddProperty(req, crtc_id, prop.crtc_mode, mode_blob);
      drmModeAtomicAddProperty(req, crtc_id, prop.crtc_active, 1);
      drmModeAtomicAddProperty(req, plane_id, prop.plane_crtc, crtc_id);
      drmModeAtomicAddProperty(req, plane_id, prop.src_x, 0);
      drmModeAtomicAddProperty(req, plane_id, prop.src_y, 0);
      drmModeAtomicAddProperty(req, plane_id, prop.src_w,
                               static_cast<std::uint64_t>(mode.width_px) << 16);
      drmModeAtomicAddProperty(req, plane_id, prop.src_h,
                               static_cast<std::uint64_t>(mode.height_px) << 16);
      drmModeAtomicAddProperty(req, plane_id, prop.crtc_x, 0);
      drmModeAtomicAddProperty(req, plane_id, prop.crtc_y, 0);
      drmModeAtomicAddProperty(req, plane_id, prop.crtc_w, mode.width_px);
      drmModeAtomicAddProperty(req, plane_id, prop.crtc_h, mode.height_px);
    }
    drmModeAtomicAddProperty(req, plane_id, prop.plane_fb, fb);
    const int ret = drmModeAtomicCommit(fd, req, flags, this);
    drmModeAtomicFree(req);
    return ret;
  }

  // Waits (up to a second) for the queued flip's completion event.
  void wait_for_flip() {
    drmEventContext events{};
    events.version = 2;
    events.page_flip_handler = &Impl::on_flip;
    flip_done = false;
    while (!flip_done) {
      pollfd p{fd, POLLIN, 0};
      const int ready = poll(&p, 1, 1000);
      if (ready < 0 && errno == EINTR) continue;
      if (ready <= 0) fail("no page flip completed within a second");
      drmHandleEvent(fd, &events);
    }
  }
};

KmsDisplay::KmsDisplay(const KmsOptions& options) : impl_(std::make_unique<Impl>()) {
  auto& k = *impl_;
  k.fd = open(options.device.c_str(), O_RDWR | O_CLOEXEC);
  if (k.fd < 0) {
    fail("cannot open " + options.device + ": " + errno_text() +
         " (no display device: use [display] backend = \"offscreen\", or run where /dev/dri "
         "exists)");
  }
  drmSetClientCap(k.fd, DRM_CLIENT_CAP_UNIVERSAL_PLANES, 1);
  k.atomic = !options.force_legacy && drmSetClientCap(k.fd, DRM_CLIENT_CAP_ATOMIC, 1) == 0;
  // On a failure below, Impl's destructor releases what was set up so far.
  k.find_output(options);
  k.saved_crtc = drmModeGetCrtc(k.fd, k.crtc_id);
  k.start_egl();
}

KmsDisplay::~KmsDisplay() = default;

int KmsDisplay::width_px() const {
  return impl_->mode.width_px;
}
int KmsDisplay::height_px() const {
  return impl_->mode.height_px;
}
bool KmsDisplay::atomic() const {
  return impl_->atomic;
}
const std::string& KmsDisplay::connector_name() const {
  return impl_->connector_name;
}
const KmsMode& KmsDisplay::mode() const {
  return impl_->mode;
}
std::int64_t KmsDisplay::flips() const {
  return impl_->flips.flips();
}
std::int64_t KmsDisplay::last_flip_us() const {
  return impl_->last_flip_us;
}

void KmsDisplay::begin_frame() {
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, impl_->mode.width_px, impl_->mode.height_px);
}

void KmsDisplay::end_frame() {
  auto& k = *impl_;
  // The finished frame becomes GBM's front buffer; scan it out.
  if (!eglSwapBuffers(k.egl_display, k.egl_surface)) fail("eglSwapBuffers failed");
  gbm_bo* bo = gbm_surface_lock_front_buffer(k.surface);
  if (bo == nullptr) fail("gbm_surface_lock_front_buffer failed");
  const std::uint32_t fb = k.framebuffer(bo);
  if (!k.mode_set) {
    // The first frame sets the mode: a blocking commit, on screen when it returns.
    const int ret =
        k.atomic ? k.atomic_commit(fb, DRM_MODE_ATOMIC_ALLOW_MODESET)
                 : drmModeSetCrtc(k.fd, k.crtc_id, fb, 0, 0, &k.connector_id, 1, &k.mode_info);
    if (ret != 0)
      fail(std::string(k.atomic ? "atomic modeset" : "drmModeSetCrtc") +
           " failed: " + errno_text());
    k.mode_set = true;
    k.flips.queue(reinterpret_cast<std::uintptr_t>(bo));
    k.flips.complete();
    k.on_screen = bo;
    return;
  }
  // Later frames flip at vblank; the flip's event says when the frame reached the screen.
  const int ret = k.atomic
                      ? k.atomic_commit(fb, DRM_MODE_ATOMIC_NONBLOCK | DRM_MODE_PAGE_FLIP_EVENT)
                      : drmModePageFlip(k.fd, k.crtc_id, fb, DRM_MODE_PAGE_FLIP_EVENT, impl_.get());
  if (ret != 0)
    fail(std::string(k.atomic ? "atomic page flip" : "drmModePageFlip") +
         " failed: " + errno_text());
  k.flips.queue(reinterpret_cast<std::uintptr_t>(bo));
  k.wait_for_flip();
  // The buffer the flip replaced may be drawn into again.
  if (auto* replaced = reinterpret_cast<gbm_bo*>(k.flips.complete())) {
    gbm_surface_release_buffer(k.surface, replaced);
  }
  k.on_screen = bo;
}

void KmsDisplay::read_pixels_into(RgbaImage& out) {
  auto& k = *impl_;
  out.width = k.mode.width_px;
  out.height = k.mode.height_px;
  out.rgba.assign(static_cast<std::size_t>(out.width) * out.height * 4, 0);
  if (k.on_screen == nullptr) return;
  std::uint32_t stride = 0;
  void* map_data = nullptr;
  auto* pixels = static_cast<const std::uint8_t*>(
      gbm_bo_map(k.on_screen, 0, 0, static_cast<std::uint32_t>(out.width),
                 static_cast<std::uint32_t>(out.height), GBM_BO_TRANSFER_READ, &stride, &map_data));
  if (pixels == nullptr) fail("gbm_bo_map of the buffer on screen failed");
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      const std::uint8_t* p = pixels + static_cast<std::size_t>(y) * stride + x * 4;  // B G R X
      std::uint8_t* q = out.rgba.data() + (static_cast<std::size_t>(y) * out.width + x) * 4;
      q[0] = p[2];
      q[1] = p[1];
      q[2] = p[0];
      q[3] = 255;
    }
  }
  gbm_bo_unmap(k.on_screen, map_data);
}

}  // namespace ultrasim::render
