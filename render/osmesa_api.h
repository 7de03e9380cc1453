// The OSMesa and OpenGL entry points shoal_render draws with, loaded from libOSMesa at the
// first figure rather than linked (internal to shoal_render).
//
// Linking libOSMesa makes every process that links shoal_render load llvmpipe's LLVM and
// run its relocations and static constructors at start: about 20 ms per process, paid
// by every `shoal sim` of a campaign that never draws. Loading it when a figure is first
// drawn leaves that cost to the programs that draw.
#pragma once

#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>
#include <GL/osmesa.h>

#include <string>

// Every function gl_canvas.cc calls; a function missing here does not compile there.
#define SHOAL_OSMESA_FUNCTIONS(X)                                                          \
  X(OSMesaCreateContextAttribs) X(OSMesaDestroyContext) X(OSMesaMakeCurrent)               \
  X(glBindFramebuffer) X(glBindRenderbuffer) X(glBindTexture) X(glBlendFuncSeparate)       \
  X(glBlitFramebuffer) X(glCheckFramebufferStatus) X(glClear) X(glClearColor)              \
  X(glClearDepth) X(glClearStencil) X(glColorPointer) X(glDeleteFramebuffers)              \
  X(glDeleteRenderbuffers) X(glDeleteTextures) X(glDepthFunc) X(glDepthMask) X(glDisable)  \
  X(glDisableClientState) X(glDrawArrays) X(glEnable) X(glEnableClientState)               \
  X(glFramebufferRenderbuffer) X(glGenFramebuffers) X(glGenRenderbuffers) X(glGenTextures) \
  X(glGetError) X(glGetIntegerv) X(glIsEnabled) X(glLoadIdentity) X(glLoadMatrixf)         \
  X(glMatrixMode) X(glPixelStorei) X(glReadPixels) X(glRenderbufferStorage)                \
  X(glRenderbufferStorageMultisample) X(glScissor) X(glStencilFunc) X(glStencilOp)         \
  X(glTexCoordPointer) X(glTexEnvi) X(glTexImage2D) X(glTexParameteri) X(glVertexPointer)  \
  X(glViewport)

namespace shoal::render {

/// One pointer per function, typed from the function's own declaration in the headers.
struct OsMesaApi {
#define SHOAL_OSMESA_POINTER(name) decltype(&::name) name = nullptr;
  SHOAL_OSMESA_FUNCTIONS(SHOAL_OSMESA_POINTER)
#undef SHOAL_OSMESA_POINTER
};

/// The library loaded: SHOAL_OSMESA_LIBRARY if set (a path, or a name the dynamic loader
/// looks up), else the SONAME of the libOSMesa the program was built against.
const char* OsMesaLibraryName();

/// Loads libOSMesa and every function above, once per process (thread-safe); the library
/// stays loaded. Null with *err naming what is missing if it cannot be loaded; a later
/// call gives the same answer.
const OsMesaApi* LoadOsMesa(std::string* err);

}  // namespace shoal::render
