// The design tools in their own shared module (libshoal_design_module.so), loaded the
// first time a command needs them: `shoal design` and the stability map of a campaign.
//
// Why: they bring CSDP (with LAPACK, ATLAS and gfortran) and Ceres (with CHOLMOD, METIS,
// OpenMP, glog and gflags): 21 of the 33 libraries `shoal` would otherwise map and relocate at
// every start. A campaign starts a `shoal sim` per point, thousands of times, and none of
// them uses any of it (docs/benchmarks.md, "A point's start").
//
// The module holds its own copy of what the design tools use of Shoal (core, scenario):
// it is loaded RTLD_LOCAL and exports nothing but shoal_design_module, so its copies never
// meet the program's. Objects cross the boundary by value, as types both sides compile
// from the same headers in the same build.
#pragma once

#include <string>

#include "core/scenario.h"
#include "design/theory_curve.h"

namespace shoal {

struct DesignOptions;  // tools/design_command.h

/// What the module gives. `version` is kDesignModuleVersion of the build that made it.
struct DesignModule {
  int version = 0;
  /// `shoal design` (tools/design_command.h: RunDesign).
  int (*run_design)(const DesignOptions& opt) = nullptr;
  /// design::ComputeTheoryPoint with its default options.
  design::TheoryPoint (*theory_point)(const Scenario& s) = nullptr;
};

/// Changes whenever DesignModule or a type it passes changes: a module from another build is
/// refused by name rather than called.
constexpr int kDesignModuleVersion = 1;

/// The module's table, loaded once per process (thread-safe); nullptr with *error set to
/// what to do when it cannot be loaded. SHOAL_DESIGN_MODULE names the file to load;
/// otherwise it is looked for next to the program and in ../design/ from it (the build tree).
const DesignModule* LoadDesignModule(std::string* error);

}  // namespace shoal

extern "C" {
/// The module's one export.
const shoal::DesignModule* shoal_design_module();
}
