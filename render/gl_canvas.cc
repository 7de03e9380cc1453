#include "render/gl_canvas.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <vector>

#include "render/osmesa_api.h"

namespace shoal::render {

namespace {
// Valid once a context exists: Context::Create loads the library before anything else.
const OsMesaApi& Gl() { return *LoadOsMesa(nullptr); }
}  // namespace

// An OSMesa context and the framebuffers of the last size drawn with it.
struct GlCanvas::Context {
  OSMesaContext osmesa = nullptr;
  unsigned char dummy[4 * 4 * 4] = {};
  int width = 0, height = 0, samples = 0;
  GLuint fbo_ms = 0, rb_color_ms = 0, rb_depth_ms = 0;
  GLuint fbo_resolve = 0, rb_color_resolve = 0;

  void ReleaseFramebuffers() {
    if (fbo_ms) Gl().glDeleteFramebuffers(1, &fbo_ms);
    if (fbo_resolve) Gl().glDeleteFramebuffers(1, &fbo_resolve);
    for (GLuint* rb : {&rb_color_ms, &rb_depth_ms, &rb_color_resolve}) {
      if (*rb) Gl().glDeleteRenderbuffers(1, rb);
      *rb = 0;
    }
    fbo_ms = fbo_resolve = 0;
    width = height = 0;
  }

  bool Create(std::string* err) {
    if (LoadOsMesa(err) == nullptr) return false;
    const int attribs[] = {OSMESA_FORMAT,
                           OSMESA_RGBA,
                           OSMESA_DEPTH_BITS,
                           0,
                           OSMESA_STENCIL_BITS,
                           0,
                           OSMESA_PROFILE,
                           OSMESA_COMPAT_PROFILE,
                           OSMESA_CONTEXT_MAJOR_VERSION,
                           3,
                           OSMESA_CONTEXT_MINOR_VERSION,
                           0,
                           0};
    osmesa = Gl().OSMesaCreateContextAttribs(attribs, nullptr);
    if (!osmesa) {
      if (err) {
        *err =
            "cannot create an OSMesa OpenGL 3.0 compatibility context (is libosmesa6 "
            "installed and using llvmpipe?)";
      }
      return false;
    }
    if (!Gl().OSMesaMakeCurrent(osmesa, dummy, GL_UNSIGNED_BYTE, 4, 4)) {
      if (err) *err = "cannot make the OSMesa context current";
      return false;
    }
    GLint max_samples = 0;
    Gl().glGetIntegerv(GL_MAX_SAMPLES, &max_samples);
    samples = std::min(4, static_cast<int>(max_samples));
    if (samples < 2) samples = 0;
    return true;
  }

  bool Resize(int w, int h, std::string* err) {
    if (w == width && h == height) return true;
    ReleaseFramebuffers();
    GLint max_rb = 0, max_vp[2] = {0, 0};
    Gl().glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
    Gl().glGetIntegerv(GL_MAX_VIEWPORT_DIMS, max_vp);
    const int limit = std::min<int>(max_rb, std::min(max_vp[0], max_vp[1]));
    if (w > limit || h > limit) {
      if (err) {
        *err = "figure size " + std::to_string(w) + "x" + std::to_string(h) +
               " exceeds this OpenGL's limit of " + std::to_string(limit) +
               " pixels per side; choose a smaller size";
      }
      return false;
    }
    Gl().glGenFramebuffers(1, &fbo_resolve);
    Gl().glGenRenderbuffers(1, &rb_color_resolve);
    Gl().glBindRenderbuffer(GL_RENDERBUFFER, rb_color_resolve);
    Gl().glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
    Gl().glBindFramebuffer(GL_FRAMEBUFFER, fbo_resolve);
    Gl().glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                              rb_color_resolve);
    Gl().glGenFramebuffers(1, &fbo_ms);
    Gl().glGenRenderbuffers(1, &rb_color_ms);
    Gl().glGenRenderbuffers(1, &rb_depth_ms);
    Gl().glBindRenderbuffer(GL_RENDERBUFFER, rb_color_ms);
    Gl().glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_RGBA8, w, h);
    Gl().glBindRenderbuffer(GL_RENDERBUFFER, rb_depth_ms);
    Gl().glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_DEPTH24_STENCIL8, w, h);
    Gl().glBindFramebuffer(GL_FRAMEBUFFER, fbo_ms);
    Gl().glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb_color_ms);
    Gl().glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER,
                              rb_depth_ms);
    if (Gl().glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE ||
        Gl().glGetError() != GL_NO_ERROR) {
      if (err) {
        *err = "cannot create a " + std::to_string(w) + "x" + std::to_string(h) +
               " off-screen framebuffer (out of memory?)";
      }
      ReleaseFramebuffers();
      return false;
    }
    width = w;
    height = h;
    return true;
  }
};

namespace {

// Contexts not in use by any canvas, shared by all threads. They are never destroyed:
// llvmpipe compiles its shaders per context (more work than drawing a figure), and Mesa
// leaks a little of every context it destroys. One thread drawing figure after figure
// uses a single context.
std::mutex g_pool_mutex;
std::vector<GlCanvas::Context*>* const g_pool = new std::vector<GlCanvas::Context*>();

GlCanvas::Context* TakeContext() {
  std::lock_guard<std::mutex> lock(g_pool_mutex);
  if (g_pool->empty()) return nullptr;
  GlCanvas::Context* c = g_pool->back();
  g_pool->pop_back();
  return c;
}

void ReturnContext(GlCanvas::Context* c) {
  std::lock_guard<std::mutex> lock(g_pool_mutex);
  g_pool->push_back(c);
}

}  // namespace

GlCanvas::~GlCanvas() {
  if (!ctx_) return;
  Gl().OSMesaMakeCurrent(nullptr, nullptr, 0, 0, 0);  // release it for another thread
  ReturnContext(ctx_);
}

int GlCanvas::samples() const { return ctx_ ? ctx_->samples : 0; }

bool GlCanvas::Init(int width, int height, std::string* err) {
  Context* c = ctx_ ? ctx_ : TakeContext();
  if (!c) {
    c = new Context();
    if (!c->Create(err)) {
      if (c->osmesa) Gl().OSMesaDestroyContext(c->osmesa);
      delete c;
      return false;
    }
  }
  ctx_ = c;  // returned to the pool by the destructor, whatever happens below
  if (!Gl().OSMesaMakeCurrent(c->osmesa, c->dummy, GL_UNSIGNED_BYTE, 4, 4)) {
    if (err) *err = "cannot make the OSMesa context current";
    return false;
  }
  if (!c->Resize(width, height, err)) return false;
  Gl().glBindFramebuffer(GL_FRAMEBUFFER, c->fbo_ms);
  Gl().glViewport(0, 0, width, height);
  // Pixel coordinates (x right, y down, z = NDC depth) to clip space.
  // clang-format off
  const GLfloat m[16] = {2.0f / static_cast<GLfloat>(width), 0, 0, 0,
                         0, -2.0f / static_cast<GLfloat>(height), 0, 0,
                         0, 0, 1, 0,
                         -1, 1, 0, 1};
  // clang-format on
  Gl().glMatrixMode(GL_PROJECTION);
  Gl().glLoadMatrixf(m);
  Gl().glMatrixMode(GL_MODELVIEW);
  Gl().glLoadIdentity();
  Gl().glDisable(GL_CULL_FACE);
  Gl().glDisable(GL_DITHER);
  Gl().glEnable(GL_BLEND);
  Gl().glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  Gl().glDepthFunc(GL_LEQUAL);
  if (c->samples > 0) Gl().glEnable(GL_MULTISAMPLE);
  Gl().glEnableClientState(GL_VERTEX_ARRAY);
  Gl().glEnableClientState(GL_COLOR_ARRAY);
  stencil_ref_ = 0;
  return true;
}

void GlCanvas::Clear(const Color& bg) {
  Gl().glDisable(GL_SCISSOR_TEST);
  Gl().glClearColor(bg.r, bg.g, bg.b, 1.0f);
  Gl().glClearDepth(1.0);
  Gl().glClearStencil(0);
  Gl().glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT | GL_STENCIL_BUFFER_BIT);
  stencil_ref_ = 0;
}

void GlCanvas::SetClip(float x0, float y0, float x1, float y1) {
  const int ix0 = std::max(0, static_cast<int>(std::floor(x0)));
  const int iy0 = std::max(0, static_cast<int>(std::floor(y0)));
  const int ix1 = std::min(ctx_->width, static_cast<int>(std::ceil(x1)));
  const int iy1 = std::min(ctx_->height, static_cast<int>(std::ceil(y1)));
  Gl().glEnable(GL_SCISSOR_TEST);
  // GL's window origin is the bottom-left corner.
  Gl().glScissor(ix0, ctx_->height - iy1, std::max(0, ix1 - ix0), std::max(0, iy1 - iy0));
}

void GlCanvas::ClearClip() { Gl().glDisable(GL_SCISSOR_TEST); }

void GlCanvas::Draw(const Mesh& mesh, Depth depth, bool once_per_pixel) {
  if (mesh.empty()) return;
  switch (depth) {
    case Depth::kOff:
      Gl().glDisable(GL_DEPTH_TEST);
      break;
    case Depth::kTest:
      Gl().glEnable(GL_DEPTH_TEST);
      Gl().glDepthMask(GL_FALSE);
      break;
    case Depth::kTestAndWrite:
      Gl().glEnable(GL_DEPTH_TEST);
      Gl().glDepthMask(GL_TRUE);
      break;
  }
  if (once_per_pixel) {
    if (++stencil_ref_ > 255) {
      const GLboolean scissor = Gl().glIsEnabled(GL_SCISSOR_TEST);
      Gl().glDisable(GL_SCISSOR_TEST);
      Gl().glClearStencil(0);
      Gl().glClear(GL_STENCIL_BUFFER_BIT);
      if (scissor) Gl().glEnable(GL_SCISSOR_TEST);
      stencil_ref_ = 1;
    }
    Gl().glEnable(GL_STENCIL_TEST);
    Gl().glStencilFunc(GL_NOTEQUAL, stencil_ref_, 0xFF);
    Gl().glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
  } else {
    Gl().glDisable(GL_STENCIL_TEST);
  }
  Gl().glVertexPointer(3, GL_FLOAT, 0, mesh.xyz.data());
  Gl().glColorPointer(4, GL_UNSIGNED_BYTE, 0, mesh.rgba.data());
  Gl().glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(mesh.vertices()));
  Gl().glDepthMask(GL_TRUE);
}

void GlCanvas::DrawLayer(int x, int y, int w, int h,
                         const std::vector<std::uint8_t>& premultiplied) {
  if (w <= 0 || h <= 0 || premultiplied.size() != static_cast<std::size_t>(w) * h * 4) return;
  GLuint tex = 0;
  Gl().glGenTextures(1, &tex);
  Gl().glBindTexture(GL_TEXTURE_2D, tex);
  Gl().glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  Gl().glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  Gl().glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  Gl().glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  Gl().glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  Gl().glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, w, h, 0, GL_RGBA, GL_UNSIGNED_BYTE,
               premultiplied.data());
  Gl().glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_REPLACE);
  Gl().glEnable(GL_TEXTURE_2D);
  Gl().glDisable(GL_DEPTH_TEST);
  Gl().glDisable(GL_STENCIL_TEST);
  Gl().glBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  Gl().glDisableClientState(GL_COLOR_ARRAY);
  Gl().glEnableClientState(GL_TEXTURE_COORD_ARRAY);
  const float x0 = static_cast<float>(x), y0 = static_cast<float>(y);
  const float x1 = x0 + static_cast<float>(w), y1 = y0 + static_cast<float>(h);
  const GLfloat pos[] = {x0, y0, 0, x1, y0, 0, x1, y1, 0, x0, y0, 0, x1, y1, 0, x0, y1, 0};
  const GLfloat uv[] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
  Gl().glVertexPointer(3, GL_FLOAT, 0, pos);
  Gl().glTexCoordPointer(2, GL_FLOAT, 0, uv);
  Gl().glDrawArrays(GL_TRIANGLES, 0, 6);
  Gl().glDisableClientState(GL_TEXTURE_COORD_ARRAY);
  Gl().glEnableClientState(GL_COLOR_ARRAY);
  Gl().glDisable(GL_TEXTURE_2D);
  Gl().glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  Gl().glBindTexture(GL_TEXTURE_2D, 0);
  Gl().glDeleteTextures(1, &tex);
}

bool GlCanvas::Read(Image* out, std::string* err) {
  Gl().glDisable(GL_SCISSOR_TEST);
  Gl().glBindFramebuffer(GL_READ_FRAMEBUFFER, ctx_->fbo_ms);
  Gl().glBindFramebuffer(GL_DRAW_FRAMEBUFFER, ctx_->fbo_resolve);
  Gl().glBlitFramebuffer(0, 0, ctx_->width, ctx_->height, 0, 0, ctx_->width, ctx_->height,
                    GL_COLOR_BUFFER_BIT, GL_NEAREST);
  Gl().glBindFramebuffer(GL_READ_FRAMEBUFFER, ctx_->fbo_resolve);
  std::vector<std::uint8_t> raw(static_cast<std::size_t>(ctx_->width) * ctx_->height * 4);
  Gl().glPixelStorei(GL_PACK_ALIGNMENT, 1);
  Gl().glReadPixels(0, 0, ctx_->width, ctx_->height, GL_RGBA, GL_UNSIGNED_BYTE, raw.data());
  Gl().glBindFramebuffer(GL_FRAMEBUFFER, ctx_->fbo_ms);
  const GLenum e = Gl().glGetError();
  if (e != GL_NO_ERROR) {
    if (err) *err = "OpenGL error " + std::to_string(e) + " while reading the image back";
    return false;
  }
  out->width = ctx_->width;
  out->height = ctx_->height;
  out->rgba.resize(raw.size());
  // glReadPixels returns the bottom row first.
  const std::size_t row = static_cast<std::size_t>(ctx_->width) * 4;
  for (int y = 0; y < ctx_->height; ++y) {
    std::memcpy(&out->rgba[static_cast<std::size_t>(y) * row],
                &raw[static_cast<std::size_t>(ctx_->height - 1 - y) * row], row);
  }
  for (std::size_t i = 3; i < out->rgba.size(); i += 4) out->rgba[i] = 255;
  return true;
}

}  // namespace shoal::render
