# Python bindings of the message types: `lcm-gen -p` of every type in SHOAL_LCM_TYPES
# (lcmtypes/CMakeLists.txt) into the build tree, <build>/python/shoal/*.py (never
# committed), with a copy of python/shoal_log.py beside them, so that
#   python3 build/python/shoal_log.py LOG
# finds the types next to itself (docs/analyze.md, "Reading a log from Python").
#
# LCM 1.3.1's generated Python runs under Python 3 with the standard library only (struct,
# io); shoal_log.py decodes through it and checks the byte counts the generated code does
# not (tests/python/shoal_log_test.py).
if(NOT SHOAL_LCM_TYPES)
  message(FATAL_ERROR "lcmtypes_python.cmake: SHOAL_LCM_TYPES is empty (include it after "
                      "add_subdirectory(lcmtypes))")
endif()

set(SHOAL_PYTHON_DIR ${PROJECT_BINARY_DIR}/python)
set(shoal_python_outputs ${SHOAL_PYTHON_DIR}/shoal/__init__.py)
foreach(type_file ${SHOAL_LCM_TYPES})
  get_filename_component(stem ${type_file} NAME_WE)
  list(APPEND shoal_python_outputs ${SHOAL_PYTHON_DIR}/shoal/${stem}.py)
endforeach()

# One lcm-gen call for every type: it writes the package's __init__.py with all of them.
# The package directory is emptied first, so that a type no longer listed leaves no module
# behind (lcm-gen adds to an existing __init__.py, it never removes a line).
add_custom_command(
  OUTPUT ${shoal_python_outputs}
  COMMAND ${CMAKE_COMMAND} -E rm -rf ${SHOAL_PYTHON_DIR}/shoal
  COMMAND ${CMAKE_COMMAND} -E make_directory ${SHOAL_PYTHON_DIR}
  COMMAND ${LCM_GEN} -p --ppath ${SHOAL_PYTHON_DIR} ${SHOAL_LCM_TYPES}
  DEPENDS ${SHOAL_LCM_TYPES}
  COMMENT "lcm-gen -p: Python message types"
  VERBATIM)
add_custom_command(
  OUTPUT ${SHOAL_PYTHON_DIR}/shoal_log.py
  COMMAND ${CMAKE_COMMAND} -E copy ${PROJECT_SOURCE_DIR}/python/shoal_log.py
          ${SHOAL_PYTHON_DIR}/shoal_log.py
  DEPENDS ${PROJECT_SOURCE_DIR}/python/shoal_log.py
  COMMENT "python/shoal_log.py into the build tree"
  VERBATIM)
add_custom_target(shoal_lcmtypes_python ALL
                  DEPENDS ${shoal_python_outputs} ${SHOAL_PYTHON_DIR}/shoal_log.py)
