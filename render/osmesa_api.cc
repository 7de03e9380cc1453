#include "render/osmesa_api.h"

#include <dlfcn.h>

#include <cstdlib>
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
  const std::string name = OsMesaLibraryName();
  // RTLD_LOCAL: Mesa's and LLVM's symbols stay out of the process's global scope.
  void* lib = dlopen(name.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (lib == nullptr) {
    const char* why = dlerror();
    out.error = "cannot load " + name +
                " for off-screen figures (install libosmesa6, or name the library in "
                "SHOAL_OSMESA_LIBRARY): " + (why ? why : "unknown error");
    return out;
  }
#define SHOAL_OSMESA_RESOLVE(name_)                                                     \
  out.api.name_ = reinterpret_cast<decltype(&::name_)>(dlsym(lib, #name_));             \
  if (out.api.name_ == nullptr && out.error.empty()) {                                  \
    out.error = name + " has no " + #name_ + " (not an OSMesa with OpenGL 3.0 framebuffers)"; \
  }
  SHOAL_OSMESA_FUNCTIONS(SHOAL_OSMESA_RESOLVE)
#undef SHOAL_OSMESA_RESOLVE
  if (!out.error.empty()) dlclose(lib);
  return out;
}

}  // namespace

const char* OsMesaLibraryName() {
  const char* chosen = std::getenv("SHOAL_OSMESA_LIBRARY");
  return chosen != nullptr && *chosen != '\0' ? chosen : SHOAL_OSMESA_SONAME;
}

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
