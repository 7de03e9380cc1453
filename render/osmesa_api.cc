#include "render/osmesa_api.h"

#include <dlfcn.h>

#include <mutex>

#ifndef SHOAL_OSMESA_SONAME
#define SHOAL_OSMESA_SONAME "libOSMesa.so.8"
#endif

namespace shoal::render {

namespace {

struct Loaded {
  OsMesaApi api;
  std::string error;  // empty when api is complete
};

Loaded Load() {
  Loaded out;
  // RTLD_LOCAL: Mesa's and LLVM's symbols stay out of the process's global scope.
  void* lib = dlopen(SHOAL_OSMESA_SONAME, RTLD_NOW | RTLD_LOCAL);
  if (lib == nullptr) {
    const char* why = dlerror();
    out.error = std::string("cannot load ") + SHOAL_OSMESA_SONAME +
                " for off-screen figures (install libosmesa6): " + (why ? why : "unknown error");
    return out;
  }
#define SHOAL_OSMESA_RESOLVE(name)                                                      \
  out.api.name = reinterpret_cast<decltype(&::name)>(dlsym(lib, #name));                \
  if (out.api.name == nullptr && out.error.empty()) {                                   \
    out.error = std::string(SHOAL_OSMESA_SONAME) + " has no " + #name +                 \
                " (an OSMesa too old for OpenGL 3.0 framebuffers?)";                    \
  }
  SHOAL_OSMESA_FUNCTIONS(SHOAL_OSMESA_RESOLVE)
#undef SHOAL_OSMESA_RESOLVE
  return out;
}

}  // namespace

const char* OsMesaLibraryName() { return SHOAL_OSMESA_SONAME; }

const OsMesaApi* LoadOsMesa(std::string* err) {
  static std::once_flag once;
  static Loaded* loaded = nullptr;  // never freed: figures may be drawn until exit
  std::call_once(once, [] { loaded = new Loaded(Load()); });
  if (!loaded->error.empty()) {
    if (err) *err = loaded->error;
    return nullptr;
  }
  return &loaded->api;
}

}  // namespace shoal::render
