# Profile-guided optimisation of shoal_core, the numerical core every vehicle and shoal sim
# step (docs/benchmarks.md, "A profile-guided core": shoal sim about 13 % faster, the same
# results to the bit). The build compiles the core a second time instrumented
# (-fprofile-generate) into shoal_pgo_train, runs it on the scenarios users run most, and
# compiles shoal_core with the counts it wrote (-fprofile-use). No floating-point
# semantics change: which branches are laid out as the common case and which calls are
# inlined does, and -ffp-contract=off keeps every product and sum as written.
#
# GCC names a count file, and identifies a function of internal linkage (a lambda, an
# anonymous namespace's), by the compile's dump name: its -dumpdir and the object's file
# name. Both compiles of core/X.cc (objects X.cc.o in two directories) are given the same
# -dumpdir, so that they agree on both and each function finds its counts.
# A change to a core source rebuilds the instrumented program, trains it again (under a
# second) and recompiles the core; the same counts from a retraining recompile nothing.
#
# Off (-DSHOAL_PGO=OFF) in a build for a debugger, and always with sanitizers, fuzzing,
# another compiler or a cross-compilation (the training runs on the build machine).
set(shoal_pgo_default OFF)
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU" AND CMAKE_BUILD_TYPE MATCHES "^(Release|RelWithDebInfo)$"
   AND NOT SHOAL_SANITIZE AND NOT SHOAL_FUZZ AND NOT CMAKE_CROSSCOMPILING)
  set(shoal_pgo_default ON)
endif()
option(SHOAL_PGO "Build shoal_core with profile-guided optimisation (GCC)" ${shoal_pgo_default})
if(NOT SHOAL_PGO)
  return()
endif()
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "GNU" OR SHOAL_SANITIZE OR SHOAL_FUZZ)
  message(FATAL_ERROR "SHOAL_PGO needs GCC and a build without SHOAL_SANITIZE and SHOAL_FUZZ")
endif()

set(shoal_pgo_dir ${CMAKE_BINARY_DIR}/pgo)
set(shoal_pgo_raw ${shoal_pgo_dir}/raw)          # what the training run writes
set(shoal_pgo_profile ${shoal_pgo_dir}/profile)  # what shoal_core's compile reads
set(shoal_pgo_trained ${shoal_pgo_dir}/trained.stamp)  # the last training run
set(shoal_pgo_changed ${shoal_pgo_dir}/changed.stamp)  # the last change of the profile
set(shoal_pgo_dumpdir ${shoal_pgo_dir}/core/)  # GCC writes nothing there: a name only
# What the training run steps: Example 2 (shoal sim and campaigns), REMUS at its limits,
# a timeline of faults and switching links, the acoustic channel.
set(shoal_pgo_seconds 600)
set(shoal_pgo_scenarios
  ${PROJECT_SOURCE_DIR}/scenarios/paper_example2.toml
  ${PROJECT_SOURCE_DIR}/scenarios/remus_realistic.toml
  ${PROJECT_SOURCE_DIR}/scenarios/faults.toml
  ${PROJECT_SOURCE_DIR}/scenarios/switching_topology.toml
  ${PROJECT_SOURCE_DIR}/scenarios/acoustic_survey.toml)

get_target_property(shoal_pgo_core_sources shoal_core SOURCES)
list(TRANSFORM shoal_pgo_core_sources PREPEND ${PROJECT_SOURCE_DIR}/core/)
get_target_property(shoal_pgo_scenario_sources shoal_scenario SOURCES)
list(TRANSFORM shoal_pgo_scenario_sources PREPEND ${PROJECT_SOURCE_DIR}/scenario/)
get_target_property(shoal_pgo_core_options shoal_core COMPILE_OPTIONS)

# The core and the scenario loader compiled into one program: linking shoal_scenario
# would bring shoal_core, which waits for this program's counts.
add_executable(shoal_pgo_train ${PROJECT_SOURCE_DIR}/tools/pgo_train.cc
               ${shoal_pgo_core_sources} ${shoal_pgo_scenario_sources})
target_include_directories(shoal_pgo_train PRIVATE ${PROJECT_SOURCE_DIR})
target_link_libraries(shoal_pgo_train PRIVATE Eigen3::Eigen tomlplusplus::tomlplusplus
                      shoal_warnings)
target_compile_options(shoal_pgo_train PRIVATE ${shoal_pgo_core_options}
                       -fprofile-generate=${shoal_pgo_raw} -fprofile-update=single
                       -dumpdir ${shoal_pgo_dumpdir})
target_link_options(shoal_pgo_train PRIVATE -fprofile-generate=${shoal_pgo_raw})

add_custom_command(
  OUTPUT ${shoal_pgo_trained}
  COMMAND ${CMAKE_COMMAND} -DTRAIN=$<TARGET_FILE:shoal_pgo_train>
          "-DARGS=${shoal_pgo_seconds};${shoal_pgo_scenarios}" -DRAW=${shoal_pgo_raw}
          -DPROFILE=${shoal_pgo_profile} -DCORE=${PROJECT_SOURCE_DIR}/core
          -DCHANGED=${shoal_pgo_changed}
          -P ${PROJECT_SOURCE_DIR}/cmake/pgo_train.cmake
  COMMAND ${CMAKE_COMMAND} -E touch ${shoal_pgo_trained}
  DEPENDS shoal_pgo_train ${shoal_pgo_scenarios} ${PROJECT_SOURCE_DIR}/cmake/pgo_train.cmake
  WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
  COMMENT "Training shoal_core's profile (shoal_pgo_train, ${shoal_pgo_seconds} s of each scenario)"
  VERBATIM)
add_custom_target(shoal_pgo_profile DEPENDS ${shoal_pgo_trained})
add_dependencies(shoal_core shoal_pgo_profile)

# -fprofile-partial-training: a function the training never ran is optimised as without a
# profile, not for size. -Wno-missing-profile: such functions are expected.
target_compile_options(shoal_core PRIVATE
  -fprofile-use=${shoal_pgo_profile} -fprofile-partial-training -Wno-missing-profile
  -dumpdir ${shoal_pgo_dumpdir})
# A new profile recompiles the core; training again to the same counts does not.
set_source_files_properties(${shoal_pgo_core_sources} DIRECTORY ${PROJECT_SOURCE_DIR}/core
                            PROPERTIES OBJECT_DEPENDS ${shoal_pgo_changed})
