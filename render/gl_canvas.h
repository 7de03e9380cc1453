// An OSMesa (llvmpipe) OpenGL context drawing triangle meshes into a 4x multisampled
// off-screen framebuffer (internal to shoal_render). Pixel coordinates: x right, y down.
//
// Contexts are kept in a process-wide pool and reused by later figures (llvmpipe compiles
// its shaders per context, which costs more than drawing a figure); a canvas holds one
// from Init to its destruction, and its framebuffers are reallocated when the size
// changes. Canvases on different threads use different contexts.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "render/figure.h"
#include "render/geometry.h"

namespace shoal::render {

class GlCanvas {
 public:
  /// kTest: hidden behind what is drawn, but hides nothing drawn later (translucent
  /// surfaces).
  enum class Depth { kOff, kTest, kTestAndWrite };

  GlCanvas() = default;
  ~GlCanvas();
  GlCanvas(const GlCanvas&) = delete;
  GlCanvas& operator=(const GlCanvas&) = delete;

  /// Makes a context current on this thread with width x height framebuffers; false with
  /// a message on failure.
  bool Init(int width, int height, std::string* err);

  void Clear(const Color& background);
  /// Restricts drawing to [x0, x1) x [y0, y1) (pixels, rounded outwards).
  void SetClip(float x0, float y0, float x1, float y1);
  void ClearClip();
  /// Draws a triangle mesh. once_per_pixel: no sample is blended twice by this mesh, so a
  /// translucent stroke does not darken where its own triangles overlap.
  void Draw(const Mesh& mesh, Depth depth = Depth::kOff, bool once_per_pixel = false);
  /// Draws a premultiplied RGBA image (rows top to bottom) of w x h pixels with its top-left
  /// corner at integer pixel (x, y), blended over what is there.
  void DrawLayer(int x, int y, int w, int h, const std::vector<std::uint8_t>& premultiplied);
  /// Resolves the multisampled image and reads it back, rows top to bottom, alpha 255.
  bool Read(Image* out, std::string* err);

  int samples() const;

  struct Context;  // defined in gl_canvas.cc

 private:
  Context* ctx_ = nullptr;
  int stencil_ref_ = 0;
};

}  // namespace shoal::render
