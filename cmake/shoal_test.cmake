# shoal_test(NAME <name> SOURCES <src>... [LIBS <lib>...] [LABELS <label>] [TIMEOUT <s>]
#            [SERIAL])   SERIAL: never run in parallel with other tests (multi-process tests)
# One helper registers every GoogleTest executable (as Ceres' ceres_test does).
include(GoogleTest)
set(SHOAL_TEST_LABELS_LEFT_OUT "" CACHE STRING
    "Labels (a list) whose GoogleTest executables are neither built by default nor registered")
function(shoal_test)
  cmake_parse_arguments(ARG "SERIAL" "NAME;TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SOURCES})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gtest_main shoal_warnings)
  target_compile_definitions(${ARG_NAME} PRIVATE
    SHOAL_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    SHOAL_BINARY_DIR="${PROJECT_BINARY_DIR}")
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  set(serial FALSE)
  if(ARG_SERIAL)
    set(serial TRUE)
  endif()
  # One label per test: gtest_discover_tests cannot pass a list inside PROPERTIES.
  set(labels unit)
  if(ARG_LABELS)
    list(GET ARG_LABELS 0 labels)
  endif()
  # A build that runs only some labels (make test-asan-ci) leaves the other tests'
  # executables out of `all` and out of CTest: compiling what will not run is most of what
  # such a build could save on two cores. The target stays, for the dependencies on it.
  if(labels IN_LIST SHOAL_TEST_LABELS_LEFT_OUT)
    set_target_properties(${ARG_NAME} PROPERTIES EXCLUDE_FROM_ALL TRUE)
    return()
  endif()
  gtest_discover_tests(${ARG_NAME}
    PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${labels}" RUN_SERIAL ${serial}
    DISCOVERY_TIMEOUT 60)
endfunction()
