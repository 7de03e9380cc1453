# Runs shoal_core's training program and copies the count files of the core's objects to
# the names shoal_core's compile reads (cmake/pgo.cmake). Touches CHANGED only if a count
# file is new or different, so that training again to the same counts recompiles nothing.
# Usage: cmake -DTRAIN=PROGRAM -DARGS=a;b;... -DRAW=DIR -DPROFILE=DIR -DCORE=SOURCE_DIR
#              -DCHANGED=FILE -P pgo_train.cmake
function(train_once prefix result)
  # Counts add up over runs: every training starts from none.
  file(REMOVE_RECURSE "${RAW}")
  execute_process(COMMAND ${prefix} "${TRAIN}" ${ARGS} RESULT_VARIABLE status)
  set(${result} "${status}" PARENT_SCOPE)
endfunction()

# Some counts are of pointer values (the alignment of copies' arguments, for example), which
# address-space randomisation changes from run to run: without it the same program trains
# to the same counts. A container may refuse the personality change (setarch fails before
# the program starts): then the program runs as it is, and the counts may differ a little.
find_program(SETARCH setarch)
set(status 1)
if(SETARCH)
  train_once("${SETARCH};-R" status)
endif()
if(NOT status EQUAL 0)
  train_once("" status)
endif()
if(NOT status EQUAL 0)
  message(FATAL_ERROR "pgo_train: ${TRAIN} failed (${status})")
endif()

# The counts of the core's sources: the training program also counts its own driver and
# the scenario loader, which shoal_core's compile does not read.
file(GLOB_RECURSE raw_files RELATIVE "${RAW}" "${RAW}/*.gcda")
set(changed FALSE)
set(count 0)
foreach(name IN LISTS raw_files)
  get_filename_component(base "${name}" NAME_WE)
  if(NOT EXISTS "${CORE}/${base}.cc")
    continue()
  endif()
  math(EXPR count "${count} + 1")
  set(dest "${PROFILE}/${name}")
  if(EXISTS "${dest}")
    file(SHA256 "${RAW}/${name}" new_hash)
    file(SHA256 "${dest}" old_hash)
    if(new_hash STREQUAL old_hash)
      continue()
    endif()
  endif()
  execute_process(COMMAND "${CMAKE_COMMAND}" -E copy "${RAW}/${name}" "${dest}"
                  RESULT_VARIABLE failed)
  if(failed)
    message(FATAL_ERROR "pgo_train: could not copy ${RAW}/${name} to ${dest}")
  endif()
  set(changed TRUE)
endforeach()
if(count EQUAL 0)
  message(FATAL_ERROR "pgo_train: the training run wrote no count file of the core in ${RAW}")
endif()
if(changed OR NOT EXISTS "${CHANGED}")
  file(TOUCH "${CHANGED}")
  message(STATUS "shoal_core's profile: ${count} count files, changed")
else()
  message(STATUS "shoal_core's profile: ${count} count files, unchanged")
endif()
