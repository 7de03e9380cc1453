#include <dlfcn.h>
#include <unistd.h>

#include <cstdlib>
#include <mutex>
#include <vector>

#include "design/module.h"

namespace shoal {
namespace {

/// The directory of the running program (/proc/self/exe), "" if unknown.
std::string ProgramDir() {
  std::vector<char> buf(4096);
  const ssize_t n = readlink("/proc/self/exe", buf.data(), buf.size() - 1);
  if (n <= 0) return "";
  const std::string path(buf.data(), static_cast<std::size_t>(n));
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? "" : path.substr(0, slash);
}

std::vector<std::string> Candidates() {
  if (const char* named = std::getenv("SHOAL_DESIGN_MODULE"); named != nullptr && *named) {
    return {named};
  }
  const std::string dir = ProgramDir();
  return {dir + "/" SHOAL_DESIGN_MODULE_FILE, dir + "/../design/" SHOAL_DESIGN_MODULE_FILE};
}

const DesignModule* Load(std::string* error) {
  const std::vector<std::string> paths = Candidates();
  std::string tried;
  for (const std::string& path : paths) {
    if (paths.size() > 1 && access(path.c_str(), R_OK) != 0) {
      tried += (tried.empty() ? "" : ", ") + path;
      continue;
    }
    void* h = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (h == nullptr) {
      *error = std::string("cannot load the design module: ") + dlerror();
      return nullptr;
    }
    using Entry = const DesignModule* (*)();
    const auto entry = reinterpret_cast<Entry>(dlsym(h, "shoal_design_module"));
    const DesignModule* m = entry != nullptr ? entry() : nullptr;
    if (m == nullptr) {
      *error = path + " is not Shoal's design module (no shoal_design_module)";
      return nullptr;
    }
    if (m->version != kDesignModuleVersion) {
      *error = path + " is a design module of another Shoal build (version " +
               std::to_string(m->version) + ", this program needs " +
               std::to_string(kDesignModuleVersion) + "): install both from one build";
      return nullptr;
    }
    return m;  // never unloaded: its code may be on the stack of whoever called it
  }
  *error = "the design module " SHOAL_DESIGN_MODULE_FILE " is not installed (looked for " +
           tried + "; SHOAL_DESIGN_MODULE names another)";
  return nullptr;
}

}  // namespace

const DesignModule* LoadDesignModule(std::string* error) {
  static std::once_flag once;
  static const DesignModule* module = nullptr;
  static std::string failure;
  std::call_once(once, [] { module = Load(&failure); });
  if (module == nullptr && error != nullptr) *error = failure;
  return module;
}

}  // namespace shoal
