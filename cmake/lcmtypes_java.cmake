# Java classes of every Shoal message type (SHOAL_LCM_TYPES), packed into
# <build>/lcmtypes/shoal_lcmtypes.jar, so that LCM's own Java tools decode Shoal's messages:
# lcm-spy finds a message's class by the 8-byte fingerprint it starts with, among the
# classes on its class path (docs/run.md, "Watching a run with lcm-spy").
#
# Needs a JDK (Debian default-jdk-headless) and LCM's Java library (liblcm-java:
# /usr/share/java/lcm.jar). Without either, the configure goes on without the jar and its
# test, and says so; SHOAL_REQUIRE_JAVA (set by `make test`, which installs both) makes
# that an error, so that the test is never left out unnoticed.
#
# Sets SHOAL_JAVA_FOUND, and when it is true: Java_JAVA_EXECUTABLE, LCM_JAR (lcm.jar),
# SHOAL_LCMTYPES_JAR (the jar's path) and the target shoal_lcmtypes_jar.
option(SHOAL_REQUIRE_JAVA "Fail the configure when the JDK or LCM's lcm.jar is missing" OFF)
set(SHOAL_JAVA_FOUND FALSE)

find_package(Java 1.8 COMPONENTS Development Runtime)
find_file(LCM_JAR lcm.jar PATHS /usr/share/java /usr/local/share/java)
if(NOT Java_FOUND OR NOT LCM_JAR)
  set(shoal_java_missing "")
  if(NOT Java_FOUND)
    list(APPEND shoal_java_missing "a JDK (javac and jar: Debian default-jdk-headless)")
  endif()
  if(NOT LCM_JAR)
    list(APPEND shoal_java_missing "LCM's lcm.jar (Debian liblcm-java)")
  endif()
  list(JOIN shoal_java_missing " and " shoal_java_missing)
  if(SHOAL_REQUIRE_JAVA)
    message(FATAL_ERROR "SHOAL_REQUIRE_JAVA is on but ${shoal_java_missing} is missing: "
                        "apt-get install default-jdk-headless liblcm-java")
  endif()
  message(WARNING "No shoal_lcmtypes.jar (lcm-spy cannot decode Shoal's messages) and no "
                  "Java decoding test: ${shoal_java_missing} is missing")
  return()
endif()

include(UseJava)
set(shoal_java_dir ${PROJECT_BINARY_DIR}/lcmtypes/java)
set(shoal_java_sources)
foreach(type_file ${SHOAL_LCM_TYPES})
  get_filename_component(stem ${type_file} NAME_WE)
  # Package `shoal`: lcm-gen writes <jpath>/shoal/<type>.java
  set(java_file ${shoal_java_dir}/shoal/${stem}.java)
  add_custom_command(
    OUTPUT ${java_file}
    COMMAND ${LCM_GEN} --java --jpath ${shoal_java_dir} ${type_file}
    DEPENDS ${type_file}
    COMMENT "lcm-gen --java ${stem}"
    VERBATIM)
  list(APPEND shoal_java_sources ${java_file})
endforeach()
add_jar(shoal_lcmtypes_jar
        SOURCES ${shoal_java_sources}
        INCLUDE_JARS ${LCM_JAR}
        OUTPUT_NAME shoal_lcmtypes
        OUTPUT_DIR ${PROJECT_BINARY_DIR}/lcmtypes)
get_target_property(SHOAL_LCMTYPES_JAR shoal_lcmtypes_jar JAR_FILE)
set(SHOAL_JAVA_FOUND TRUE)
message(STATUS "Java classes of the message types: ${SHOAL_LCMTYPES_JAR} (${Java_VERSION_STRING}, ${LCM_JAR})")
