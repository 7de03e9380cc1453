#include "design/module.h"

#include "tools/design_command.h"

namespace {

shoal::design::TheoryPoint TheoryPoint(const shoal::Scenario& s) {
  return shoal::design::ComputeTheoryPoint(s);
}

}  // namespace

extern "C" __attribute__((visibility("default"))) const shoal::DesignModule*
shoal_design_module() {
  static const shoal::DesignModule m{shoal::kDesignModuleVersion, &shoal::RunDesign,
                                     &TheoryPoint};
  return &m;
}
