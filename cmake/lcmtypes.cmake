# shoal_lcm_types(TARGET <name> TYPES <file.lcm>...)
# Generates C++ headers with lcm-gen into the build tree only (never committed) and
# exposes them through an INTERFACE target.
function(shoal_lcm_types)
  cmake_parse_arguments(ARG "" "TARGET" "TYPES" ${ARGN})
  set(out_dir ${CMAKE_CURRENT_BINARY_DIR}/include)
  set(headers)
  foreach(type_file ${ARG_TYPES})
    get_filename_component(abs ${type_file} ABSOLUTE)
    get_filename_component(stem ${type_file} NAME_WE)
    # Package `shoal`: lcm-gen writes <out>/shoal/<type>.hpp
    set(header ${out_dir}/shoal/${stem}.hpp)
    add_custom_command(
      OUTPUT ${header}
      COMMAND ${LCM_GEN} --cpp --cpp-hpath ${out_dir} ${abs}
      DEPENDS ${abs}
      COMMENT "lcm-gen ${stem}"
      VERBATIM)
    list(APPEND headers ${header})
  endforeach()
  add_custom_target(${ARG_TARGET}_gen DEPENDS ${headers})
  add_library(${ARG_TARGET} INTERFACE)
  add_dependencies(${ARG_TARGET} ${ARG_TARGET}_gen)
  target_include_directories(${ARG_TARGET} INTERFACE ${out_dir})
endfunction()
